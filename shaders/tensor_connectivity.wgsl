// Tensor-mass on the connectivity layout: one invocation per node gathers its row's blocks.
// Prepended with common.wgsl, node_gather.wgsl, tensor_gather.wgsl and tensor_products.wgsl; the twin is
// `twin::tensor_mass`.

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n) {
        return;
    }
    update_node_tensor(i, i * p.width, p.width);
}

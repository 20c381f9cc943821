// Tensor-mass on the valence layout: each node finds its bucket (valence_buckets.wgsl) and
// gathers its row's blocks. Prepended with common.wgsl, node_gather.wgsl, valence_buckets.wgsl
// tensor_gather.wgsl and tensor_products.wgsl; the twin is `twin::tensor_mass`.

@group(1) @binding(0) var<storage, read> table: BucketTable;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n || table.count == 0u) {
        return;
    }
    let row = valence_row(i);
    if (row.z == 0u) {
        return;
    }
    update_node_tensor(i, row.x, row.y);
}

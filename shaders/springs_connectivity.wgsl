// Connectivity layout: one invocation per node gathers its `width` slots (slots[i * width + s])
// and integrates itself. Prepended with common.wgsl and node_gather.wgsl; the twin is `twin::springs_connectivity`.

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n) {
        return;
    }
    update_node(i, i * p.width, p.width);
}

// Self-contact broad phase, pass 2 (prefix sum, step 1): one invocation per block of 256 hash
// buckets sums its block. Prepended with self_grid.wgsl.

@group(0) @binding(0) var<uniform> gp: GridParams;
@group(0) @binding(1) var<storage, read> counts: array<u32>;
@group(0) @binding(2) var<storage, read_write> block_sums: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    if (b >= gp.blocks) {
        return;
    }
    var s = 0u;
    for (var i = b * 256u; i < (b + 1u) * 256u; i = i + 1u) {
        s = s + counts[i];
    }
    block_sums[b] = s;
}

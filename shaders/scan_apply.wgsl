// Self-contact broad phase, pass 4 (prefix sum, step 3): one invocation per block of 256
// buckets writes each bucket's start in the entry list, and the same into the scatter cursors.
// Prepended with self_grid.wgsl.

@group(0) @binding(0) var<uniform> gp: GridParams;
@group(0) @binding(1) var<storage, read> counts: array<u32>;
@group(0) @binding(2) var<storage, read> block_sums: array<u32>;
@group(0) @binding(3) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(4) var<storage, read_write> cursors: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    if (b >= gp.blocks) {
        return;
    }
    var run = block_sums[b];
    for (var i = b * 256u; i < (b + 1u) * 256u; i = i + 1u) {
        offsets[i] = run;
        cursors[i] = run;
        run = run + counts[i];
    }
}

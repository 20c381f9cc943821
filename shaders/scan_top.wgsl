// Self-contact broad phase, pass 3 (prefix sum, step 2): one invocation turns the block sums
// into exclusive block offsets (a few thousand additions at most). Prepended with
// self_grid.wgsl.

@group(0) @binding(0) var<uniform> gp: GridParams;
@group(0) @binding(1) var<storage, read_write> block_sums: array<u32>;

@compute @workgroup_size(1)
fn main() {
    var run = 0u;
    for (var b = 0u; b < gp.blocks; b = b + 1u) {
        let s = block_sums[b];
        block_sums[b] = run;
        run = run + s;
    }
}

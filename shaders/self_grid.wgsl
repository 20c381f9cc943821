// Self-contact broad phase, shared part: parameters, the bounding box of a surface triangle at
// the current positions, and the spatial hash of a grid cell. Prepended to each pass of the
// self-contact broad phase (self_count, scan_blocks, scan_top, scan_apply, self_scatter,
// self_pairs); the twin is `twin::broad_self`.

// Mirrors `collide::self_broad::GridParams` (32 bytes).
struct GridParams {
    triangles: u32,
    table: u32,        // hash table size, a power of two
    inv_cell: f32,     // 1 / cell size, 1/m
    half_margin: f32,  // each box is widened by this, m
    capacity: u32,     // pairs the output buffer holds
    row: u32,          // invocations per dispatch row
    blocks: u32,       // blocks of 256 buckets
    pad: u32,
}

// Boxes spanning more cells than this per axis set the overflow flag (the host grows the cell).
const MAX_SPAN: i32 = 2;

fn tri_box_lo(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, m: f32) -> vec3<f32> {
    return min(min(a, b), c) - vec3<f32>(m);
}

fn tri_box_hi(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, m: f32) -> vec3<f32> {
    return max(max(a, b), c) + vec3<f32>(m);
}

fn cell_of(p: vec3<f32>, inv_cell: f32) -> vec3<i32> {
    return vec3<i32>(floor(p * inv_cell));
}

fn hash_cell(c: vec3<i32>, table: u32) -> u32 {
    let h = (c.x * 73856093) ^ (c.y * 19349663) ^ (c.z * 83492791);
    return bitcast<u32>(h) & (table - 1u);
}

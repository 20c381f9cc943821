// Self-contact broad phase, pass 5: each triangle writes its index into the entry list at the
// bucket of every cell its widened box overlaps. Prepended with self_grid.wgsl.

@group(0) @binding(0) var<uniform> gp: GridParams;
@group(0) @binding(1) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> disp: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> cursors: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read_write> entries: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x + gid.y * gp.row;
    if (t >= gp.triangles) {
        return;
    }
    let tri = triangles[t];
    let a = rest[tri.x].xyz + disp[tri.x].xyz;
    let b = rest[tri.y].xyz + disp[tri.y].xyz;
    let c = rest[tri.z].xyz + disp[tri.z].xyz;
    let c0 = cell_of(tri_box_lo(a, b, c, gp.half_margin), gp.inv_cell);
    let c1 = cell_of(tri_box_hi(a, b, c, gp.half_margin), gp.inv_cell);
    if (any(c1 - c0 >= vec3<i32>(MAX_SPAN))) {
        return;
    }
    for (var z = c0.z; z <= c1.z; z = z + 1) {
        for (var y = c0.y; y <= c1.y; y = y + 1) {
            for (var x = c0.x; x <= c1.x; x = x + 1) {
                let slot = atomicAdd(&cursors[hash_cell(vec3<i32>(x, y, z), gp.table)], 1u);
                entries[slot] = t;
            }
        }
    }
}

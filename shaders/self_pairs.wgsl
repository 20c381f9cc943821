// Self-contact broad phase, pass 6: each triangle t tests the triangles u > t in the buckets of
// its cells; pairs that share a node are skipped, and a pair whose widened boxes overlap is
// reported only from the cell holding the lower corner of the boxes' intersection, so each
// pair is reported once whatever cells and hash collisions they share. Pairs go to `pairs`
// through an atomic counter; past `capacity` only the counter grows (the host regrows and runs
// again). Prepended with self_grid.wgsl.

@group(0) @binding(0) var<uniform> gp: GridParams;
@group(0) @binding(1) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> disp: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> counts: array<u32>;
@group(0) @binding(5) var<storage, read> offsets: array<u32>;
@group(0) @binding(6) var<storage, read> entries: array<u32>;
@group(0) @binding(7) var<storage, read_write> pairs: array<vec2<u32>>;
@group(0) @binding(8) var<storage, read_write> count: atomic<u32>;

fn corner(i: u32) -> vec3<f32> {
    return rest[i].xyz + disp[i].xyz;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x + gid.y * gp.row;
    if (t >= gp.triangles) {
        return;
    }
    let tri = triangles[t];
    let a = corner(tri.x);
    let b = corner(tri.y);
    let c = corner(tri.z);
    let lo = tri_box_lo(a, b, c, gp.half_margin);
    let hi = tri_box_hi(a, b, c, gp.half_margin);
    let c0 = cell_of(lo, gp.inv_cell);
    let c1 = cell_of(hi, gp.inv_cell);
    if (any(c1 - c0 >= vec3<i32>(MAX_SPAN))) {
        return;
    }
    for (var z = c0.z; z <= c1.z; z = z + 1) {
        for (var y = c0.y; y <= c1.y; y = y + 1) {
            for (var x = c0.x; x <= c1.x; x = x + 1) {
                let cell = vec3<i32>(x, y, z);
                let h = hash_cell(cell, gp.table);
                let start = offsets[h];
                for (var e = start; e < start + counts[h]; e = e + 1u) {
                    let u = entries[e];
                    if (u <= t) {
                        continue;
                    }
                    let o = triangles[u];
                    if (any(tri.xyz == o.xxx) || any(tri.xyz == o.yyy) || any(tri.xyz == o.zzz)) {
                        continue;
                    }
                    let p = corner(o.x);
                    let q = corner(o.y);
                    let r = corner(o.z);
                    let lo2 = tri_box_lo(p, q, r, gp.half_margin);
                    let hi2 = tri_box_hi(p, q, r, gp.half_margin);
                    if (any(hi < lo2) || any(hi2 < lo)) {
                        continue;
                    }
                    if (any(cell_of(max(lo, lo2), gp.inv_cell) != cell)) {
                        continue;
                    }
                    let slot = atomicAdd(&count, 1u);
                    if (slot < gp.capacity) {
                        pairs[slot] = vec2<u32>(t, u);
                    }
                }
            }
        }
    }
}

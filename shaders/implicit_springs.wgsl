// The springs' part of `implicit_solve.wgsl`: each spring's Jacobian blocks from its current
// geometry, and a node's setup terms gathered over its springs (the layout's `cursor` and
// `next_slot`). Per spring seen from node i towards j, with d the current spring vector, l its
// length, u = d / l and t = 1 - rest / l (clamped at 0 under the definite linearisation):
//   K_s w = k (t w + (1 - t) u (u . w)),  D_s w = c u (u . w),
// and (K w)_i = sum_s K_s (w_j - w_i), likewise D. The twin is `twin::implicit_solve`. The geometry and block product are in
// implicit_spring_block.wgsl.

// Node i's setup terms over its springs: force, K v, and the diagonal block (h^2 k t summed as
// the isotropic part, the rest's symmetric entries xx, xy, xz, yy, yz, zz).
fn node_terms(i: u32, ui: vec3<f32>, vi: vec3<f32>) -> Terms {
    var f = vec3<f32>(0.0);
    var kv = vec3<f32>(0.0);
    var iso = 0.0;
    var da = vec4<f32>(0.0);
    var db = vec2<f32>(0.0);
    var c = cursor(i);
    loop {
        let s = next_slot(&c);
        if (s.other == EMPTY) {
            break;
        }
        let g = geometry(s, ui);
        if (!g.ok) {
            continue;
        }
        let dv = vel[s.other].xyz - vi;
        var mag = s.k * (g.l - s.rest);
        if (q.damped != 0u) {
            mag = mag + s.c * dot3(dv, g.u);
        }
        f = f + mag * g.u;
        let uw = dot3(g.u, dv);
        kv = kv + s.k * (g.t * dv + (1.0 - g.t) * uw * g.u);
        let h2k = (q.h * q.h) * s.k;
        iso = iso + h2k * g.t;
        var along = h2k * (1.0 - g.t);
        if (q.damped != 0u) {
            along = along + q.h * s.c;
        }
        da = da + along * vec4<f32>(g.u.x * g.u.x, g.u.x * g.u.y, g.u.x * g.u.z, g.u.y * g.u.y);
        db = db + along * vec2<f32>(g.u.y * g.u.z, g.u.z * g.u.z);
    }
    return Terms(f, kv, iso, da, db);
}

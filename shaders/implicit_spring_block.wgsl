// A spring's geometry and Jacobian block product for the implicit solve, shared by the
// springs' node walk (implicit_springs.wgsl) and the edge layout's atomic variant
// (implicit_atomic.wgsl). The twin is `twin::implicit_solve` (`geometry`, `block_product`).

// The spring geometry of a slot: direction and transverse term; `ok` false at zero length.
struct Geometry {
    u: vec3<f32>,
    l: f32,
    t: f32,
    ok: bool,
}

fn geometry(s: Slot, ui: vec3<f32>) -> Geometry {
    let d = s.edge + (cur[s.other].xyz - ui);
    let l = length(d);
    if (l <= 0.0) {
        return Geometry(vec3<f32>(0.0), 0.0, 0.0, false);
    }
    var t = 1.0 - s.rest / l;
    if (q.definite != 0u) {
        t = max(t, 0.0);
    }
    return Geometry(d / l, l, t, true);
}

// h D_s w + h^2 K_s w for the relative vector w of one slot.
fn block_product(s: Slot, g: Geometry, w: vec3<f32>) -> vec3<f32> {
    let uw = dot3(g.u, w);
    let kw = s.k * (g.t * w + (1.0 - g.t) * uw * g.u);
    var out = (q.h * q.h) * kw;
    if (q.damped != 0u) {
        out = out + q.h * (s.c * uw * g.u);
    }
    return out;
}

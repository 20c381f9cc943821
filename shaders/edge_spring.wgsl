// The spring record of the edge layout and the force of one spring on its `a` end, shared by
// the edge spring passes. Prepended (after common.wgsl) by the Rust side of each pass; the pass
// declares the bindings `p`, `second_in` and `cur` this reads. The twin is `twin::edge_spring`.

// Mirrors `lancet::layout::edges::EdgeSpring` (32 bytes).
struct EdgeSpring {
    edge: vec3<f32>,   // rest vector from a to b, m
    rest: f32,
    k: f32,
    c: f32,
    a: u32,
    b: u32,
}

// Force of spring `sp` on its `a` end (the `b` end gets the opposite); twin of
// `layout::edges::EdgeLayout::spring_forces_cpu`.
fn edge_force(sp: EdgeSpring) -> vec3<f32> {
    let ua = cur[sp.a].xyz;
    let ub = cur[sp.b].xyz;
    var dv = vec3<f32>(0.0);
    if (p.damped != 0u) {
        dv = velocity(p, ub, second_in[sp.b].xyz) - velocity(p, ua, second_in[sp.a].xyz);
    }
    let slot = Slot(sp.edge, sp.rest, sp.k, sp.c, sp.b, 0u);
    return slot_force(p, slot, sp.edge + (ub - ua), dv);
}

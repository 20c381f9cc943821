//! Twin of `shaders/edge_spring.wgsl`: the force of one edge-layout spring on its `a` end, which
//! every edge spring pass computes ([`super::springs_edges`], [`super::accumulate_fixed`],
//! [`super::accumulate_float`]).

use crate::layout::edges::EdgeSpring;
use crate::physics::{spring_force, velocity, StepParams};

/// The force of spring `s` on its `a` end (the `b` end gets the opposite), as `edge_force` in
/// `shaders/edge_spring.wgsl` computes it; the fourth component is zero.
pub fn edge_force(
    p: &StepParams,
    s: &EdgeSpring,
    cur: &[[f32; 4]],
    second: &[[f32; 4]],
) -> [f32; 4] {
    let (a, b) = (s.a as usize, s.b as usize);
    let d = [
        s.edge[0] + (cur[b][0] - cur[a][0]),
        s.edge[1] + (cur[b][1] - cur[a][1]),
        s.edge[2] + (cur[b][2] - cur[a][2]),
    ];
    let dv = if p.damped {
        let (va, vb) = (
            velocity(p, cur[a], second[a]),
            velocity(p, cur[b], second[b]),
        );
        [vb[0] - va[0], vb[1] - va[1], vb[2] - va[2]]
    } else {
        [0.0; 3]
    };
    let f = spring_force(p, s.k, s.rest, s.c, d, dv);
    [f[0], f[1], f[2], 0.0]
}

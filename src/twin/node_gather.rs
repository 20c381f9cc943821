//! Twin of `shaders/node_gather.wgsl`: the gather-and-integrate of one node over a run of its
//! slots, which the connectivity and valence passes share (each adds only the walk over its
//! own table: [`super::springs_connectivity`], [`super::springs_valence`]).

use crate::layout::Slot;
use crate::physics::{integrate, spring_force, velocity, StepParams};

/// The update of node `i` from its slots, in the order the WGSL computes it: the spring forces
/// of its slots up to the first empty one, then the integration. A fixed node (`inv_mass` 0)
/// stays at rest. Returns the next displacement and the next second state.
pub fn node_update(
    p: &StepParams,
    slots: &[Slot],
    inv_mass: f32,
    cur: &[[f32; 4]],
    second: &[[f32; 4]],
    i: usize,
) -> ([f32; 4], [f32; 4]) {
    if inv_mass == 0.0 {
        return ([0.0; 4], [0.0; 4]);
    }
    let ui = cur[i];
    let vi = velocity(p, ui, second[i]);
    let mut f = [0.0f32; 3];
    for s in slots {
        if s.other == Slot::EMPTY {
            break;
        }
        let j = s.other as usize;
        let d = [
            s.edge[0] + (cur[j][0] - ui[0]),
            s.edge[1] + (cur[j][1] - ui[1]),
            s.edge[2] + (cur[j][2] - ui[2]),
        ];
        let dv = if p.damped {
            let vj = velocity(p, cur[j], second[j]);
            [vj[0] - vi[0], vj[1] - vi[1], vj[2] - vi[2]]
        } else {
            [0.0; 3]
        };
        let fs = spring_force(p, s.k, s.rest, s.c, d, dv);
        for a in 0..3 {
            f[a] += fs[a];
        }
    }
    integrate(p, ui, second[i], vi, f, inv_mass)
}

//! Twin of the edge layout's float-atomic implicit solve on the finite elements' blocks
//! (`shaders/implicit_atomic_tensor.wgsl` over `implicit_solve.wgsl`,
//! `engine::gpu::implicit_atomic`): each record's setup terms seen from its `a` end (its block)
//! and from its `b` end (the block transposed) added to that end, and each iteration's two
//! block products added to their ends, in one of the orders a device may take (records in
//! order, `a` before `b`); fixed nodes get nothing. With a force given per node (the
//! corotational corner forces gathered) it replaces the blocks' own. The rest of the solve is
//! [`super::implicit_solve`]'s; the blocks' arithmetic is [`super::implicit_tensor`]'s.

use super::implicit_solve::{
    add, finish_cpu, finish_setup, iterate_cpu, product_pass, scale, setup_with, start_cpu, status,
    sub, v3, Scalars, SolveParams, SolveVectors, Terms,
};
use super::implicit_tensor::{product_term, tensor_terms};
use crate::layout::edges::EdgeLayout;
use crate::layout::tensor_blocks::TensorBlocks;

/// Add `t` to `n` (the shader's `add_tensor_terms`).
fn add_terms(n: &mut Terms, t: &Terms) {
    n.f = add(n.f, t.f);
    n.kv = add(n.kv, t.kv);
    n.iso += t.iso;
    for c in 0..4 {
        n.da[c] += t.da[c];
    }
    for c in 0..2 {
        n.db[c] += t.db[c];
    }
}

/// The `setup_records` pass: every node's summed setup terms.
pub(crate) fn setup_records_cpu(
    p: &SolveParams,
    blocks: &TensorBlocks,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    (cur, vel): (&[[f32; 4]], &[[f32; 4]]),
) -> Vec<Terms> {
    let stride = blocks.stride();
    let mut acc = vec![Terms::default(); cur.len()];
    for (r, s) in layout.springs.iter().enumerate() {
        let (a, b) = (s.a as usize, s.b as usize);
        let du = sub(v3(cur[b]), v3(cur[a]));
        let dv = sub(v3(vel[b]), v3(vel[a]));
        for (node, t, du, dv) in [
            (a, false, du, dv),
            (b, true, scale(-1.0, du), scale(-1.0, dv)),
        ] {
            let mut terms = Terms::default();
            tensor_terms(p, blocks, &mut terms, (r * stride, t), du, dv);
            if inv_mass[node] != 0.0 {
                add_terms(&mut acc[node], &terms);
            }
        }
    }
    acc
}

/// The `setup` pass on the accumulated terms, with each node's force taken from `forces`
/// where given (`element_force`).
pub(crate) fn setup_cpu(
    p: &SolveParams,
    terms: &[Terms],
    inv_mass: &[f32],
    vel: &[[f32; 4]],
    forces: Option<&[[f32; 3]]>,
) -> SolveVectors {
    let identity = [[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.0]];
    setup_with(terms.len(), |i| {
        if inv_mass[i] == 0.0 {
            return ([0.0; 3], identity);
        }
        let mut t = terms[i];
        if let Some(f) = forces {
            t.f = f[i];
        }
        finish_setup(p, inv_mass[i], v3(vel[i]), &t)
    })
}

/// The `spring_multiply` then `multiply` passes: each record's `a` share added at `a`, its
/// `b` share at `b`, then `A p` at every node and the partials (nothing once the solve has
/// ended).
pub fn multiply_cpu(
    p: &SolveParams,
    blocks: &TensorBlocks,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    v: &mut SolveVectors,
) {
    if v.scalars.status != status::RUNNING {
        return;
    }
    let stride = blocks.stride();
    let mut sum = vec![[0.0f32; 3]; v.p.len()];
    for (r, s) in layout.springs.iter().enumerate() {
        let (a, b) = (s.a as usize, s.b as usize);
        let d = sub(v3(v.p[b]), v3(v.p[a]));
        if inv_mass[a] != 0.0 {
            sum[a] = add(sum[a], product_term(p, blocks, r * stride, false, d));
        }
        if inv_mass[b] != 0.0 {
            let out = product_term(p, blocks, r * stride, true, scale(-1.0, d));
            sum[b] = add(sum[b], out);
        }
    }
    product_pass(v, |i, w| {
        if inv_mass[i] == 0.0 {
            return [0.0; 3];
        }
        let m = (1.0 + p.h * p.alpha) / inv_mass[i];
        add(scale(m, v3(w[i])), sum[i])
    });
}

/// One implicit step of the float-atomic variant on the blocks, on the CPU as its passes take
/// it (the records and the adds in record order); `forces` as `setup_cpu`. Returns the next
/// displacements and velocities and the final scalars.
pub fn implicit_step_cpu(
    p: &SolveParams,
    blocks: &TensorBlocks,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    (cur, vel): (&[[f32; 4]], &[[f32; 4]]),
    forces: Option<&[[f32; 3]]>,
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Scalars) {
    let terms = setup_records_cpu(p, blocks, layout, inv_mass, (cur, vel));
    let mut v = setup_cpu(p, &terms, inv_mass, vel, forces);
    start_cpu(p, &mut v);
    iterate_cpu(p, &mut v, |v| multiply_cpu(p, blocks, layout, inv_mass, v));
    let (next, vel_out) = finish_cpu(p, inv_mass, cur, vel, &v).expect("the solve ended");
    (next, vel_out, v.scalars)
}

/// One corotational implicit step of the float-atomic variant on the CPU, from the rotations
/// `rotations` (the warm start, updated in place): the tet pass, the blocks
/// ([`super::corotational_implicit::blocks_cpu`]), the gathered corner forces, then
/// [`implicit_step_cpu`] on them. `p` is the engine's step constants, `solve` the solve's.
#[allow(clippy::too_many_arguments)]
pub fn corotational_step_cpu(
    p: &crate::physics::StepParams,
    solve: &SolveParams,
    table: &crate::layout::tet_table::TetTable,
    pairs: &crate::layout::tet_pairs::TetPairs,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    (cur, vel): (&[[f32; 4]], &[[f32; 4]]),
    rotations: &mut [[f32; 4]],
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Scalars) {
    let forces = table.tet_pass_cpu(p, cur, vel, rotations);
    let blocks = super::corotational_implicit::blocks_cpu(table, pairs, rotations, table.damped);
    let f = table.gather_cpu(&forces, cur.len());
    implicit_step_cpu(solve, &blocks, layout, inv_mass, (cur, vel), Some(&f))
}

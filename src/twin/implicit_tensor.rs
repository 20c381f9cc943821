//! Twin of the tensor-mass implicit solve (`shaders/implicit_tensor.wgsl` with
//! `implicit_slots_tensor.wgsl` or `implicit_tensor_edges.wgsl`, pass
//! `engine::gpu::implicit`): the setup terms and the product read the constant tensor-mass
//! blocks ([`TensorBlocks`]) where the springs' solve computes each spring's Jacobian block;
//! the conjugate-gradient passes are [`super::implicit_solve`]'s. Rounding and order are the
//! shader's. The float64 specification is [`crate::physics::BackwardEuler`] on
//! [`crate::physics::TensorMass`].

use super::implicit_solve::{
    add, dot3, finish_cpu, finish_setup, iterate_cpu, product_pass, scale, setup_with, start_cpu,
    status, sub, v3, v4, Scalars, SolveParams, SolveVectors, Terms,
};
use crate::layout::edges::{EdgeLayout, B_END};
use crate::layout::tensor_blocks::{slot_walk, TensorBlocks};
use crate::layout::PackedLayout;

/// One neighbour of a node as the device walks it: the slot (or record) whose block couples
/// them, the neighbour, and whether the block is read transposed (from a record's `b` end).
pub type Neighbour = (usize, u32, bool);

/// Each node slot's neighbours in the order the device walks them: the connectivity row with
/// its continuations, the valence row up to its first empty slot, or the incidence row.
pub fn tensor_rows(layout: &PackedLayout) -> Vec<Vec<Neighbour>> {
    let mut rows = vec![Vec::new(); layout.node_slots()];
    match layout {
        PackedLayout::Edges(e) => {
            for (i, row) in rows.iter_mut().enumerate().take(e.node_count()) {
                *row = e
                    .row(i)
                    .iter()
                    .map(|&entry| {
                        let r = (entry & !B_END) as usize;
                        let s = &e.springs[r];
                        if entry & B_END != 0 {
                            (r, s.a, true)
                        } else {
                            (r, s.b, false)
                        }
                    })
                    .collect();
            }
        }
        _ => {
            for (i, slot, j) in slot_walk(layout) {
                rows[i as usize].push((slot, j, false));
            }
        }
    }
    rows
}

/// The block at row `b` of `blocks` times `w`, or its transpose times `w`: `block_mul`.
fn block_mul(blocks: &TensorBlocks, b: usize, t: bool, w: [f32; 3]) -> [f32; 3] {
    let r = |k: usize| v3(blocks.rows[b + k]);
    let (r0, r1, r2) = (r(0), r(1), r(2));
    if t {
        return add(add(scale(w[0], r0), scale(w[1], r1)), scale(w[2], r2));
    }
    [dot3(r0, w), dot3(r1, w), dot3(r2, w)]
}

/// The block's symmetric part: `sym_a`, `sym_b`.
fn sym(blocks: &TensorBlocks, b: usize) -> ([f32; 4], [f32; 2]) {
    let r = |k: usize| v3(blocks.rows[b + k]);
    let (r0, r1, r2) = (r(0), r(1), r(2));
    (
        [r0[0], 0.5 * (r0[1] + r1[0]), 0.5 * (r0[2] + r2[0]), r1[1]],
        [0.5 * (r1[2] + r2[1]), r2[2]],
    )
}

/// `tensor_terms`: one neighbour's share of the setup terms.
pub(crate) fn tensor_terms(
    p: &SolveParams,
    blocks: &TensorBlocks,
    terms: &mut Terms,
    (b, t): (usize, bool),
    du: [f32; 3],
    dv: [f32; 3],
) {
    terms.f = sub(terms.f, block_mul(blocks, b, t, du));
    terms.kv = sub(terms.kv, block_mul(blocks, b, t, dv));
    let h2 = p.h * p.h;
    let (sa, sb) = sym(blocks, b);
    let mut ea = sa.map(|x| h2 * x);
    let mut eb = sb.map(|x| h2 * x);
    if p.damped {
        terms.f = sub(terms.f, block_mul(blocks, b + 3, t, dv));
        let (ca, cb) = sym(blocks, b + 3);
        ea = std::array::from_fn(|c| ea[c] + p.h * ca[c]);
        eb = std::array::from_fn(|c| eb[c] + p.h * cb[c]);
    }
    terms.da = std::array::from_fn(|c| terms.da[c] - ea[c]);
    terms.db = std::array::from_fn(|c| terms.db[c] - eb[c]);
}

/// `tensor_product_term`: `(h^2 K + h C) d` of the block at row `b`.
pub(crate) fn product_term(
    p: &SolveParams,
    blocks: &TensorBlocks,
    b: usize,
    t: bool,
    d: [f32; 3],
) -> [f32; 3] {
    let mut out = scale(p.h * p.h, block_mul(blocks, b, t, d));
    if p.damped {
        out = add(out, scale(p.h, block_mul(blocks, b + 3, t, d)));
    }
    out
}

/// The `setup` pass on the tensor-mass blocks (`rows` from [`tensor_rows`]).
pub fn setup_cpu(
    p: &SolveParams,
    blocks: &TensorBlocks,
    rows: &[Vec<Neighbour>],
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
) -> SolveVectors {
    setup_forced(p, blocks, rows, inv_mass, (cur, vel), None)
}

/// [`setup_cpu`] with each node's force given (`element_force` of
/// `implicit_corotational.wgsl`: the corotational corner forces gathered), where `forces` is
/// `Some`; the blocks' own force (`implicit_tensor_force.wgsl`) where it is `None`.
pub fn setup_forced(
    p: &SolveParams,
    blocks: &TensorBlocks,
    rows: &[Vec<Neighbour>],
    inv_mass: &[f32],
    (cur, vel): (&[[f32; 4]], &[[f32; 4]]),
    forces: Option<&[[f32; 3]]>,
) -> SolveVectors {
    let identity = [[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.0]];
    let stride = blocks.stride();
    setup_with(cur.len(), |i| {
        if inv_mass[i] == 0.0 {
            return ([0.0; 3], identity);
        }
        let (ui, vi) = (v3(cur[i]), v3(vel[i]));
        let mut terms = Terms::default();
        for &(slot, j, t) in &rows[i] {
            let j = j as usize;
            let (du, dv) = (sub(v3(cur[j]), ui), sub(v3(vel[j]), vi));
            tensor_terms(p, blocks, &mut terms, (slot * stride, t), du, dv);
        }
        if let Some(f) = forces {
            terms.f = f[i];
        }
        finish_setup(p, inv_mass[i], vi, &terms)
    })
}

/// The node-centric layouts' `multiply` pass on the blocks: `A p`, partials `(p . A p, 0)`.
pub fn multiply_cpu(
    p: &SolveParams,
    blocks: &TensorBlocks,
    rows: &[Vec<Neighbour>],
    inv_mass: &[f32],
    v: &mut SolveVectors,
) {
    let stride = blocks.stride();
    product_pass(v, |i, w| {
        if inv_mass[i] == 0.0 {
            return [0.0; 3];
        }
        let wi = v3(w[i]);
        let mut sum = [0.0f32; 3];
        for &(slot, j, t) in &rows[i] {
            let d = sub(v3(w[j as usize]), wi);
            sum = add(sum, product_term(p, blocks, slot * stride, t, d));
        }
        let m = (1.0 + p.h * p.alpha) / inv_mass[i];
        add(scale(m, wi), sum)
    });
}

/// The edge layout's `spring_multiply` pass on the blocks: per record `(a, b)` the `a` end's
/// share at `2 r`, the `b` end's at `2 r + 1` (`previous` while the solve is not running).
pub fn record_multiply_cpu(
    p: &SolveParams,
    blocks: &TensorBlocks,
    layout: &EdgeLayout,
    v: &SolveVectors,
    previous: &[[f32; 4]],
) -> Vec<[f32; 4]> {
    if v.scalars.status != status::RUNNING {
        return previous.to_vec();
    }
    let stride = blocks.stride();
    let mut out = vec![[0.0f32; 4]; 2 * layout.springs.len()];
    for (r, s) in layout.springs.iter().enumerate() {
        let d = sub(v3(v.p[s.b as usize]), v3(v.p[s.a as usize]));
        out[2 * r] = v4(product_term(p, blocks, r * stride, false, d));
        out[2 * r + 1] = v4(product_term(p, blocks, r * stride, true, scale(-1.0, d)));
    }
    out
}

/// The edge layout's `multiply` pass on the blocks: each node's ends' shares gathered in
/// incidence order, partials `(p . A p, 0)`.
pub fn gather_multiply_cpu(
    p: &SolveParams,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    values: &[[f32; 4]],
    v: &mut SolveVectors,
) {
    product_pass(v, |i, w| {
        if inv_mass[i] == 0.0 {
            return [0.0; 3];
        }
        let mut sum = [0.0f32; 3];
        for &e in layout.row(i) {
            let end = usize::from(e & B_END != 0);
            sum = add(sum, v3(values[2 * (e & !B_END) as usize + end]));
        }
        let m = (1.0 + p.h * p.alpha) / inv_mass[i];
        add(scale(m, v3(w[i])), sum)
    });
}

/// One tensor-mass implicit step of `layout` as the device takes it: `setup`, `start`,
/// iterations (the edge layout's product as the record pass and the gather) until the solve
/// ends, `finish`. Returns the next displacements and velocities and the final scalars.
pub fn implicit_step_cpu(
    p: &SolveParams,
    blocks: &TensorBlocks,
    layout: &PackedLayout,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Scalars) {
    implicit_step_forced(p, blocks, layout, inv_mass, cur, vel, None)
}

/// [`implicit_step_cpu`] with each node's force given where `forces` is `Some` (see
/// [`setup_forced`]): the corotational step's solve.
pub fn implicit_step_forced(
    p: &SolveParams,
    blocks: &TensorBlocks,
    layout: &PackedLayout,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
    forces: Option<&[[f32; 3]]>,
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Scalars) {
    let rows = tensor_rows(layout);
    let mut v = setup_forced(p, blocks, &rows, inv_mass, (cur, vel), forces);
    start_cpu(p, &mut v);
    let mut values = Vec::new();
    if let PackedLayout::Edges(e) = layout {
        values = vec![[0.0f32; 4]; 2 * e.springs.len()];
    }
    iterate_cpu(p, &mut v, |v| match layout {
        PackedLayout::Edges(e) => {
            values = record_multiply_cpu(p, blocks, e, v, &values);
            gather_multiply_cpu(p, e, inv_mass, &values, v);
        }
        _ => multiply_cpu(p, blocks, &rows, inv_mass, v),
    });
    let (next, vel_out) = finish_cpu(p, inv_mass, cur, vel, &v).expect("the solve ended");
    (next, vel_out, v.scalars)
}

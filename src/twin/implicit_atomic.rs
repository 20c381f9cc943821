//! Twin of the edge layout's float-atomic implicit solve (`shaders/implicit_atomic.wgsl` over
//! `implicit_solve.wgsl`, `engine::gpu::implicit`): each spring's setup terms seen from its `a`
//! end added to both ends (force and `K v` negated at `b`), and each iteration's spring
//! products added at `a` and subtracted at `b`, in one of the orders a device may take
//! (records in order, `a` before `b`); fixed nodes get nothing. The rest of the solve is
//! [`super::implicit_solve`]'s.

use super::implicit_solve::{
    add, block_product, dot3, finish_cpu, finish_setup, geometry, iterate_cpu, product_pass, scale,
    setup_with, start_cpu, status, sub, v3, Scalars, SolveParams, SolveVectors, Terms,
};
use crate::layout::edges::EdgeLayout;
use crate::layout::Slot;

/// Record `s` seen from its `a` end (the other end `b`).
fn seen_from_a(layout: &EdgeLayout, r: usize) -> Slot {
    let s = &layout.springs[r];
    Slot {
        edge: s.edge,
        rest: s.rest,
        k: s.k,
        c: s.c,
        other: s.b,
        pad: 0,
    }
}

/// One spring's setup terms seen from node `i` (the shader's `spring_terms`).
fn spring_terms(p: &SolveParams, s: &Slot, cur: &[[f32; 4]], vel: &[[f32; 4]], i: usize) -> Terms {
    let (ui, vi) = (v3(cur[i]), v3(vel[i]));
    let Some((u, l, t)) = geometry(p, s, cur, ui) else {
        return Terms::default();
    };
    let dv = sub(v3(vel[s.other as usize]), vi);
    let mut mag = s.k * (l - s.rest);
    if p.damped {
        mag += s.c * dot3(dv, u);
    }
    let uw = dot3(u, dv);
    let kv = scale(s.k, add(scale(t, dv), scale((1.0 - t) * uw, u)));
    let h2k = (p.h * p.h) * s.k;
    let mut along = h2k * (1.0 - t);
    if p.damped {
        along += p.h * s.c;
    }
    let e = [u[0] * u[0], u[0] * u[1], u[0] * u[2], u[1] * u[1]];
    let f = [u[1] * u[2], u[2] * u[2]];
    Terms {
        f: scale(mag, u),
        kv,
        iso: h2k * t,
        da: e.map(|x| along * x),
        db: f.map(|x| along * x),
    }
}

/// The `setup_records` pass: every node's summed setup terms.
pub(crate) fn setup_records_cpu(
    p: &SolveParams,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
) -> Vec<Terms> {
    let mut acc = vec![Terms::default(); cur.len()];
    for (r, s) in layout.springs.iter().enumerate() {
        let t = spring_terms(p, &seen_from_a(layout, r), cur, vel, s.a as usize);
        for (node, sign) in [(s.a as usize, 1.0f32), (s.b as usize, -1.0)] {
            if inv_mass[node] == 0.0 {
                continue;
            }
            let n = &mut acc[node];
            n.f = add(n.f, scale(sign, t.f));
            n.kv = add(n.kv, scale(sign, t.kv));
            n.iso += t.iso;
            for c in 0..4 {
                n.da[c] += t.da[c];
            }
            for c in 0..2 {
                n.db[c] += t.db[c];
            }
        }
    }
    acc
}

/// The `setup` pass on the accumulated terms.
pub(crate) fn setup_atomic_cpu(
    p: &SolveParams,
    terms: &[Terms],
    inv_mass: &[f32],
    vel: &[[f32; 4]],
) -> SolveVectors {
    let identity = [[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.0]];
    setup_with(terms.len(), |i| {
        if inv_mass[i] == 0.0 {
            return ([0.0; 3], identity);
        }
        finish_setup(p, inv_mass[i], v3(vel[i]), &terms[i])
    })
}

/// The `spring_multiply` then `multiply` passes: each record's product added at `a` and
/// subtracted at `b`, then `A p` at every node and the partials (nothing once the solve has
/// ended).
pub fn multiply_atomic_cpu(
    p: &SolveParams,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    v: &mut SolveVectors,
) {
    if v.scalars.status != status::RUNNING {
        return;
    }
    let mut sum = vec![[0.0f32; 3]; cur.len()];
    for (r, s) in layout.springs.iter().enumerate() {
        let seen = seen_from_a(layout, r);
        let (a, b) = (s.a as usize, s.b as usize);
        let Some((u, _, t)) = geometry(p, &seen, cur, v3(cur[a])) else {
            continue;
        };
        let out = block_product(p, &seen, u, t, sub(v3(v.p[b]), v3(v.p[a])));
        if inv_mass[a] != 0.0 {
            sum[a] = add(sum[a], out);
        }
        if inv_mass[b] != 0.0 {
            sum[b] = add(sum[b], scale(-1.0, out));
        }
    }
    product_pass(v, |i, w| {
        if inv_mass[i] == 0.0 {
            return [0.0; 3];
        }
        let m = (1.0 + p.h * p.alpha) / inv_mass[i];
        sub(scale(m, v3(w[i])), sum[i])
    });
}

/// One implicit step of the float-atomic variant on the CPU, as its passes take it (the
/// records and the adds in record order). Returns the next displacements and velocities and
/// the final scalars.
pub fn implicit_step_atomic_cpu(
    p: &SolveParams,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Scalars) {
    let terms = setup_records_cpu(p, layout, inv_mass, cur, vel);
    let mut v = setup_atomic_cpu(p, &terms, inv_mass, vel);
    start_cpu(p, &mut v);
    iterate_cpu(p, &mut v, |v| {
        multiply_atomic_cpu(p, layout, inv_mass, cur, v)
    });
    let (next, vel_out) = finish_cpu(p, inv_mass, cur, vel, &v).expect("the solve ended");
    (next, vel_out, v.scalars)
}

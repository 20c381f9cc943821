//! The conjugate gradients of the fast engine's backward Euler (`implicit.rs`): the solve with
//! its stopping rule, the step of the iterates, the preconditioners (block Jacobi, one
//! symmetric Gauss-Seidel sweep per block of nodes, or the sparse Cholesky factor of
//! `implicit_factor.rs`), the search direction and the product `A p` over the rows the step
//! assembled. Every dot product is summed in float64 block by block in block order, so any
//! number of threads gives the same bits.

use super::factor::{apply_factor, prepare};
use super::laned;
use super::passes::over_blocks;
use super::rows::{dot64, rows_of, sym_mul, Entries, Rows};
use super::{Held, Implicit, Iterate, NodeSystem};
use crate::engine::fast::{Graph, P};
use crate::physics::{Preconditioner, SolverSettings};

/// Solve `A y = b` (`bb = b . b`) by preconditioned conjugate gradients, as the float64
/// integrator does, from `y = 0` or, with `guess`, from the last velocity change `dv` (zero on
/// fixed nodes); the iterations and the final relative residual (to `|b|` either way).
pub(super) fn solve(
    imp: &mut Implicit,
    g: &Graph,
    settings: SolverSettings,
    bb: f64,
    guess: bool,
) -> (u32, f64) {
    let factored = settings.preconditioner.is_factored();
    let single = settings.preconditioner == Preconditioner::Factored;
    let sgs = matches!(
        settings.preconditioner,
        Preconditioner::Auto | Preconditioner::SymmetricGaussSeidel
    );
    let elements = imp.elements;
    let Implicit {
        starts,
        blocks,
        full,
        nodes,
        cg,
        p,
        ap,
        dv,
        partials,
        held,
        lanes,
        wide,
        factor,
        stats,
        ..
    } = imp;
    let (nodes, held) = (&nodes[..], &*held);
    let blocks = rows_of(starts, blocks, full, lanes, elements, *wide);
    // The factor, taken or refreshed first where it is missing or stale; without one (a
    // failed factorisation) the solve is block Jacobi's.
    let mut factor = if factored {
        prepare(factor, stats, nodes, blocks, g, single)
    } else {
        None
    };
    if bb == 0.0 {
        cg.iter_mut().for_each(|it| it.y = [0.0; 4]);
        return (0, 0.0);
    }
    let b_norm = bb.sqrt();
    if guess {
        // The guess's product, through `p`: `r = b - A y`.
        let dv = &dv[..];
        over_blocks(p, partials, |start, out| {
            for (k, o) in out.iter_mut().enumerate() {
                let i = start + k;
                *o = if g.fixed[i] { [0.0; 4] } else { dv[i] };
            }
            [0.0; 2]
        });
        product(g, blocks, nodes, p, ap, partials, Some(held));
    }
    let (p0, ap0) = (&p[..], &ap[..]);
    let [rr, mut rz] = over_blocks(cg, partials, |start, out| {
        for (k, it) in out.iter_mut().enumerate() {
            let i = start + k;
            let b = nodes[i].b;
            (it.y, it.r) = if guess {
                (p0[i], [0, 1, 2, 3].map(|c| b[c] - ap0[i][c]))
            } else {
                ([0.0; 4], b)
            };
        }
        precondition(start, out, nodes, blocks, g, sgs);
        held.filter(start, out, |it| &mut it.r);
        held.filter(start, out, |it| &mut it.z);
        out.iter().fold([0.0; 2], |s, it| {
            [s[0] + dot64(it.r, it.r), s[1] + dot64(it.r, it.z)]
        })
    });
    // The residual is judged before the factor is applied: a converged residual needs no
    // preconditioning, and on the factored path that saves a pair of triangular solves, the
    // most expensive pass of the iteration.
    let mut residual = rr.sqrt() / b_norm;
    if residual <= settings.tolerance {
        return (0, residual);
    }
    if let Some(f) = factor.as_deref_mut() {
        rz = apply_factor(f, cg, partials, g, held, stats)[1];
    }
    direction(p, cg, partials, None);
    for iteration in 1..=settings.max_iterations {
        let [pap, _] = product(g, blocks, nodes, p, ap, partials, Some(held));
        if pap <= 0.0 {
            // Not positive definite along `p` (an exact linearisation under compression):
            // stop with what has been reached, as the float64 integrator does.
            return (iteration, residual);
        }
        let alpha = (rz / pap) as f32;
        let [rr, mut rz_next] = advance(cg, partials, nodes, blocks, g, sgs, held, p, ap, alpha);
        residual = rr.sqrt() / b_norm;
        if residual <= settings.tolerance {
            return (iteration, residual);
        }
        if let Some(f) = factor.as_deref_mut() {
            rz_next = apply_factor(f, cg, partials, g, held, stats)[1];
        }
        let beta = (rz_next / rz) as f32;
        rz = rz_next;
        direction(p, cg, partials, Some(beta));
    }
    (settings.max_iterations, residual)
}

/// `y += alpha p`, `r -= alpha Ap`, `z = P r`; returns `(r . r, r . z)`.
#[allow(clippy::too_many_arguments)]
fn advance(
    cg: &mut [Iterate],
    partials: &mut [[f64; 2]],
    nodes: &[NodeSystem],
    blocks: Rows,
    g: &Graph,
    sgs: bool,
    held: &Held,
    p: &[P],
    ap: &[P],
    alpha: f32,
) -> [f64; 2] {
    over_blocks(cg, partials, |start, out| {
        for (k, it) in out.iter_mut().enumerate() {
            let i = start + k;
            for c in 0..3 {
                it.y[c] += alpha * p[i][c];
                it.r[c] -= alpha * ap[i][c];
            }
        }
        precondition(start, out, nodes, blocks, g, sgs);
        held.filter(start, out, |it| &mut it.z);
        out.iter().fold([0.0; 2], |s, it| {
            [s[0] + dot64(it.r, it.r), s[1] + dot64(it.r, it.z)]
        })
    })
}

/// `z = P r` over one block of nodes starting at `start`: block Jacobi, or one symmetric
/// Gauss-Seidel sweep over the block's own nodes, `P^-1 = (D - L) D^-1 (D - U)` with `D` the
/// diagonal blocks and `-L`, `-U` the spring blocks between nodes of the block (the system's
/// off-diagonal blocks are `-S_ij`). Couplings to other blocks are left out, so the blocks
/// are independent (any number of threads gives the same bits) and `P` stays symmetric
/// positive definite. Fixed nodes are projected out: `z = 0` there.
fn precondition(
    start: usize,
    out: &mut [Iterate],
    nodes: &[NodeSystem],
    blocks: Rows,
    g: &Graph,
    sgs: bool,
) {
    if !sgs {
        for (k, it) in out.iter_mut().enumerate() {
            let z = sym_mul(&nodes[start + k].inverse, it.r);
            it.z = [z[0], z[1], z[2], 0.0];
        }
        return;
    }
    let end = start + out.len();
    // Each row's lower part, then the rest (`assemble` put them so): each sweep reads only
    // its own part, and the two together read the row once.
    let lower = |i: usize| 0..nodes[i].lower as usize;
    let upper = |i: usize| nodes[i].lower as usize..blocks.len(i);
    // Forward: `(D - L) w = r`, `w` kept in `z`.
    for k in 0..out.len() {
        let i = start + k;
        if g.fixed[i] {
            out[k].z = [0.0; 4];
            continue;
        }
        let r = out[k].r;
        let acc = blocks.accumulate(i, lower(i), [r[0], r[1], r[2]], false, |j| {
            Some(out[j - start].z)
        });
        let z = sym_mul(&nodes[i].inverse, [acc[0], acc[1], acc[2], 0.0]);
        out[k].z = [z[0], z[1], z[2], 0.0];
    }
    // Backward: `(D - U) z = D w`, i.e. `z_i = w_i + D_i^-1 sum_(j > i) S_ij z_j`.
    for k in (0..out.len()).rev() {
        let i = start + k;
        if g.fixed[i] {
            continue;
        }
        let acc = blocks.accumulate(i, upper(i), [0.0; 3], false, |j| {
            (j > i && j < end).then(|| out[j - start].z)
        });
        let z = sym_mul(&nodes[i].inverse, [acc[0], acc[1], acc[2], 0.0]);
        for (out, z) in out[k].z.iter_mut().zip(z) {
            *out += z;
        }
    }
}

/// `p = z + beta p` (`p = z` without `beta`).
fn direction(p: &mut [P], cg: &[Iterate], partials: &mut [[f64; 2]], beta: Option<f32>) {
    over_blocks(p, partials, |start, out| {
        for (k, p) in out.iter_mut().enumerate() {
            let z = cg[start + k].z;
            *p = match beta {
                None => z,
                Some(beta) => [0, 1, 2, 3].map(|c| z[c] + beta * p[c]),
            };
        }
        [0.0; 2]
    });
}

/// `Ap` on the free nodes (zero on the fixed ones, where `p` is zero too: their right-hand
/// side is zero and their preconditioner the identity), filtered by `held` where given;
/// returns `(p . Ap, 0)`.
pub(super) fn product(
    g: &Graph,
    blocks: Rows,
    nodes: &[NodeSystem],
    p: &[P],
    ap: &mut [P],
    partials: &mut [[f64; 2]],
    held: Option<&Held>,
) -> [f64; 2] {
    over_blocks(ap, partials, |start, out| {
        if let Entries::Elements(_) = blocks.entries {
            let mut sum = 0.0f64;
            for (k, o) in out.iter_mut().enumerate() {
                let i = start + k;
                if g.fixed[i] {
                    *o = [0.0; 4];
                    continue;
                }
                // The row is read through the blocks' own `other`: 40 bytes an entry, the
                // springs are not touched.
                let diag = sym_mul(&nodes[i].diag, p[i]);
                let acc = blocks.accumulate(i, 0..blocks.len(i), diag, true, |j| Some(p[j]));
                *o = [acc[0], acc[1], acc[2], 0.0];
                sum += dot64(p[i], *o);
            }
            if let Some(held) = held {
                held.filter(start, out, |o| o);
            }
            return [sum, 0.0];
        }
        // The blocks are read lane by lane (`implicit_sliced.rs`): 24 bytes an entry beside the
        // springs' neighbour index, the springs themselves are not touched.
        #[cfg(target_arch = "x86_64")]
        let sum = if blocks.wide {
            // SAFETY: `wide` is true only when the CPU reported AVX2 and FMA.
            unsafe { laned::product_slices_wide(g, blocks.lanes, nodes, p, start, out) }
        } else {
            laned::product_slices(g, blocks.lanes, nodes, p, start, out)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let sum = laned::product_slices(g, blocks.lanes, nodes, p, start, out);
        if let Some(held) = held {
            // `p` has no normal part on a constrained node, so `p . Ap` is unchanged.
            held.filter(start, out, |o| o);
        }
        [sum, 0.0]
    })
}

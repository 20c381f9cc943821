//! Backward Euler's system with a finite-element force model on the fast engine: the same
//! equations, solver and preconditioners as the springs' (`implicit.rs`), on the elements'
//! full 3x3 blocks (`elements_jacobian.rs` forms them: tensor-mass's constant `K` and `C`,
//! corotational's `R K_e R^T` with each tet's rotation frozen at the linearisation's state,
//! Rayleigh's damping in the system).
//!
//! The rows are the springs' rows (the tet edges), assembled again at every linearisation: a
//! cut's patched rows and tets need nothing more. The diagonal block is the mass term plus the
//! sum of the row's blocks (an element's block rows sum to zero), symmetrised: the product,
//! the block-Jacobi inverse and the Gauss-Seidel sweep then all read the one set of blocks.

use super::{
    dot64, inverse, over_blocks, Graph, Implicit, Lin, NodeSystem, Params, SharedRows, IDENTITY,
};
use crate::engine::fast::elements::FastElements;

/// Form every free node's row, diagonal block, preconditioner and right-hand side from the
/// finite elements `fem` at the state `at`; returns `b . b`.
pub(super) fn assemble(
    imp: &mut Implicit,
    g: &Graph,
    p: Params,
    fem: &mut FastElements,
    at: Lin,
) -> f64 {
    let (x, v, newton) = match at {
        Lin::Start(x, v) => (x, v, None),
        Lin::Iterate => (&imp.xk[..], &imp.vk[..], Some(&imp.dv[..])),
    };
    fem.linearize(x, v);
    let fem = &*fem;
    let blocks = SharedRows(imp.full.as_mut_ptr(), imp.full.len());
    let starts = &imp.starts[..];
    let h = p.h;
    let [bb, _] = over_blocks(&mut imp.nodes, &mut imp.partials, |start, out| {
        let mut bb = 0.0f64;
        for (k, node) in out.iter_mut().enumerate() {
            let i = start + k;
            if g.fixed[i] {
                *node = NodeSystem {
                    diag: IDENTITY,
                    inverse: IDENTITY,
                    b: [0.0; 4],
                    lower: 0,
                };
                continue;
            }
            let (first, end) = (starts[i] as usize, starts[i + 1] as usize);
            // SAFETY: rows are disjoint, consecutive ranges (`Implicit::fit`), and node `i`'s
            // row is written only here, by the one task that owns node `i`.
            let row = unsafe { blocks.row(first, end) };
            let (f, kv) = fem.implicit_row(i, g, x, v, h, row);
            let mut sum = [0.0f32; 9];
            for e in row.iter() {
                for (s, m) in sum.iter_mut().zip(e.m) {
                    *s += m;
                }
            }
            // Blocks coupling `i` to an earlier node of its own block first (the Gauss-Seidel
            // sweep's lower part, see `precondition`); the product reads them in any order.
            let mut lower = 0;
            for e in 0..row.len() {
                let j = row[e].other as usize;
                if j >= start && j < i {
                    row.swap(lower, e);
                    lower += 1;
                }
            }
            let mh = (1.0 + h * p.alpha) / g.inv_mass[i];
            let diag = [
                sum[0] + mh,
                sum[4] + mh,
                sum[8] + mh,
                0.5 * (sum[1] + sum[3]),
                0.5 * (sum[2] + sum[6]),
                0.5 * (sum[5] + sum[7]),
            ];
            let m = 1.0 / g.inv_mass[i];
            let vi = v[i];
            let mut b = [0.0f32; 4];
            for a in 0..3 {
                let total = f[a] + m * p.gravity[a] - p.alpha * m * vi[a];
                b[a] = match newton {
                    None => h * (total + h * kv[a]),
                    Some(dv) => h * total - m * dv[i][a],
                };
            }
            bb += dot64(b, b);
            *node = NodeSystem {
                diag,
                inverse: inverse(&diag),
                b,
                lower: lower as u32,
            };
        }
        [bb, 0.0]
    });
    bb
}

//! Twins of the corotational implicit step's own parts (`engine::gpu::corotational_implicit`):
//! the block pass (`shaders/corotational_blocks.wgsl`), and the whole step as the device takes
//! it: the tet pass ([`TetTable::tet_pass_cpu`]: rotations and corner forces), the blocks, then
//! the tensor-mass solve ([`super::implicit_tensor`]) with the gathered corner forces as its
//! force (`shaders/implicit_corotational.wgsl`). Rounding and order are the shaders'. The
//! float64 specification is [`crate::physics::BackwardEuler`] on
//! [`crate::physics::Corotational`].

use super::corotational::rotation_minus_identity;
use super::implicit_solve::{Scalars, SolveParams};
use super::implicit_tensor;
use crate::layout::tensor_blocks::TensorBlocks;
use crate::layout::tet_pairs::TetPairs;
use crate::layout::tet_table::TetTable;
use crate::layout::PackedLayout;
use crate::physics::StepParams;

type V3 = [f32; 3];

/// WGSL's `dot` of three lanes, summed left to right.
fn dot3(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn xyz(v: [f32; 4]) -> V3 {
    [v[0], v[1], v[2]]
}

/// Corner `a`'s gradient of the tet with shape rows `s` (`corner_gradient`).
fn corner_gradient(s: &[[f32; 4]; 3], a: usize) -> V3 {
    if a == 0 {
        let sum = add(add(xyz(s[0]), xyz(s[1])), xyz(s[2]));
        return sum.map(|c| -c);
    }
    xyz(s[a - 1])
}

/// `R w`, `m = R - I` (`rotate`).
fn rotate(m: &[V3; 3], w: V3) -> V3 {
    let rr = [
        [m[0][0] + 1.0, m[0][1], m[0][2]],
        [m[1][0], m[1][1] + 1.0, m[1][2]],
        [m[2][0], m[2][1], m[2][2] + 1.0],
    ];
    [dot3(rr[0], w), dot3(rr[1], w), dot3(rr[2], w)]
}

/// `block_row`.
fn block_row(k: V3, r: usize, ra: V3, rb: V3) -> V3 {
    let e = [0, 1, 2].map(|c| if c == r { 1.0f32 } else { 0.0 });
    [0, 1, 2].map(|c| dot3(k, [e[c], ra[c], rb[c]]))
}

/// `s + beta w`, lane by lane (`plus_scaled3`).
fn plus_scaled(s: V3, w: V3, beta: f32) -> V3 {
    [0, 1, 2].map(|c| s[c] * 1.0 + w[c] * beta)
}

/// The block pass: per slot of `pairs`, `K' = sum_t R_t K_t,ab R_t^T` (then `C' = sum_t beta_t
/// ...` where `damped`) from the tets' shapes in `table` and the rotations `rotations` (unit
/// quaternions, table order), as `corotational_blocks.wgsl` sums them.
pub fn blocks_cpu(
    table: &TetTable,
    pairs: &TetPairs,
    rotations: &[[f32; 4]],
    damped: bool,
) -> TensorBlocks {
    let stride = if damped { 6 } else { 3 };
    let mut rows = vec![[0.0f32; 4]; pairs.rows.len() * stride];
    for (slot, &[start, end]) in pairs.rows.iter().enumerate() {
        let mut k = [[0.0f32; 3]; 3];
        let mut c = [[0.0f32; 3]; 3];
        for &code in &pairs.pairs[start as usize..end as usize] {
            let (t, a, b) = (
                (code / 16) as usize,
                (code / 4 % 4) as usize,
                (code % 4) as usize,
            );
            let s = &table.shape[t];
            let (ba, bb) = (corner_gradient(s, a), corner_gradient(s, b));
            let m = rotation_minus_identity(rotations[t]);
            let (ra, rb) = (rotate(&m, ba), rotate(&m, bb));
            let (lam, mu, beta) = (s[0][3], 0.5 * s[1][3], s[2][3]);
            let iso = mu * dot3(ba, bb);
            for r in 0..3 {
                let row = block_row([iso, mu * rb[r], lam * ra[r]], r, ra, rb);
                k[r] = add(k[r], row);
                if damped {
                    c[r] = plus_scaled(c[r], row, beta);
                }
            }
        }
        let at = slot * stride;
        for r in 0..3 {
            rows[at + r] = [k[r][0], k[r][1], k[r][2], 0.0];
            if damped {
                rows[at + 3 + r] = [c[r][0], c[r][1], c[r][2], 0.0];
            }
        }
    }
    TensorBlocks { damped, rows }
}

/// One corotational implicit step of `layout` as the device takes it, from the rotations
/// `rotations` (the warm start, updated in place): the tet pass at the step's start, the
/// blocks, the gathered corner forces, then the tensor-mass solve on them
/// ([`implicit_tensor::implicit_step_forced`]). `p` is the engine's step constants (the tet
/// pass's velocity), `solve` the solve's. Returns the next displacements and velocities and
/// the final scalars.
#[allow(clippy::too_many_arguments)]
pub fn implicit_step_cpu(
    p: &StepParams,
    solve: &SolveParams,
    table: &TetTable,
    pairs: &TetPairs,
    layout: &PackedLayout,
    inv_mass: &[f32],
    (cur, vel): (&[[f32; 4]], &[[f32; 4]]),
    rotations: &mut [[f32; 4]],
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Scalars) {
    let forces = table.tet_pass_cpu(p, cur, vel, rotations);
    let blocks = blocks_cpu(table, pairs, rotations, table.damped);
    let f = table.gather_cpu(&forces, cur.len());
    implicit_tensor::implicit_step_forced(solve, &blocks, layout, inv_mass, cur, vel, Some(&f))
}

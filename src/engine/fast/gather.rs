//! The spring forces of one slice (`sliced.rs`) written with AVX2/FMA intrinsics: the eight
//! neighbours of a group are read as eight 16-byte rows (position or velocity, padded to four
//! floats) and transposed in registers into one vector per axis, instead of 24 scalar loads
//! inserted lane by lane. The arithmetic is the portable kernel's ([`super::sliced::group_force`]),
//! with fused multiply-adds; it differs from it only by their rounding.

use super::sliced::{Sliced, LANES, V3};
use super::P;
use std::arch::x86_64::*;

/// The rows `idx[l]` of `rows`, transposed: their x, y and z as three vectors of eight lanes.
///
/// # Safety
/// The CPU has AVX2 and FMA, and every `idx[l]` is below `rows.len()`.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn rows_of(rows: &[P], idx: &[u32; LANES]) -> [__m256; 3] {
    let base = rows.as_ptr();
    // SAFETY: the caller guarantees each index is within `rows`; a row is four floats.
    let row = |l: usize| unsafe { _mm_loadu_ps(base.add(idx[l] as usize) as *const f32) };
    // Rows l and l + 4 share a 256-bit register: [r_l | r_{l+4}].
    let a0 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(0)), row(4));
    let a1 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(1)), row(5));
    let a2 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(2)), row(6));
    let a3 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(3)), row(7));
    // A 4x4 transpose in each 128-bit half.
    let t0 = _mm256_unpacklo_ps(a0, a1); // x0 x1 y0 y1 | x4 x5 y4 y5
    let t1 = _mm256_unpackhi_ps(a0, a1); // z0 z1 w0 w1 | z4 z5 w4 w5
    let t2 = _mm256_unpacklo_ps(a2, a3); // x2 x3 y2 y3 | x6 x7 y6 y7
    let t3 = _mm256_unpackhi_ps(a2, a3); // z2 z3 w2 w3 | z6 z7 w6 w7
    [
        _mm256_shuffle_ps::<0x44>(t0, t2),
        _mm256_shuffle_ps::<0xEE>(t0, t2),
        _mm256_shuffle_ps::<0x44>(t1, t3),
    ]
}

/// The spring forces on the nodes of slice `b`, as `kernels::slice_forces` computes them
/// (lanes past the last node hold nothing useful).
///
/// # Safety
/// The CPU has AVX2 and FMA; `x` and `w` hold the `sl.nodes()` nodes the layout indexes
/// (every neighbour index in a group is below it, as [`Sliced`] keeps them), and slice `b`
/// exists.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn slice_forces<const DAMPED: bool>(
    sl: &Sliced,
    x: &[P],
    w: &[P],
    b: usize,
    w_scale: f32,
) -> V3 {
    let base = b * LANES;
    // Lanes past the last node read the last node: their results are never stored.
    let last = x.len() - 1;
    let own: [u32; LANES] = std::array::from_fn(|l| (base + l).min(last) as u32);
    // SAFETY (every `rows_of` below): `own` is clamped into `x`, and the groups' neighbours
    // are below `sl.nodes()`, which the caller guarantees is the length of `x` and `w`.
    let ui = unsafe { rows_of(x, &own) };
    let zero = _mm256_setzero_ps();
    let wi = if DAMPED {
        unsafe { rows_of(w, &own) }
    } else {
        [zero; 3]
    };
    let one = _mm256_set1_ps(1.0);
    let ws = _mm256_set1_ps(w_scale);
    let mut acc = [zero; 3];
    let [start, end] = sl.slices[b];
    let (start, end) = (start as usize, end as usize);
    // SAFETY (the loads): `Group` and the damping rows are arrays of eight f32 (`loadu`).
    let load = |a: &[f32; LANES]| unsafe { _mm256_loadu_ps(a.as_ptr()) };
    for (k, g) in sl.groups[start..end].iter().enumerate() {
        let uj = unsafe { rows_of(x, &g.other) };
        let d: [__m256; 3] =
            std::array::from_fn(|a| _mm256_add_ps(load(&g.edge[a]), _mm256_sub_ps(uj[a], ui[a])));
        let l2 = _mm256_fmadd_ps(
            d[2],
            d[2],
            _mm256_fmadd_ps(d[1], d[1], _mm256_mul_ps(d[0], d[0])),
        );
        // A zero-length spring (padding, coincident nodes) has no direction: nothing.
        let inv = _mm256_and_ps(
            _mm256_div_ps(one, _mm256_sqrt_ps(l2)),
            _mm256_cmp_ps::<_CMP_GT_OQ>(l2, zero),
        );
        let mut s = _mm256_mul_ps(load(&g.k), _mm256_fnmadd_ps(load(&g.rest), inv, one));
        if DAMPED {
            let wj = unsafe { rows_of(w, &g.other) };
            let dw: [__m256; 3] = std::array::from_fn(|a| _mm256_sub_ps(wj[a], wi[a]));
            let along = _mm256_fmadd_ps(
                dw[2],
                d[2],
                _mm256_fmadd_ps(dw[1], d[1], _mm256_mul_ps(dw[0], d[0])),
            );
            let c = load(&sl.damping[start + k]);
            s = _mm256_fmadd_ps(
                _mm256_mul_ps(c, along),
                _mm256_mul_ps(ws, _mm256_mul_ps(inv, inv)),
                s,
            );
        }
        for a in 0..3 {
            acc[a] = _mm256_fmadd_ps(s, d[a], acc[a]);
        }
    }
    let mut out = [[0.0f32; LANES]; 3];
    for a in 0..3 {
        // SAFETY: `out[a]` is eight f32.
        unsafe { _mm256_storeu_ps(out[a].as_mut_ptr(), acc[a]) };
    }
    out
}

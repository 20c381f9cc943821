//! The fast engine's step of a block of nodes written with AVX2/FMA intrinsics, eight nodes
//! (a slice of `sliced.rs`) at a time, one a lane.
//!
//! The spring forces: the eight neighbours of a group are read as eight 16-byte rows
//! (position or velocity, padded to four floats) and transposed in registers into one vector
//! per axis, instead of 24 scalar loads inserted lane by lane. The arithmetic is the portable
//! kernel's ([`super::sliced::group_force`]) with fused multiply-adds, so it differs from it
//! only by their rounding (and, in the AVX-512 copy, by the estimate of `1 / l`: see below).
//!
//! The update: the portable kernels' (`kernels.rs`: `verlet_block`, `euler_block`, `advance`
//! and `physics::Compensation`) operation for operation, unfused, on the eight lanes at once,
//! the new rows transposed back and stored whole; given the same forces it gives the same
//! bits.
//!
//! One code, compiled twice (`kernels::wide`): for AVX2 and FMA, and for those with AVX-512F
//! and VL, where each spring's `1 / l` comes from an estimate and a Newton step instead of the
//! divider ([`short_scale`]; a uniform layout's rest length, `sqrt(|e|^2)`, still takes a
//! square root, off the chain). The two give different bits, a float32 rounding or two
//! apart, and so may CPUs of different makers with AVX-512: the estimate is bounded to
//! 2^-14, not specified to the bit. Its functions are `#[inline(always)]` without target features of
//! their own, so that each copy is compiled whole with its wrapper's.

use super::sliced::{Sliced, Uniform, LANES};
use super::{Graph, Params, P};
use std::arch::x86_64::*;

/// The rows of a group's other ends (`at`, [`super::sliced::Group::at`]: twice each row's
/// index) in `rows`, transposed: their x, y and z as three vectors of eight lanes. Each row's
/// address is `base + at * 8`, one x86 addressing mode, so no lane's index is shifted first.
///
/// # Safety
/// The CPU has AVX2 and FMA, and every `at[l]` is even with `at[l] / 2` below `rows.len()`
/// (an odd one would read half a row past its row).
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn rows_at(rows: &[P], at: &[u32; LANES]) -> [__m256; 3] {
    // Half rows: 8 bytes, the largest scale an x86 address takes.
    let base = rows.as_ptr() as *const [f32; 2];
    // SAFETY: the caller guarantees each `at[l]` is even and `at[l] / 2` a row within
    // `rows`: half row `at[l]` starts that row, which is two half rows long.
    let row = |l: usize| unsafe { _mm_loadu_ps(base.add(at[l] as usize) as *const f32) };
    let pair = |l: usize| _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(l)), row(l + 4));
    let [x, y, z, _] = transpose4([pair(0), pair(1), pair(2), pair(3)]);
    [x, y, z]
}

/// The rows `idx[l]` of `rows`, transposed: their x, y, z and `w` (the compensation) as four
/// vectors of eight lanes.
///
/// # Safety
/// The CPU has AVX2 and FMA, and every `idx[l]` is below `rows.len()`.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn rows4(rows: &[P], idx: &[u32; LANES]) -> [__m256; 4] {
    let base = rows.as_ptr();
    // SAFETY: the caller guarantees each index is within `rows`; a row is four floats.
    let row = |l: usize| unsafe { _mm_loadu_ps(base.add(idx[l] as usize) as *const f32) };
    // Rows l and l + 4 share a 256-bit register: [r_l | r_{l+4}].
    let a0 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(0)), row(4));
    let a1 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(1)), row(5));
    let a2 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(2)), row(6));
    let a3 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(3)), row(7));
    transpose4([a0, a1, a2, a3])
}

/// Rows `[r_l | r_{l+4}]` for `l = 0..4` (two rows of four floats a register) as their x, y, z
/// and w across eight lanes: a 4x4 transpose in each 128-bit half.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn transpose4([a0, a1, a2, a3]: [__m256; 4]) -> [__m256; 4] {
    let t0 = _mm256_unpacklo_ps(a0, a1); // x0 x1 y0 y1 | x4 x5 y4 y5
    let t1 = _mm256_unpackhi_ps(a0, a1); // z0 z1 w0 w1 | z4 z5 w4 w5
    let t2 = _mm256_unpacklo_ps(a2, a3); // x2 x3 y2 y3 | x6 x7 y6 y7
    let t3 = _mm256_unpackhi_ps(a2, a3); // z2 z3 w2 w3 | z6 z7 w6 w7
    [
        _mm256_shuffle_ps::<0x44>(t0, t2),
        _mm256_shuffle_ps::<0xEE>(t0, t2),
        _mm256_shuffle_ps::<0x44>(t1, t3),
        _mm256_shuffle_ps::<0xEE>(t1, t3),
    ]
}

/// [`rows4`] of the eight consecutive rows from `start`, without reading their indices.
///
/// # Safety
/// The CPU has AVX2 and FMA, and `start + 8 <= rows.len()`.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn rows4_from(rows: &[P], start: usize) -> [__m256; 4] {
    // SAFETY: the caller's; a row is four floats.
    let row = |l: usize| unsafe { _mm_loadu_ps(rows.as_ptr().add(start + l) as *const f32) };
    let pair = |l: usize| _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(row(l)), row(l + 4));
    transpose4([pair(0), pair(1), pair(2), pair(3)])
}

/// Store the eight lanes of `v` (x, y, z, w) as the rows `out[0..out.len()]` (eight at most:
/// a last, partial slice stores its nodes only): the transpose of [`rows4`].
#[inline]
#[target_feature(enable = "avx2,fma")]
fn store_rows(v: [__m256; 4], out: &mut [P]) {
    let t0 = _mm256_unpacklo_ps(v[0], v[1]); // x0 y0 x1 y1 | x4 y4 x5 y5
    let t1 = _mm256_unpackhi_ps(v[0], v[1]); // x2 y2 x3 y3 | x6 y6 x7 y7
    let t2 = _mm256_unpacklo_ps(v[2], v[3]); // z0 w0 z1 w1 | z4 w4 z5 w5
    let t3 = _mm256_unpackhi_ps(v[2], v[3]); // z2 w2 z3 w3 | z6 w6 z7 w7
                                             // [r_l | r_{l+4}] for l = 0..4.
    let pairs = [
        _mm256_shuffle_ps::<0x44>(t0, t2),
        _mm256_shuffle_ps::<0xEE>(t0, t2),
        _mm256_shuffle_ps::<0x44>(t1, t3),
        _mm256_shuffle_ps::<0xEE>(t1, t3),
    ];
    if out.len() == LANES {
        // A full slice: straight into `out`.
        let o = out.as_mut_ptr() as *mut f32;
        for (l, p) in pairs.into_iter().enumerate() {
            // SAFETY: `out` holds eight rows of four f32.
            unsafe {
                _mm_storeu_ps(o.add(4 * l), _mm256_castps256_ps128(p));
                _mm_storeu_ps(o.add(4 * (l + 4)), _mm256_extractf128_ps::<1>(p));
            }
        }
        return;
    }
    let mut rows = [[0.0f32; 4]; LANES];
    for (l, p) in pairs.into_iter().enumerate() {
        // SAFETY: each row is four f32.
        unsafe {
            _mm_storeu_ps(rows[l].as_mut_ptr(), _mm256_castps256_ps128(p));
            _mm_storeu_ps(rows[l + 4].as_mut_ptr(), _mm256_extractf128_ps::<1>(p));
        }
    }
    let n = out.len();
    out.copy_from_slice(&rows[..n]);
}

/// How many groups ahead of the one being evaluated [`prefetch`] asks for: 3 KiB of groups,
/// well inside the first-level cache. 16 to 31 measured alike at 100k nodes (12-13% a damped
/// step, 5-6% an undamped one), 8 gave less (measurements.md, twelfth slice).
const AHEAD: usize = 24;

/// Ask for the entry [`AHEAD`] places after `at` in `v` to be brought into the first-level
/// cache without displacing what the step keeps in the others (`NTA`: it is read once).
/// A prefetch never faults, so an address past the end of `v` is harmless; it is computed
/// with `wrapping_add` and never dereferenced.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn prefetch<T>(v: &[T], at: usize) {
    let p = v.as_ptr().wrapping_add(at + AHEAD) as *const i8;
    let size = std::mem::size_of::<T>();
    let mut line = 0;
    while line < size {
        _mm_prefetch::<_MM_HINT_NTA>(p.wrapping_add(line));
        line += 64;
    }
}

/// The spring forces on the nodes of slice `b`, whose own displacements and second states
/// are `ui` and `wi` (lanes past the last node hold nothing useful). Each spring's scale from
/// a division and a square root, or where `SHORT` from [`short_scale`].
///
/// Compiled inside the callers of [`block`], with their target features.
///
/// # Safety
/// The CPU has AVX2 and FMA, and AVX-512F and VL where `SHORT`; `x` and `w` hold the
/// `sl.nodes()` nodes the layout indexes (every group's
/// [`Group::at`](super::sliced::Group::at) holds `2 j` with `j` below it, as `Group::set_node`
/// writes them), and slice `b` exists.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn slice_forces<const DAMPED: bool, const UNIFORM: bool, const SHORT: bool>(
    sl: &Sliced,
    x: &[P],
    w: &[P],
    b: usize,
    w_scale: f32,
    ui: &[__m256; 4],
    wi: &[__m256; 4],
) -> [__m256; 3] {
    // SAFETY (the intrinsics and the loads): the caller's target features; `Group`,
    // `Material` and the damping rows are arrays of eight f32 (`loadu`).
    unsafe {
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let ws = _mm256_set1_ps(w_scale);
        let mut acc = [zero; 3];
        let [start, end] = sl.slices[b];
        let (start, end) = (start as usize, end as usize);
        let u = sl.uniform.unwrap_or(Uniform { k: 0.0, c: 0.0 });
        let (k_all, c_all) = (_mm256_set1_ps(u.k), _mm256_set1_ps(u.c));
        let load = |a: &[f32; LANES]| _mm256_loadu_ps(a.as_ptr());
        for (k, g) in sl.groups[start..end].iter().enumerate() {
            // The groups (and their constants) are one stream read once a step, which the
            // hardware's prefetchers fell behind on: ask for each [`AHEAD`] groups early,
            // past the slice's end into the next slice's (they are laid out one after the
            // other).
            prefetch(&sl.groups, start + k);
            if !UNIFORM {
                prefetch(&sl.material, start + k);
                if DAMPED {
                    prefetch(&sl.damping, start + k);
                }
            }
            // Each `g.at()` entry is `2 j` with `j` below `sl.nodes()`, the length of `x`
            // and `w` (`Group::set_node`).
            let uj = rows_at(x, g.at());
            let e: [__m256; 3] = std::array::from_fn(|a| load(&g.edge[a]));
            let d: [__m256; 3] =
                std::array::from_fn(|a| _mm256_add_ps(e[a], _mm256_sub_ps(uj[a], ui[a])));
            // The rest length (a uniform layout's is its edge's, never stored) and stiffness.
            let (rest, stiff) = if UNIFORM {
                let le2 = _mm256_fmadd_ps(
                    e[2],
                    e[2],
                    _mm256_fmadd_ps(e[1], e[1], _mm256_mul_ps(e[0], e[0])),
                );
                (le2, k_all)
            } else {
                let m = &sl.material[start + k];
                (load(&m.rest), load(&m.k))
            };
            // A zero-length spring (padding, coincident nodes) has no direction: nothing.
            let some;
            // `k (1 - L / l)`, and the damping's `1 / l^2`.
            let (mut s, inv2) = if SHORT {
                let l2 = _mm256_add_ps(
                    _mm256_fmadd_ps(d[0], d[0], _mm256_mul_ps(d[1], d[1])),
                    _mm256_mul_ps(d[2], d[2]),
                );
                some = _mm256_cmp_ps::<_CMP_GT_OQ>(l2, zero);
                let rest = if UNIFORM { _mm256_sqrt_ps(rest) } else { rest };
                short_scale::<DAMPED>(l2, rest, stiff)
            } else {
                let l2 = _mm256_fmadd_ps(
                    d[2],
                    d[2],
                    _mm256_fmadd_ps(d[1], d[1], _mm256_mul_ps(d[0], d[0])),
                );
                some = _mm256_cmp_ps::<_CMP_GT_OQ>(l2, zero);
                if UNIFORM {
                    // L / l = sqrt(|e|^2 / l^2).
                    let inv2 = _mm256_and_ps(_mm256_div_ps(one, l2), some);
                    let ratio = _mm256_sqrt_ps(_mm256_mul_ps(rest, inv2));
                    (_mm256_mul_ps(stiff, _mm256_sub_ps(one, ratio)), inv2)
                } else {
                    let inv = _mm256_and_ps(_mm256_div_ps(one, _mm256_sqrt_ps(l2)), some);
                    let s = _mm256_mul_ps(stiff, _mm256_fnmadd_ps(rest, inv, one));
                    (s, _mm256_mul_ps(inv, inv))
                }
            };
            if DAMPED {
                let wj = rows_at(w, g.at());
                let dw: [__m256; 3] = std::array::from_fn(|a| _mm256_sub_ps(wj[a], wi[a]));
                let along = _mm256_fmadd_ps(
                    dw[2],
                    d[2],
                    _mm256_fmadd_ps(dw[1], d[1], _mm256_mul_ps(dw[0], d[0])),
                );
                let c = if UNIFORM {
                    c_all
                } else {
                    load(&sl.damping[start + k])
                };
                s = _mm256_fmadd_ps(_mm256_mul_ps(c, along), _mm256_mul_ps(ws, inv2), s);
            }
            if SHORT {
                // The estimate of a zero length's inverse is infinite: its scale is NaN.
                s = _mm256_and_ps(s, some);
            }
            for a in 0..3 {
                acc[a] = _mm256_fmadd_ps(s, d[a], acc[a]);
            }
        }
        acc
    }
}

/// A spring's scale `k (1 - L / l)` and, where `DAMPED`, `1 / l^2`, from `l^2`, the rest
/// length `L` and the stiffness `k`, without the divider: `1 / l` from the 14-bit estimate
/// `y0` and one Newton step, `y = y0 (1 + r)` with `r = 1/2 - l^2 y0^2 / 2`, and `L / l`
/// taken as `L y0 + (L y0) r`.
///
/// The group loop is bound by the latency of each group's chain against the instructions the
/// core keeps in flight, more than by its arithmetic: a division then a square root put
/// about 26 cycles on that chain, the estimate and its step about 15. With the 32 registers
/// AVX-512 brings, a damped step takes 0.82 of the AVX2 kernel's time at 18k nodes and 0.90
/// at 100k, an undamped one 0.92-0.93 (measurements.md, fourteenth slice). The step brings
/// the estimate's 2^-14 to a float32 rounding or two: the errors against the float64 engine
/// after 1,000 steps are those of the division and square root.
///
/// Lanes of zero length come out NaN (an infinite estimate times zero); the caller masks them.
///
/// # Safety
/// The CPU has AVX-512F and VL (and the caller's AVX2 and FMA).
#[inline(always)]
unsafe fn short_scale<const DAMPED: bool>(l2: __m256, rest: __m256, k: __m256) -> (__m256, __m256) {
    // SAFETY: the caller's target features.
    unsafe {
        let half = _mm256_set1_ps(0.5);
        let y0 = _mm256_rsqrt14_ps(l2);
        let ly0 = _mm256_mul_ps(rest, y0);
        let r = _mm256_fnmadd_ps(_mm256_mul_ps(_mm256_mul_ps(half, l2), y0), y0, half);
        let ratio = _mm256_fmadd_ps(ly0, r, ly0);
        let s = _mm256_fnmadd_ps(k, ratio, k);
        if !DAMPED {
            return (s, _mm256_setzero_ps());
        }
        let y = _mm256_fmadd_ps(y0, r, y0);
        (s, _mm256_mul_ps(y, y))
    }
}

/// The step of nodes `start..` (`start` a multiple of [`LANES`]) from displacements `x` and
/// second states `s` into `xo` and `so`: Verlet's (`VERLET`, `s` the last steps) or symplectic
/// Euler's (`s` the velocities), as `kernels::verlet_block` and `kernels::euler_block` make it.
///
/// Compiled inside the wrappers of `kernels::wide` (AVX2 and FMA; and AVX-512F and VL, where
/// `SHORT`), with their target features.
///
/// # Safety
/// The CPU has AVX2 and FMA, and AVX-512F and VL where `SHORT`; `x` and `s` hold the
/// `sl.nodes()` nodes the layout indexes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn block<
    const DAMPED: bool,
    const UNIFORM: bool,
    const VERLET: bool,
    const SHORT: bool,
>(
    g: &Graph,
    sl: &Sliced,
    p: Params,
    x: &[P],
    s: &[P],
    start: usize,
    xo: &mut [P],
    so: &mut [P],
) {
    let last = x.len() - 1;
    let w_scale = if VERLET { p.inv_h } else { 1.0 };
    for (k, (xo, so)) in xo.chunks_mut(LANES).zip(so.chunks_mut(LANES)).enumerate() {
        let b = start / LANES + k;
        let base = b * LANES;
        // A full slice reads its rows, masses and flags as the eight consecutive entries
        // they are; only the last, partial one gathers them lane by lane.
        let full = xo.len() == LANES;
        let (xi, si) = if full {
            // SAFETY: a full slice's eight rows are within `x` and `s`.
            unsafe { (rows4_from(x, base), rows4_from(s, base)) }
        } else {
            // Lanes past the last node read the last node: their results are never stored.
            let own: [u32; LANES] = std::array::from_fn(|l| (base + l).min(last) as u32);
            // SAFETY: `own` is clamped into `x` and `s` (the caller guarantees their lengths).
            unsafe { (rows4(x, &own), rows4(s, &own)) }
        };
        // SAFETY: as above; slice `b` exists since its nodes are being stepped.
        let f = unsafe { slice_forces::<DAMPED, UNIFORM, SHORT>(sl, x, s, b, w_scale, &xi, &si) };
        // SAFETY: the caller's target features.
        unsafe { update::<VERLET>(g, p, base, &xi, &si, &f, xo, so) };
    }
}

/// The update of the slice of nodes from `base` (`xo.len()` of them), from their rows `xi`
/// and `si` and forces `f`, into `xo` and `so`: the portable kernels' operations, lane by lane.
/// Compiled inside [`block`]'s callers like it (a call a slice cost 3-5% of a step).
///
/// # Safety
/// The CPU has AVX2 and FMA.
#[inline(always)]
#[allow(clippy::too_many_arguments, unused_unsafe)]
unsafe fn update<const VERLET: bool>(
    g: &Graph,
    p: Params,
    base: usize,
    xi: &[__m256; 4],
    si: &[__m256; 4],
    f: &[__m256; 3],
    xo: &mut [P],
    so: &mut [P],
) {
    // SAFETY: the caller's target features.
    unsafe {
        let splat = _mm256_set1_ps;
        let (mul, add, sub) = (_mm256_mul_ps, _mm256_add_ps, _mm256_sub_ps);
        let full = xo.len() == LANES;
        let (m, fixed) = if full {
            let (m, f) = (
                &g.inv_mass[base..base + LANES],
                &g.fixed[base..base + LANES],
            );
            // SAFETY: eight f32; eight `bool`s (a byte each, 0 or 1) widened to a lane each
            // and compared with 0 into the all-ones mask of a fixed node.
            unsafe {
                let f = _mm256_cvtepu8_epi32(_mm_loadl_epi64(f.as_ptr() as *const __m128i));
                let f = _mm256_cmpgt_epi32(f, _mm256_setzero_si256());
                (_mm256_loadu_ps(m.as_ptr()), _mm256_castsi256_ps(f))
            }
        } else {
            let mut inv_mass = [0.0f32; LANES];
            let mut fixed = [0i32; LANES];
            for l in 0..xo.len() {
                inv_mass[l] = g.inv_mass[base + l];
                fixed[l] = -(g.fixed[base + l] as i32);
            }
            // SAFETY: eight f32 and eight i32.
            unsafe {
                (
                    _mm256_loadu_ps(inv_mass.as_ptr()),
                    _mm256_castsi256_ps(_mm256_loadu_si256(fixed.as_ptr() as *const __m256i)),
                )
            }
        };
        // The new second state and the step, axis by axis, in the portable kernels' order.
        let mut s_new = [_mm256_setzero_ps(); 4];
        let mut step = [_mm256_setzero_ps(); 3];
        for c in 0..3 {
            let pull = add(mul(f[c], m), splat(p.gravity[c]));
            if VERLET {
                let a = sub(pull, mul(mul(splat(p.alpha), si[c]), splat(p.inv_h)));
                s_new[c] = add(si[c], mul(splat(p.h2), a));
                step[c] = s_new[c];
            } else {
                let a = sub(pull, mul(splat(p.alpha), si[c]));
                s_new[c] = add(si[c], mul(splat(p.h), a));
                step[c] = mul(splat(p.h), s_new[c]);
            }
        }
        // `kernels::advance`: the step plus what rounding lost last time, and what it loses now.
        let carried = decode(xi, si[3]);
        let mut x_new = [_mm256_setzero_ps(); 4];
        let mut lost = [_mm256_setzero_ps(); 3];
        for c in 0..3 {
            let t = add(step[c], carried[c]);
            let sum = add(xi[c], t);
            let bb = sub(sum, xi[c]);
            x_new[c] = sum;
            lost[c] = add(sub(xi[c], sub(sum, bb)), sub(t, bb));
        }
        (x_new[3], s_new[3]) = encode(&x_new, lost);
        // Fixed nodes keep their row and lose their second state.
        for c in 0..4 {
            x_new[c] = _mm256_blendv_ps(x_new[c], xi[c], fixed);
            s_new[c] = _mm256_andnot_ps(fixed, s_new[c]);
        }
        store_rows(x_new, xo);
        store_rows(s_new, so);
    }
}

/// `ulp(m) / 2^12` of each lane's displacement `u` (`m` its largest component), and the lanes
/// where that is a normal float32 (`physics::Compensation::unit`, lane by lane).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn unit(u: &[__m256; 4]) -> (__m256i, __m256) {
    let abs = |v: __m256| _mm256_andnot_ps(_mm256_set1_ps(-0.0), v);
    let m = _mm256_max_ps(_mm256_max_ps(abs(u[0]), abs(u[1])), abs(u[2]));
    let e = _mm256_srli_epi32::<23>(_mm256_castps_si256(m));
    // 23 + 12 = 35 < e < 255.
    let ok = _mm256_and_si256(
        _mm256_cmpgt_epi32(e, _mm256_set1_epi32(35)),
        _mm256_cmpgt_epi32(_mm256_set1_epi32(255), e),
    );
    let unit = _mm256_slli_epi32::<23>(_mm256_sub_epi32(e, _mm256_set1_epi32(35)));
    (unit, _mm256_castsi256_ps(ok))
}

/// `physics::Compensation::decode` lane by lane: the residuals stored in the `w` lanes of the
/// displacement `u` and of the second state (`second_w`).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn decode(u: &[__m256; 4], second_w: __m256) -> [__m256; 3] {
    let (unit, ok) = unit(u);
    let unit = _mm256_castsi256_ps(unit);
    let clamp = |v: __m256, lo: f32, hi: f32| {
        _mm256_min_ps(_mm256_max_ps(v, _mm256_set1_ps(lo)), _mm256_set1_ps(hi))
    };
    let packed = _mm256_cvttps_epi32(clamp(u[3], -8_388_608.0, 8_388_607.0));
    let qx = _mm256_sub_epi32(
        _mm256_and_si256(
            _mm256_add_epi32(packed, _mm256_set1_epi32(2048)),
            _mm256_set1_epi32(4095),
        ),
        _mm256_set1_epi32(2048),
    );
    let qy = _mm256_srai_epi32::<12>(_mm256_sub_epi32(packed, qx));
    let qz = _mm256_cvttps_epi32(clamp(second_w, -2047.0, 2047.0));
    [qx, qy, qz].map(|q| _mm256_and_ps(_mm256_mul_ps(_mm256_cvtepi32_ps(q), unit), ok))
}

/// `physics::Compensation::encode` lane by lane: the `w` lanes (displacement, second state)
/// that keep `lost` with displacement `u`.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn encode(u: &[__m256; 4], lost: [__m256; 3]) -> (__m256, __m256) {
    let (unit, ok) = unit(u);
    let inv = _mm256_castsi256_ps(_mm256_sub_epi32(_mm256_set1_epi32(254 << 23), unit));
    let q = lost.map(|e| {
        let r = _mm256_round_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(
            _mm256_mul_ps(e, inv),
        );
        _mm256_min_ps(
            _mm256_max_ps(r, _mm256_set1_ps(-2047.0)),
            _mm256_set1_ps(2047.0),
        )
    });
    let xw = _mm256_add_ps(q[0], _mm256_mul_ps(q[1], _mm256_set1_ps(4096.0)));
    (_mm256_and_ps(xw, ok), _mm256_and_ps(q[2], ok))
}

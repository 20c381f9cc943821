//! The fast engine's inner loops: the spring forces of a slice of nodes (`sliced.rs`), the
//! Verlet and symplectic Euler updates of a block of nodes (AVX2/FMA, or those and AVX-512,
//! where the processor has them, chosen at run time), and the parallel iteration over blocks.

use super::sliced::{group_force, Material, Sliced, LANES as SLICE, V3};
use super::*;

/// The instructions the explicit step's kernels use, from the fewest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Simd {
    /// Plain Rust, vectorised by the compiler as it can.
    Portable,
    /// AVX2 and FMA (`gather.rs`), each spring's scale from a division and a square root.
    Avx2,
    /// The AVX2 kernels with AVX-512F and VL besides: each spring's scale from the 14-bit
    /// reciprocal square root estimate and a Newton step (`gather::short_scale`), and 32
    /// vector registers.
    Avx512,
}

impl Simd {
    /// The most this CPU has.
    pub(super) fn best() -> Simd {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            if !(has!("avx2") && has!("fma")) {
                return Simd::Portable;
            }
            if has!("avx512f") && has!("avx512vl") {
                return Simd::Avx512;
            }
            Simd::Avx2
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            Simd::Portable
        }
    }

    /// Whether the AVX2 and FMA kernels run (the explicit step's, and the others').
    pub(super) fn wide(self) -> bool {
        self >= Simd::Avx2
    }
}

/// The block kernels for AVX2 and FMA, and for those with AVX-512F and VL: one code
/// (`gather::block`) compiled inside each with its target features.
#[cfg(target_arch = "x86_64")]
pub(super) mod wide {
    use super::{Graph, Params, Sliced, P};

    /// The block kernel of one set of target features: Verlet's where `VERLET`, symplectic
    /// Euler's otherwise (`s` the last steps or the velocities).
    macro_rules! block {
        ($features:literal, $short:literal, $name:ident) => {
            #[target_feature(enable = $features)]
            #[allow(clippy::too_many_arguments)]
            pub(in crate::engine::fast) fn $name<
                const DAMPED: bool,
                const UNIFORM: bool,
                const VERLET: bool,
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
                // SAFETY: this function's own features; the step checks the state's length.
                unsafe {
                    super::super::gather::block::<DAMPED, UNIFORM, VERLET, $short>(
                        g, sl, p, x, s, start, xo, so,
                    )
                }
            }
        };
    }

    block!("avx2,fma", false, block_avx2);
    block!("avx2,fma,avx512f,avx512vl", true, block_avx512);
}

/// Step the block from `start` with the kernels of `simd`: Verlet's where `VERLET`, symplectic
/// Euler's otherwise.
///
/// # Safety
/// `simd` at most what the CPU has ([`Simd::best`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn step_block<const DAMPED: bool, const UNIFORM: bool, const VERLET: bool>(
    simd: Simd,
    g: &Graph,
    sl: &Sliced,
    p: Params,
    x: &[P],
    s: &[P],
    start: usize,
    xo: &mut [P],
    so: &mut [P],
) {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: the caller's.
        unsafe {
            match simd {
                Simd::Avx512 => {
                    return wide::block_avx512::<DAMPED, UNIFORM, VERLET>(
                        g, sl, p, x, s, start, xo, so,
                    )
                }
                Simd::Avx2 => {
                    return wide::block_avx2::<DAMPED, UNIFORM, VERLET>(
                        g, sl, p, x, s, start, xo, so,
                    )
                }
                Simd::Portable => {}
            }
        }
    }
    let _ = simd;
    if VERLET {
        verlet_block::<DAMPED, UNIFORM>(g, sl, p, x, s, start, xo, so)
    } else {
        euler_block::<DAMPED, UNIFORM>(g, sl, p, x, s, start, xo, so)
    }
}

/// The spring forces on the nodes of slice `b` (eight lanes, one a node; lanes past the last
/// node hold nothing useful), on displacements `x` with damping on the second state `w` scaled
/// by `w_scale` (`1 / h` for Verlet's steps, 1 for velocities).
#[inline(always)]
fn slice_forces<const DAMPED: bool, const UNIFORM: bool>(
    sl: &Sliced,
    x: &[P],
    w: &[P],
    b: usize,
    w_scale: f32,
) -> V3 {
    let base = b * SLICE;
    let mut ui = [[0.0f32; SLICE]; 3];
    let mut wi = [[0.0f32; SLICE]; 3];
    for l in 0..SLICE.min(x.len() - base) {
        for a in 0..3 {
            ui[a][l] = x[base + l][a];
            if DAMPED {
                wi[a][l] = w[base + l][a];
            }
        }
    }
    let mut acc = [[0.0f32; SLICE]; 3];
    let [start, end] = sl.slices[b];
    // A uniform layout's constants, in every lane (the kernel reads lane 0).
    let u = sl
        .uniform
        .unwrap_or(super::sliced::Uniform { k: 0.0, c: 0.0 });
    let one = Material {
        rest: [0.0; SLICE],
        k: [u.k; SLICE],
    };
    let one_c = [u.c; SLICE];
    const NONE: [f32; SLICE] = [0.0; SLICE];
    for k in start as usize..end as usize {
        let (m, c) = if UNIFORM {
            (&one, &one_c)
        } else {
            (&sl.material[k], if DAMPED { &sl.damping[k] } else { &NONE })
        };
        group_force::<DAMPED, UNIFORM>(&sl.groups[k], m, c, x, w, &ui, &wi, w_scale, &mut acc);
    }
    acc
}

/// Verlet for nodes `start..` (`start` a multiple of the slice size), on displacements `x` and
/// last steps `d = x - x_prev`: `d+ = d + h^2 a(x, d / h)`, `x+ = x + d+` (compensated,
/// [`advance`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn verlet_block<const DAMPED: bool, const UNIFORM: bool>(
    g: &Graph,
    sl: &Sliced,
    p: Params,
    x: &[P],
    d: &[P],
    start: usize,
    xo: &mut [P],
    dout: &mut [P],
) {
    for (s, (xo, dout)) in xo.chunks_mut(SLICE).zip(dout.chunks_mut(SLICE)).enumerate() {
        let b = start / SLICE + s;
        let f = slice_forces::<DAMPED, UNIFORM>(sl, x, d, b, p.inv_h);
        for (l, (xo, dout)) in xo.iter_mut().zip(dout.iter_mut()).enumerate() {
            let i = b * SLICE + l;
            let (xi, di) = (x[i], d[i]);
            if g.fixed[i] {
                *xo = xi;
                *dout = [0.0; 4];
                continue;
            }
            let m = g.inv_mass[i];
            let mut step = [0.0f32; 3];
            for c in 0..3 {
                let a = f[c][l] * m + p.gravity[c] - p.alpha * di[c] * p.inv_h;
                dout[c] = di[c] + p.h2 * a;
                step[c] = dout[c];
            }
            advance(xi, di, step, xo, dout);
        }
    }
}

/// Symplectic Euler for nodes `start..` (`start` a multiple of the slice size):
/// `v+ = v + h a(u, v)`, `u+ = u + h v+` (compensated, [`advance`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn euler_block<const DAMPED: bool, const UNIFORM: bool>(
    g: &Graph,
    sl: &Sliced,
    p: Params,
    x: &[P],
    v: &[P],
    start: usize,
    xo: &mut [P],
    vo: &mut [P],
) {
    for (s, (xo, vo)) in xo.chunks_mut(SLICE).zip(vo.chunks_mut(SLICE)).enumerate() {
        let b = start / SLICE + s;
        let f = slice_forces::<DAMPED, UNIFORM>(sl, x, v, b, 1.0);
        for (l, (xo, vo)) in xo.iter_mut().zip(vo.iter_mut()).enumerate() {
            let i = b * SLICE + l;
            let (xi, vi) = (x[i], v[i]);
            if g.fixed[i] {
                *xo = xi;
                *vo = [0.0; 4];
                continue;
            }
            let m = g.inv_mass[i];
            let mut step = [0.0f32; 3];
            for c in 0..3 {
                let a = f[c][l] * m + p.gravity[c] - p.alpha * vi[c];
                vo[c] = vi[c] + p.h * a;
                step[c] = p.h * vo[c];
            }
            advance(xi, vi, step, xo, vo);
        }
    }
}

/// `xo = x + step` plus what rounding lost at the last step, and what it loses now, kept in
/// the `w` lanes of `xo` and `so` (the next second state), as `physics::integrate` does.
#[inline(always)]
pub(super) fn advance(x: P, second: P, step: [f32; 3], xo: &mut P, so: &mut P) {
    use crate::physics::Compensation;
    let carried = Compensation::decode(x, second);
    let mut lost = [0.0f32; 3];
    for c in 0..3 {
        let t = step[c] + carried[c];
        let s = x[c] + t;
        let bb = s - x[c];
        xo[c] = s;
        lost[c] = (x[c] - (s - bb)) + (t - bb);
    }
    (xo[3], so[3]) = Compensation::encode(*xo, lost);
}

/// Run `f(first node, block of a, block of b)` over blocks of two output buffers of the same
/// length, in parallel with the `parallel` feature.
pub(super) fn for_block_pairs(
    a: &mut [P],
    b: &mut [P],
    f: impl Fn(usize, &mut [P], &mut [P]) + Sync + Send,
) {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        // Every block a task of its own: rayon otherwise cuts the range into a few pieces a
        // thread and cuts further only what another thread steals, so a thread slowed by a
        // busy neighbour on its core (as the 2-core machine's are, from minute to minute)
        // holds a piece the other cannot share. 1-3% a step at 100k nodes there
        // (measurements.md, twelfth slice); the same bits either way.
        a.par_chunks_mut(BLOCK)
            .zip(b.par_chunks_mut(BLOCK))
            .enumerate()
            .with_max_len(1)
            .for_each(|(i, (ca, cb))| f(i * BLOCK, ca, cb));
    }
    #[cfg(not(feature = "parallel"))]
    for (i, (ca, cb)) in a.chunks_mut(BLOCK).zip(b.chunks_mut(BLOCK)).enumerate() {
        f(i * BLOCK, ca, cb);
    }
}

/// `x_j - x_i` from the rest edge vector and displacements `u`: the small displacement
/// difference is never rounded against the body's size.
#[inline(always)]
pub(super) fn spring_vector(edge: [f32; 3], ui: P, uj: P) -> [f32; 3] {
    [
        edge[0] + (uj[0] - ui[0]),
        edge[1] + (uj[1] - ui[1]),
        edge[2] + (uj[2] - ui[2]),
    ]
}

//! The fast engine's inner loops: the spring force of one adjacency entry, the Verlet and
//! symplectic Euler updates of a block of nodes (AVX2/FMA where the processor has them, chosen
//! at run time), and the parallel iteration over blocks.

use super::*;

/// The stored velocity of node `j` (symplectic Euler) or its last step, `h` times it (Verlet).
#[inline(always)]
pub(super) fn w_of<const DAMP: u8>(a: &[P], b: &[P], j: usize) -> [f32; 3] {
    let _ = b;
    [a[j][0], a[j][1], a[j][2]]
}

/// Total spring force on node `i` at displacements `x`: elastic `k (l - L) u` plus, when
/// damped, `c ((w_j - w_i) . u) u * w_scale` with `w` from [`w_of`]. Coincident nodes have no
/// direction and give nothing, as in the reference engine (their inverse length is set to 0,
/// which also makes the padding lanes of a partial chunk, with `k = c = 0`, contribute 0).
#[inline(always)]
pub(super) fn spring_force<const DAMP: u8>(
    g: &Graph,
    x: &[P],
    wa: &[P],
    wb: &[P],
    i: usize,
    w_scale: f32,
) -> [f32; 3] {
    let ui = x[i];
    let wi = w_of::<DAMP>(wa, wb, i);
    let mut acc = [[0.0f32; LANES]; 3];
    let first = g.rows[i][0] as usize;
    for (n, chunk) in g.row(i).chunks(LANES).enumerate() {
        let mut d = [[0.0f32; LANES]; 3];
        let mut dw = [[0.0f32; LANES]; 3];
        let (mut k, mut rest, mut c) = ([0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES]);
        for (l, e) in chunk.iter().enumerate() {
            let j = e.other as usize;
            let v = spring_vector(e.edge, ui, x[j]);
            (k[l], rest[l]) = (e.k, e.rest);
            if DAMP != UNDAMPED {
                c[l] = g.damping[first + n * LANES + l];
            }
            let wj = if DAMP != UNDAMPED {
                w_of::<DAMP>(wa, wb, j)
            } else {
                [0.0; 3]
            };
            for a in 0..3 {
                d[a][l] = v[a];
                dw[a][l] = wj[a] - wi[a];
            }
        }
        for l in 0..LANES {
            let l2 = d[0][l] * d[0][l] + d[1][l] * d[1][l] + d[2][l] * d[2][l];
            let inv_raw = 1.0 / l2.sqrt();
            let inv = if l2 > 0.0 { inv_raw } else { 0.0 };
            // Force magnitude over length: multiplies the unnormalised `d`.
            let mut s = k[l] * (1.0 - rest[l] * inv);
            if DAMP != UNDAMPED {
                let along = dw[0][l] * d[0][l] + dw[1][l] * d[1][l] + dw[2][l] * d[2][l];
                s += c[l] * along * w_scale * inv * inv;
            }
            for a in 0..3 {
                acc[a][l] += s * d[a][l];
            }
        }
    }
    acc.map(|lanes| lanes.iter().sum())
}

/// Whether the kernels may use AVX2 and FMA on this CPU.
pub(super) fn wide_simd() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The block kernels compiled for AVX2 and FMA: the same source, inlined into functions with
/// those target features, so the lane arrays become 256-bit vectors and fused multiply-adds.
#[cfg(target_arch = "x86_64")]
pub(super) mod wide {
    use super::{Graph, Params, P};

    #[target_feature(enable = "avx2,fma")]
    pub(in crate::engine::fast) fn verlet_block<const DAMPED: bool>(
        g: &Graph,
        p: Params,
        x: &[P],
        d: &[P],
        start: usize,
        xo: &mut [P],
        dout: &mut [P],
    ) {
        super::verlet_block::<DAMPED>(g, p, x, d, start, xo, dout)
    }

    #[target_feature(enable = "avx2,fma")]
    pub(in crate::engine::fast) fn euler_block<const DAMPED: bool>(
        g: &Graph,
        p: Params,
        x: &[P],
        v: &[P],
        start: usize,
        xo: &mut [P],
        vo: &mut [P],
    ) {
        super::euler_block::<DAMPED>(g, p, x, v, start, xo, vo)
    }
}

/// Verlet for nodes `start..`, on displacements `x` and last steps `d = x - x_prev`:
/// `d+ = d + h^2 a(x, d / h)`, `x+ = x + d+` (compensated, [`advance`]).
#[inline(always)]
pub(super) fn verlet_block<const DAMPED: bool>(
    g: &Graph,
    p: Params,
    x: &[P],
    d: &[P],
    start: usize,
    xo: &mut [P],
    dout: &mut [P],
) {
    for ((xo, dout), i) in xo.iter_mut().zip(dout.iter_mut()).zip(start..) {
        let (xi, di) = (x[i], d[i]);
        if g.fixed[i] {
            *xo = xi;
            *dout = [0.0; 4];
            continue;
        }
        // Spring damping reads each neighbour's velocity `d / h`: a kernel of its own; without
        // damping the plain one reads displacements only.
        let f = if DAMPED {
            spring_force::<DAMPED_VELOCITY>(g, x, d, d, i, p.inv_h)
        } else {
            spring_force::<UNDAMPED>(g, x, d, d, i, 0.0)
        };
        let m = g.inv_mass[i];
        let mut step = [0.0f32; 3];
        for c in 0..3 {
            let a = f[c] * m + p.gravity[c] - p.alpha * di[c] * p.inv_h;
            dout[c] = di[c] + p.h2 * a;
            step[c] = dout[c];
        }
        advance(xi, di, step, xo, dout);
    }
}

/// Symplectic Euler for nodes `start..`: `v+ = v + h a(u, v)`, `u+ = u + h v+` (compensated,
/// [`advance`]).
#[inline(always)]
pub(super) fn euler_block<const DAMPED: bool>(
    g: &Graph,
    p: Params,
    x: &[P],
    v: &[P],
    start: usize,
    xo: &mut [P],
    vo: &mut [P],
) {
    for ((xo, vo), i) in xo.iter_mut().zip(vo.iter_mut()).zip(start..) {
        let (xi, vi) = (x[i], v[i]);
        if g.fixed[i] {
            *xo = xi;
            *vo = [0.0; 4];
            continue;
        }
        let f = if DAMPED {
            spring_force::<DAMPED_VELOCITY>(g, x, v, v, i, 1.0)
        } else {
            spring_force::<UNDAMPED>(g, x, v, v, i, 1.0)
        };
        let m = g.inv_mass[i];
        let mut step = [0.0f32; 3];
        for c in 0..3 {
            let a = f[c] * m + p.gravity[c] - p.alpha * vi[c];
            vo[c] = vi[c] + p.h * a;
            step[c] = p.h * vo[c];
        }
        advance(xi, vi, step, xo, vo);
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
        a.par_chunks_mut(BLOCK)
            .zip(b.par_chunks_mut(BLOCK))
            .enumerate()
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

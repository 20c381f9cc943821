//! Linearised backward Euler on the fast engine: the float32 twin of
//! [`crate::physics::BackwardEuler`] over the engine's own adjacency rows.
//!
//! A step solves, on the free nodes, the float64 integrator's equations
//!
//! ```text
//! ((1 + h alpha) M - h D - h^2 K) dv = h (F(u, v) + h K v),   v+ = v + dv,   u+ = u + h v+
//! ```
//!
//! (`F` the springs' force with their damping, plus gravity and the mass damping
//! `-alpha M v`; `K`, `D` the springs' stiffness and damping derivatives at `u`, with the same
//! [`Linearization`]; fixed nodes projected out) by conjugate gradients preconditioned with the
//! inverse 3x3 diagonal blocks (block Jacobi), with the same tolerance, cap and further Newton
//! iterations ([`SolverSettings`]).
//!
//! Once per linearisation every node walks its adjacency row and forms each spring's symmetric
//! 3x3 block `S = h c u u^T + h^2 k (u u^T + t (I - u u^T))` (the float32 twin of
//! [`crate::physics::spring_stiffness_block`], `t = 1 - L/l` clamped at zero by
//! [`Linearization::Definite`], plus the spring's damping), its force, `K v` and its diagonal
//! block `(1 + h alpha) m I + sum S` in the same walk. The blocks are kept beside the row, at
//! the entry's index, with the other end's index (28 bytes an entry): a product
//! `A w_i = A_ii w_i - sum_j S_ij w_j` then streams them once, nothing is assembled into a
//! global matrix, and a cut's patched rows are simply walked again at the next step. (A
//! product that recomputed each block from the geometry would read the 32-byte entry, its
//! damping and both ends' displacements and take a square root and a division per spring, in
//! every one of the tens of iterations that share one geometry.) The two ends of a spring see
//! exactly opposite spring vectors, so `S_ij = S_ji` bit for bit and the system is symmetric.
//!
//! Determinism: every dot product is summed in float64, node by node within blocks of
//! [`BLOCK`] nodes and then block by block in block order, so that one thread and many give
//! the same bits. Nothing is allocated per step or per iteration: the scratch keeps room like
//! the engine's own arrays and grows only when a cut adds past it.

use super::kernels::spring_vector;
use super::{FastEngine, Graph, Params, BLOCK, P};
use crate::model::room::spare;
use crate::physics::{Linearization, SolverSettings, SolverStats};

/// A symmetric 3x3 matrix as `[xx, yy, zz, xy, xz, yz]`.
type Sym = [f32; 6];

/// One adjacency entry's block of the system, with the entry's other end.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C)]
struct Block {
    s: Sym,
    other: u32,
}

/// A node's diagonal block, its inverse (the preconditioner) and its right-hand side.
#[derive(Debug, Clone, Copy, Default)]
struct NodeSystem {
    diag: Sym,
    inverse: Sym,
    b: P,
}

/// A node's solution, residual and preconditioned residual in the conjugate gradients.
#[derive(Debug, Clone, Copy, Default)]
struct Iterate {
    y: P,
    r: P,
    z: P,
}

/// The implicit step's settings, statistics and scratch.
pub(super) struct Implicit {
    settings: SolverSettings,
    stats: SolverStats,
    /// Indexed like the adjacency: the block of each live entry (holes are never read).
    blocks: Vec<Block>,
    nodes: Vec<NodeSystem>,
    cg: Vec<Iterate>,
    /// The search direction, gathered by neighbours: kept apart so a gather reads 16 bytes.
    p: Vec<P>,
    ap: Vec<P>,
    /// The velocity change over the Newton iterations so far.
    dv: Vec<P>,
    /// The Newton iterate's displacements and velocities (used from the second iteration).
    xk: Vec<P>,
    vk: Vec<P>,
    /// Per block of nodes: the two float64 partial sums of the pass that just ran.
    partials: Vec<[f64; 2]>,
}

impl Implicit {
    /// Scratch for `nodes` nodes and `entries` adjacency entries, with room for cuts.
    pub(super) fn new(settings: SolverSettings, nodes: usize, entries: usize) -> Self {
        fn room<T: Default + Clone>(n: usize) -> Vec<T> {
            let mut v = Vec::with_capacity(n + spare(n));
            v.resize(n, T::default());
            v
        }
        Implicit {
            settings,
            stats: SolverStats::default(),
            blocks: room(entries),
            nodes: room(nodes),
            cg: room(nodes),
            p: room(nodes),
            ap: room(nodes),
            dv: room(nodes),
            xk: room(nodes),
            vk: room(nodes),
            partials: room(nodes.div_ceil(BLOCK)),
        }
    }

    /// What the solver did so far.
    pub(super) fn stats(&self) -> SolverStats {
        self.stats
    }

    /// The scratch arrays and their bytes, for [`crate::engine::Engine::memory`].
    pub(super) fn buffers(&self) -> Vec<(String, u64)> {
        let n = self.nodes.len() as u64;
        let p = std::mem::size_of::<P>() as u64;
        vec![
            (
                "implicit: spring blocks".to_string(),
                self.blocks.len() as u64 * std::mem::size_of::<Block>() as u64,
            ),
            (
                "implicit: diagonal blocks and right-hand side".to_string(),
                n * std::mem::size_of::<NodeSystem>() as u64,
            ),
            (
                "implicit: solver vectors (y, r, z, p, Ap, dv, Newton iterate)".to_string(),
                n * (std::mem::size_of::<Iterate>() as u64 + 6 * p),
            ),
        ]
    }

    /// The bytes one conjugate-gradient iteration streams at least: the blocks of the live
    /// entries, each node's diagonal block and preconditioner, and the vectors read and written
    /// (p and Ap in the product, y, r, z, p and Ap in the update, z and p in the direction).
    pub(super) fn bytes_per_iteration(&self, live_entries: usize) -> u64 {
        let n = self.nodes.len() as u64;
        let p = std::mem::size_of::<P>() as u64;
        let sym = std::mem::size_of::<Sym>() as u64;
        live_entries as u64 * std::mem::size_of::<Block>() as u64
            + n * (sym + 2 * p)
            + n * (sym + 2 * std::mem::size_of::<Iterate>() as u64 + 2 * p)
            + n * 3 * p
    }

    /// Size the scratch to `n` nodes and `entries` adjacency entries: only after a cut, and
    /// within the room kept unless the cut added more.
    fn fit(&mut self, n: usize, entries: usize) {
        if self.nodes.len() != n || self.blocks.len() != entries {
            self.blocks.resize(entries, Block::default());
            for v in [
                &mut self.p,
                &mut self.ap,
                &mut self.dv,
                &mut self.xk,
                &mut self.vk,
            ] {
                v.resize(n, [0.0; 4]);
            }
            self.nodes.resize(n, NodeSystem::default());
            self.cg.resize(n, Iterate::default());
            self.partials.resize(n.div_ceil(BLOCK), [0.0; 2]);
        }
    }

    fn record(&mut self, (iterations, residual): (u32, f64)) {
        let s = &mut self.stats;
        s.solves += 1;
        s.iterations += iterations as u64;
        s.max_iterations = s.max_iterations.max(iterations);
        s.last_residual = residual;
        if residual > self.settings.tolerance {
            s.capped += 1;
        }
    }
}

impl FastEngine {
    /// One linearised backward Euler step (and any further Newton iterations).
    pub(super) fn step_backward_euler(&mut self) {
        let n = self.x.len();
        let Some(imp) = self.implicit.as_mut() else {
            unreachable!("an engine built for backward Euler has its solver scratch");
        };
        imp.fit(n, self.graph.adj.len());
        let (g, params) = (&self.graph, self.params);
        let settings = imp.settings;
        // The first iterate is Baraff and Witkin's: linearised at the start of the step.
        assemble(
            imp,
            g,
            params,
            settings.linearization,
            Lin::Start(&self.x, &self.second),
        );
        let result = solve(imp, g, settings);
        imp.record(result);
        update_dv(imp, params, &self.x, &self.second, true);
        for _ in 1..settings.newton_iterations.max(1) {
            // Newton on `g(y) = M (y - v) - h F(u + h y, y)` at `y = v + dv`.
            assemble(imp, g, params, settings.linearization, Lin::Iterate);
            let result = solve(imp, g, settings);
            imp.record(result);
            update_dv(imp, params, &self.x, &self.second, false);
        }
        let dv = &imp.dv;
        let h = params.h;
        for_pairs(&mut self.x, &mut self.second, |start, xs, vs| {
            for (k, (x, v)) in xs.iter_mut().zip(vs.iter_mut()).enumerate() {
                let i = start + k;
                if g.fixed[i] {
                    *v = [0.0; 4];
                    continue;
                }
                for c in 0..3 {
                    v[c] += dv[i][c];
                    x[c] += h * v[c];
                }
            }
        });
    }

    /// The bytes one conjugate-gradient iteration of backward Euler streams at least (the
    /// spring blocks of the live adjacency entries, the diagonal blocks and the solver
    /// vectors it reads and writes); `None` for the explicit schemes. Set beside
    /// [`crate::engine::EngineMemory::bytes_per_step`], which counts the explicit step's.
    pub fn bytes_per_cg_iteration(&self) -> Option<u64> {
        let live = self.graph.adj.len() - self.graph.holes;
        self.implicit.as_ref().map(|i| i.bytes_per_iteration(live))
    }

    /// What the implicit solver did so far (`None` for the explicit schemes).
    pub(super) fn implicit_stats(&self) -> Option<SolverStats> {
        self.implicit.as_ref().map(Implicit::stats)
    }
}

/// Where the system is linearised: at the step's start `(u, v)` (right-hand side
/// `h (F + h K v)`), or at the Newton iterate `(xk, vk)` kept in the scratch (right-hand side
/// `h F(xk, vk) - M dv`).
#[derive(Clone, Copy)]
enum Lin<'a> {
    Start(&'a [P], &'a [P]),
    Iterate,
}

/// Form every free node's spring blocks, diagonal block, preconditioner and right-hand side.
fn assemble(imp: &mut Implicit, g: &Graph, p: Params, lin: Linearization, at: Lin) {
    let (x, v, newton) = match at {
        Lin::Start(x, v) => (x, v, None),
        Lin::Iterate => (&imp.xk[..], &imp.vk[..], Some(&imp.dv[..])),
    };
    let blocks = SharedBlocks(imp.blocks.as_mut_ptr(), imp.blocks.len());
    let damped = !g.damping.is_empty();
    let (h, h2) = (p.h, p.h * p.h);
    let definite = lin == Linearization::Definite;
    over_blocks(&mut imp.nodes, &mut imp.partials, |start, out| {
        for (k, node) in out.iter_mut().enumerate() {
            let i = start + k;
            if g.fixed[i] {
                *node = NodeSystem {
                    diag: IDENTITY,
                    inverse: IDENTITY,
                    b: [0.0; 4],
                };
                continue;
            }
            let [first, end] = g.rows[i];
            // SAFETY: rows are disjoint ranges of the adjacency (a patch moves a row, leaving
            // a hole, and never shares entries), and node `i`'s row is written only here, by
            // the one task that owns node `i`.
            let row_blocks = unsafe { blocks.row(first as usize, end as usize) };
            let (xi, vi) = (x[i], v[i]);
            let (mut f, mut kv, mut sum) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 6]);
            for (e_at, (e, out)) in g.row(i).iter().zip(row_blocks.iter_mut()).enumerate() {
                let j = e.other as usize;
                let d = spring_vector(e.edge, xi, x[j]);
                let l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if l2 <= 0.0 {
                    // No direction: no force and no block, as in the float64 model.
                    *out = Block {
                        s: [0.0; 6],
                        other: e.other,
                    };
                    continue;
                }
                let inv = 1.0 / l2.sqrt();
                let u = [d[0] * inv, d[1] * inv, d[2] * inv];
                let c = if damped {
                    g.damping[first as usize + e_at]
                } else {
                    0.0
                };
                let dvel = [0, 1, 2].map(|a| v[j][a] - vi[a]);
                let along = dvel[0] * u[0] + dvel[1] * u[1] + dvel[2] * u[2];
                // Tension over stiffness, `1 - L/l`: the elastic force is `k t d`.
                let t = 1.0 - e.rest * inv;
                let tc = if definite { t.max(0.0) } else { t };
                for a in 0..3 {
                    f[a] += e.k * t * d[a] + c * along * u[a];
                    kv[a] += e.k * ((1.0 - tc) * along * u[a] + tc * dvel[a]);
                }
                let (a, b) = (h * c + h2 * e.k * (1.0 - tc), h2 * e.k * tc);
                let s = [
                    a * u[0] * u[0] + b,
                    a * u[1] * u[1] + b,
                    a * u[2] * u[2] + b,
                    a * u[0] * u[1],
                    a * u[0] * u[2],
                    a * u[1] * u[2],
                ];
                for (acc, s) in sum.iter_mut().zip(s) {
                    *acc += s;
                }
                *out = Block { s, other: e.other };
            }
            let m = 1.0 / g.inv_mass[i];
            let mh = (1.0 + h * p.alpha) * m;
            let mut diag = sum;
            for d in &mut diag[..3] {
                *d += mh;
            }
            let mut b = [0.0f32; 4];
            for a in 0..3 {
                let total = f[a] + m * p.gravity[a] - p.alpha * m * vi[a];
                b[a] = match newton {
                    None => h * (total + h * kv[a]),
                    Some(dv) => h * total - m * dv[i][a],
                };
            }
            *node = NodeSystem {
                diag,
                inverse: inverse(&diag),
                b,
            };
        }
        [0.0; 2]
    });
}

/// Solve `A y = b` from `y = 0` by preconditioned conjugate gradients, as the float64
/// integrator does; the iterations and the final relative residual.
fn solve(imp: &mut Implicit, g: &Graph, settings: SolverSettings) -> (u32, f64) {
    let Implicit {
        blocks,
        nodes,
        cg,
        p,
        ap,
        partials,
        ..
    } = imp;
    let nodes = &nodes[..];
    // y = 0, r = b, z = P r.
    let [bb, mut rz] = over_blocks(cg, partials, |start, out| {
        let mut sums = [0.0f64; 2];
        for (k, it) in out.iter_mut().enumerate() {
            let s = &nodes[start + k];
            let z = sym_mul(&s.inverse, s.b);
            *it = Iterate {
                y: [0.0; 4],
                r: s.b,
                z: [z[0], z[1], z[2], 0.0],
            };
            sums[0] += dot64(s.b, s.b);
            sums[1] += dot64(s.b, it.z);
        }
        sums
    });
    if bb == 0.0 {
        return (0, 0.0);
    }
    let b_norm = bb.sqrt();
    direction(p, cg, partials, None);
    let mut residual = 1.0;
    for iteration in 1..=settings.max_iterations {
        let [pap, _] = product(g, blocks, nodes, p, ap, partials);
        if pap <= 0.0 {
            // Not positive definite along `p` (an exact linearisation under compression):
            // stop with what has been reached, as the float64 integrator does.
            return (iteration, residual);
        }
        let alpha = (rz / pap) as f32;
        let [rr, rz_next] = advance(cg, partials, nodes, p, ap, alpha);
        residual = rr.sqrt() / b_norm;
        if residual <= settings.tolerance {
            return (iteration, residual);
        }
        let beta = (rz_next / rz) as f32;
        rz = rz_next;
        direction(p, cg, partials, Some(beta));
    }
    (settings.max_iterations, residual)
}

/// `y += alpha p`, `r -= alpha Ap`, `z = P r`; returns `(r . r, r . z)`.
fn advance(
    cg: &mut [Iterate],
    partials: &mut [[f64; 2]],
    nodes: &[NodeSystem],
    p: &[P],
    ap: &[P],
    alpha: f32,
) -> [f64; 2] {
    over_blocks(cg, partials, |start, out| {
        let mut sums = [0.0f64; 2];
        for (k, it) in out.iter_mut().enumerate() {
            let i = start + k;
            for c in 0..3 {
                it.y[c] += alpha * p[i][c];
                it.r[c] -= alpha * ap[i][c];
            }
            let z = sym_mul(&nodes[i].inverse, it.r);
            it.z = [z[0], z[1], z[2], 0.0];
            sums[0] += dot64(it.r, it.r);
            sums[1] += dot64(it.r, it.z);
        }
        sums
    })
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
/// side is zero and their preconditioner the identity); returns `(p . Ap, 0)`.
fn product(
    g: &Graph,
    blocks: &[Block],
    nodes: &[NodeSystem],
    p: &[P],
    ap: &mut [P],
    partials: &mut [[f64; 2]],
) -> [f64; 2] {
    over_blocks(ap, partials, |start, out| {
        let mut sum = 0.0f64;
        for (k, o) in out.iter_mut().enumerate() {
            let i = start + k;
            if g.fixed[i] {
                *o = [0.0; 4];
                continue;
            }
            let [first, end] = g.rows[i];
            // The row is read through the blocks' own `other`: 28 bytes an entry, the graph's
            // 32-byte entries are not touched.
            let mut acc = sym_mul(&nodes[i].diag, p[i]);
            for b in &blocks[first as usize..end as usize] {
                let q = sym_mul(&b.s, p[b.other as usize]);
                for c in 0..3 {
                    acc[c] -= q[c];
                }
            }
            *o = [acc[0], acc[1], acc[2], 0.0];
            sum += dot64(p[i], *o);
        }
        [sum, 0.0]
    })
}

/// After a solve: `dv = y` (the first) or `dv += y`; where more Newton iterations follow, the
/// iterate `vk = v + dv`, `xk = u + h vk` too (fixed nodes stay at rest).
fn update_dv(imp: &mut Implicit, p: Params, x: &[P], v: &[P], first: bool) {
    let newton = imp.settings.newton_iterations > 1;
    let Implicit {
        cg,
        dv,
        xk,
        vk,
        partials,
        ..
    } = imp;
    let cg = &cg[..];
    over_blocks(dv, partials, |start, out| {
        for (k, d) in out.iter_mut().enumerate() {
            let y = cg[start + k].y;
            *d = if first {
                y
            } else {
                [0, 1, 2, 3].map(|c| d[c] + y[c])
            };
        }
        [0.0; 2]
    });
    if newton {
        let dv = &dv[..];
        for_pairs(xk, vk, |start, xs, vs| {
            for (k, (xo, vo)) in xs.iter_mut().zip(vs.iter_mut()).enumerate() {
                let i = start + k;
                *vo = [0, 1, 2, 3].map(|c| v[i][c] + dv[i][c]);
                *xo = [0, 1, 2, 3].map(|c| x[i][c] + p.h * vo[c]);
            }
        });
    }
}

/// Run `f(first node, block)` over blocks of [`BLOCK`] nodes of `out` (in parallel with the
/// `parallel` feature), each returning two partial sums; returns their sums taken in block
/// order, the same whatever the number of threads.
fn over_blocks<T: Send>(
    out: &mut [T],
    partials: &mut [[f64; 2]],
    f: impl Fn(usize, &mut [T]) -> [f64; 2] + Sync + Send,
) -> [f64; 2] {
    let blocks = out.len().div_ceil(BLOCK);
    let partials = &mut partials[..blocks];
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        out.par_chunks_mut(BLOCK)
            .zip(partials.par_iter_mut())
            .enumerate()
            .for_each(|(b, (chunk, part))| *part = f(b * BLOCK, chunk));
    }
    #[cfg(not(feature = "parallel"))]
    for (b, (chunk, part)) in out.chunks_mut(BLOCK).zip(partials.iter_mut()).enumerate() {
        *part = f(b * BLOCK, chunk);
    }
    partials
        .iter()
        .fold([0.0; 2], |acc, p| [acc[0] + p[0], acc[1] + p[1]])
}

/// Like [`over_blocks`] over two arrays of the same length, with nothing summed.
fn for_pairs(a: &mut [P], b: &mut [P], f: impl Fn(usize, &mut [P], &mut [P]) + Sync + Send) {
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

/// The blocks array, written row by row from the assembly's tasks.
#[derive(Clone, Copy)]
struct SharedBlocks(*mut Block, usize);

// SAFETY: the pointer is only used to write disjoint rows (see `SharedBlocks::row`), while the
// `Vec` it points into is borrowed mutably by the assembly and not otherwise touched.
unsafe impl Send for SharedBlocks {}
unsafe impl Sync for SharedBlocks {}

impl SharedBlocks {
    /// The blocks `first..end`.
    ///
    /// # Safety
    /// No two live calls may have overlapping ranges, and `first <= end <= len`.
    #[allow(clippy::mut_from_ref)]
    unsafe fn row(&self, first: usize, end: usize) -> &mut [Block] {
        assert!(first <= end && end <= self.1, "a row past the adjacency");
        std::slice::from_raw_parts_mut(self.0.add(first), end - first)
    }
}

const IDENTITY: Sym = [1.0, 1.0, 1.0, 0.0, 0.0, 0.0];

/// `s w` for the symmetric `s`.
#[inline(always)]
fn sym_mul(s: &Sym, w: P) -> [f32; 3] {
    [
        s[0] * w[0] + s[3] * w[1] + s[4] * w[2],
        s[3] * w[0] + s[1] * w[1] + s[5] * w[2],
        s[4] * w[0] + s[5] * w[1] + s[2] * w[2],
    ]
}

/// `a . b` over three components, in float64.
#[inline(always)]
fn dot64(a: P, b: P) -> f64 {
    a[0] as f64 * b[0] as f64 + a[1] as f64 * b[1] as f64 + a[2] as f64 * b[2] as f64
}

/// The inverse of a symmetric block, formed in float64; the identity where it is singular (a
/// massless node with no springs), as the float64 integrator does.
fn inverse(s: &Sym) -> Sym {
    let [a, b, c, d, e, f] = s.map(|v| v as f64);
    let cof = [
        b * c - f * f,
        a * c - e * e,
        a * b - d * d,
        e * f - d * c,
        d * f - b * e,
        d * e - a * f,
    ];
    let det = a * cof[0] + d * cof[3] + e * cof[4];
    if det == 0.0 || !det.is_finite() {
        return IDENTITY;
    }
    cof.map(|v| (v / det) as f32)
}

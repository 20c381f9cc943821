//! Linearised backward Euler on the fast engine: the float32 twin of
//! [`crate::physics::BackwardEuler`] over the engine's own spring rows (read out of the sliced
//! layout, `sliced.rs`).
//!
//! A step solves, on the free nodes, the float64 integrator's equations
//!
//! ```text
//! ((1 + h alpha) M - h D - h^2 K) dv = h (F(u, v) + h K v),   v+ = v + dv,   u+ = u + h v+
//! ```
//!
//! (`F` the springs' force with their damping, plus gravity and the mass damping
//! `-alpha M v`; `K`, `D` the springs' stiffness and damping derivatives at `u`, with the same
//! [`Linearization`]; fixed nodes projected out) by conjugate gradients with the same tolerance,
//! cap and further Newton iterations ([`SolverSettings`]), started from the last step's velocity
//! change ([`SolverSettings::warm_start`]) and preconditioned by one symmetric Gauss-Seidel
//! sweep within each block of [`BLOCK`] nodes ([`Preconditioner::SymmetricGaussSeidel`](crate::physics::Preconditioner::SymmetricGaussSeidel), the
//! default here) or by the inverse 3x3 diagonal blocks (block Jacobi, as the float64 integrator).
//! The sweep reads the spring blocks the product reads and nothing else: a cut's patched rows
//! need no refactorisation and no recolouring, and the blocks are independent of each other, so
//! any number of threads gives the same bits.
//!
//! Once per linearisation every node walks its spring row and forms each spring's symmetric
//! 3x3 block `S = h c u u^T + h^2 k (u u^T + t (I - u u^T))` (the float32 twin of
//! [`crate::physics::spring_stiffness_block`], `t = 1 - L/l` clamped at zero by
//! [`Linearization::Definite`], plus the spring's damping), its force, `K v` and its diagonal
//! block `(1 + h alpha) m I + sum S` in the same walk. The blocks are kept twice: lane by lane
//! beside the sliced springs' groups (24 bytes an entry, padding included), which the product
//! `A w_i = A_ii w_i - sum_j S_ij w_j` streams eight nodes at a time (`implicit_sliced.rs`),
//! and row by row, the rows laid end to end without padding (the Gauss-Seidel sweep's lower
//! part first in each row, each block with the other end's index, 28 bytes an entry), which
//! the sweep reads node after node. Nothing is assembled into a global matrix, and a cut's
//! patched rows are simply walked again at the next step. (A
//! product that recomputed each block from the geometry would read the 24-byte spring end, its
//! damping and both ends' displacements and take a square root and a division per spring, in
//! every one of the tens of iterations that share one geometry.) The two ends of a spring see
//! exactly opposite spring vectors, so `S_ij = S_ji` bit for bit and the system is symmetric.
//!
//! Nodes a tool holds are filtered out of the solve along the tool's normal as the float64
//! integrator filters them (`implicit_contact.rs`), and each constraint's force is read from
//! the impulse the filter removed.
//!
//! Determinism: every dot product is summed in float64, node by node within blocks of
//! [`BLOCK`] nodes and then block by block in block order, so that one thread and many give
//! the same bits. Nothing is allocated per step or per iteration: the scratch keeps room like
//! the engine's own arrays and grows only when a cut adds past it.

use super::kernels::spring_vector;
use super::{sliced, FastEngine, Graph, Params, BLOCK, P};
use crate::model::room::spare;
use crate::physics::{Linearization, SolverSettings, SolverStats};
pub(in crate::engine::fast) use contact::Held;
use contact::{constrain, impulses};

#[path = "implicit_contact.rs"]
mod contact;
#[cfg(feature = "factor")]
#[path = "implicit_factor.rs"]
mod factor;
#[cfg(not(feature = "factor"))]
#[path = "implicit_factor_off.rs"]
mod factor;
use factor::Factor;
#[path = "implicit_elements.rs"]
mod element_system;
#[path = "implicit_sliced.rs"]
mod laned;
use laned::{Lanes, SharedLanes};
#[path = "implicit_cg.rs"]
mod cg;
use cg::{product, solve};
#[path = "implicit_passes.rs"]
mod passes;
#[path = "implicit_rows.rs"]
mod rows;
use passes::{for_pairs, over_blocks};
use rows::{dot64, node_system, rows_of, sym_mul, SharedRows, IDENTITY};

/// A symmetric 3x3 matrix as `[xx, yy, zz, xy, xz, yz]`.
type Sym = [f32; 6];

/// One adjacency entry's block of the system, with the entry's other end.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C)]
struct Block {
    s: Sym,
    other: u32,
}

/// One adjacency entry's block of a finite-element system in full, `B_ij = -A_ij` (a tet's
/// blocks are not symmetric one by one: `B_ji = B_ij^T`), row major, with the entry's other
/// end (40 bytes an entry).
#[derive(Debug, Clone, Copy, Default)]
#[repr(C)]
pub(in crate::engine::fast) struct FullBlock {
    pub(in crate::engine::fast) m: [f32; 9],
    pub(in crate::engine::fast) other: u32,
}

/// A node's diagonal block, its inverse (the preconditioner) and its right-hand side.
#[derive(Debug, Clone, Copy, Default)]
struct NodeSystem {
    diag: Sym,
    inverse: Sym,
    b: P,
    /// How many of the row's blocks, first in the row, couple the node to an earlier node of
    /// its own block of [`BLOCK`] nodes: the symmetric Gauss-Seidel sweep's lower part (the
    /// rest of the row holds the upper part and the couplings to other blocks).
    lower: u32,
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
    /// Node `i`'s blocks are `blocks[starts[i]..starts[i + 1]]`: the rows of the sliced
    /// springs laid end to end without padding, formed again at each step (a cut may have
    /// changed any row's length).
    starts: Vec<u32>,
    /// Row by row: each spring end's block, the row's lower part first (springs only).
    blocks: Vec<Block>,
    /// Row by row: each adjacency entry's block in full, the row's lower part first (finite
    /// elements only, see `implicit_elements.rs`).
    full: Vec<FullBlock>,
    /// Whether the system is the finite elements' (`full`) rather than the springs'.
    elements: bool,
    /// The same blocks lane by lane beside the sliced springs' groups, for the product
    /// (`implicit_sliced.rs`).
    lanes: Vec<Lanes>,
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
    /// The nodes held on tools' planes, and the constraints' forces.
    pub(super) held: Held,
    /// Whether the CPU has AVX2 and FMA and the engine uses them (`FastEngine::wide`).
    wide: bool,
    /// The sparse Cholesky factor of [`Preconditioner::Factored`](crate::physics::Preconditioner::Factored), once taken.
    factor: Option<Factor>,
}

impl Implicit {
    /// Scratch for `nodes` nodes, `entries` adjacency entries and `groups` groups of the sliced
    /// springs, with room for cuts.
    pub(super) fn new(
        settings: SolverSettings,
        nodes: usize,
        entries: usize,
        groups: usize,
    ) -> Self {
        fn room<T: Default + Clone>(n: usize) -> Vec<T> {
            let mut v = Vec::with_capacity(n + spare(n));
            v.resize(n, T::default());
            v
        }
        Implicit {
            settings,
            stats: SolverStats::default(),
            starts: room(nodes + 1),
            blocks: room(entries),
            full: Vec::new(),
            elements: false,
            lanes: room(groups),
            nodes: room(nodes),
            cg: room(nodes),
            p: room(nodes),
            ap: room(nodes),
            dv: room(nodes),
            xk: room(nodes),
            vk: room(nodes),
            partials: room(nodes.div_ceil(BLOCK)),
            held: Held::default(),
            wide: false,
            factor: None,
        }
    }

    /// Solve the finite elements' system (their 3x3 blocks in full) instead of the springs'.
    pub(super) fn for_elements(&mut self) {
        let entries = self.blocks.len();
        self.blocks = Vec::new();
        self.full = Vec::with_capacity(entries + spare(entries));
        self.full.resize(entries, FullBlock::default());
        self.lanes = Vec::new();
        self.elements = true;
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
            if self.elements {
                (
                    "implicit: element blocks".to_string(),
                    self.full.len() as u64 * std::mem::size_of::<FullBlock>() as u64,
                )
            } else {
                (
                    "implicit: spring blocks".to_string(),
                    self.blocks.len() as u64 * std::mem::size_of::<Block>() as u64,
                )
            },
            (
                "implicit: spring blocks, lane by lane".to_string(),
                self.lanes.len() as u64 * std::mem::size_of::<Lanes>() as u64,
            ),
            (
                "implicit: row starts".to_string(),
                self.starts.len() as u64 * 4,
            ),
            (
                "implicit: diagonal blocks and right-hand side".to_string(),
                n * std::mem::size_of::<NodeSystem>() as u64,
            ),
            (
                "implicit: solver vectors (y, r, z, p, Ap, dv, Newton iterate)".to_string(),
                n * (std::mem::size_of::<Iterate>() as u64 + 6 * p),
            ),
            (
                "implicit: sparse Cholesky factor".to_string(),
                self.factor.as_ref().map_or(0, Factor::bytes),
            ),
        ]
    }

    /// The bytes one block-Jacobi conjugate-gradient iteration streams at least: the product's
    /// lane-by-lane blocks and neighbour indices over `slots` spring-end slots (padding
    /// included; the finite elements' full blocks of the `live_entries` instead), each node's diagonal block and preconditioner, and the vectors read and
    /// written (p and Ap in the product, y, r, z, p and Ap in the update, z and p in the
    /// direction). The Gauss-Seidel sweep reads the row-wise blocks once more.
    pub(super) fn bytes_per_iteration(&self, slots: usize, live_entries: usize) -> u64 {
        let n = self.nodes.len() as u64;
        let p = std::mem::size_of::<P>() as u64;
        let sym = std::mem::size_of::<Sym>() as u64;
        let entries = if self.elements {
            live_entries as u64 * std::mem::size_of::<FullBlock>() as u64
        } else {
            slots as u64 * (sym + 4)
        };
        entries
            + n * (sym + 2 * p)
            + n * (sym + 2 * std::mem::size_of::<Iterate>() as u64 + 2 * p)
            + n * 3 * p
    }

    /// Lay the rows of `g` end to end and size the scratch to its nodes and spring ends: the
    /// sizes change only after a cut, and within the room kept unless the cut added more.
    fn fit(&mut self, g: &Graph) {
        let n = g.springs.nodes();
        self.starts.resize(n + 1, 0);
        let mut at = 0u32;
        for i in 0..n {
            self.starts[i] = at;
            at += g.springs.len(i) as u32;
        }
        self.starts[n] = at;
        let entries = at as usize;
        if !self.elements {
            self.lanes
                .resize(g.springs.groups.len(), [[0.0; sliced::LANES]; 6]);
        }
        let stored = if self.elements {
            self.full.len()
        } else {
            self.blocks.len()
        };
        if self.nodes.len() != n || stored != entries {
            if self.elements {
                self.full.resize(entries, FullBlock::default());
            } else {
                self.blocks.resize(entries, Block::default());
            }
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
        let Some(imp) = self.implicit.as_mut() else {
            unreachable!("an engine built for backward Euler has its solver scratch");
        };
        imp.fit(&self.graph);
        imp.wide = self.simd.wide();
        let (g, params) = (&self.graph, self.params);
        let settings = imp.settings;
        let mut fem = self.elements.as_mut();
        // The first iterate is Baraff and Witkin's: linearised at the start of the step, and
        // started from the last step's velocity change (still in `dv`) with a warm start.
        let bb = match fem.as_deref_mut() {
            Some(fem) => {
                element_system::assemble(imp, g, params, fem, Lin::Start(&self.x, &self.second))
            }
            None => assemble(
                imp,
                g,
                params,
                settings.linearization,
                Lin::Start(&self.x, &self.second),
            ),
        };
        let bb = constrain(imp, g, params, Some((&self.x, &self.second)), bb);
        let result = solve(imp, g, settings, bb, settings.warm_start);
        imp.record(result);
        if let Some(f) = imp.factor.as_mut() {
            f.observe(result.0);
        }
        impulses(imp, g, params, true);
        update_dv(imp, params, &self.x, &self.second, true);
        for _ in 1..settings.newton_iterations.max(1) {
            // Newton on `g(y) = M (y - v) - h F(u + h y, y)` at `y = v + dv`.
            let bb = match fem.as_deref_mut() {
                Some(fem) => element_system::assemble(imp, g, params, fem, Lin::Iterate),
                None => assemble(imp, g, params, settings.linearization, Lin::Iterate),
            };
            let bb = constrain(imp, g, params, None, bb);
            let result = solve(imp, g, settings, bb, false);
            imp.record(result);
            if let Some(f) = imp.factor.as_mut() {
                f.observe(result.0);
            }
            impulses(imp, g, params, false);
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
        let sl = &self.graph.springs;
        let slots: usize = sl
            .slices
            .iter()
            .map(|[a, b]| (b - a) as usize * sliced::LANES)
            .sum();
        let live = self.graph.springs.live;
        self.implicit
            .as_ref()
            .map(|i| i.bytes_per_iteration(slots, live))
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

/// Form every free node's spring blocks, diagonal block, preconditioner and right-hand side;
/// returns `b . b`.
fn assemble(imp: &mut Implicit, g: &Graph, p: Params, lin: Linearization, at: Lin) -> f64 {
    let (x, v, newton) = match at {
        Lin::Start(x, v) => (x, v, None),
        Lin::Iterate => (&imp.xk[..], &imp.vk[..], Some(&imp.dv[..])),
    };
    let blocks = SharedRows(imp.blocks.as_mut_ptr(), imp.blocks.len());
    let lanes = SharedLanes(imp.lanes.as_mut_ptr(), imp.lanes.len());
    let starts = &imp.starts[..];
    let (h, h2) = (p.h, p.h * p.h);
    let definite = lin == Linearization::Definite;
    let [bb, _] = over_blocks(&mut imp.nodes, &mut imp.partials, |start, out| {
        let mut bb = 0.0f64;
        for (k, node) in out.iter_mut().enumerate() {
            let i = start + k;
            // SAFETY: node `i`'s lane is written only here, by the one task that owns it, and
            // `fit` sized the lanes to these slices.
            let mut lane = unsafe { lanes.node(&g.springs, i) };
            if g.fixed[i] {
                lane.finish();
                *node = NodeSystem {
                    diag: IDENTITY,
                    inverse: IDENTITY,
                    b: [0.0; 4],
                    lower: 0,
                };
                continue;
            }
            let (first, end) = (starts[i], starts[i + 1]);
            // SAFETY: rows are disjoint, consecutive ranges (`Implicit::fit`), and node `i`'s
            // row is written only here, by the one task that owns node `i`.
            let row_blocks = unsafe { blocks.row(first as usize, end as usize) };
            let (xi, vi) = (x[i], v[i]);
            let (mut f, mut kv, mut sum) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 6]);
            // Blocks coupling `i` to an earlier node of its own block go first in the row, the
            // others last (see `precondition`); the product reads them in any order.
            let (mut lower, mut last) = (0usize, row_blocks.len());
            let mut place = |j: usize, block: Block| {
                if j >= start && j < i {
                    row_blocks[lower] = block;
                    lower += 1;
                } else {
                    last -= 1;
                    row_blocks[last] = block;
                }
            };
            for (e, c) in g.springs.row(i) {
                let j = e.other as usize;
                let d = spring_vector(e.edge, xi, x[j]);
                let l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if l2 <= 0.0 {
                    // No direction: no force and no block, as in the float64 model.
                    let s = [0.0; 6];
                    lane.push(&s);
                    place(j, Block { s, other: e.other });
                    continue;
                }
                let inv = 1.0 / l2.sqrt();
                let u = [d[0] * inv, d[1] * inv, d[2] * inv];
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
                lane.push(&s);
                place(j, Block { s, other: e.other });
            }
            lane.finish();
            let m = 1.0 / g.inv_mass[i];
            let mh = (1.0 + h * p.alpha) * m;
            let mut diag = sum;
            for d in &mut diag[..3] {
                *d += mh;
            }
            let dv = newton.map(|dv| dv[i]);
            let (system, b2) = node_system(p, m, vi, (f, kv), dv, diag, lower);
            *node = system;
            bb += b2;
        }
        [bb, 0.0]
    });
    bb
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

//! The fast float32 CPU engine: node-centric gather, nodes reordered for locality,
//! multi-threaded over blocks of nodes (feature `parallel`).
//!
//! Every node owns its row of springs, each spring appearing twice, once in the row of each
//! end; the rows are stored once, eight nodes' rows side by side a SIMD vector (`sliced.rs`),
//! which the step reads directly and everything else (a cut's patch, `patch.rs`; backward
//! Euler, `implicit.rs`; the finite elements' rows) reads a row at a time out of its lane. A
//! node sums the forces of its row and integrates itself in the same pass,
//! so that threads write disjoint nodes and need no atomics; the price is that every spring's
//! length is computed twice. Positions are read from buffers nobody writes during the pass:
//! both integrators write the new displacements and second states (Verlet's last step
//! `u - u_prev`, symplectic Euler's velocity) beside the old ones and swap.
//!
//! Nodes are renumbered internally by reverse Cuthill–McKee so that a node's neighbours lie
//! close to it in memory; everything the [`Engine`] trait exposes is in the packed model's
//! order.
//!
//! The state is stored as displacements from rest, not positions: float32 keeps a value to
//! about 6e-8 of its magnitude, and a position's magnitude is the body's size while a
//! displacement's is the motion's. Verlet keeps its last step `u - u_prev` rather than the
//! previous displacement, so its velocity is never the difference of two rounded states, and
//! both integrators keep what rounding `u + step` loses (`physics::Compensation`): far below
//! the stable bound a step is a few ulps of the displacement, and without both most of it
//! would be rounded away (see `tests/engine/float32_precision.rs`). Spring vectors are
//! `e_ij + (u_j - u_i)`, the rest edge vector `e_ij` stored with the spring end (rounded once
//! from float64, so the rest shape keeps float32 precision of each edge).

mod elements;
mod fused;
#[cfg(target_arch = "x86_64")]
mod gather;
mod health;
mod implicit;
mod kernels;
mod near;
use near::ReadAhead;
mod pages;
use kernels::*;
mod patch;
mod sliced;
pub(crate) use sliced::check_size;
mod threads;
pub use threads::on_threads;

use super::{Engine, Integrator, SimConfig};
use crate::model::room::{copy_with_room, spare};
use crate::model::{PackedModel, PackedSpring};

/// A position or velocity, padded to 16 bytes so that a node is one aligned load.
type P = [f32; 4];

/// Nodes per parallel task: large enough that scheduling costs little next to the work
/// (about 14 springs per node in a tet mesh), small enough to balance two to a few dozen cores;
/// a whole number of slices of the sliced layout (`sliced.rs`).
const BLOCK: usize = 1024;
const _: () = assert!(BLOCK.is_multiple_of(sliced::LANES) && BLOCK.is_multiple_of(SIGMA));

/// Nodes per window of the valence sort that follows the locality order ([`sigma_sort`]):
/// eight slices, so that a node moves at most 63 places from where reverse Cuthill–McKee put
/// it.
const SIGMA: usize = 64;

/// Sort `order` by falling valence within windows of [`SIGMA`] nodes ("sigma sorting" of a
/// sliced ELLPACK layout), stably: the eight nodes of a slice then have rows of nearly one
/// length, so the slice pads less, while every node stays among its neighbours in memory.
fn sigma_sort(order: &mut [u32], model: &PackedModel) {
    let mut valence = vec![0u32; model.node_count()];
    for s in model.springs() {
        for &i in &s.nodes {
            valence[i as usize] += 1;
        }
    }
    for w in order.chunks_mut(SIGMA) {
        w.sort_by_key(|&o| std::cmp::Reverse(valence[o as usize]));
    }
}

/// One spring as seen from one of its ends (stored lane by lane in `sliced::Group`).
#[derive(Debug, Clone, Copy)]
struct Entry {
    /// The other end, internal index.
    other: u32,
    /// Rest vector from this node to the other, m: computed in float64 and rounded once, so
    /// the rest shape is kept to float32 precision of the edge, not of the coordinates.
    edge: [f32; 3],
    /// Rest length, m.
    rest: f32,
    /// Stiffness, N/m.
    k: f32,
}

/// Per-step constants.
#[derive(Debug, Clone, Copy)]
struct Params {
    h: f32,
    h2: f32,
    inv_h: f32,
    gravity: [f32; 3],
    alpha: f32,
}

/// Read-only model data in internal order.
struct Graph {
    /// Every node's springs, as the explicit step reads them and everything else reads rows
    /// out of them (`sliced.rs`).
    springs: sliced::Sliced,
    inv_mass: Vec<f32>,
    fixed: Vec<bool>,
}

/// Float32 node-centric engine.
pub struct FastEngine {
    graph: Graph,
    params: Params,
    integrator: Integrator,
    /// Whether any spring has damping: the undamped kernel skips the neighbours' velocities.
    damped: bool,
    /// The instructions the kernels use: at most what the CPU has (detected at run time; less
    /// through `set_wide_simd` and `set_avx512`). The
    /// kernels are compiled again for AVX2 and FMA, which step about 1.5x faster than the
    /// baseline x86-64 build, and for those with AVX-512F and VL besides.
    simd: Simd,
    /// `order[internal] = model index`.
    order: Vec<u32>,
    /// `rank[model index] = internal`.
    rank: Vec<u32>,
    /// Rest positions in model order, returned exactly for fixed nodes.
    rest: Vec<[f64; 3]>,
    /// Rest positions in internal order, float32: a scan for the nodes in a box reads them
    /// next to the displacements instead of gathering `rest` node by node.
    rest_inner: Vec<P>,
    /// Current displacements from rest.
    x: pages::PageVec<P>,
    /// Verlet: last steps `u - u_prev`. Symplectic Euler: velocities. The `w` lanes of both
    /// arrays hold the rounding `physics::Compensation` carries to the next step.
    second: pages::PageVec<P>,
    /// Output buffers of the next step.
    x_next: pages::PageVec<P>,
    second_next: pages::PageVec<P>,
    /// A box whose nodes the next step finds after its last iteration
    /// ([`Engine::prefetch_near`]).
    near_ahead: Option<([f64; 3], [f64; 3])>,
    /// The nodes found in that box after the last step, until the state changes.
    read_ahead: Option<ReadAhead>,
    /// How reads of the nodes near a blade were served.
    near_reads: super::NearReads,
    /// Backward Euler's solver and its scratch (`None` for the explicit schemes).
    implicit: Option<implicit::Implicit>,
    /// The finite-element model that replaces the springs' force, if any
    /// ([`FastEngine::with_force_model`]).
    elements: Option<elements::FastElements>,
    /// Whether explicit steps are made two in one sweep where they can be (`fused.rs`): off
    /// by default: on a shared two-core machine they ran slower than single steps on two
    /// threads, for all the memory traffic they save (see `examples/fused_steps.rs`).
    fuse: bool,
    /// Pairs of steps made in one sweep.
    fused_pairs: u64,
}

impl FastEngine {
    /// Start at rest at the rest positions.
    pub fn new(model: &PackedModel, config: SimConfig) -> Self {
        let n = model.node_count();
        let mut order = config.node_order.order(model).order;
        if config.node_order == super::NodeOrdering::Locality {
            sigma_sort(&mut order, model);
        }
        let rest_inner = order
            .iter()
            .map(|&o| rest_f32(model.rest[o as usize]))
            .collect();
        let mut rank = vec![0u32; n];
        for (new, &old) in order.iter().enumerate() {
            rank[old as usize] = new as u32;
        }
        let graph = build_graph(model, &order, &rank);
        let h = config.dt as f32;
        let g = model.gravity;
        let params = Params {
            h,
            h2: h * h,
            inv_h: 1.0 / h,
            gravity: [g[0] as f32, g[1] as f32, g[2] as f32],
            alpha: model.mass_damping as f32,
        };
        // Node arrays keep room for cuts' new nodes (see `model::room::spare`).
        let zeros = || {
            let mut v: pages::PageVec<P> = pages::with_capacity(n + spare(n));
            v.resize(n, [0.0; 4]);
            v
        };
        let x = zeros();
        let second = zeros();
        let mut engine = FastEngine {
            damped: model.springs().iter().any(|s| s.damping != 0.0),
            simd: Simd::best(),
            graph,
            params,
            integrator: config.integrator,
            x_next: zeros(),
            second_next: zeros(),
            x,
            second,
            order,
            rank,
            rest_inner,
            rest: copy_with_room(&model.rest),
            near_ahead: None,
            read_ahead: None,
            near_reads: Default::default(),
            implicit: None,
            elements: None,
            fuse: false,
            fused_pairs: 0,
        };
        if config.integrator.is_implicit() {
            engine.implicit = Some(implicit::Implicit::new(
                config.solver,
                n,
                engine.graph.springs.live,
                engine.graph.springs.groups.len(),
            ));
        }
        engine.order.reserve(spare(n));
        engine.rank.reserve(spare(n));
        engine.rest_inner.reserve(spare(n));
        engine.graph.inv_mass.reserve(spare(n));
        engine.graph.fixed.reserve(spare(n));
        engine
    }

    /// Step with the finite-element force model `kind` of `model` (the model this engine was
    /// built on) instead of the springs (see `elements.rs`); `Springs` changes nothing. With
    /// backward Euler the implicit solve takes the elements' 3x3 blocks as its Jacobian
    /// (`implicit_elements.rs`). Fails where the model cannot have that force model (no tets, a
    /// tet without Young's modulus).
    pub fn with_force_model(
        mut self,
        model: &PackedModel,
        kind: crate::physics::ForceModelKind,
    ) -> crate::Result<Self> {
        self.elements =
            elements::FastElements::new(kind, model, &self.graph, &self.order, &self.rank)?;
        if let (Some(_), Some(imp)) = (&self.elements, &mut self.implicit) {
            imp.for_elements();
        }
        Ok(self)
    }

    /// The name of the force model it steps.
    pub fn force_model_name(&self) -> &'static str {
        use crate::physics::ForceModel;
        self.elements
            .as_ref()
            .map_or("springs", |e| e.reference().name())
    }

    /// Use the wide kernels or not (for comparing them with the baseline ones): on, the best
    /// the CPU has (AVX2 and FMA, and AVX-512 where it has that too, whatever
    /// [`FastEngine::set_avx512`] said before); off, the baseline kernels. Returns whether
    /// the AVX2/FMA kernels are now in use.
    pub fn set_wide_simd(&mut self, on: bool) -> bool {
        self.simd = if on { Simd::best() } else { Simd::Portable };
        self.simd.wide()
    }

    /// Let the explicit step use AVX-512F and VL where the CPU has them (the default) or
    /// keep to AVX2 and FMA (for comparing the two kernels): the AVX-512 kernel takes each
    /// spring's `1 / l` from an estimate and a Newton step instead of a division and a square
    /// root, a float32 rounding or two apart. Only with the wide kernels on
    /// ([`FastEngine::set_wide_simd`]); returns whether it is now in use.
    pub fn set_avx512(&mut self, on: bool) -> bool {
        if self.simd.wide() {
            self.simd = if on { Simd::best() } else { Simd::Avx2 };
        }
        self.simd == Simd::Avx512
    }

    /// Make explicit steps two in one sweep where the threads' ranges allow, or always one at
    /// a time (the default); the two give the same bits. Returns the setting.
    pub fn set_fused_steps(&mut self, on: bool) -> bool {
        self.fuse = on;
        on
    }

    /// Pairs of explicit steps made in one sweep so far (`fused.rs`).
    pub fn fused_step_pairs(&self) -> u64 {
        self.fused_pairs
    }

    /// One step of position Verlet on (displacement, last step); then swap old and new.
    fn step_verlet(&mut self) {
        self.step_explicit::<true>();
    }

    /// One step of symplectic Euler; then swap old and new.
    fn step_euler(&mut self) {
        self.step_explicit::<false>();
    }

    /// One explicit step (Verlet's where `VERLET`, else symplectic Euler's) from the state into
    /// the output buffers, the kernel chosen by damping, the layout's constants (per end or
    /// [`sliced::Uniform`]) and the CPU; then swap old and new.
    fn step_explicit<const VERLET: bool>(&mut self) {
        let (g, sl, p) = (&self.graph, &self.graph.springs, self.params);
        let (x, s) = (&self.x, &self.second);
        // The AVX2 kernel reads neighbours unchecked: the layout's indices are below its node
        // count, so the state must hold that many nodes.
        assert!(sl.nodes() == x.len() && s.len() == x.len());
        let (damped, uniform, simd) = (self.damped, sl.uniform.is_some(), self.simd);
        for_block_pairs(&mut self.x_next, &mut self.second_next, |start, xo, so| {
            // SAFETY: `simd` is at most what the CPU reported (`Simd::best`).
            unsafe {
                match (damped, uniform) {
                    (true, true) => {
                        step_block::<true, true, VERLET>(simd, g, sl, p, x, s, start, xo, so)
                    }
                    (true, false) => {
                        step_block::<true, false, VERLET>(simd, g, sl, p, x, s, start, xo, so)
                    }
                    (false, true) => {
                        step_block::<false, true, VERLET>(simd, g, sl, p, x, s, start, xo, so)
                    }
                    (false, false) => {
                        step_block::<false, false, VERLET>(simd, g, sl, p, x, s, start, xo, so)
                    }
                }
            }
        });
        std::mem::swap(&mut self.x, &mut self.x_next);
        std::mem::swap(&mut self.second, &mut self.second_next);
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.order.len()
    }

    /// Number of entries of the adjacency: twice the number of springs.
    pub fn adjacency_len(&self) -> usize {
        self.graph.springs.live
    }

    /// The stiffness (N/m) and damping (N s/m) every spring shares, where the layout keeps
    /// them once instead of per spring end (every spring of one material with its rest length
    /// its rest edge's: 16 bytes an end instead of 24, or 28 damped); `None` where they are
    /// stored per end.
    pub fn uniform_springs(&self) -> Option<(f64, f64)> {
        self.graph.springs.uniform.map(|u| (u.k as f64, u.c as f64))
    }

    /// Largest `|internal index of a node - internal index of a neighbour|` (the bandwidth the
    /// reordering reduces).
    pub fn bandwidth(&self) -> usize {
        (0..self.node_count())
            .flat_map(|i| {
                self.graph
                    .springs
                    .row(i)
                    .map(move |(e, _)| i.abs_diff(e.other as usize))
            })
            .max()
            .unwrap_or(0)
    }

    /// A vector of the state in model order, `f` mapping (internal index) to a value.
    /// Position of packed node `i`, m (fixed nodes exactly at rest).
    fn position_at(&self, i: usize) -> [f64; 3] {
        let r = self.rest[self.order[i] as usize];
        if self.graph.fixed[i] {
            r
        } else {
            let u = to_f64(self.x[i]);
            [r[0] + u[0], r[1] + u[1], r[2] + u[2]]
        }
    }

    /// Velocity of packed node `i`, m/s.
    fn velocity_at(&self, i: usize) -> [f64; 3] {
        match self.integrator {
            Integrator::Verlet => {
                let inv_h = 1.0 / self.params.h as f64;
                to_f64(self.second[i]).map(|d| d * inv_h)
            }
            Integrator::SymplecticEuler | Integrator::BackwardEuler => to_f64(self.second[i]),
        }
    }

    /// `f` of the packed index of each model node in `nodes`.
    fn at_nodes(
        &self,
        nodes: &[u32],
        f: impl Fn(usize) -> [f64; 3],
    ) -> crate::Result<Vec<[f64; 3]>> {
        let n = self.order.len();
        nodes
            .iter()
            .map(|&o| match self.rank.get(o as usize) {
                Some(&i) => Ok(f(i as usize)),
                None => Err(super::bad_node(o, n)),
            })
            .collect()
    }

    fn in_model_order(&self, f: impl Fn(usize) -> [f64; 3]) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; self.order.len()];
        for (i, &o) in self.order.iter().enumerate() {
            out[o as usize] = f(i);
        }
        out
    }
}

impl Engine for FastEngine {
    fn name(&self) -> String {
        "cpu-fast-f32".into()
    }

    fn solver_stats(&self) -> Option<crate::physics::SolverStats> {
        self.implicit_stats()
    }

    fn bytes_per_solver_iteration(&self) -> Option<u64> {
        self.bytes_per_cg_iteration()
    }

    fn differences_from_rebuild(&self, model: &PackedModel) -> crate::Result<Vec<String>> {
        let mut out = self.graph_differences(model);
        if let Some(e) = &self.elements {
            out.extend(e.differences(model, &self.graph, &self.order, &self.rank)?);
        }
        Ok(out)
    }

    fn elastic_energy(&self, model: &PackedModel, x: &[[f64; 3]]) -> f64 {
        match &self.elements {
            Some(e) => e.energy(x),
            None => model.elastic_energy(x),
        }
    }

    fn memory(&self) -> super::EngineMemory {
        let n = self.x.len() as u64;
        let sl = &self.graph.springs;
        let p = std::mem::size_of::<P>() as u64;
        let springs = sl.groups.len() as u64 * sl.group_bytes() as u64 + sl.index_bytes();
        let mut buffers = vec![
            (
                match sl.uniform {
                    Some(_) => "springs (slices of 8 nodes, a node a lane; one material)",
                    None => "springs (slices of 8 nodes, a node a lane)",
                }
                .to_string(),
                springs,
            ),
            ("order and rank".to_string(), n * 8),
            ("inverse masses".to_string(), n * 4),
            ("fixed flags".to_string(), n),
            ("displacements (2 buffers)".to_string(), 2 * n * p),
            (
                match self.integrator {
                    Integrator::Verlet => "steps (2 buffers)",
                    Integrator::SymplecticEuler | Integrator::BackwardEuler => {
                        "velocities (2 buffers)"
                    }
                }
                .to_string(),
                2 * n * p,
            ),
        ];
        if let Some(imp) = &self.implicit {
            buffers.extend(imp.buffers());
        }
        // A step streams the sliced springs once (padding lanes included), reads the current
        // state and writes the next; neighbours' state is re-read from cache, not memory, when
        // the order is local. With finite elements, the element arrays replace the springs in
        // the step.
        let state = 4 * n * p;
        let bytes_per_step = match &self.elements {
            Some(e) => {
                buffers.extend(e.buffers());
                e.bytes_per_step() + n * 5 + state
            }
            None => {
                let live = sl.groups.len() - sl.holes;
                live as u64 * sl.group_bytes() as u64 + sl.index_bytes() + n * 5 + state
            }
        };
        super::EngineMemory {
            stats: crate::layout::MemoryStats::new(
                buffers,
                sl.padding_bytes(),
                n as usize,
                sl.live / 2,
            ),
            bytes_per_step,
        }
    }

    fn patch(
        &mut self,
        model: &PackedModel,
        diff: &crate::model::ModelDiff,
    ) -> crate::Result<Option<super::PatchCost>> {
        self.read_ahead = None;
        if self
            .elements
            .as_ref()
            .is_some_and(|e| e.needs_rebuild(&diff.added_tets))
        {
            return Ok(None);
        }
        let nodes_before = self.order.len();
        let Some(mut cost) = self.patch_in_place(model, diff) else {
            return Ok(None);
        };
        if let Some(e) = &mut self.elements {
            cost.uploaded_bytes += e.patch(
                model,
                diff,
                nodes_before,
                &self.graph,
                &self.order,
                &self.rank,
            )?;
            cost.layout_bytes = self.memory().stats.total;
        }
        Ok(Some(cost))
    }

    fn step(&mut self, steps: u32) {
        self.read_ahead = None;
        let mut left = steps;
        while left > 0 {
            left -= 1;
            if self.elements.is_some() && !self.integrator.is_implicit() {
                self.step_elements();
                continue;
            }
            // Nothing happens between the steps of one call: two can share a sweep.
            let paired = left > 0
                && self.fuse
                && self.elements.is_none()
                && match self.integrator {
                    Integrator::Verlet => self.step_pair::<true>(),
                    Integrator::SymplecticEuler => self.step_pair::<false>(),
                    Integrator::BackwardEuler => false,
                };
            if paired {
                left -= 1;
                continue;
            }
            match self.integrator {
                Integrator::Verlet => self.step_verlet(),
                Integrator::SymplecticEuler => self.step_euler(),
                Integrator::BackwardEuler => self.step_backward_euler(),
            }
        }
        self.read_near_ahead();
    }

    fn set_contact_constraints(&mut self, constraints: &[crate::physics::NodeConstraint]) -> bool {
        let Some(imp) = self.implicit.as_mut() else {
            return false;
        };
        imp.held = implicit::Held::new(constraints, &self.rank, &self.graph.fixed, &self.rest);
        true
    }

    fn contact_constraint_forces(&self) -> Vec<f64> {
        self.implicit
            .as_ref()
            .map_or(Vec::new(), |imp| imp.held.forces.clone())
    }

    fn positions(&self) -> Vec<[f64; 3]> {
        self.in_model_order(|i| self.position_at(i))
    }

    fn velocities(&self) -> Vec<[f64; 3]> {
        self.in_model_order(|i| self.velocity_at(i))
    }

    fn nodes_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> crate::Result<Vec<(u32, [f64; 3])>> {
        Ok(self.read_near(lo, hi))
    }

    fn prefetch_near(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        self.near_ahead = Some((lo, hi));
    }

    fn divergence_probe(&self) -> Option<crate::Result<super::Health>> {
        Some(Ok(self.probe()))
    }

    fn near_reads(&self) -> super::NearReads {
        self.near_reads
    }

    fn node_positions(&self, nodes: &[u32]) -> crate::Result<Vec<[f64; 3]>> {
        self.at_nodes(nodes, |i| self.position_at(i))
    }

    fn node_velocities(&self, nodes: &[u32]) -> crate::Result<Vec<[f64; 3]>> {
        self.at_nodes(nodes, |i| self.velocity_at(i))
    }

    fn correct_positions(&mut self, nodes: &[u32], positions: &[[f64; 3]]) -> crate::Result<()> {
        self.read_ahead = None;
        super::check_correction(nodes, positions, self.order.len())?;
        let inv_h = 1.0 / self.params.h as f64;
        for (&o, p) in nodes.iter().zip(positions) {
            let i = self.rank[o as usize] as usize;
            if self.graph.fixed[i] {
                continue;
            }
            let r = self.rest[o as usize];
            let u = [p[0] - r[0], p[1] - r[1], p[2] - r[2]];
            // The move goes into the second state as if the step had made it: the velocity
            // gains it over h, Verlet's step gains it whole.
            let scale = match self.integrator {
                Integrator::SymplecticEuler | Integrator::BackwardEuler => inv_h,
                Integrator::Verlet => 1.0,
            };
            let old = to_f64(self.x[i]);
            let v = to_f64(self.second[i]);
            self.second[i] = to_p([0, 1, 2].map(|c| v[c] + (u[c] - old[c]) * scale));
            self.x[i] = to_p(u);
        }
        Ok(())
    }

    fn set_time_step(&mut self, dt: f64) -> crate::Result<super::PatchCost> {
        // Exactly what an engine built at `dt` and given this state would hold: the state
        // through float64, the parameters as `new` computes them.
        let (x, v) = self.state();
        let h = dt as f32;
        self.params.h = h;
        self.params.h2 = h * h;
        self.params.inv_h = 1.0 / h;
        self.set_state(&x, &v);
        Ok(super::PatchCost::parameters_only(
            std::mem::size_of::<Params>() as u64,
            self.memory().stats.total,
        ))
    }

    fn set_state(&mut self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) {
        self.read_ahead = None;
        let h = self.params.h as f64;
        for (i, &o) in self.order.iter().enumerate() {
            let o = o as usize;
            let (u, v) = if self.graph.fixed[i] {
                ([0.0; 3], [0.0; 3])
            } else {
                let (x, r) = (positions[o], self.rest[o]);
                ([x[0] - r[0], x[1] - r[1], x[2] - r[2]], velocities[o])
            };
            self.x[i] = to_p(u);
            self.second[i] = match self.integrator {
                Integrator::Verlet => to_p([v[0] * h, v[1] * h, v[2] * h]),
                Integrator::SymplecticEuler | Integrator::BackwardEuler => to_p(v),
            };
        }
    }
}

/// Spring `s` as seen from its end `end` (0 or 1), whose other end has internal index `other`,
/// with its damping. The rest edge vector is formed in float64 from the first end to the second
/// and negated for the second, so both ends (and a patch) round it the same way.
fn entry_of(s: &PackedSpring, end: usize, other: u32, rest: &[[f64; 3]]) -> (Entry, f32) {
    let (ra, rb) = (rest[s.nodes[0] as usize], rest[s.nodes[1] as usize]);
    let sign = if end == 0 { 1.0 } else { -1.0 };
    let e = Entry {
        other,
        edge: [0, 1, 2].map(|c| (sign * (rb[c] - ra[c])) as f32),
        rest: s.rest_length as f32,
        k: s.stiffness as f32,
    };
    (e, s.damping as f32)
}

/// The springs in internal order, each row sorted by neighbour so that a row walks memory
/// forwards.
fn build_graph(model: &PackedModel, order: &[u32], rank: &[u32]) -> Graph {
    let n = model.node_count();
    let mut rows: Vec<sliced::Row> = vec![Vec::new(); n];
    for s in model.springs() {
        let (a, b) = (rank[s.nodes[0] as usize], rank[s.nodes[1] as usize]);
        rows[a as usize].push(entry_of(s, 0, b, &model.rest));
        rows[b as usize].push(entry_of(s, 1, a, &model.rest));
    }
    for r in &mut rows {
        r.sort_by_key(|(e, _)| e.other);
    }
    let damped = model.springs().iter().any(|s| s.damping != 0.0);
    Graph {
        springs: sliced::Sliced::build(&rows, damped),
        inv_mass: order
            .iter()
            .map(|&o| (1.0 / model.mass[o as usize]) as f32)
            .collect(),
        fixed: order.iter().map(|&o| model.fixed[o as usize]).collect(),
    }
}

fn to_p(v: [f64; 3]) -> P {
    [v[0] as f32, v[1] as f32, v[2] as f32, 0.0]
}

fn rest_f32(r: [f64; 3]) -> P {
    [r[0] as f32, r[1] as f32, r[2] as f32, 0.0]
}

fn to_f64(p: P) -> [f64; 3] {
    [p[0] as f64, p[1] as f64, p[2] as f64]
}

//! The CPU twins of the GPU passes, one file per pass, each named like its shader: the same
//! float32 arithmetic in the same order, so that a pass and its twin agree bit for bit on a
//! device that rounds like the CPU (lavapipe) and within a stated tolerance elsewhere. The
//! device tests run each pass against its twin on random, non-trivial inputs.
//!
//! The physics of one step (the force law, the integrators) is not here: it lives in
//! [`crate::physics`], and the twins call it as the shaders call `shaders/common.wgsl`. Where
//! a twin is also the real code path of the engines (the CPU engines' self-contact broad
//! phase, the fast engine's state blend at a patch, the GPU engine's narrowing of a read made
//! ahead), this is the one implementation and the engines call it. Twins that read a layout are methods of that layout's type, so the tests
//! call `layout.step_cpu(..)` whatever file the twin sits in; this module imports the layouts,
//! the collision types and the physics, never the engines.
//!
//! | pass (`src/engine/gpu/`) | shader (`shaders/`) | twin (`src/twin/`) | tests comparing them |
//! |---|---|---|---|
//! | `springs_connectivity` | `springs_connectivity.wgsl` + `node_gather.wgsl` | [`springs_connectivity`]: `ConnectivityLayout::step_cpu`, over [`node_gather::node_update`] | `tests/gpu/gpu_layouts.rs`, `gpu_patch.rs`, `gpu_limits.rs`, `twin_tolerance.rs` |
//! | `springs_valence` | `springs_valence.wgsl` + `node_gather.wgsl` | [`springs_valence`]: `ValenceLayout::step_cpu`, over [`node_gather::node_update`] | `tests/gpu/gpu_valence.rs`, `gpu_layouts.rs`, `gpu_patch.rs` |
//! | `springs_edges` (gather) | `springs_edges.wgsl` + `edge_spring.wgsl` | [`springs_edges`]: `EdgeLayout::spring_forces_cpu`, over [`edge_spring::edge_force`] | `tests/gpu/gpu_edges.rs`, `gpu_layouts.rs`, `gpu_patch.rs` |
//! | `springs_edges` (gather) | `gather_edges.wgsl` | [`gather_edges`]: `EdgeLayout::gather_cpu`, `integrate_cpu`, `step_cpu` | `tests/gpu/gpu_edges.rs`, `gpu_layouts.rs`, `gpu_patch.rs` |
//! | `atomic_edges` (fixed point) | `accumulate_fixed.wgsl` + `fixed_point.wgsl` + `edge_spring.wgsl` | [`accumulate_fixed`]: `EdgeLayout::accumulate_fixed_cpu` | `tests/gpu/gpu_edges.rs` (`edge_variant_step_equals_its_cpu_twin_on_random_inputs`, `fixed_point_overflow_sets_the_flag_the_host_reads`) |
//! | `atomic_edges` (fixed point) | `integrate_fixed.wgsl` + `fixed_point.wgsl` | [`integrate_fixed`]: `EdgeLayout::fixed_forces`, `step_fixed_cpu` | `tests/gpu/gpu_edges.rs` |
//! | `atomic_edges` (float) | `accumulate_float.wgsl` + `edge_spring.wgsl` | [`accumulate_float`]: `EdgeLayout::accumulate_float_cpu` | `tests/gpu/gpu_edges.rs` (within a tolerance: the order of the adds varies) |
//! | `atomic_edges` (float) | `integrate_float.wgsl` | [`integrate_float`]: `EdgeLayout::step_float_cpu` | `tests/gpu/gpu_edges.rs` |
//! | `tensor_mass` (connectivity, valence) | `tensor_gather.wgsl` + `tensor_connectivity.wgsl` or `tensor_valence.wgsl` (over `node_gather.wgsl`'s bindings) | [`tensor_mass`]: `TensorBlocks::node_forces_cpu`, `step_cpu` | `tests/gpu/gpu_tensor_mass.rs` |
//! | `tensor_mass` (edges, gather) | `tensor_edges.wgsl` then `tensor_gather_edges.wgsl` | [`tensor_mass`]: `TensorBlocks::record_forces_cpu`, `gather_edges_cpu`, `step_cpu` | `tests/gpu/gpu_tensor_mass.rs` |
//! | `tensor_atomic` (edges, atomics) | `tensor_accumulate_fixed.wgsl` or `tensor_accumulate_float.wgsl` (over `tensor_products.wgsl` and `tensor_block.wgsl`), then `integrate_fixed.wgsl` or `integrate_float.wgsl` | [`tensor_atomic`]: `TensorBlocks::accumulate_fixed_cpu`, `accumulate_float_cpu`, `step_atomic_cpu` | `tests/gpu/gpu_tensor_atomic.rs` (fixed point bit for bit; float atomics within a tolerance: the order of the adds varies) |
//! | `corotational` (every layout) | `corotational_tets.wgsl` then `corotational_gather.wgsl` (over `common.wgsl`'s `integrate`) | [`corotational`]: `TetTable::tet_pass_cpu`, `gather_cpu`, `step_cpu` | `tests/gpu/gpu_corotational.rs` (within 1e-5 of the motion: the rotation's last iterations round differently on lavapipe) |
//! | `health` | `health.wgsl` | [`health`]: [`health::health_cpu`] | `tests/gpu/gpu_health.rs` (`device_probe_equals_its_twin`) |
//! | `implicit` (every layout) | `implicit_solve.wgsl` (entry points `setup`, `start`, `multiply`, `step_length`, `update`, `residual`, `direction`, `finish`) with `implicit_slots.wgsl` or, on the edge layout, `implicit_edges.wgsl` (`spring_multiply`, and its gather in `multiply`) | [`implicit_solve`]: one function per entry point, [`implicit_solve::implicit_step_cpu`] and [`implicit_solve::implicit_step_edges_cpu`] the whole step | `tests/gpu/gpu_implicit.rs` |
//! | `implicit` (edges, float atomics; springs) | `implicit_solve.wgsl` with `implicit_spring_block.wgsl` and `implicit_atomic.wgsl` (`setup_records`, `node_terms`, `spring_multiply`, `product`) | [`implicit_atomic`]: [`implicit_atomic::implicit_step_atomic_cpu`] the whole step, the adds in record order | `tests/gpu/gpu_implicit_atomic.rs` (within the solver's tolerance: the order of the adds varies) |
//! | `implicit_atomic` (edges, float atomics; tensor-mass, corotational) | `implicit_solve.wgsl` with `implicit_tensor.wgsl`, the force model's `element_force`, `implicit_atomic_acc.wgsl` and `implicit_atomic_tensor.wgsl` (`setup_records`, `node_terms`, `spring_multiply`, `product`) | [`implicit_atomic_tensor`]: [`implicit_atomic_tensor::implicit_step_cpu`] and [`implicit_atomic_tensor::corotational_step_cpu`] the whole step, the adds in record order | `tests/gpu/gpu_implicit_atomic_fem.rs` (within the solver's tolerance: the order of the adds varies) |
//! | `implicit`, tensor-mass (every layout) | `implicit_solve.wgsl` with `implicit_tensor.wgsl` and `implicit_slots.wgsl` + `implicit_slots_tensor.wgsl` or, on the edge layout, `implicit_tensor_edges.wgsl` (`node_terms`, `product`, `spring_multiply`) | [`implicit_tensor`]: `setup_cpu`, `multiply_cpu`, `record_multiply_cpu`, `gather_multiply_cpu`; [`implicit_tensor::implicit_step_cpu`] the whole step | `tests/gpu/gpu_implicit_tensor.rs` |
//! | `broad_tool` | `broad_tool.wgsl` | [`broad_tool`]: [`broad_tool::cull_cpu`] | `tests/gpu/gpu_broad_phase.rs` |
//! | `broad_self` | `self_count`, `scan_blocks`, `scan_top`, `scan_apply`, `self_scatter`, `self_pairs.wgsl` over `self_grid.wgsl` | [`broad_self`]: [`broad_self::self_pairs_cpu`] (the whole chain; the CPU engines' self-contact broad phase) | `tests/gpu/gpu_self_contact.rs` |
//! | `nodes_near` | `nodes_near.wgsl` | [`nodes_near`]: [`nodes_near::nodes_near_cpu`] | `tests/gpu/gpu_nodes_near.rs` (`device_finds_the_nodes_its_twin_finds`) |
//! | `move_state` | `move_state.wgsl` | [`move_state`]: [`move_state::move_state_cpu`], `StateMove::apply_to` | `tests/gpu/gpu_patch.rs` (`state_moves_on_the_device_follow_the_nodes`), `gpu_limits.rs` |
//! | `time_step` | `time_step.wgsl` | [`time_step`]: [`time_step::rescale_previous`] (in `physics`) | `tests/gpu/gpu_patch.rs` (`a_time_step_change_rescales_like_its_twin_and_steps_like_a_rebuild`) |
//! | `embed_surface` | `embed_surface.wgsl` | [`embed_surface`]: [`embed_surface::embed_surface_cpu`] | `tests/gpu/gpu_embed_surface.rs` (`device_surface_equals_its_twin`) |
//! | `report::device_copy` | `device_copy.wgsl` | [`device_copy`]: [`device_copy::device_copy_cpu`] | `tests/gpu/gpu_limits.rs` (`the_device_copy_copies_every_entry_once_folded_or_not`) |
//!
//! `engine::gpu::surface_nodes` has no shader (an index kept on the host) and so no twin; the
//! scan passes (`scan_*.wgsl`) are checked through the whole self-contact chain, whose output
//! is the only one read back.
//!
//! [`steps`] is the one twin stepper: every test that steps a twin more than once goes
//! through it (or [`PackedLayout::steps_cpu`], which calls it), so that the state rotates as
//! the device's buffers do in one place.

pub mod accumulate_fixed;
pub mod accumulate_float;
#[cfg(feature = "collide")]
pub mod broad_self;
pub mod broad_tool;
pub mod corotational;
pub mod corotational_implicit;
pub mod device_copy;
pub mod edge_spring;
pub mod embed_surface;
pub mod gather_edges;
pub mod health;
pub mod implicit_atomic;
pub mod implicit_atomic_tensor;
pub mod implicit_solve;
pub mod implicit_tensor;
pub mod integrate_fixed;
pub mod integrate_float;
pub mod move_state;
pub mod node_gather;
pub mod nodes_near;
pub mod springs_connectivity;
pub mod springs_edges;
pub mod springs_valence;
pub mod tensor_atomic;
pub mod tensor_mass;
pub mod time_step;

use crate::layout::edges::{Accumulation, EdgeLayout, FixedPoint};
use crate::layout::PackedLayout;
use crate::physics::StepParams;

/// A node state in layout order: the current displacements and the second state (the
/// last steps for Verlet, the velocities for symplectic Euler).
pub type State = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// `n` steps of a twin `step` from `state`, the state swapping as the device's buffers do:
/// the next displacements and second state (Verlet's last step, symplectic Euler's velocity)
/// become the current ones. `step` takes the step parameters, the current displacements and
/// the second state, and returns the next of each.
pub fn steps<F>(p: &StepParams, state: State, n: usize, mut step: F) -> State
where
    F: FnMut(&StepParams, &[[f32; 4]], &[[f32; 4]]) -> State,
{
    let _ = p;
    let (mut cur, mut second) = state;
    for _ in 0..n {
        (cur, second) = step(p, &cur, &second);
    }
    (cur, second)
}

impl EdgeLayout {
    /// One step of `accumulation` on the CPU (fixed point with [`EdgeLayout::fixed_point`]
    /// constants supplied as `fp`; the overflow flag is dropped).
    pub fn step_variant_cpu(
        &self,
        accumulation: Accumulation,
        p: &StepParams,
        fp: &FixedPoint,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> State {
        match accumulation {
            Accumulation::Gather => self.step_cpu(p, cur, second),
            Accumulation::AtomicFixed => {
                let (u, s, _) = self.step_fixed_cpu(p, fp, cur, second);
                (u, s)
            }
            Accumulation::AtomicFloat => self.step_float_cpu(p, cur, second),
        }
    }
}

impl PackedLayout {
    /// One step on the CPU exactly as the layout's GPU passes take it (the gather variant for
    /// edges); see [`ConnectivityLayout::step_cpu`](crate::layout::connectivity::ConnectivityLayout::step_cpu).
    pub fn step_cpu(&self, p: &StepParams, cur: &[[f32; 4]], second: &[[f32; 4]]) -> State {
        match self {
            Self::Connectivity(c) => c.step_cpu(p, cur, second),
            Self::Valence(v) => v.step_cpu(p, cur, second),
            Self::Edges(e) => e.step_cpu(p, cur, second),
        }
    }

    /// `n` steps of the layout's CPU twin from `state` (layout order) through [`steps`]. The
    /// edge layout steps in `accumulation`, with the fixed-point constants `fixed` (read by
    /// `AtomicFixed` only); the node-centric layouts have one pass and ignore both.
    pub fn steps_cpu(
        &self,
        p: &StepParams,
        accumulation: Accumulation,
        fixed: &FixedPoint,
        state: State,
        n: usize,
    ) -> State {
        steps(p, state, n, |p, cur, second| match self {
            Self::Edges(e) => e.step_variant_cpu(accumulation, p, fixed, cur, second),
            other => other.step_cpu(p, cur, second),
        })
    }
}

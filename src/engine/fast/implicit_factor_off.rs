//! The factored preconditioner's place when lancet is built without the `factor` feature:
//! there is never a factor (`Simulation` refuses `Preconditioner::Factored` before an engine
//! is built), so the solver's calls into it are no-ops the compiler removes. The factor itself
//! is `implicit_factor.rs`.

use super::rows::Rows;
use super::{Held, Iterate, NodeSystem};
use crate::engine::fast::Graph;
use crate::physics::SolverStats;

/// No factor can exist without the feature: an uninhabited type.
pub(super) enum Factor {}

impl Factor {
    /// Never called: there is no factor.
    pub(super) fn observe(&mut self, _iterations: u32) {
        match *self {}
    }

    /// Never called: there is no factor.
    pub(super) fn bytes(&self) -> u64 {
        match *self {}
    }
}

/// Without the feature there is no factor to precondition with.
pub(super) fn prepare<'a>(
    _slot: &'a mut Option<Factor>,
    _stats: &mut SolverStats,
    _nodes: &[NodeSystem],
    _blocks: Rows,
    _g: &Graph,
    _single: bool,
) -> Option<&'a mut Factor> {
    None
}

/// Never called: there is no factor.
pub(super) fn apply_factor(
    f: &mut Factor,
    _cg: &mut [Iterate],
    _partials: &mut [[f64; 2]],
    _g: &Graph,
    _held: &Held,
    _stats: &mut SolverStats,
) -> [f64; 2] {
    match *f {}
}

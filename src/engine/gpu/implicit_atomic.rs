//! The implicit solve on the edge layout's float-atomic variant, which has no incidence table:
//! a record pass adds each record's setup terms to its two ends' float accumulators before
//! `setup`, and the product adds each record's block products at its ends
//! (`shaders/implicit_atomic_acc.wgsl`). Springs: `shaders/implicit_atomic.wgsl`, twin
//! [`crate::twin::implicit_atomic`]. Tensor-mass and corotational (the latter on the blocks
//! its block pass writes, its force the gathered corner forces):
//! `shaders/implicit_atomic_tensor.wgsl`, the block read transposed at a record's `b` end,
//! twin [`crate::twin::implicit_atomic_tensor`]. The fixed-point variant is refused here.

use super::implicit::SolveModel;
use crate::engine::Integrator;
use crate::error::{Error, Result};
use crate::layout::edges::Accumulation;
use crate::layout::LayoutKind;

/// The springs' solve on the float-atomic variant.
const SPRINGS: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_spring_block.wgsl"),
    include_str!("../../../shaders/implicit_atomic_acc.wgsl"),
    include_str!("../../../shaders/implicit_atomic.wgsl")
);

/// The tensor-mass solve on the float-atomic variant.
const TENSOR: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_tensor.wgsl"),
    include_str!("../../../shaders/implicit_tensor_force.wgsl"),
    include_str!("../../../shaders/implicit_atomic_acc.wgsl"),
    include_str!("../../../shaders/implicit_atomic_tensor.wgsl")
);

/// The corotational solve on the float-atomic variant: the tensor-mass one on the step's
/// blocks, its force the tet pass's corner forces.
const COROTATIONAL: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_tensor.wgsl"),
    include_str!("../../../shaders/implicit_corotational.wgsl"),
    include_str!("../../../shaders/implicit_atomic_acc.wgsl"),
    include_str!("../../../shaders/implicit_atomic_tensor.wgsl")
);

/// The float-atomic variant's solve for `model`.
pub(super) fn source(model: SolveModel) -> &'static str {
    match model {
        SolveModel::Springs => SPRINGS,
        SolveModel::TensorMass => TENSOR,
        SolveModel::Corotational => COROTATIONAL,
    }
}

/// Refuse an implicit integrator on the edge layout's fixed-point variant (every force model
/// runs on the gather and the float-atomic variants).
pub(super) fn check_layout(
    integrator: Integrator,
    kind: LayoutKind,
    accumulation: Accumulation,
) -> Result<()> {
    if integrator.is_implicit()
        && kind == LayoutKind::Edges
        && accumulation == Accumulation::AtomicFixed
    {
        return Err(Error::Unsupported(
            "the GPU engine's implicit step (integrator BackwardEuler) does not run on the edge \
             layout's fixed-point accumulation (the conjugate gradients' products shrink by \
             orders of magnitude within a solve, below any one fixed-point scale): use \
             --accumulation gather or atomic-float, or --layout connectivity"
                .into(),
        ));
    }
    Ok(())
}

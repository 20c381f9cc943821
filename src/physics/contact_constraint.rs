//! Tool contact inside the implicit solve: a node a tool pushes is held on the tool's tangent
//! plane for the next step by Baraff and Witkin's filtering, and the force the tool puts on it
//! is read from the solve (the constraint's multiplier) rather than from a position correction.
//!
//! A constrained node's velocity change is split along the plane's normal `n`: its normal part
//! is prescribed (`z`, so that the node ends the step on the plane), its tangential part is
//! solved for. Conjugate gradients then run on the filtered system `S A S y = S (b - A z)`,
//! `S = I - n n^T` on constrained nodes, as fixed nodes are projected out with `S = 0`; the
//! velocity change is `y + z`. What the filter removed is the constraint's impulse: `A (y + z)
//! - b` is zero on the free directions and `h lambda n` on a constrained node, `lambda` the
//! normal force the tool put on the node over the step (N; positive pushes along `n`). The
//! constraint is bilateral within the step; the contact response releases a node whose
//! `lambda` came out non-positive (the tool would have had to pull it).

use super::force_model::{dot, Vec3};

/// One node held on a tool's tangent plane for the next implicit step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeConstraint {
    /// The node (model index).
    pub node: u32,
    /// Unit normal of the plane, pointing out of the tool: the direction the tool pushes.
    pub normal: [f64; 3],
    /// The plane `normal . x = offset` (m) the node ends the step on.
    pub offset: f64,
    /// The caller's label (the contact response's tool index), handed back with the force.
    pub tag: u32,
}

impl NodeConstraint {
    /// The normal velocity change (m/s) that takes a node at `x` moving at `v` onto the plane
    /// in one backward Euler step of `h`: `x + h (v + dv)` on the plane.
    pub fn velocity_change(&self, x: Vec3, v: Vec3, h: f64) -> f64 {
        (self.offset - dot(self.normal, x)) / h - dot(self.normal, v)
    }

    /// Whether the constraint is usable: a finite unit normal and a finite offset.
    pub fn is_valid(&self) -> bool {
        let n2 = dot(self.normal, self.normal);
        self.offset.is_finite() && n2.is_finite() && (n2 - 1.0).abs() < 1e-6
    }
}

/// `a - n (n . a)`: `a` without its part along the unit `n`.
pub fn project_out(a: Vec3, n: Vec3) -> Vec3 {
    let d = dot(a, n);
    [0, 1, 2].map(|c| a[c] - d * n[c])
}

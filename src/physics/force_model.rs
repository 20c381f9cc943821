//! The force-model seam: the internal force of a model's elements on its nodes, and the
//! derivatives of that force an implicit integrator solves with.
//!
//! A [`ForceModel`] is stated in float64 on positions and velocities in the model's node
//! order: it is the reference of every engine's force kernel (the float32 CPU kernels and the
//! WGSL passes are its twins, in their own precision and order). Springs implement it today
//! ([`super::SpringForces`]); a finite-element model implements it beside them, contributing
//! per-node and per-edge terms (a 3x3 block where springs have a scalar stiffness), which is
//! what the three layouts store per node and per edge.
//!
//! The derivatives are given as products, never as assembled matrices: an implicit integrator
//! solves `(M - h D - h^2 K) dv = rhs` by conjugate gradients, which needs only `K w` and
//! `D w` for a vector `w` and, for a Jacobi preconditioner, the 3x3 diagonal blocks of `K` and
//! `D`. On the GPU those products are gathers over the same layouts as the force.

/// A 3-vector in float64.
pub type Vec3 = [f64; 3];
/// A 3x3 matrix in float64, row major.
pub type Mat3 = [[f64; 3]; 3];

/// Which stiffness matrix [`ForceModel::add_stiffness_product`] applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Linearization {
    /// The exact derivative of the elastic force with respect to positions. For springs it is
    /// indefinite where a spring is compressed (the transverse term `k (1 - L/l)` is negative
    /// there), so a system `M - h^2 K` built on it may lose positive definiteness at large `h`.
    Exact,
    /// The derivative with every element's indefinite part clamped so that `-K` is positive
    /// semi-definite (for springs, the transverse term of a compressed spring set to zero, as
    /// Choi and Ko do): `M - h D - h^2 K` is then positive definite for any `h`, and conjugate
    /// gradients always apply. The price is a slower Newton convergence under compression; at
    /// one Newton step per time step (Baraff and Witkin), a small extra damping of compressed
    /// springs' transverse motion.
    #[default]
    Definite,
}

/// The internal force of a model's elements on its nodes (elastic and damping; gravity, mass
/// damping and contact are the integrator's and the simulation's), with its derivatives.
///
/// All slices are indexed by node; `x` are positions (m), `v` velocities (m/s). The `add_*`
/// methods add into `out` so that several models (or several kinds of element) can sum their
/// contributions into one vector.
pub trait ForceModel: Sync {
    /// A short name for reports ("springs", "tensor-mass", ...).
    fn name(&self) -> &'static str;

    /// Add the force at positions `x` and velocities `v` (N) into `f`.
    fn add_forces(&self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]);

    /// Elastic potential energy at positions `x`, J (zero at rest): the elastic part of
    /// [`ForceModel::add_forces`] is minus its gradient.
    fn potential_energy(&self, x: &[Vec3]) -> f64;

    /// Add `K w` into `out`, where `K` is the derivative of the elastic force with respect to
    /// positions at `x`, as `lin` linearises it. The damping force's dependence on positions
    /// (through its direction) is left out, as Baraff and Witkin leave it out: it vanishes
    /// where the relative velocity does.
    fn add_stiffness_product(&self, x: &[Vec3], lin: Linearization, w: &[Vec3], out: &mut [Vec3]);

    /// Add `D w` into `out`, where `D` is the (exact) derivative of the damping force with
    /// respect to velocities at positions `x`.
    fn add_damping_product(&self, x: &[Vec3], w: &[Vec3], out: &mut [Vec3]);

    /// Add the 3x3 diagonal blocks of `K` (as `lin` linearises it) into `stiffness` and of
    /// `D` into `damping`, one per node: what a block-Jacobi preconditioner inverts.
    fn add_diagonal_blocks(
        &self,
        x: &[Vec3],
        lin: Linearization,
        stiffness: &mut [Mat3],
        damping: &mut [Mat3],
    );
}

/// `a - b`.
pub(crate) fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a . b`.
pub(crate) fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `m v`.
pub(crate) fn mat_vec(m: &Mat3, v: Vec3) -> Vec3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// `acc += s v`.
pub(crate) fn axpy(acc: &mut Vec3, s: f64, v: Vec3) {
    for c in 0..3 {
        acc[c] += s * v[c];
    }
}

//! The tets of a packed model with their region's material: what the finite-element force
//! models ([`crate::physics::TensorMass`], [`crate::physics::Corotational`]) are built from.

use super::material::Material;

/// A tet in dense form, with the material of its region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackedTet {
    /// Dense node indices of its four corners, positively oriented (as the mesh keeps them).
    pub nodes: [u32; 4],
    /// Its region tag (0 where the mesh has none), for messages.
    pub region: i32,
    /// The material of its region: a finite-element model reads Young's modulus and Poisson's
    /// ratio from [`super::Stiffness::Material`] and Rayleigh's `beta` from
    /// [`super::SpringDamping::StiffnessProportional`].
    pub material: Material,
}

//! Placing a scene's mesh: a scale factor, then a rotation, then a translation, as SOFA's mesh
//! loaders apply their `scale`, `rotation` and `translation`. A mesh file without units (the
//! SOFA liver reads as a 6.5 m organ) or in millimetres is brought to metres here, before
//! anything else in the scene (region boxes, fixed-node selectors, tools) is placed against it.

use nalgebra::{Point3, Rotation3};
use serde::{Deserialize, Serialize};

use crate::mesh::TetMesh;

/// How a scene's mesh, read or generated, is placed: every rest position `p` becomes
/// `translation + R (scale p)`, `R` the rotation.
///
/// ```ron
/// mesh_transform: (scale: 0.001, rotation: (0.0, 0.0, 90.0), translation: (0.0, 0.0, 0.05)),
/// ```
///
/// Every field is optional: the default is no change.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MeshTransform {
    /// Uniform scale factor, applied first: 0.001 for a file in millimetres. Finite and
    /// positive (a negative factor would turn every tet inside out).
    pub scale: f64,
    /// Rotation in degrees about the x, then the y, then the z axis (fixed axes; SOFA's
    /// `rotation`), applied to the scaled mesh about the origin.
    pub rotation: [f64; 3],
    /// Translation, m, applied last.
    pub translation: [f64; 3],
}

impl Default for MeshTransform {
    fn default() -> Self {
        MeshTransform {
            scale: 1.0,
            rotation: [0.0; 3],
            translation: [0.0; 3],
        }
    }
}

impl MeshTransform {
    /// Whether the transform leaves every position where it is.
    pub fn is_identity(&self) -> bool {
        *self == MeshTransform::default()
    }

    /// Check the numbers: a finite positive scale, finite angles and translation. The message
    /// says which field and what to give instead.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(format!(
                "scale {} must be finite and positive (0.001 for a file in millimetres); to \
                 mirror a mesh, mirror the file",
                self.scale
            ));
        }
        for (what, v) in [
            ("rotation", self.rotation),
            ("translation", self.translation),
        ] {
            if v.iter().any(|c| !c.is_finite()) {
                return Err(format!("{what} {v:?} must be finite"));
            }
        }
        Ok(())
    }

    /// Where the transform takes the point `p`.
    pub fn apply(&self, p: Point3<f64>) -> Point3<f64> {
        let [rx, ry, rz] = self.rotation.map(f64::to_radians);
        // nalgebra's roll, pitch, yaw: about x, then y, then z, on fixed axes.
        let r = Rotation3::from_euler_angles(rx, ry, rz);
        Point3::from(r * (p.coords * self.scale) + nalgebra::Vector3::from(self.translation))
    }

    /// Move every rest position of `mesh`. Tets keep their orientation: a rotation and a
    /// positive scale preserve it.
    pub fn apply_to(&self, mesh: &mut TetMesh) {
        if self.is_identity() {
            return;
        }
        let keys: Vec<_> = mesh.nodes().map(|(k, n)| (k, n.rest)).collect();
        for (k, p) in keys {
            mesh.set_rest(k, self.apply(p));
        }
    }
}

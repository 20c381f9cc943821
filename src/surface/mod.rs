//! Render surfaces: a detailed triangle surface (an organ as an artist modelled it) drawn in
//! place of the coarse simulation tets, and its embedding in the simulation mesh so that it
//! follows the deformation.
//!
//! - [`RenderSurface`]: vertex positions and triangles, read from Wavefront OBJ, STL or PLY by
//!   [`read`] (feature `surface-formats`).
//! - [`embed`]: each vertex bound to the simulation mesh (barycentric coordinates in the tet that
//!   holds it; an offset from the nearest boundary face for a vertex outside the mesh), and the
//!   deformed surface evaluated from the node positions on the CPU.
//! - [`vtp`]: the deformed surface per frame as VTK PolyData for ParaView (feature `vtu`).
//! - [`glb`]: triangle meshes per frame (the deformed surface, the tools) as binary glTF for
//!   Blender, three.js and ParaView (feature `glb`).
//! - [`colour`]: the displacement colour map of the pictures and the `.glb` vertex colours.
//! - [`rebind`]: after a cut, the vertices of the tets it changed bound again to the tet on
//!   their side (only those; a carved vertex with nothing left on its side is dropped).
//! - [`cap`]: after a cut, the triangles the blade crossed split at its sweep (a vertex per
//!   side at each crossing) and each side of the opening capped, so that the drawn surface
//!   stays closed and outward; the new vertices are bound on their own side.
//! - [`gap`]: the distance between the drawn surface and the simulation boundary.
//! - [`grid`]: the uniform grid that finds a vertex's tet and nearest boundary face without
//!   testing every tet.

#[cfg(feature = "cut")]
pub mod cap;
#[cfg(feature = "cut")]
mod cap_bind;
#[cfg(feature = "cut")]
mod cap_fill;
#[cfg(feature = "cut")]
mod cap_sweep;
pub mod colour;
pub mod embed;
pub mod gap;
#[cfg(feature = "glb")]
pub mod glb;
pub mod grid;
#[cfg(feature = "surface-formats")]
pub mod read;
#[cfg(feature = "cut")]
pub mod rebind;
#[cfg(all(feature = "formats", feature = "vtu"))]
pub mod vtp;

#[cfg(feature = "cut")]
pub use cap::{Capped, Capper};
pub use embed::{Binding, Embedding};
#[cfg(feature = "cut")]
pub use rebind::{CutChange, Rebinder, Rebound};

use crate::error::{Error, Result};

/// A triangle surface to render: positions (in the simulation mesh's units and frame) and
/// triangles as indices into them, counter-clockwise seen from outside where the source is.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderSurface {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Triangles, three vertex indices each.
    pub triangles: Vec<[u32; 3]>,
}

impl RenderSurface {
    /// A surface from its arrays, checked: every position finite, every index names a vertex.
    /// `what` names the source in messages (a file name, "the surface given").
    pub fn new(positions: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>, what: &str) -> Result<Self> {
        if let Some(i) = positions
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return Err(Error::Mesh(format!(
                "{what}: vertex {i} is at {:?}, not a finite position; fix or remove it",
                positions[i]
            )));
        }
        let n = positions.len();
        if let Some(t) = triangles
            .iter()
            .position(|t| t.iter().any(|&v| v as usize >= n))
        {
            return Err(Error::Mesh(format!(
                "{what}: triangle {t} uses vertex {:?} but there are {n} vertices",
                triangles[t]
            )));
        }
        Ok(RenderSurface {
            positions,
            triangles,
        })
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The same surface with every position mapped by `f` (a scene's scale and placement).
    pub fn mapped(&self, f: impl Fn([f64; 3]) -> [f64; 3]) -> Self {
        RenderSurface {
            positions: self.positions.iter().map(|&p| f(p)).collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// Axis-aligned bounds of the positions, `None` without vertices.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| {
            (
                [0, 1, 2].map(|c| lo[c].min(p[c])),
                [0, 1, 2].map(|c| hi[c].max(p[c])),
            )
        }))
    }
}

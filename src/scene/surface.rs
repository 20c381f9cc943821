//! A scene's render surface: read from an OBJ, STL or PLY file, placed by the scene's
//! `mesh_transform` like the mesh, embedded in the mesh at rest, and written per frame beside
//! the mesh's frames as `<series>_surface_<NNNNNN>.vtp`, listed in `<series>_surface.pvd`.
//!
//! ```ron
//! surface: File("organ.obj"),
//! ```
//!
//! The path is found as the mesh's is (relative to the scene file's folder, or
//! `$LANCET_MESH_DIR/...`). Cuts add nodes at the end of the node order and remove none, so
//! the embedding made at rest stays valid through them; its vertices follow the nodes they
//! were bound to (the side of a cut that kept the original nodes).

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::schema::{resolve_mesh_path, Scene};
use crate::error::Result;
use crate::mesh::TetMesh;
use crate::surface::read::read_surface;
use crate::surface::vtp::VtpSeries;
use crate::surface::{Embedding, RenderSurface};

/// Where a scene's render surface comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SurfaceSource {
    /// A Wavefront OBJ, STL or PLY file, by extension.
    File(String),
}

/// `surface: File("...")` without `Some(...)`: the field is optional, its value is not.
pub(super) fn deserialize<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Option<SurfaceSource>, D::Error> {
    SurfaceSource::deserialize(d).map(Some)
}

/// Written as it is read (skipped when absent).
pub(super) fn serialize<S: Serializer>(
    s: &Option<SurfaceSource>,
    ser: S,
) -> Result<S::Ok, S::Error> {
    match s {
        Some(source) => source.serialize(ser),
        None => ser.serialize_none(),
    }
}

/// What a run did with its render surface (`RunSummary::surface`).
#[derive(Debug, Clone, Serialize)]
pub struct SurfaceReport {
    /// Vertices of the surface.
    pub vertices: usize,
    /// Its triangles.
    pub triangles: usize,
    /// Vertices bound outside the mesh (by an offset from their nearest boundary face).
    pub outside: usize,
    /// Frames written (`.vtp` files).
    pub frames_written: usize,
    /// The `.pvd` series of the surface, if written.
    pub pvd: Option<PathBuf>,
}

/// The surface of a running scene, its embedding and its series of frames.
pub struct SurfaceStage {
    surface: RenderSurface,
    embedding: Embedding,
    series: Option<VtpSeries>,
}

impl SurfaceStage {
    /// Read, place and embed the scene's surface (`None` for a scene without one); frames go
    /// to `dir` (the run's output folder, if it writes frames) as the series `<stem>_surface`.
    pub fn new(
        scene: &Scene,
        scene_path: &Path,
        mesh: &TetMesh,
        dir: Option<&Path>,
        stem: &str,
    ) -> Result<Option<Self>> {
        let Some(SurfaceSource::File(file)) = &scene.surface else {
            return Ok(None);
        };
        let scene_dir = scene_path.parent().unwrap_or(Path::new("."));
        let path = resolve_mesh_path(file, scene_dir, scene_path)?;
        let t = scene.mesh_transform;
        let surface = read_surface(&path)?.mapped(|p| t.apply(Point3::from(p)).into());
        let embedding = Embedding::new(mesh, &surface)?;
        let series = dir.map(|d| VtpSeries::new(d, &format!("{stem}_surface")));
        Ok(Some(SurfaceStage {
            surface,
            embedding,
            series,
        }))
    }

    /// Write a frame at `time` from the node positions `x` (dense order), if frames are
    /// written.
    pub fn frame(&mut self, time: f64, x: &[[f64; 3]]) -> Result<()> {
        if let Some(series) = &mut self.series {
            series.frame(time, &self.surface, &self.embedding.evaluate(x))?;
        }
        Ok(())
    }

    /// The surface at rest (placed) and its vertices at node positions `x` (dense order).
    pub fn deformed(&self, x: &[[f64; 3]]) -> (&RenderSurface, Vec<[f64; 3]>) {
        (&self.surface, self.embedding.evaluate(x))
    }

    /// What was done, for the run's summary.
    pub fn report(&self) -> SurfaceReport {
        SurfaceReport {
            vertices: self.surface.vertex_count(),
            triangles: self.surface.triangles.len(),
            outside: self.embedding.outside_count(),
            frames_written: self.series.as_ref().map_or(0, VtpSeries::frames),
            pvd: self.series.as_ref().map(VtpSeries::pvd_path),
        }
    }
}

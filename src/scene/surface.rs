//! A scene's render surface: read from an OBJ, STL or PLY file, placed by the scene's
//! `mesh_transform` like the mesh, embedded in the mesh at rest, and written per frame beside
//! the mesh's frames as `<series>_surface_<NNNNNN>.vtp`, listed in `<series>_surface.pvd`.
//!
//! ```ron
//! surface: File("organ.obj"),
//! ```
//!
//! The path is found as the mesh's is (relative to the scene file's folder, or
//! `$LANCET_MESH_DIR/...`). After each cut the vertices of the tets it changed are bound again
//! to the tet on their side ([`crate::surface::rebind`]; a carved vertex with nothing left on
//! its side is dropped with its triangles), the triangles the blade crossed are split at its
//! sweep and each side of the opening is capped ([`crate::surface::cap`]), so that the drawn
//! surface stays closed and outward.

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::schema::{resolve_mesh_path, Scene};
use crate::error::Result;
use crate::mesh::TetMesh;
use crate::surface::gap::{boundary_gap, Gap};
use crate::surface::read::read_surface;
use crate::surface::vtp::VtpSeries;
use crate::surface::{Capper, CutChange, Embedding, Rebinder, RenderSurface};
use crate::world::cutting::Cutting;

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
    /// Cuts the surface followed (rebinding the vertices of the tets each changed).
    pub rebinds: usize,
    /// Vertices rebound, over all cuts.
    pub vertices_rebound: usize,
    /// Vertices dropped (carved, nothing left on their side), with their triangles.
    pub dropped: usize,
    /// Time to rebind after a cut, ms: median.
    pub rebind_p50_ms: f64,
    /// 99th percentile, ms.
    pub rebind_p99_ms: f64,
    /// Largest, ms.
    pub rebind_max_ms: f64,
    /// Vertices the cuts added (crossings of the blade, two per crossing, and slit ends), at
    /// the end.
    pub vertices_added: usize,
    /// Triangles drawn at the end (the surface's, split where a blade crossed them, and the
    /// caps).
    pub triangles_drawn: usize,
    /// Cap triangles at the end.
    pub cap_triangles: usize,
    /// Rims left open at the last cut (their triangulation failed); 0 when closed.
    pub open_rims: usize,
    /// Time to split and cap after a cut, ms: median.
    pub cap_p50_ms: f64,
    /// 99th percentile, ms.
    pub cap_p99_ms: f64,
    /// Largest, ms.
    pub cap_max_ms: f64,
    /// Distance from the drawn vertices to the simulation boundary at rest, m.
    pub gap_rest: Gap,
    /// The same at the end of the run (cut and deformed).
    pub gap_end: Gap,
}

/// The surface of a running scene, its embedding and its series of frames.
pub struct SurfaceStage {
    surface: RenderSurface,
    embedding: Embedding,
    series: Option<VtpSeries>,
    /// Made at the first cut.
    rebinder: Option<Rebinder>,
    capper: Capper,
    /// The surface as drawn once cut: the vertices the cuts added appended, split and capped
    /// triangles, dropped vertices' triangles left out.
    drawn: Option<RenderSurface>,
    rebind_s: Vec<f64>,
    cap_s: Vec<f64>,
    cap_triangles: usize,
    open_rims: usize,
    vertices_rebound: usize,
    gap_rest: Gap,
    gap_end: Gap,
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
        let rest: Vec<[f64; 3]> = mesh.nodes().map(|(_, n)| n.rest.into()).collect();
        let gap_rest = boundary_gap(&embedding, mesh, &rest);
        Ok(Some(SurfaceStage {
            capper: Capper::new(surface.vertex_count(), &surface.triangles),
            surface,
            embedding,
            series,
            rebinder: None,
            drawn: None,
            rebind_s: Vec::new(),
            cap_s: Vec::new(),
            cap_triangles: 0,
            open_rims: 0,
            vertices_rebound: 0,
            gap_rest,
            gap_end: Gap::default(),
        }))
    }

    /// Follow the cuts `cut` made since the last call: rebind the vertices of the tets each
    /// changed, then split and cap the surface at the blade's sweep, the strokes before it
    /// that changed no tet included ([`crate::world::cutting::CutMade::earlier`]).
    pub fn after_cuts(&mut self, cut: &mut Cutting) {
        let made = cut.take_cuts();
        if made.is_empty() {
            return;
        }
        let cutter = cut.cutter();
        let (mesh, faces) = (cutter.mesh(), cutter.faces());
        let embedding = &mut self.embedding;
        let rebinder = self
            .rebinder
            .get_or_insert_with(|| Rebinder::new(mesh, embedding));
        for m in &made {
            if !m.tets.is_empty() {
                let r = rebinder.rebind(
                    embedding,
                    &CutChange {
                        mesh,
                        faces,
                        tets: &m.tets,
                        sweep: &m.sweep,
                    },
                );
                self.rebind_s.push(r.seconds);
                self.vertices_rebound += r.vertices.len();
            }
            // The strokes that changed no tet before it cut the surface too: the mesh opens
            // under them at this cut (separating opens a tet once the blade is through it).
            for stroke in &m.earlier {
                self.capper.follow(stroke);
            }
            let capped = self.capper.cut(embedding, mesh, &m.sweep);
            self.cap_s.push(capped.seconds);
            self.cap_triangles = capped.cap_triangles;
            self.open_rims = capped.open;
            self.drawn = Some(RenderSurface {
                positions: embedding.rest.clone(),
                triangles: capped.triangles,
            });
        }
    }

    /// Measure the gap to the simulation boundary at the end of the run (`mesh` as cut, node
    /// positions `x`). The runner has given the surface the blades' last strokes before
    /// ([`crate::world::World::finish_cuts`], then [`SurfaceStage::after_cuts`]).
    pub fn finish(&mut self, mesh: &TetMesh, x: &[[f64; 3]]) {
        self.gap_end = boundary_gap(&self.embedding, mesh, x);
    }

    /// The embedding as rebound so far.
    pub fn embedding(&self) -> &Embedding {
        &self.embedding
    }

    /// Write a frame at `time` from the node positions `x` (dense order), if frames are
    /// written.
    pub fn frame(&mut self, time: f64, x: &[[f64; 3]]) -> Result<()> {
        if let Some(series) = &mut self.series {
            let surface = self.drawn.as_ref().unwrap_or(&self.surface);
            series.frame(time, surface, &self.embedding.evaluate(x))?;
        }
        Ok(())
    }

    /// The surface as drawn at rest (placed; split and capped once cut) and its vertices at
    /// node positions `x` (dense order).
    pub fn deformed(&self, x: &[[f64; 3]]) -> (&RenderSurface, Vec<[f64; 3]>) {
        (self.drawn(), self.embedding.evaluate(x))
    }

    /// The surface as drawn at rest: as read until a cut, then split and capped.
    pub fn drawn(&self) -> &RenderSurface {
        self.drawn.as_ref().unwrap_or(&self.surface)
    }

    /// What was done, for the run's summary.
    pub fn report(&self) -> SurfaceReport {
        SurfaceReport {
            vertices: self.surface.vertex_count(),
            triangles: self.surface.triangles.len(),
            outside: self.embedding.outside_count(),
            frames_written: self.series.as_ref().map_or(0, VtpSeries::frames),
            pvd: self.series.as_ref().map(VtpSeries::pvd_path),
            rebinds: self.rebind_s.len(),
            vertices_rebound: self.vertices_rebound,
            dropped: self.embedding.dropped_count(),
            rebind_p50_ms: 1e3 * percentile(&self.rebind_s, 0.5),
            rebind_p99_ms: 1e3 * percentile(&self.rebind_s, 0.99),
            rebind_max_ms: 1e3 * self.rebind_s.iter().copied().fold(0.0, f64::max),
            vertices_added: self.embedding.len() - self.surface.vertex_count(),
            triangles_drawn: self.drawn().triangles.len(),
            cap_triangles: self.cap_triangles,
            open_rims: self.open_rims,
            cap_p50_ms: 1e3 * percentile(&self.cap_s, 0.5),
            cap_p99_ms: 1e3 * percentile(&self.cap_s, 0.99),
            cap_max_ms: 1e3 * self.cap_s.iter().copied().fold(0.0, f64::max),
            gap_rest: self.gap_rest,
            gap_end: self.gap_end,
        }
    }
}

/// The `q` quantile of `samples` (nearest rank), 0 without samples.
fn percentile(samples: &[f64], q: f64) -> f64 {
    let mut l = samples.to_vec();
    l.sort_by(f64::total_cmp);
    match l.len() {
        0 => 0.0,
        n => l[((q * (n - 1) as f64).round() as usize).min(n - 1)],
    }
}

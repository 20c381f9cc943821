//! What a run shows at each frame, beyond the tet mesh's `.vtu`: the tissue's surface and the
//! tools as triangle meshes ([`Frame`]), written beside the VTU frames as binary glTF
//! (`<series>_<NNNNNN>.glb`: a node `tissue` and one per tool) and, for scenes with tools, the
//! tools as a VTP series ParaView opens (`<series>_tools.pvd`), and handed to any
//! [`FrameSink`] the caller gives ([`super::runner::run_scene_with`]; `lancet render` draws
//! them).
//!
//! The tissue's surface is the render surface where the scene has one (deformed by its
//! embedding), else the boundary of the tet mesh as cut so far, so that the faces a cut opened
//! show.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::schema::Scene;
use super::surface::SurfaceStage;
use crate::collide::Tool;
use crate::error::Result;
use crate::mesh::TetMesh;
use crate::surface::colour::displacement_colour;
use crate::surface::glb::{GlbMesh, GlbSeries};
use crate::surface::vtp::VtpSeries;
use crate::surface::RenderSurface;

/// One mesh of a frame, at its current positions.
#[derive(Debug, Clone)]
pub struct FrameMesh {
    /// "tissue", or the tool's name.
    pub name: String,
    /// The triangles at the frame's positions (scene frame, m).
    pub surface: RenderSurface,
    /// Each vertex's displacement from rest, m (the tissue's; empty for a tool).
    pub displacement: Vec<f64>,
}

/// What a run shows at one frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// The frame's number, from 0 (the rest state, before the first step).
    pub index: usize,
    /// Simulated time, s.
    pub time: f64,
    /// Steps taken.
    pub step: u64,
    /// The tissue's surface.
    pub tissue: FrameMesh,
    /// The tools, in the scene's order.
    pub tools: Vec<FrameMesh>,
}

impl Frame {
    /// The largest displacement of the tissue's surface, m (0 without vertices).
    pub fn max_displacement(&self) -> f64 {
        self.tissue.displacement.iter().copied().fold(0.0, f64::max)
    }
}

/// Something that takes each frame of a run (a picture writer, a test).
pub trait FrameSink {
    /// Take one frame; an error ends the run with it.
    fn frame(&mut self, frame: &Frame) -> Result<()>;
}

impl<F: FnMut(&Frame) -> Result<()>> FrameSink for F {
    fn frame(&mut self, frame: &Frame) -> Result<()> {
        self(frame)
    }
}

/// The tissue's surface at node positions `x` (dense order), with displacements from `rest`:
/// the render surface of `surface` if there is one, else the boundary of `mesh` (its vertices
/// only those the boundary uses, in the order first used).
pub fn tissue(
    mesh: &TetMesh,
    surface: Option<&SurfaceStage>,
    x: &[[f64; 3]],
    rest: &[[f64; 3]],
) -> FrameMesh {
    let distance = |a: &[f64; 3], b: &[f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    if let Some(stage) = surface {
        let (at_rest, positions) = stage.deformed(x);
        let displacement = positions
            .iter()
            .zip(&at_rest.positions)
            .map(|(p, r)| distance(p, r))
            .collect();
        return FrameMesh {
            name: "tissue".into(),
            surface: RenderSurface {
                positions,
                triangles: at_rest.triangles.clone(),
            },
            displacement,
        };
    }
    let boundary = crate::collide::broad::Surface::of(mesh).triangles;
    let mut vertex = vec![u32::MAX; x.len()];
    let mut positions = Vec::new();
    let mut displacement = Vec::new();
    let triangles = boundary
        .iter()
        .map(|t| {
            t.map(|n| {
                let n = n as usize;
                if vertex[n] == u32::MAX {
                    vertex[n] = positions.len() as u32;
                    positions.push(x[n]);
                    // A node the model has no rest position for (none should be) shows as
                    // undisplaced rather than failing the frame.
                    displacement.push(rest.get(n).map_or(0.0, |r| distance(&x[n], r)));
                }
                vertex[n]
            })
        })
        .collect();
    FrameMesh {
        name: "tissue".into(),
        surface: RenderSurface {
            positions,
            triangles,
        },
        displacement,
    }
}

/// The scene's tools at their current poses, as meshes named after them.
pub fn tools(scene: &Scene, tools: &[Tool]) -> Vec<FrameMesh> {
    scene
        .tools
        .iter()
        .zip(tools)
        .map(|(s, t)| FrameMesh {
            name: s.name.clone(),
            surface: t.shape.mesh(t.pose()),
            displacement: Vec::new(),
        })
        .collect()
}

/// The base colour of the tools in the `.glb` frames and pictures: a light steel grey.
pub const TOOL_COLOUR: [f32; 3] = [0.72, 0.74, 0.78];

/// The `.glb` meshes of a frame: the tissue with the vertex `colours` given, the tools grey.
pub fn glb_meshes<'a>(frame: &'a Frame, colours: &'a [[f32; 3]]) -> Vec<GlbMesh<'a>> {
    let mut meshes = vec![GlbMesh {
        name: &frame.tissue.name,
        positions: &frame.tissue.surface.positions,
        triangles: &frame.tissue.surface.triangles,
        colours: Some(colours),
        base_colour: [1.0; 4],
    }];
    meshes.extend(frame.tools.iter().map(|t| GlbMesh {
        name: &t.name,
        positions: &t.surface.positions,
        triangles: &t.surface.triangles,
        colours: None,
        base_colour: [TOOL_COLOUR[0], TOOL_COLOUR[1], TOOL_COLOUR[2], 1.0],
    }));
    meshes
}

/// The tissue's vertex colours: displacement on `[0, max]`, viridis.
pub fn tissue_colours(frame: &Frame, max: f64) -> Vec<[f32; 3]> {
    frame
        .tissue
        .displacement
        .iter()
        .map(|&d| displacement_colour(d, max))
        .collect()
}

/// What a run wrote of its frames besides the VTU series (`RunSummary::frame_files`).
#[derive(Debug, Clone, Serialize)]
pub struct FrameFilesReport {
    /// `.glb` frames written (`<series>_<NNNNNN>.glb`).
    pub glb_frames: usize,
    /// The first of them.
    pub glb_first: Option<PathBuf>,
    /// The tools' VTP series (scenes with tools).
    pub tools_pvd: Option<PathBuf>,
}

/// The files a run writes per frame besides the VTU series: the `.glb` frames, and the tools'
/// VTP series for scenes with tools.
pub struct FrameFiles {
    glb: GlbSeries,
    tools: Option<VtpSeries>,
}

impl FrameFiles {
    /// Frames into `dir` as the series `stem` (the VTU series' name).
    pub fn new(dir: &Path, stem: &str, scene: &Scene) -> Self {
        FrameFiles {
            glb: GlbSeries::new(dir, stem),
            tools: (!scene.tools.is_empty()).then(|| VtpSeries::new(dir, &format!("{stem}_tools"))),
        }
    }

    /// Write `frame`: the tissue coloured on the frame's own displacement range.
    pub fn write(&mut self, frame: &Frame) -> Result<()> {
        let colours = tissue_colours(frame, frame.max_displacement());
        self.glb.frame(&glb_meshes(frame, &colours))?;
        if let Some(series) = self.tools.as_mut() {
            let mut all = RenderSurface::default();
            for t in &frame.tools {
                let first = all.positions.len() as u32;
                all.positions.extend_from_slice(&t.surface.positions);
                all.triangles
                    .extend(t.surface.triangles.iter().map(|tri| tri.map(|v| v + first)));
            }
            series.frame(frame.time, &all, &all.positions)?;
        }
        Ok(())
    }

    /// What was written.
    pub fn report(&self) -> FrameFilesReport {
        FrameFilesReport {
            glb_frames: self.glb.frames(),
            glb_first: (self.glb.frames() > 0).then(|| self.glb.frame_path(0)),
            tools_pvd: self.tools.as_ref().map(VtpSeries::pvd_path),
        }
    }
}

/// Where a run's frames go besides the VTU series: its frame files (when it writes output) and
/// the caller's sink.
pub struct FrameOutputs<'a> {
    files: Option<FrameFiles>,
    sink: Option<&'a mut dyn FrameSink>,
    next: usize,
}

impl<'a> FrameOutputs<'a> {
    /// Frames to `files` and `sink`, either or both absent.
    pub fn new(files: Option<FrameFiles>, sink: Option<&'a mut dyn FrameSink>) -> Self {
        FrameOutputs {
            files,
            sink,
            next: 0,
        }
    }

    /// Whether anything takes frames.
    pub fn is_active(&self) -> bool {
        self.files.is_some() || self.sink.is_some()
    }

    /// Make the next frame from the simulation's state (`x` its positions, `mesh` the mesh as
    /// cut so far, `tools` at their poses) and hand it on.
    pub fn emit(
        &mut self,
        scene: &Scene,
        sim: &crate::engine::Simulation,
        mesh: &TetMesh,
        x: &[[f64; 3]],
        surface: Option<&SurfaceStage>,
        tool_list: &[Tool],
    ) -> Result<()> {
        if !self.is_active() {
            return Ok(());
        }
        let frame = Frame {
            index: self.next,
            time: sim.time(),
            step: sim.steps(),
            tissue: tissue(mesh, surface, x, &sim.model().rest),
            tools: tools(scene, tool_list),
        };
        self.next += 1;
        if let Some(files) = self.files.as_mut() {
            files.write(&frame)?;
        }
        if let Some(sink) = self.sink.as_mut() {
            sink.frame(&frame)?;
        }
        Ok(())
    }

    /// What the frame files hold, if any were written.
    pub fn report(&self) -> Option<FrameFilesReport> {
        self.files.as_ref().map(FrameFiles::report)
    }
}

//! Pictures of a scene run: a [`FrameSink`] that draws each frame after the rest state (the
//! tissue's surface coloured by displacement, the tools grey), adds the colour bar and writes
//! `<stem>_<NNNNNN>.png`, NNNNNN the frame's number.
//!
//! The camera is fitted once, to the tissue's surface at rest (the first frame), so that
//! motion shows against a fixed view; the tools are not in the fit (a long blade would shrink
//! the tissue). Up in the picture is against the scene's gravity (+z without gravity) unless
//! given.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use serde::Serialize;

use super::png_out::{draw_legend, write_png};
use super::{Camera, DrawMesh, Paint, Renderer, View};
use crate::engine::gpu::GpuContext;
use crate::error::Result;
use crate::scene::frames::{tissue_colours, Frame, FrameSink, TOOL_COLOUR};
use crate::scene::Scene;

/// How the pictures look.
#[derive(Debug, Clone, PartialEq)]
pub struct PictureOptions {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Camera direction and zoom.
    pub view: View,
    /// Up in the picture (`None`: against the scene's gravity).
    pub up: Option<Vector3<f64>>,
    /// Top of the colour range, m (`None`: each frame's largest displacement).
    pub colour_max: Option<f64>,
    /// Draw the colour bar.
    pub legend: bool,
}

impl Default for PictureOptions {
    fn default() -> Self {
        PictureOptions {
            width: 800,
            height: 600,
            view: View::default(),
            up: None,
            colour_max: None,
            legend: true,
        }
    }
}

/// One picture written.
#[derive(Debug, Clone, Serialize)]
pub struct Picture {
    /// The file.
    pub path: PathBuf,
    /// The frame's simulated time, s.
    pub time: f64,
    /// The displacement at the top of the colour bar, m.
    pub colour_max: f64,
    /// The fraction of pixels the tissue and tools cover (not the background or the bar).
    pub coverage: f64,
}

/// Up against `scene`'s gravity, +z without gravity.
pub fn scene_up(scene: &Scene) -> Vector3<f64> {
    let g = Vector3::from(scene.gravity);
    (-g).try_normalize(0.0).unwrap_or_else(Vector3::z)
}

/// Draws a run's frames to PNG files.
pub struct PngFrames {
    renderer: Renderer,
    options: PictureOptions,
    up: Vector3<f64>,
    dir: PathBuf,
    stem: String,
    camera: Option<Camera>,
    /// What was written, in order.
    pub pictures: Vec<Picture>,
}

impl PngFrames {
    /// Pictures of a run of `scene` into `dir` (created) as `<stem>_<NNNNNN>.png`, drawn on
    /// `ctx`'s device.
    pub fn new(
        ctx: &GpuContext,
        scene: &Scene,
        dir: &Path,
        stem: &str,
        options: PictureOptions,
    ) -> Result<Self> {
        std::fs::create_dir_all(dir).map_err(|e| crate::Error::io(dir, e))?;
        Ok(PngFrames {
            renderer: Renderer::new(ctx, options.width, options.height)?,
            up: options.up.unwrap_or_else(|| scene_up(scene)),
            options,
            dir: dir.to_path_buf(),
            stem: stem.to_string(),
            camera: None,
            pictures: Vec::new(),
        })
    }

    /// The camera, once the first frame has fitted it.
    pub fn camera(&self) -> Option<&Camera> {
        self.camera.as_ref()
    }
}

impl FrameSink for PngFrames {
    fn frame(&mut self, frame: &Frame) -> Result<()> {
        let camera = match self.camera {
            Some(c) => c,
            None => {
                let tissue = DrawMesh {
                    positions: &frame.tissue.surface.positions,
                    triangles: &frame.tissue.surface.triangles,
                    paint: Paint::Solid([0.0; 3]),
                };
                let (lo, hi) = super::mesh_draw::bounds(&[tissue]).unwrap_or(([0.0; 3], [0.0; 3]));
                let c = Camera::fit(lo, hi, self.up, &self.options.view, self.renderer.aspect());
                self.camera = Some(c);
                c
            }
        };
        // The rest state only fits the camera: its picture would be a single colour.
        if frame.index == 0 {
            return Ok(());
        }
        let colour_max = self
            .options
            .colour_max
            .unwrap_or_else(|| frame.max_displacement());
        let colours = tissue_colours(frame, colour_max);
        let mut meshes = vec![DrawMesh {
            positions: &frame.tissue.surface.positions,
            triangles: &frame.tissue.surface.triangles,
            paint: Paint::PerVertex(&colours),
        }];
        meshes.extend(frame.tools.iter().map(|t| DrawMesh {
            positions: &t.surface.positions,
            triangles: &t.surface.triangles,
            paint: Paint::Solid(TOOL_COLOUR),
        }));
        let mut image = self.renderer.render(&meshes, &camera)?;
        let background = self
            .renderer
            .background
            .map(|c| super::png_out::to_byte(c as f32));
        let covered = image
            .rgba
            .chunks_exact(4)
            .filter(|p| p[..3] != background[..3])
            .count();
        if self.options.legend {
            draw_legend(&mut image);
        }
        let path = self
            .dir
            .join(format!("{}_{:06}.png", self.stem, frame.index));
        write_png(&path, &image)?;
        self.pictures.push(Picture {
            path,
            time: frame.time,
            colour_max,
            coverage: covered as f64 / (image.width as f64 * image.height as f64),
        });
        Ok(())
    }
}

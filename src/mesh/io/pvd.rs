//! ParaView `.pvd` time series (placeholder until the VTU writer lands).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::mesh::TetMesh;

/// Writes VTU frames and a `.pvd` collection.
pub struct PvdWriter;

/// Options of the VTU files.
#[derive(Default)]
pub struct VtuOptions;

impl PvdWriter {
    /// Start a series.
    pub fn new(_dir: &Path, _stem: &str, _opts: VtuOptions) -> Result<Self> {
        Err(Error::Unsupported(
            "vtu writing is not available yet".into(),
        ))
    }
    /// Write a frame.
    pub fn frame(&mut self, _t: f64, _m: &TetMesh, _x: Option<&[[f64; 3]]>) -> Result<PathBuf> {
        Err(Error::Unsupported(
            "vtu writing is not available yet".into(),
        ))
    }
    /// Frames written.
    pub fn frames(&self) -> usize {
        0
    }
}

//! ParaView `.pvd` time series: one `.vtu` per frame and a collection file listing them.
//!
//! The collection is rewritten (atomically) after every frame, so a run that stops early, or is
//! watched while it runs, always leaves a series ParaView can open.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::vtu::{atomic_write, write_vtu, VtuOptions};
use crate::error::{Error, Result};
use crate::mesh::TetMesh;

/// Writes frames `<dir>/<stem>_<NNNNNN>.vtu` and keeps `<dir>/<stem>.pvd` listing them.
#[derive(Debug, Clone)]
pub struct PvdWriter {
    dir: PathBuf,
    stem: String,
    opts: VtuOptions,
    /// Time and file name (relative to `dir`) of each frame written.
    frames: Vec<(f64, String)>,
}

impl PvdWriter {
    /// Start a series in `dir` (created if missing), writing an empty collection right away.
    /// An existing `<stem>.pvd` is replaced, and the frame files of an earlier series of the
    /// same name (`<stem>_<NNNNNN>.vtu`) are removed first, so that a rerun with fewer frames
    /// leaves none that its collection does not list.
    pub fn new(dir: &Path, stem: &str, opts: VtuOptions) -> Result<Self> {
        if stem.is_empty() || stem.contains(['/', '\\']) || stem == "." || stem == ".." {
            return Err(Error::io(
                dir.join(stem),
                invalid(format!(
                    "series name {stem:?} must be a plain, non-empty file name"
                )),
            ));
        }
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        remove_frames(dir, stem)?;
        let w = PvdWriter {
            dir: dir.to_path_buf(),
            stem: stem.to_string(),
            opts,
            frames: Vec::new(),
        };
        w.write_collection()?;
        Ok(w)
    }

    /// Write a frame at simulation time `time` (finite, greater than the previous frame's) and
    /// update the collection. `positions` are current positions in
    /// [`TetMesh::dense_nodes`] order, `None` for the rest shape. Returns the frame's path.
    pub fn frame(
        &mut self,
        time: f64,
        mesh: &TetMesh,
        positions: Option<&[[f64; 3]]>,
    ) -> Result<PathBuf> {
        let last = self.frames.last().map(|f| f.0);
        if !time.is_finite() || last.is_some_and(|t| time <= t) {
            return Err(Error::io(
                self.pvd_path(),
                invalid(format!(
                    "frame time {time} must be finite and greater than the previous {}",
                    last.map_or("(none)".to_string(), |t| t.to_string())
                )),
            ));
        }
        let name = format!("{}_{:06}.vtu", self.stem, self.frames.len());
        let path = self.dir.join(&name);
        write_vtu(&path, mesh, positions, &self.opts)?;
        self.frames.push((time, name));
        self.write_collection()?;
        Ok(path)
    }

    /// Number of frames written.
    pub fn frames(&self) -> usize {
        self.frames.len()
    }

    /// The collection file, `<dir>/<stem>.pvd`.
    pub fn pvd_path(&self) -> PathBuf {
        self.dir.join(format!("{}.pvd", self.stem))
    }

    fn write_collection(&self) -> Result<()> {
        atomic_write(&self.pvd_path(), |w| {
            writeln!(w, "<?xml version=\"1.0\"?>")?;
            writeln!(
                w,
                "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">"
            )?;
            writeln!(w, "  <Collection>")?;
            for (time, file) in &self.frames {
                // `{}` of an f64 reads back to the same value.
                writeln!(
                    w,
                    "    <DataSet timestep=\"{time}\" group=\"\" part=\"0\" file=\"{}\"/>",
                    quick_xml::escape::escape(file.as_str())
                )?;
            }
            writeln!(w, "  </Collection>")?;
            writeln!(w, "</VTKFile>")
        })
    }
}

/// Remove the files `<stem>_<six digits>.vtu` in `dir`: the frames of an earlier series.
fn remove_frames(dir: &Path, stem: &str) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let frame_number = name
            .strip_prefix(stem)
            .and_then(|r| r.strip_prefix('_'))
            .and_then(|r| r.strip_suffix(".vtu"));
        if frame_number.is_some_and(|n| n.len() == 6 && n.bytes().all(|b| b.is_ascii_digit())) {
            let path = entry.path();
            std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        }
    }
    Ok(())
}

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

//! ParaView `.pvd` time series: one `.vtu` per frame and a collection file listing them.
//!
//! The collection is rewritten (atomically: a temporary file renamed over it) after every
//! frame, so a run that stops early, is killed, or is watched while it runs, always leaves a
//! series ParaView can open. Syncing to disk, which costs more than writing a small frame, is
//! kept off the per-frame path: frames and collection are synced together every
//! [`SYNC_EVERY`] and when the series is finished. A crash of the system itself (not of the
//! process) can lose the frames written since the last sync: they may then be missing or
//! empty, though the collection lists them.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::vtu::{is_temp_of, replace_file, write_vtu_synced, VtuOptions};
use crate::error::{Error, Result};
use crate::mesh::TetMesh;

/// How long frames may stay unsynced: written (whole, under their final name) but possibly
/// only in the system's cache.
pub const SYNC_EVERY: Duration = Duration::from_secs(5);

/// Writes frames `<dir>/<stem>_<NNNNNN>.vtu` and keeps `<dir>/<stem>.pvd` listing them.
///
/// Call [`PvdWriter::finish`] at the end to sync what is not yet on disk (dropping the writer
/// does the same, but cannot report an error).
#[derive(Debug)]
pub struct PvdWriter {
    dir: PathBuf,
    stem: String,
    opts: VtuOptions,
    /// Time and file name (relative to `dir`) of each frame written.
    frames: Vec<(f64, String)>,
    /// Frames written since the last sync.
    unsynced: Vec<PathBuf>,
    last_sync: Instant,
}

impl PvdWriter {
    /// Start a series in `dir` (created if missing), writing an empty collection right away.
    /// An existing `<stem>.pvd` is replaced, and the frame files of an earlier series of the
    /// same name (`<stem>_<NNNNNN>.vtu`) are removed first, so that a rerun with fewer frames
    /// leaves none that its collection does not list, and so are the hidden temporary files a
    /// killed writer of the series left (`.<stem>_<NNNNNN>.vtu.<pid>.tmp`,
    /// `.<stem>.pvd.<pid>.tmp`).
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
            unsynced: Vec::new(),
            last_sync: Instant::now(),
        };
        w.write_collection(true)?;
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
        write_vtu_synced(&path, mesh, positions, &self.opts, false)?;
        self.frames.push((time, name));
        self.unsynced.push(path.clone());
        if self.last_sync.elapsed() >= SYNC_EVERY {
            self.finish()?;
        } else {
            self.write_collection(false)?;
        }
        Ok(path)
    }

    /// Sync the frames written since the last sync, then the collection listing them, then
    /// the folder (which holds their names): frames first, so that a collection on disk after
    /// a sync lists only frames on disk. Done every [`SYNC_EVERY`] while frames are written;
    /// call it once more at the end.
    pub fn finish(&mut self) -> Result<()> {
        for path in &self.unsynced {
            std::fs::OpenOptions::new()
                .write(true)
                .open(path)
                .and_then(|f| f.sync_all())
                .map_err(|e| Error::io(path, e))?;
        }
        self.write_collection(true)?;
        sync_dir(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        self.unsynced.clear();
        self.last_sync = Instant::now();
        Ok(())
    }

    /// Number of frames written.
    pub fn frames(&self) -> usize {
        self.frames.len()
    }

    /// The collection file, `<dir>/<stem>.pvd`.
    pub fn pvd_path(&self) -> PathBuf {
        self.dir.join(format!("{}.pvd", self.stem))
    }

    fn write_collection(&self, sync: bool) -> Result<()> {
        write_collection(&self.pvd_path(), &self.frames, sync)
    }
}

impl Drop for PvdWriter {
    /// Sync what [`PvdWriter::finish`] was not called for (a run that ended in an error).
    fn drop(&mut self) {
        if !self.unsynced.is_empty() {
            let _ = self.finish();
        }
    }
}

/// Sync a folder, so that the names of the files just renamed into it survive a crash of the
/// system. Only Unix can open a folder to sync it; elsewhere the rename is left to the system.
fn sync_dir(dir: &Path) -> io::Result<()> {
    #[cfg(unix)]
    std::fs::File::open(dir)?.sync_all()?;
    #[cfg(not(unix))]
    let _ = dir;
    Ok(())
}

/// Whether `name` is a frame of the series `stem`: `<stem>_<six digits>.vtu`.
fn is_frame_of(name: &str, stem: &str) -> bool {
    name.strip_prefix(stem)
        .and_then(|r| r.strip_prefix('_'))
        .and_then(|r| r.strip_suffix(".vtu"))
        .is_some_and(|n| n.len() == 6 && n.bytes().all(|b| b.is_ascii_digit()))
}

/// Remove the files of an earlier series `stem` in `dir`: its frames `<stem>_<six digits>.vtu`,
/// and the hidden temporary files a killed writer left of its frames and collection.
fn remove_frames(dir: &Path, stem: &str) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let pvd = format!("{stem}.pvd");
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let temp_of_series = name.strip_prefix('.').is_some_and(|r| {
            let target = r.rsplitn(3, '.').nth(2).unwrap_or_default();
            (target == pvd || is_frame_of(target, stem)) && is_temp_of(name, target)
        });
        if is_frame_of(name, stem) || temp_of_series {
            let path = entry.path();
            std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        }
    }
    Ok(())
}

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

/// Write (atomically: a temporary file renamed over the old one) the `.pvd` collection at `path` listing each
/// `(time, file)` frame; `sync` flushes it to disk. The VTU series and the render surface's VTP
/// series both list their frames through it.
pub fn write_collection(path: &Path, frames: &[(f64, String)], sync: bool) -> Result<()> {
    replace_file(path, sync, |w| {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">"
        )?;
        writeln!(w, "  <Collection>")?;
        for (time, file) in frames {
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

//! The deformed render surface per frame as VTK XML PolyData (`.vtp`, which ParaView opens),
//! with its own `.pvd` series beside the tet mesh's: `<stem>_surface_<NNNNNN>.vtp` listed in
//! `<stem>_surface.pvd`. Each frame carries the vertex positions and their displacements from
//! rest (point data `displacement`, to colour by). Written as ASCII with shortest round-trip
//! numbers: a frame reads back to the same float64 positions.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::RenderSurface;
use crate::error::{Error, Result};
use crate::mesh::io::vtu::replace_file;

/// Write one `.vtp` frame: `surface`'s triangles at `positions` (one per vertex), with the
/// displacement from `surface.positions` as point data. Written whole to a temporary file and
/// renamed over `path`.
pub fn write_vtp(path: &Path, surface: &RenderSurface, positions: &[[f64; 3]]) -> Result<()> {
    if positions.len() != surface.positions.len() {
        return Err(Error::io(
            path,
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "{} positions for a surface of {} vertices",
                    positions.len(),
                    surface.positions.len()
                ),
            ),
        ));
    }
    replace_file(path, false, |w| {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" \
             header_type=\"UInt64\">"
        )?;
        writeln!(w, "<PolyData>")?;
        writeln!(
            w,
            "<Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"0\" \
             NumberOfStrips=\"0\" NumberOfPolys=\"{}\">",
            positions.len(),
            surface.triangles.len()
        )?;
        writeln!(w, "<PointData Vectors=\"displacement\">")?;
        let displacement = positions
            .iter()
            .zip(&surface.positions)
            .map(|(x, r)| [x[0] - r[0], x[1] - r[1], x[2] - r[2]]);
        vectors(w, "displacement", displacement)?;
        writeln!(w, "</PointData>")?;
        writeln!(w, "<Points>")?;
        vectors(w, "positions", positions.iter().copied())?;
        writeln!(w, "</Points>")?;
        writeln!(w, "<Polys>")?;
        writeln!(
            w,
            "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">"
        )?;
        for t in &surface.triangles {
            writeln!(w, "{} {} {}", t[0], t[1], t[2])?;
        }
        writeln!(w, "</DataArray>")?;
        writeln!(
            w,
            "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">"
        )?;
        for k in 1..=surface.triangles.len() {
            write!(w, "{} ", 3 * k)?;
        }
        writeln!(w, "\n</DataArray>")?;
        writeln!(w, "</Polys>")?;
        writeln!(w, "</Piece>\n</PolyData>\n</VTKFile>")
    })
}

/// A Float64 three-component data array.
fn vectors(
    w: &mut impl Write,
    name: &str,
    values: impl Iterator<Item = [f64; 3]>,
) -> io::Result<()> {
    writeln!(
        w,
        "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"3\" format=\"ascii\">"
    )?;
    // `{:?}` of an f64 is its shortest round-trip form.
    for p in values {
        writeln!(w, "{:?} {:?} {:?}", p[0], p[1], p[2])?;
    }
    writeln!(w, "</DataArray>")
}

/// A series of surface frames and the `.pvd` listing them, rewritten after every frame.
#[derive(Debug)]
pub struct VtpSeries {
    dir: PathBuf,
    stem: String,
    frames: Vec<(f64, String)>,
}

impl VtpSeries {
    /// Start the series `<dir>/<stem>.pvd` (the folder must exist); frames of an earlier series
    /// of the same name are overwritten as the new ones are written.
    pub fn new(dir: &Path, stem: &str) -> Self {
        VtpSeries {
            dir: dir.to_path_buf(),
            stem: stem.to_string(),
            frames: Vec::new(),
        }
    }

    /// Write the frame at `time` (after the previous one) and list it. Returns its path.
    pub fn frame(
        &mut self,
        time: f64,
        surface: &RenderSurface,
        positions: &[[f64; 3]],
    ) -> Result<PathBuf> {
        let name = format!("{}_{:06}.vtp", self.stem, self.frames.len());
        let path = self.dir.join(&name);
        write_vtp(&path, surface, positions)?;
        self.frames.push((time, name));
        crate::mesh::io::pvd::write_collection(&self.pvd_path(), &self.frames, false)?;
        Ok(path)
    }

    /// Frames written.
    pub fn frames(&self) -> usize {
        self.frames.len()
    }

    /// The collection file, `<dir>/<stem>.pvd`.
    pub fn pvd_path(&self) -> PathBuf {
        self.dir.join(format!("{}.pvd", self.stem))
    }
}

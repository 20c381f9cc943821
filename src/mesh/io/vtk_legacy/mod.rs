//! Reader for legacy VTK `.vtk` files (versions 2.0 to 5.1), ASCII or binary, holding an
//! `UNSTRUCTURED_GRID`.
//!
//! Both cell layouts are read: the classic one (`CELLS n size`, each cell as its point count
//! then its point ids) and the 5.1 one (`CELLS offsets connectivity` followed by `OFFSETS` and
//! `CONNECTIVITY` arrays). Binary data is big-endian, as the VTK file-format document says.
//! A cell data array whose name looks like a region tag (`region`, `material`, `physical`,
//! `tag`, `CellEntityIds`, `gmsh:physical`) becomes the region of each tet; other attribute
//! arrays are skipped with a note.
//!
//! Here: the header and the section loop; `data.rs` reads values (ASCII or binary),
//! `cells.rs` the cells and `attributes.rs` the attribute data.

mod attributes;
mod cells;
mod data;
use attributes::Attached;
use cells::Cells;
use data::{Data, Scalar};

use std::path::Path;

use super::text::{capped, Bin, Lines, Tokens};
use super::vtk_cells::CellTally;
use super::{Format, RawMesh};
use crate::error::{Error, Location, Result};

/// The reader's state.
struct Vtk<'a> {
    toks: Tokens<'a>,
    path: &'a Path,
    binary: bool,
    /// Major version: 5 and above use the OFFSETS/CONNECTIVITY cell layout.
    major: u32,
    raw: RawMesh,
    points_read: bool,
    cells: Option<Cells>,
    region: Option<(String, Vec<f64>, Location)>,
    attached: Attached,
}

/// Parse a legacy VTK file; `path` is used in messages only.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    let mut lines = Lines::new(path, bytes, None);
    let major = version(&mut lines)?;
    // The title: any text, possibly empty.
    match lines.next_raw() {
        Some(r) => r.map(|_| ())?,
        None => return Err(truncated_header(path)),
    }
    let binary = encoding(&mut lines)?;
    dataset(&mut lines)?;
    let mut vtk = Vtk {
        toks: Tokens::new(lines),
        path,
        binary,
        major,
        raw: RawMesh::new(Format::VtkLegacy { binary }),
        points_read: false,
        cells: None,
        region: None,
        attached: Attached::Dataset,
    };
    while let Some((kw, args)) = vtk.keyword_line()? {
        vtk.section(&kw.to_ascii_uppercase(), &args)?;
    }
    vtk.build()
}

/// The error for a file that ends inside the header.
fn truncated_header(path: &Path) -> Error {
    Error::parse(
        path,
        Location::Unknown,
        None,
        "file ends inside the vtk header",
        "the file is truncated; export it again",
    )
}

/// Check the first line (`# vtk DataFile Version x.y`) and return the major version.
fn version(lines: &mut Lines) -> Result<u32> {
    let first = lines
        .next_raw()
        .ok_or_else(|| truncated_header(lines.path()))?;
    let not_vtk = |lines: &Lines| {
        lines.error(
            None,
            "not a legacy vtk file (the first line must be `# vtk DataFile Version x.y`)",
            "check that the file is a .vtk legacy file, not .vtu or another format",
        )
    };
    let first = first.map_err(|_| not_vtk(lines))?;
    let lower = first.trim().to_ascii_lowercase();
    let Some(v) = lower
        .strip_prefix('#')
        .map(str::trim_start)
        .and_then(|s| s.strip_prefix("vtk datafile version"))
    else {
        return Err(not_vtk(lines));
    };
    let major = v.trim().split('.').next().unwrap_or("");
    let major: u32 = lines.int(major, "vtk file version", None)?;
    if !(1..=5).contains(&major) {
        return Err(lines.error(
            None,
            format!("vtk file version {} is not supported", v.trim()),
            "lancet reads legacy versions 2.0 to 5.1",
        ));
    }
    Ok(major)
}

/// `ASCII` or `BINARY`; true for binary.
fn encoding(lines: &mut Lines) -> Result<bool> {
    let line = lines
        .next_line()
        .transpose()?
        .ok_or_else(|| truncated_header(lines.path()))?;
    match line.to_ascii_uppercase().as_str() {
        "ASCII" => Ok(false),
        "BINARY" => Ok(true),
        _ => Err(lines.error(
            None,
            format!("expected ASCII or BINARY, found {:?}", clip(line)),
            "the third line of a legacy vtk file names the encoding",
        )),
    }
}

/// `DATASET UNSTRUCTURED_GRID`; other datasets are rejected.
fn dataset(lines: &mut Lines) -> Result<()> {
    let line = lines
        .next_line()
        .transpose()?
        .ok_or_else(|| truncated_header(lines.path()))?;
    let mut it = line.split_ascii_whitespace();
    let (kw, ty) = (it.next().unwrap_or(""), it.next().unwrap_or(""));
    if !kw.eq_ignore_ascii_case("DATASET") {
        return Err(lines.error(
            None,
            format!("expected DATASET, found {:?}", clip(line)),
            "the fourth line of a legacy vtk file names the dataset type",
        ));
    }
    if !ty.eq_ignore_ascii_case("UNSTRUCTURED_GRID") {
        return Err(lines.error(
            None,
            format!("dataset type {ty} is not supported; lancet reads UNSTRUCTURED_GRID"),
            "save the tetrahedral mesh as an unstructured grid (paraview: save data as .vtk \
             after `extract cells by type` or `tetrahedralize`)",
        ));
    }
    Ok(())
}

/// At most 40 characters, for messages.
fn clip(s: &str) -> String {
    s.chars().take(40).collect()
}

/// Whether a cell data array named `name` holds region tags.
fn is_region_name(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    [
        "region",
        "material",
        "physical",
        "cellentityids",
        "entityid",
    ]
    .iter()
    .any(|k| lower.contains(k))
        || lower
            .split(|c: char| !c.is_ascii_alphanumeric())
            .any(|w| w == "tag" || w == "tags")
}

impl<'a> Vtk<'a> {
    /// The next keyword line as (keyword as written, arguments); `None` at the end.
    fn keyword_line(&mut self) -> Result<Option<(&'a str, Vec<&'a str>)>> {
        if !self.toks.line_done() {
            let extra = self.toks.rest_of_line();
            return Err(self.toks.error(
                None,
                format!(
                    "more values than declared, starting at {:?}",
                    clip(extra[0])
                ),
                "the count in the section header is smaller than the data",
            ));
        }
        let Some(kw) = self.toks.next_token().transpose()? else {
            return Ok(None);
        };
        let args = self.toks.rest_of_line();
        Ok(Some((kw, args)))
    }

    /// Read one section.
    fn section(&mut self, kw: &str, args: &[&'a str]) -> Result<()> {
        match kw {
            "POINTS" => self.points(args),
            "CELLS" => self.cells(args),
            "CELL_TYPES" => self.cell_types(args),
            "CELL_DATA" => {
                self.attached = Attached::Cells(self.count(args.first(), "cell data count")?);
                Ok(())
            }
            "POINT_DATA" => {
                self.attached = Attached::Points(self.count(args.first(), "point data count")?);
                Ok(())
            }
            "FIELD" => self.field(args),
            "METADATA" => self.skip_metadata(),
            "SCALARS"
            | "COLOR_SCALARS"
            | "LOOKUP_TABLE"
            | "VECTORS"
            | "NORMALS"
            | "TENSORS"
            | "TENSORS6"
            | "TEXTURE_COORDINATES"
            | "GLOBAL_IDS"
            | "PEDIGREE_IDS" => self.attribute(kw, args),
            "DATASET" => Err(self.toks.error(
                None,
                "a second DATASET line",
                "a legacy vtk file holds one dataset",
            )),
            _ if kw.parse::<f64>().is_ok() => Err(self.toks.error(
                None,
                format!("more values than declared: found {kw} where a keyword should be"),
                "the count in the previous section's header is smaller than its data",
            )),
            _ => Err(self.toks.error(
                None,
                format!("unknown vtk keyword {:?}", clip(kw)),
                "expected POINTS, CELLS, CELL_TYPES, CELL_DATA or POINT_DATA",
            )),
        }
    }

    /// Parse a count argument.
    fn count(&self, tok: Option<&&str>, what: &str) -> Result<usize> {
        match tok {
            Some(t) => self.toks_int(t, what),
            None => Err(self.toks.error(
                None,
                format!("missing {what}"),
                "the keyword needs its count",
            )),
        }
    }

    /// Parse `t` as a non-negative integer at the current line.
    fn toks_int<T: std::str::FromStr>(&self, t: &str, what: &str) -> Result<T> {
        super::text::parse_int(t, what, self.path, self.toks.loc(), None)
    }

    /// A type argument.
    fn scalar(&self, tok: Option<&&str>) -> Result<Scalar> {
        let name = tok.copied().unwrap_or("");
        Scalar::parse(name).ok_or_else(|| {
            self.toks.error(
                None,
                format!("unknown data type {:?}", clip(name)),
                "expected a vtk type such as float, double, int or vtktypeint64",
            )
        })
    }

    /// Run `f` over the data that follows the current keyword line, then move past it.
    fn with_data<T>(&mut self, f: impl FnOnce(&mut Data<'_, 'a>) -> Result<T>) -> Result<T> {
        if !self.binary {
            return f(&mut Data::Ascii(&mut self.toks));
        }
        let lines = self.toks.lines();
        let mut data = Data::Binary(Bin::new(self.path, lines.bytes(), lines.byte_pos(), true));
        let out = f(&mut data)?;
        if let Data::Binary(b) = data {
            self.toks.lines().seek(b.pos);
        }
        Ok(out)
    }

    /// Bytes left after the current line: bounds capacities taken from counts.
    fn remaining(&mut self) -> usize {
        let l = self.toks.lines();
        l.bytes().len() - l.byte_pos()
    }

    /// `POINTS n type` and 3n coordinates.
    fn points(&mut self, args: &[&'a str]) -> Result<()> {
        if self.points_read {
            return Err(self
                .toks
                .error(None, "a second POINTS section", "merge the points"));
        }
        self.points_read = true;
        let n: usize = self.count(args.first(), "point count")?;
        if u32::try_from(n).is_err() {
            return Err(self.toks.error(None, "too many points", "split the mesh"));
        }
        let ty = self.scalar(args.get(1))?;
        let cap = capped(n, self.remaining(), 6);
        let mut points = Vec::with_capacity(cap);
        self.with_data(|d| {
            for i in 0..n {
                let mut p = [0.0; 3];
                for c in p.iter_mut() {
                    *c = d
                        .float(ty, "coordinate", Some(i as i64))
                        .map_err(Error::about_node)?;
                }
                points.push(p);
            }
            Ok(())
        })?;
        self.raw.point_ids = (0..points.len() as i64).collect();
        self.raw.points = points;
        Ok(())
    }

    /// Turn cells into tets and triangles.
    fn build(mut self) -> Result<RawMesh> {
        if !self.points_read {
            return Err(self.error_at_end("the file has no POINTS section"));
        }
        let cells = self.cells.take().unwrap_or_default();
        if cells.starts.len() != cells.types.len() {
            return Err(self.error_at_end(&format!(
                "CELLS lists {} cells but CELL_TYPES lists {}",
                cells.starts.len(),
                cells.types.len()
            )));
        }
        let region = self.region.take();
        if let Some((name, v, loc)) = &region {
            if v.len() != cells.starts.len() {
                return Err(Error::parse(
                    self.path,
                    *loc,
                    None,
                    format!(
                        "region array {name:?} has {} values for {} cells",
                        v.len(),
                        cells.starts.len()
                    ),
                    "the CELL_DATA count must equal the number of cells",
                ));
            }
        }
        let mut tally = CellTally::default();
        for i in 0..cells.starts.len() {
            let tag = region.as_ref().map_or(0.0, |r| r.1[i]);
            self.cell(&cells, i, tag, &mut tally)?;
        }
        tally.notes(&mut self.raw.notes);
        Ok(self.raw)
    }

    /// An error about the file as a whole.
    fn error_at_end(&self, msg: &str) -> Error {
        Error::parse(
            self.path,
            Location::Unknown,
            None,
            msg.to_string(),
            "the file is truncated or incomplete; export it again",
        )
    }
}

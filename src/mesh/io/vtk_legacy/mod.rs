//! Reader for legacy VTK `.vtk` files (versions 2.0 to 5.1), ASCII or binary, holding an
//! `UNSTRUCTURED_GRID`.
//!
//! Both cell layouts are read: the classic one (`CELLS n size`, each cell as its point count
//! then its point ids) and the 5.1 one (`CELLS offsets connectivity` followed by `OFFSETS` and
//! `CONNECTIVITY` arrays). Binary data is big-endian, as the VTK file-format document says.
//! A cell data array whose name looks like a region tag (`region`, `material`, `physical`,
//! `tag`, `CellEntityIds`, `gmsh:physical`) becomes the region of each tet; other attribute
//! arrays are skipped with a note.

use std::path::Path;

use super::text::{capped, Bin, Lines, Tokens};
use super::vtk_cells::{unsupported_message, CellKind, CellTally, UNSUPPORTED_HINT};
use super::{Format, RawMesh, RawTet, RawTriangle};
use crate::error::{Error, Location, Result};

/// A data type named in a VTK file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    Bit,
    /// Signed integer of this many bytes.
    Int(usize),
    /// Unsigned integer of this many bytes.
    UInt(usize),
    Float(usize),
    Str,
}

impl Scalar {
    /// The type named `name`, if VTK knows it.
    fn parse(name: &str) -> Option<Scalar> {
        let s = match name.to_ascii_lowercase().as_str() {
            "bit" => Scalar::Bit,
            "char" | "vtktypeint8" => Scalar::Int(1),
            "unsigned_char" | "vtktypeuint8" => Scalar::UInt(1),
            "short" | "vtktypeint16" => Scalar::Int(2),
            "unsigned_short" | "vtktypeuint16" => Scalar::UInt(2),
            "int" | "vtktypeint32" => Scalar::Int(4),
            "unsigned_int" | "vtktypeuint32" => Scalar::UInt(4),
            "long" | "vtktypeint64" | "vtkidtype" => Scalar::Int(8),
            "unsigned_long" | "vtktypeuint64" => Scalar::UInt(8),
            "float" => Scalar::Float(4),
            "double" => Scalar::Float(8),
            "string" | "utf8_string" => Scalar::Str,
            _ => return None,
        };
        Some(s)
    }
}

/// Numbers from an ASCII token stream or a big-endian binary block.
enum Data<'r, 'a> {
    Ascii(&'r mut Tokens<'a>),
    Binary(Bin<'a>),
}

impl Data<'_, '_> {
    /// Where the next (binary) or last (ASCII) value is.
    fn loc(&self) -> Location {
        match self {
            Data::Ascii(t) => t.loc(),
            Data::Binary(b) => Location::Byte(b.pos as u64),
        }
    }

    /// An error at the current position.
    fn error(&self, element: Option<i64>, msg: impl Into<String>, hint: &str) -> Error {
        match self {
            Data::Ascii(t) => t.error(element, msg, hint),
            Data::Binary(b) => b.error(element, msg, hint),
        }
    }

    /// One integer value of type `ty`.
    fn int(&mut self, ty: Scalar, what: &str, element: Option<i64>) -> Result<i64> {
        match self {
            Data::Ascii(t) => t.int(what, element),
            Data::Binary(b) => match ty {
                Scalar::Int(4) => b.i32(what).map(i64::from),
                Scalar::Int(8) => b.i64(what),
                Scalar::Int(n) => Ok(be_int(b.take(n, what)?, true)),
                Scalar::UInt(8) => {
                    let v = b.u64(what)?;
                    i64::try_from(v).map_err(|_| {
                        b.pos -= 8;
                        b.error(element, format!("{what} {v} is too large"), "fix the value")
                    })
                }
                Scalar::UInt(n) => Ok(be_int(b.take(n, what)?, false)),
                _ => Err(b.error(
                    element,
                    format!("{what} must be stored as integers, not {ty:?}"),
                    "write the array as int or vtktypeint64",
                )),
            },
        }
    }

    /// One value of type `ty` as a float (finite).
    fn float(&mut self, ty: Scalar, what: &str, element: Option<i64>) -> Result<f64> {
        if !matches!(ty, Scalar::Float(_)) && matches!(self, Data::Binary(_)) {
            return self.int(ty, what, element).map(|v| v as f64);
        }
        match self {
            Data::Ascii(t) => t.f64(what, element),
            Data::Binary(b) => {
                let start = b.pos;
                let v = match ty {
                    Scalar::Float(4) => b.f32(what)? as f64,
                    _ => b.f64(what)?,
                };
                if !v.is_finite() {
                    b.pos = start;
                    return Err(b.error(
                        element,
                        format!("{what} is {v}, not a finite number"),
                        "replace NaN or infinite values with real coordinates",
                    ));
                }
                Ok(v)
            }
        }
    }

    /// Skip `n` values of type `ty`.
    fn skip(&mut self, ty: Scalar, n: usize, what: &str) -> Result<()> {
        match self {
            Data::Ascii(t) => {
                for _ in 0..n {
                    t.expect(what)?;
                }
                Ok(())
            }
            Data::Binary(b) => {
                let bytes = match ty {
                    Scalar::Bit => n.div_ceil(8),
                    Scalar::Int(s) | Scalar::UInt(s) | Scalar::Float(s) => {
                        n.checked_mul(s).ok_or_else(|| {
                            b.error(None, format!("{what}: size overflows"), "fix the count")
                        })?
                    }
                    Scalar::Str => {
                        return Err(b.error(
                            None,
                            format!("{what}: binary string arrays are not supported"),
                            "remove the array or write the file as ascii",
                        ))
                    }
                };
                b.take(bytes, what).map(|_| ())
            }
        }
    }
}

/// A big-endian integer of up to 8 bytes, sign-extended when `signed`.
fn be_int(bytes: &[u8], signed: bool) -> i64 {
    let mut v: i64 = if signed && bytes.first().is_some_and(|b| b & 0x80 != 0) {
        -1
    } else {
        0
    };
    for &b in bytes {
        v = (v << 8) | b as i64;
    }
    v
}

/// The cells as read: flat point lists, their starts, and where each cell was.
#[derive(Default)]
struct Cells {
    conn: Vec<i64>,
    starts: Vec<usize>,
    locs: Vec<Location>,
    types: Vec<(i64, Location)>,
}

/// Where attribute data being read belongs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Attached {
    /// Before any `CELL_DATA`/`POINT_DATA` (a dataset-level `FIELD`).
    Dataset,
    Cells(usize),
    Points(usize),
}

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

    /// `CELLS`, in the layout of the file's version.
    fn cells(&mut self, args: &[&'a str]) -> Result<()> {
        if self.cells.as_ref().is_some_and(|c| !c.starts.is_empty()) {
            return Err(self
                .toks
                .error(None, "a second CELLS section", "merge the cells"));
        }
        let a: usize = self.count(args.first(), "cell count")?;
        let b: usize = self.count(args.get(1), "cell list size")?;
        let types = self.cells.take().map(|c| c.types).unwrap_or_default();
        let mut cells = if self.major >= 5 {
            self.cells_offsets(a, b)?
        } else {
            self.cells_classic(a, b)?
        };
        cells.types = types;
        self.cells = Some(cells);
        Ok(())
    }

    /// Classic layout: `n` cells, each `k id1 .. idk`, `size` values in all.
    fn cells_classic(&mut self, n: usize, size: usize) -> Result<Cells> {
        let mut cells = Cells::default();
        let cap = capped(size, self.remaining(), 2);
        cells.conn.reserve(cap);
        cells.starts.reserve(capped(n, cap, 2));
        cells.locs.reserve(capped(n, cap, 2));
        let ty = Scalar::Int(4);
        self.with_data(|d| {
            let mut used = 0usize;
            for i in 0..n {
                let id = Some(i as i64 + 1);
                let loc = d.loc();
                let k = d.int(ty, "cell point count", id)?;
                let k = usize::try_from(k)
                    .ok()
                    .filter(|&k| k <= size.saturating_sub(used + 1))
                    .ok_or_else(|| {
                        d.error(
                            id,
                            format!("cell point count {k} does not fit the declared size {size}"),
                            "the CELLS counts and the cell lists disagree",
                        )
                    })?;
                cells.starts.push(cells.conn.len());
                cells.locs.push(if matches!(d, Data::Ascii(_)) {
                    d.loc()
                } else {
                    loc
                });
                for _ in 0..k {
                    cells.conn.push(d.int(ty, "point id", id)?);
                }
                used += k + 1;
            }
            if used != size {
                return Err(d.error(
                    None,
                    format!("CELLS declares size {size} but the {n} cell lists hold {used} values"),
                    "fix the size in the CELLS line",
                ));
            }
            Ok(())
        })?;
        Ok(cells)
    }

    /// The keyword line that must come next (`OFFSETS`, `CONNECTIVITY`), with its type.
    fn expect_array(&mut self, name: &str) -> Result<Scalar> {
        let Some((kw, args)) = self.keyword_line()? else {
            return Err(self.toks.error(
                None,
                format!("file ends before the {name} array"),
                "the file is truncated; export it again",
            ));
        };
        if !kw.eq_ignore_ascii_case(name) {
            return Err(self.toks.error(
                None,
                format!(
                    "expected {name} after CELLS (vtk 5 layout), found {:?}",
                    clip(kw)
                ),
                "vtk 5.x files list cells as OFFSETS then CONNECTIVITY",
            ));
        }
        self.scalar(args.first())
    }

    /// 5.x layout: `offsets` offsets and `conn` point ids.
    fn cells_offsets(&mut self, n_off: usize, n_conn: usize) -> Result<Cells> {
        let ty = self.expect_array("OFFSETS")?;
        let mut offsets = Vec::with_capacity(capped(n_off, self.remaining(), 2));
        self.with_data(|d| {
            let mut last = 0i64;
            for i in 0..n_off {
                let o = d.int(ty, "offset", None)?;
                let bad = (i == 0 && o != 0) || o < last || o as u128 > n_conn as u128;
                if bad {
                    return Err(d.error(
                        None,
                        format!("offset {o} is out of order or beyond the {n_conn} point ids"),
                        "offsets start at 0, never decrease and end at the connectivity size",
                    ));
                }
                last = o;
                offsets.push(o as usize);
            }
            if n_off > 0 && last as usize != n_conn {
                return Err(d.error(
                    None,
                    format!("the last offset is {last}, not the connectivity size {n_conn}"),
                    "fix the CELLS line or the offsets",
                ));
            }
            Ok(())
        })?;
        let ty = self.expect_array("CONNECTIVITY")?;
        let mut cells = Cells::default();
        cells.conn.reserve(capped(n_conn, self.remaining(), 2));
        let n_cells = n_off.saturating_sub(1);
        cells.starts = offsets[..n_cells].to_vec();
        self.with_data(|d| {
            let mut next = 0;
            for j in 0..n_conn {
                let v = d.int(ty, "point id", None)?;
                // Every cell is located at its first point id (empty cells at the next one).
                while next < n_cells && offsets[next] <= j {
                    cells.locs.push(d.loc());
                    next += 1;
                }
                cells.conn.push(v);
            }
            cells.locs.resize(n_cells, d.loc());
            Ok(())
        })?;
        Ok(cells)
    }

    /// `CELL_TYPES n` and n type codes.
    fn cell_types(&mut self, args: &[&'a str]) -> Result<()> {
        let n: usize = self.count(args.first(), "cell type count")?;
        let mut types = Vec::with_capacity(capped(n, self.remaining(), 2));
        self.with_data(|d| {
            for i in 0..n {
                let t = d.int(Scalar::Int(4), "cell type", Some(i as i64 + 1))?;
                types.push((t, d.loc()));
            }
            Ok(())
        })?;
        if self.cells.as_ref().is_some_and(|c| !c.types.is_empty()) {
            return Err(self
                .toks
                .error(None, "a second CELL_TYPES section", "merge them"));
        }
        self.cells.get_or_insert_with(Cells::default).types = types;
        Ok(())
    }

    /// How many tuples the current attribute block has.
    fn tuples(&self, kw: &str) -> Result<usize> {
        match self.attached {
            Attached::Cells(n) | Attached::Points(n) => Ok(n),
            Attached::Dataset => Err(self.toks.error(
                None,
                format!("{kw} before CELL_DATA or POINT_DATA"),
                "attribute data must follow a CELL_DATA or POINT_DATA line",
            )),
        }
    }

    /// An attribute array (`SCALARS`, `VECTORS`, ...): the region array, or skipped.
    fn attribute(&mut self, kw: &str, args: &[&'a str]) -> Result<()> {
        let n = self.tuples(kw)?;
        let name = args.first().copied().unwrap_or("");
        let arg = |i: usize| args.get(i);
        let (ty, per_tuple) = match kw {
            "SCALARS" => {
                let ncomp = match arg(2) {
                    Some(t) => self.toks_int(t, "component count")?,
                    None => 1,
                };
                let ty = self.scalar(arg(1))?;
                self.skip_lookup_table_line();
                (ty, ncomp)
            }
            "COLOR_SCALARS" => {
                let ty = if self.binary {
                    Scalar::UInt(1)
                } else {
                    Scalar::Float(4)
                };
                (ty, self.count(arg(1), "color component count")?)
            }
            "LOOKUP_TABLE" => {
                let ty = if self.binary {
                    Scalar::UInt(1)
                } else {
                    Scalar::Float(4)
                };
                let size: usize = self.count(arg(1), "lookup table size")?;
                return self.skip_array(kw, name, ty, size, 4);
            }
            "VECTORS" | "NORMALS" => (self.scalar(arg(1))?, 3),
            "TENSORS" => (self.scalar(arg(1))?, 9),
            "TENSORS6" => (self.scalar(arg(1))?, 6),
            "TEXTURE_COORDINATES" => (self.scalar(arg(2))?, self.count(arg(1), "dimension")?),
            _ => (self.scalar(arg(1))?, 1),
        };
        if kw == "SCALARS" && per_tuple == 1 && self.wants_region(name) {
            return self.read_region(name, ty, n);
        }
        self.skip_array(kw, name, ty, n, per_tuple)
    }

    /// Whether the array `name` in the current block should become the region tags.
    fn wants_region(&self, name: &str) -> bool {
        matches!(self.attached, Attached::Cells(_)) && self.region.is_none() && is_region_name(name)
    }

    /// Consume the `LOOKUP_TABLE name` line that usually follows `SCALARS`.
    fn skip_lookup_table_line(&mut self) {
        let l = self.toks.lines();
        let is_table = l
            .peek_line()
            .and_then(|r| r.ok())
            .is_some_and(|s| s.to_ascii_uppercase().starts_with("LOOKUP_TABLE"));
        if is_table {
            l.next_line();
        }
    }

    /// Skip `n * per_tuple` values, with a note.
    fn skip_array(
        &mut self,
        kw: &str,
        name: &str,
        ty: Scalar,
        n: usize,
        per_tuple: usize,
    ) -> Result<()> {
        let total = n.checked_mul(per_tuple).ok_or_else(|| {
            self.toks.error(
                None,
                format!("{kw} {name}: size overflows"),
                "fix the counts",
            )
        })?;
        let what = format!("{} {name}", kw.to_ascii_lowercase());
        self.with_data(|d| d.skip(ty, total, &what))?;
        let place = match self.attached {
            Attached::Cells(_) => "cell data",
            Attached::Points(_) => "point data",
            Attached::Dataset => "field data",
        };
        self.raw
            .notes
            .push(format!("skipped {place} array {kw} {name:?}"));
        self.skip_metadata_if_any()
    }

    /// Read the region tags of the cells.
    fn read_region(&mut self, name: &str, ty: Scalar, n: usize) -> Result<()> {
        let loc = self.toks.loc();
        let mut v = Vec::with_capacity(capped(n, self.remaining(), 2));
        self.with_data(|d| {
            for i in 0..n {
                v.push(d.float(ty, "region tag", Some(i as i64 + 1))?);
            }
            Ok(())
        })?;
        self.raw
            .notes
            .push(format!("used cell data array {name:?} as the region tag"));
        self.region = Some((name.to_string(), v, loc));
        self.skip_metadata_if_any()
    }

    /// `FIELD name k` and its k arrays `name ncomp ntuples type`.
    fn field(&mut self, args: &[&'a str]) -> Result<()> {
        let k: usize = self.count(args.get(1), "field array count")?;
        for _ in 0..k {
            let Some((name, a)) = self.keyword_line()? else {
                return Err(self.toks.error(
                    None,
                    format!("file ends inside a FIELD of {k} arrays"),
                    "the file is truncated or the array count is wrong",
                ));
            };
            if name.eq_ignore_ascii_case("NULL_ARRAY") {
                continue;
            }
            let ncomp: usize = self.count(a.first(), "field array component count")?;
            let ntuples: usize = self.count(a.get(1), "field array tuple count")?;
            let ty = self.scalar(a.get(2))?;
            if ncomp == 1 && self.wants_region(name) {
                self.read_region(name, ty, ntuples)?;
            } else {
                self.skip_array("FIELD", name, ty, ntuples, ncomp)?;
            }
        }
        Ok(())
    }

    /// Skip a `METADATA` block: lines up to the next blank line.
    fn skip_metadata(&mut self) -> Result<()> {
        let lines = self.toks.lines();
        while let Some(l) = lines.next_raw() {
            if l?.trim().is_empty() {
                break;
            }
        }
        Ok(())
    }

    /// Skip a `METADATA` block if one comes next.
    fn skip_metadata_if_any(&mut self) -> Result<()> {
        let next = self.toks.lines().peek_line().and_then(|r| r.ok());
        if next.is_some_and(|s| s.eq_ignore_ascii_case("METADATA")) {
            self.toks.lines().next_line();
            self.skip_metadata()?;
        }
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

    /// Convert cell `i`.
    fn cell(&mut self, cells: &Cells, i: usize, tag: f64, tally: &mut CellTally) -> Result<()> {
        let (ty, _) = cells.types[i];
        let start = cells.starts[i];
        let end = cells.starts.get(i + 1).copied().unwrap_or(cells.conn.len());
        let ids = &cells.conn[start..end.max(start)];
        let loc = cells.locs[i];
        let id = i as i64 + 1;
        let err = |msg: String, hint: &str| Error::parse(self.path, loc, Some(id), msg, hint);
        let kind = CellKind::of(ty);
        tally.record(kind);
        match kind {
            CellKind::VertexOrLine | CellKind::OtherSurface => return Ok(()),
            CellKind::Volume(_) | CellKind::Unknown => {
                return Err(err(unsupported_message(ty), UNSUPPORTED_HINT))
            }
            _ => {}
        }
        if let Some(msg) = kind.wrong_points(ty, ids.len()) {
            return Err(err(msg, "fix the cell's point list or its type"));
        }
        let n = self.raw.points.len() as i64;
        let mut nodes = [0u32; 4];
        for (slot, &p) in nodes.iter_mut().zip(&ids[..kind.corners()]) {
            if !(0..n).contains(&p) {
                return Err(err(
                    format!("references point {p}, which is not defined (the file has {n})"),
                    "vtk point ids start at 0; check the cell's point list",
                ));
            }
            *slot = p as u32;
        }
        tally.fractional_tags += (tag.fract() != 0.0) as usize;
        let region = tag.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32;
        if kind.corners() == 3 {
            let tri = [nodes[0], nodes[1], nodes[2]];
            self.raw.triangles.push(RawTriangle {
                nodes: tri,
                tag: region,
            });
            return Ok(());
        }
        self.raw.tets.push(RawTet {
            nodes,
            region,
            id,
            location: loc,
        });
        Ok(())
    }
}

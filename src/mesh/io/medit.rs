//! Reader for ASCII Medit `.mesh` files (INRIA; written by Gmsh, TetGen, CGAL, fTetWild).
//!
//! The file is a stream of keywords, each followed by a count and that many rows; counts and
//! rows may wrap across lines, so the reader works on tokens. `Vertices` rows are `x y z ref`,
//! `Tetrahedra` rows `v1 v2 v3 v4 ref` (1-based vertex numbers, ref = region), `Triangles` rows
//! `v1 v2 v3 ref`. Other sections whose row size is known are skipped with a note.

use std::path::Path;

use super::text::{Lines, Tokens};
use super::{Format, RawMesh, RawTet, RawTriangle};
use crate::error::{Error, Location, Result};

/// A tet as read, before its vertex numbers are checked against the vertex count (sections may
/// come in any order).
struct PendingTet {
    vertices: [i64; 4],
    region: i32,
    id: i64,
    location: Location,
}

/// What is known while reading.
struct State {
    raw: RawMesh,
    dim: usize,
    tets: Vec<PendingTet>,
    triangles: Vec<([i64; 3], i32, Location)>,
}

/// Parse an ASCII Medit file; `path` is used in messages only.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    let meshb = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("meshb"));
    if meshb || is_binary(bytes) {
        return Err(Error::parse(
            path,
            Location::Byte(0),
            None,
            "binary medit files (.meshb) are not supported",
            "convert it to ascii .mesh (for example `gmsh file.meshb -save -o file.mesh` \
             or medit/mmg tools)",
        ));
    }
    let mut toks = Tokens::new(Lines::new(path, bytes, Some(b'#')));
    let mut st = State {
        raw: RawMesh::new(Format::Medit),
        dim: 3,
        tets: Vec::new(),
        triangles: Vec::new(),
    };
    while let Some(kw) = toks.next_token().transpose()? {
        if kw.eq_ignore_ascii_case("End") {
            break;
        }
        section(&mut toks, kw, &mut st)?;
    }
    resolve(st, path)
}

/// Whether the bytes start like a binary `.meshb` file: the 32-bit integer 1 in either byte
/// order (the code that tells the reader the endianness).
fn is_binary(bytes: &[u8]) -> bool {
    matches!(bytes.get(..4), Some([1, 0, 0, 0]) | Some([0, 0, 0, 1]))
}

/// Rows of sections that are skipped, by their number of tokens per row (`None` = depends on
/// the dimension, `dim` tokens, as for normals and tangents).
fn skipped_row_len(kw: &str, dim: usize) -> Option<usize> {
    let n = match kw.to_ascii_lowercase().as_str() {
        "edges" => 3,
        "corners"
        | "ridges"
        | "requiredvertices"
        | "requirededges"
        | "requiredtriangles"
        | "requiredquadrilaterals"
        | "requiredtetrahedra" => 1,
        "normals" | "tangents" => dim,
        "normalatvertices" | "tangentatvertices" => 2,
        "normalattrianglevertices" | "tangentatedges" => 3,
        "edgesp2" => 4,
        "trianglesp2" => 7,
        "quadrilaterals" => 5,
        _ => return None,
    };
    Some(n)
}

/// Volume elements lancet cannot simulate, with their tokens per row.
fn unsupported_volume(kw: &str) -> Option<(&'static str, usize)> {
    match kw.to_ascii_lowercase().as_str() {
        "hexahedra" => Some(("hexahedra", 9)),
        "prisms" => Some(("prisms", 7)),
        "pyramids" => Some(("pyramids", 6)),
        _ => None,
    }
}

/// Read one keyword's section.
fn section(toks: &mut Tokens, kw: &str, st: &mut State) -> Result<()> {
    match kw.to_ascii_lowercase().as_str() {
        "meshversionformatted" => {
            let v: i64 = toks.int("mesh version", None)?;
            if !(1..=4).contains(&v) {
                return Err(toks.error(
                    None,
                    format!("unknown medit mesh version {v}"),
                    "expected 1, 2, 3 or 4",
                ));
            }
        }
        "dimension" => {
            let d: usize = toks.int("dimension", None)?;
            if d != 3 {
                return Err(toks.error(
                    None,
                    format!("dimension is {d}; lancet reads 3d volume meshes only"),
                    "export a 3d tetrahedral mesh",
                ));
            }
            st.dim = d;
        }
        "vertices" => vertices(toks, st)?,
        "tetrahedra" => tetrahedra(toks, st, 4, "tetrahedra")?,
        "tetrahedrap2" => tetrahedra(toks, st, 10, "tetrahedra p2")?,
        "triangles" => triangles(toks, st)?,
        _ => skip_section(toks, kw, st)?,
    }
    Ok(())
}

/// Skip a known section, or fail on one that cannot be skipped or simulated.
fn skip_section(toks: &mut Tokens, kw: &str, st: &mut State) -> Result<()> {
    if let Some((name, row)) = unsupported_volume(kw) {
        let n = count(toks, name)?;
        if n > 0 {
            return Err(toks.error(
                None,
                format!("unsupported element type ({name}); lancet simulates tetrahedra only"),
                "convert the mesh to tetrahedra",
            ));
        }
        return skip_rows(toks, 0, row, name);
    }
    let Some(row) = skipped_row_len(kw, st.dim) else {
        return Err(toks.error(
            None,
            format!("unknown medit section {kw:?}"),
            "lancet reads Vertices, Tetrahedra and Triangles and skips the usual others; \
             remove this section",
        ));
    };
    let n = count(toks, kw)?;
    skip_rows(toks, n, row, kw)?;
    if n > 0 {
        st.raw
            .notes
            .push(format!("skipped medit section {kw} ({n} rows)"));
    }
    Ok(())
}

/// Skip `n` rows of `row` tokens each.
fn skip_rows(toks: &mut Tokens, n: usize, row: usize, what: &str) -> Result<()> {
    let mut rows = Rows {
        start: toks.lines().line(),
        toks,
        what,
        n,
        k: 0,
    };
    for k in 0..n {
        rows.k = k;
        for _ in 0..row {
            rows.token()?;
        }
    }
    Ok(())
}

/// A section's row count.
fn count(toks: &mut Tokens, what: &str) -> Result<usize> {
    toks.int(&format!("count of {what}"), None)
}

/// The file's end inside a section: name how many rows were expected.
fn truncated(toks: &Tokens, what: &str, n: usize, k: usize, start: usize) -> Error {
    toks.error(
        None,
        format!("the file ends after {k} of the {n} {what} declared at line {start}"),
        "the file is truncated or the count is wrong",
    )
}

/// A row of one section being read: where the rows are counted for messages.
struct Rows<'t, 'a> {
    /// The line of the section's keyword.
    start: usize,
    toks: &'t mut Tokens<'a>,
    what: &'t str,
    n: usize,
    k: usize,
}

impl<'a> Rows<'_, 'a> {
    /// The next token of row `k`, or an error saying the file ended inside the section.
    fn token(&mut self) -> Result<&'a str> {
        match self.toks.next_token() {
            Some(t) => t,
            None => Err(truncated(self.toks, self.what, self.n, self.k, self.start)),
        }
    }

    /// The next token as an integer.
    fn int<T: std::str::FromStr>(&mut self, field: &str, id: i64) -> Result<T> {
        let t = self.token()?;
        self.toks.lines().int(t, field, Some(id))
    }

    /// The next token as a finite float.
    fn f64(&mut self, field: &str, id: i64) -> Result<f64> {
        let t = self.token()?;
        self.toks.lines().f64(t, field, Some(id))
    }
}

/// `Vertices n` and its rows `x y z ref`.
fn vertices(toks: &mut Tokens, st: &mut State) -> Result<()> {
    let n = count(toks, "vertices")?;
    let mut rows = Rows {
        start: toks.lines().line(),
        toks,
        what: "vertices",
        n,
        k: 0,
    };
    for k in 0..n {
        rows.k = k;
        let id = st.raw.points.len() as i64 + 1;
        let mut p = [0.0; 3];
        for c in p.iter_mut() {
            *c = rows.f64("coordinate", id).map_err(Error::about_node)?;
        }
        // The vertex reference (a boundary tag) is not used by the simulation.
        rows.int::<i64>("vertex reference", id)
            .map_err(Error::about_node)?;
        st.raw.points.push(p);
        st.raw.point_ids.push(id);
    }
    Ok(())
}

/// `Tetrahedra n` (or `TetrahedraP2`) and its rows of `nodes` vertex numbers and a ref.
fn tetrahedra(toks: &mut Tokens, st: &mut State, nodes: usize, what: &str) -> Result<()> {
    let n = count(toks, what)?;
    let mut rows = Rows {
        start: toks.lines().line(),
        toks,
        what,
        n,
        k: 0,
    };
    for k in 0..n {
        rows.k = k;
        let id = st.tets.len() as i64 + 1;
        let mut vertices = [0i64; 4];
        let mut location = Location::Unknown;
        for j in 0..nodes {
            let v: i64 = rows.int("vertex number", id)?;
            if j == 0 {
                location = rows.toks.loc();
            }
            if let Some(slot) = vertices.get_mut(j) {
                *slot = v;
            }
        }
        let region = rows.int("reference", id)?;
        st.tets.push(PendingTet {
            vertices,
            region,
            id,
            location,
        });
    }
    if nodes == 10 && n > 0 {
        st.raw.notes.push(format!(
            "took the 4 corner nodes of {n} p2 (10-node) tet(s)"
        ));
    }
    Ok(())
}

/// `Triangles n` and its rows `v1 v2 v3 ref`; `Triangles 0` is common and fine.
fn triangles(toks: &mut Tokens, st: &mut State) -> Result<()> {
    let n = count(toks, "triangles")?;
    let mut rows = Rows {
        start: toks.lines().line(),
        toks,
        what: "triangles",
        n,
        k: 0,
    };
    for k in 0..n {
        rows.k = k;
        let id = st.triangles.len() as i64 + 1;
        let mut v = [0i64; 3];
        for slot in v.iter_mut() {
            *slot = rows.int("vertex number", id)?;
        }
        let tag = rows.int("reference", id)?;
        st.triangles.push((v, tag, rows.toks.loc()));
    }
    Ok(())
}

/// Check vertex numbers (1-based) and build the raw mesh.
fn resolve(mut st: State, path: &Path) -> Result<RawMesh> {
    let n = st.raw.points.len() as i64;
    let index = |v: i64, id: i64, loc: Location| -> Result<u32> {
        if (1..=n).contains(&v) {
            Ok((v - 1) as u32)
        } else {
            Err(Error::parse(
                path,
                loc,
                Some(id),
                format!("references vertex {v}, which is not defined (the file has {n} vertices)"),
                "medit vertex numbers start at 1; check the element's vertex list",
            ))
        }
    };
    for t in &st.tets {
        let mut nodes = [0u32; 4];
        for (slot, &v) in nodes.iter_mut().zip(&t.vertices) {
            *slot = index(v, t.id, t.location)?;
        }
        st.raw.tets.push(RawTet {
            nodes,
            region: t.region,
            id: t.id,
            location: t.location,
        });
    }
    for (k, (v, tag, loc)) in st.triangles.iter().enumerate() {
        let mut nodes = [0u32; 3];
        for (slot, &x) in nodes.iter_mut().zip(v) {
            *slot = index(x, k as i64 + 1, *loc)?;
        }
        st.raw.triangles.push(RawTriangle { nodes, tag: *tag });
    }
    Ok(st.raw)
}

//! Reader for Vega `.veg` files (VegaFEM, iMSTK).
//!
//! Sections start with `*`: `*VERTICES` (header `N 3 0 0`, rows `id x y z`), `*ELEMENTS`
//! (element type `TET`/`TETS`, header `M 4 0`, rows `id n1 n2 n3 n4`), `*MATERIAL name` (line
//! `ENU, density, E, nu`), `*SET name` (comma-separated element ids over any number of lines)
//! and `*REGION` (lines `setName, materialName`). The k-th `*REGION` line gives its elements
//! region tag k; elements in no region keep 0. `#` starts a comment. Rows may separate values
//! by commas as well as white space.

use std::collections::HashMap;
use std::path::Path;

use super::text::{capped, Lines};
use super::{FileMaterial, Format, IdMap, RawMesh, RawTet};
use crate::error::{Error, Location, Result};

/// A `*REGION` line: which set gets the next region tag.
struct RegionLine {
    set: String,
    material: String,
    location: Location,
}

/// Everything read so far.
struct State {
    raw: RawMesh,
    ids: IdMap,
    /// Element id -> index in `raw.tets`.
    elements: HashMap<i64, usize>,
    materials: Vec<(String, FileMaterial)>,
    sets: HashMap<String, Vec<(i64, Location)>>,
    regions: Vec<RegionLine>,
    seen_vertices: bool,
}

/// Parse a Vega file; `path` is used in messages only.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    let mut lines = Lines::new(path, bytes, Some(b'#'));
    let mut st = State {
        raw: RawMesh::new(Format::Vega),
        ids: IdMap::default(),
        elements: HashMap::new(),
        materials: Vec::new(),
        sets: HashMap::new(),
        regions: Vec::new(),
        seen_vertices: false,
    };
    let mut next = lines.next_line().transpose()?;
    while let Some(line) = next {
        next = section(&mut lines, line, &mut st)?;
    }
    assign_regions(&mut st, path)?;
    pick_material(&mut st);
    Ok(st.raw)
}

/// The values of a data line, separated by white space and/or commas.
fn values(line: &str) -> Vec<&str> {
    line.split(|c: char| c == ',' || c.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
        .collect()
}

/// Read the section that `line` starts; returns the line that starts the next one.
fn section<'a>(lines: &mut Lines<'a>, line: &'a str, st: &mut State) -> Result<Option<&'a str>> {
    let Some(head) = line.strip_prefix('*') else {
        return Err(lines.error(
            None,
            format!(
                "expected a section such as *VERTICES, found {:?}",
                clip(line)
            ),
            "vega data rows must follow a *VERTICES, *ELEMENTS, *SET or *REGION line",
        ));
    };
    let (name, arg) = match head.split_once(|c: char| c.is_ascii_whitespace()) {
        Some((n, a)) => (n, a.trim()),
        None => (head, ""),
    };
    match name.to_ascii_uppercase().as_str() {
        "VERTICES" => vertices(lines, st)?,
        "ELEMENTS" => elements(lines, st)?,
        "MATERIAL" => material(lines, arg, st)?,
        "SET" => return set(lines, arg, st),
        "REGION" => return regions(lines, st),
        "INCLUDE" => {
            return Err(lines.error(
                None,
                "*INCLUDE is not supported",
                "paste the included file's content in place of the *INCLUDE line",
            ))
        }
        _ => {
            return Err(lines.error(
                None,
                format!("unknown section *{name}"),
                "vega files have *VERTICES, *ELEMENTS, *MATERIAL, *SET and *REGION sections",
            ))
        }
    }
    lines.next_line().transpose()
}

/// At most 40 characters of a line, for messages.
fn clip(s: &str) -> String {
    s.chars().take(40).collect()
}

/// The header line `count dim ...` after `*VERTICES`/the element type; returns the first two.
fn header(lines: &mut Lines, what: &str) -> Result<(usize, usize)> {
    let line = lines.expect_line(what)?;
    let v = values(line);
    if v.len() < 2 {
        return Err(lines.error(
            None,
            format!("{what} needs a count and a size, found {:?}", clip(line)),
            "write for example `100 3 0 0` after *VERTICES or `50 4 0` after TET",
        ));
    }
    Ok((
        lines.int(v[0], "count", None)?,
        lines.int(v[1], "size", None)?,
    ))
}

/// The next data row of a section with `n` declared rows, `k` read so far.
fn row<'a>(lines: &mut Lines<'a>, what: &str, n: usize, k: usize) -> Result<Vec<&'a str>> {
    let short = |lines: &Lines| {
        lines.error(
            None,
            format!("the header declares {n} {what} but only {k} rows follow"),
            "the file is truncated or the count is wrong",
        )
    };
    match lines.peek_line().transpose()? {
        Some(l) if !l.starts_with('*') => {
            lines.next_line();
            Ok(values(l))
        }
        _ => {
            lines.next_line();
            Err(short(lines))
        }
    }
}

/// `*VERTICES`: header `N 3 0 0` and rows `id x y z`.
fn vertices(lines: &mut Lines, st: &mut State) -> Result<()> {
    if st.seen_vertices {
        return Err(lines.error(None, "second *VERTICES section", "merge the vertex lists"));
    }
    st.seen_vertices = true;
    let (n, dim) = header(lines, "the *VERTICES header")?;
    if dim != 3 {
        return Err(lines.error(
            None,
            format!("vertices have dimension {dim}; lancet reads 3d meshes only"),
            "the header should read `<count> 3 0 0`",
        ));
    }
    let cap = capped(n, lines.bytes().len() - lines.byte_pos(), 8);
    st.raw.points.reserve(cap);
    st.raw.point_ids.reserve(cap);
    for k in 0..n {
        let v = row(lines, "vertices", n, k)?;
        let id: i64 = lines.int(v.first().copied().unwrap_or(""), "vertex id", None)?;
        if v.len() != 4 {
            return Err(lines.error(
                Some(id),
                format!("vertex row has {} values, expected 4 (id x y z)", v.len()),
                "fix the row",
            ));
        }
        let mut p = [0.0; 3];
        for (c, t) in p.iter_mut().zip(&v[1..]) {
            *c = lines
                .f64(t, "coordinate", Some(id))
                .map_err(Error::about_node)?;
        }
        let index = u32::try_from(st.raw.points.len()).map_err(|_| {
            lines
                .error(Some(id), "too many vertices", "split the mesh")
                .about_node()
        })?;
        st.ids.insert(id, index, lines.path(), lines.loc())?;
        st.raw.points.push(p);
        st.raw.point_ids.push(id);
    }
    Ok(())
}

/// `*ELEMENTS`: type line, header `M 4 0`, rows `id n1 n2 n3 n4`.
fn elements(lines: &mut Lines, st: &mut State) -> Result<()> {
    if !st.seen_vertices {
        return Err(lines.error(
            None,
            "*ELEMENTS comes before *VERTICES",
            "put the *VERTICES section first",
        ));
    }
    let ty = lines.expect_line("the element type after *ELEMENTS")?;
    match ty.to_ascii_uppercase().as_str() {
        "TET" | "TETS" | "TETRAHEDRA" => {}
        "CUBIC" | "CUBE" | "CUBES" => {
            return Err(lines.error(
                None,
                "unsupported element type (cubes); lancet simulates tetrahedra only",
                "convert the voxel mesh to tets (for example split each cube into six tets)",
            ))
        }
        _ => {
            return Err(lines.error(
                None,
                format!("unsupported element type {:?}", clip(ty)),
                "vega element types are TET and CUBIC; lancet reads TET",
            ))
        }
    }
    let (m, npe) = header(lines, "the *ELEMENTS header")?;
    if npe != 4 {
        return Err(lines.error(
            None,
            format!("{npe} nodes per element; tets have 4"),
            "the header should read `<count> 4 0`",
        ));
    }
    st.raw
        .tets
        .reserve(capped(m, lines.bytes().len() - lines.byte_pos(), 10));
    for k in 0..m {
        let v = row(lines, "elements", m, k)?;
        element(lines, &v, st)?;
    }
    Ok(())
}

/// One element row.
fn element(lines: &Lines, v: &[&str], st: &mut State) -> Result<()> {
    let id: i64 = lines.int(v.first().copied().unwrap_or(""), "element id", None)?;
    if v.len() != 5 {
        return Err(lines.error(
            Some(id),
            format!(
                "element row has {} values, expected 5 (id and 4 nodes)",
                v.len()
            ),
            "fix the row",
        ));
    }
    let mut nodes = [0u32; 4];
    for (slot, t) in nodes.iter_mut().zip(&v[1..]) {
        let node: i64 = lines.int(t, "node id", Some(id))?;
        *slot = st.ids.get(node, lines.path(), lines.loc(), id)?;
    }
    if st.elements.insert(id, st.raw.tets.len()).is_some() {
        return Err(lines.error(
            Some(id),
            format!("element id {id} is defined twice"),
            "give every element a unique id",
        ));
    }
    st.raw.tets.push(RawTet {
        nodes,
        region: 0,
        id,
        location: lines.loc(),
    });
    Ok(())
}

/// `*MATERIAL name` and its parameter line.
fn material(lines: &mut Lines, name: &str, st: &mut State) -> Result<()> {
    let line = lines.expect_line("the material parameters")?;
    let v = values(line);
    let kind = v.first().copied().unwrap_or("");
    if !kind.eq_ignore_ascii_case("ENU") {
        // Other Vega material models (orthotropic, Mooney-Rivlin) have no mass-spring
        // equivalent; the region still counts so that tags stay in file order.
        st.raw.notes.push(format!(
            "ignored material {name:?} of type {kind:?} (only ENU materials are read)"
        ));
        return Ok(());
    }
    if v.len() != 4 {
        return Err(lines.error(
            None,
            format!(
                "ENU material has {} values, expected 3",
                v.len().saturating_sub(1)
            ),
            "write `ENU, density, youngs_modulus, poisson_ratio`",
        ));
    }
    let m = FileMaterial {
        density: lines.f64(v[1], "density", None)?,
        youngs_modulus: lines.f64(v[2], "young's modulus", None)?,
        poisson_ratio: lines.f64(v[3], "poisson ratio", None)?,
    };
    st.materials.push((name.to_string(), m));
    Ok(())
}

/// `*SET name` and its element ids, until the next section.
fn set<'a>(lines: &mut Lines<'a>, name: &str, st: &mut State) -> Result<Option<&'a str>> {
    if name.is_empty() {
        return Err(lines.error(None, "*SET without a name", "write `*SET name`"));
    }
    let mut members = Vec::new();
    while let Some(line) = lines.next_line().transpose()? {
        if line.starts_with('*') {
            st.sets.insert(name.to_string(), members);
            return Ok(Some(line));
        }
        for t in values(line) {
            members.push((lines.int(t, "element id in set", None)?, lines.loc()));
        }
    }
    st.sets.insert(name.to_string(), members);
    Ok(None)
}

/// `*REGION` and its `setName, materialName` lines, until the next section.
fn regions<'a>(lines: &mut Lines<'a>, st: &mut State) -> Result<Option<&'a str>> {
    loop {
        let Some(line) = lines.next_line().transpose()? else {
            return Ok(None);
        };
        if line.starts_with('*') {
            return Ok(Some(line));
        }
        let v = values(line);
        if v.len() != 2 {
            return Err(lines.error(
                None,
                format!("region line has {} values, expected 2", v.len()),
                "write `setName, materialName`",
            ));
        }
        st.regions.push(RegionLine {
            set: v[0].to_string(),
            material: v[1].to_string(),
            location: lines.loc(),
        });
    }
}

/// Give the elements of the k-th region's set region tag k.
fn assign_regions(st: &mut State, path: &Path) -> Result<()> {
    for (k, r) in st.regions.iter().enumerate() {
        let tag = i32::try_from(k + 1).unwrap_or(i32::MAX);
        let known = st.materials.iter().any(|(n, _)| *n == r.material);
        if !known {
            st.raw.notes.push(format!(
                "region {tag} refers to material {:?}, which has no ENU parameters here",
                r.material
            ));
        }
        // Vega defines `allElements` implicitly.
        if r.set == "allElements" && !st.sets.contains_key(&r.set) {
            st.raw.tets.iter_mut().for_each(|t| t.region = tag);
            continue;
        }
        let Some(members) = st.sets.get(&r.set) else {
            return Err(Error::parse(
                path,
                r.location,
                None,
                format!("region refers to set {:?}, which is not defined", r.set),
                "define it with *SET before or after the region",
            ));
        };
        for &(id, loc) in members {
            let Some(&i) = st.elements.get(&id) else {
                return Err(Error::parse(
                    path,
                    loc,
                    Some(id),
                    format!("set {:?} lists element {id}, which is not defined", r.set),
                    "check the set's element ids against *ELEMENTS",
                ));
            };
            st.raw.tets[i].region = tag;
        }
    }
    Ok(())
}

/// The file's material: the first ENU material, noted when there are several.
fn pick_material(st: &mut State) {
    if let Some((name, m)) = st.materials.first() {
        st.raw.material = Some(*m);
        if st.materials.len() > 1 {
            st.raw.notes.push(format!(
                "the file defines {} materials; reported the first ({name}); regions tell \
                 the elements apart",
                st.materials.len()
            ));
        }
    }
}

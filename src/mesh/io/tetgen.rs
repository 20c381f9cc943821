//! Reader for TetGen `.node`/`.ele` pairs.
//!
//! `.node`: header `<#points> <dim 3> <#attributes> <boundary marker 0|1>`, then rows
//! `id x y z [attributes] [marker]`. `.ele`: header `<#tets> <4|10> <#region attributes>`, then
//! rows `id n1 .. n4 [n5 .. n10] [region]`. Numbering starts at 0 or 1 "as the file says": ids
//! are mapped through `IdMap`, so either works, and so do sparse ids. `#` starts a comment.

use std::path::{Path, PathBuf};

use super::text::{capped, tokens, Lines};
use super::{Format, IdMap, LoadedMesh, RawMesh, RawTet};
use crate::error::{Error, Result};

/// Read the pair given either file of it (`X.node` or `X.ele`); the other is found next to it.
pub fn read_pair(path: &Path) -> Result<LoadedMesh> {
    let (node_path, ele_path) = pair_paths(path);
    let read = |p: &PathBuf, other: &PathBuf| {
        std::fs::read(p).map_err(|e| {
            let msg = format!(
                "cannot read tetgen file {} (a .node/.ele pair needs both files; given {}): {e}",
                p.display(),
                other.display()
            );
            Error::io(p, std::io::Error::new(e.kind(), msg))
        })
    };
    let node_bytes = read(&node_path, &ele_path)?;
    let ele_bytes = read(&ele_path, &node_path)?;
    parse(&node_bytes, &ele_bytes, &node_path, &ele_path)?.finish(&ele_path)
}

/// The `.node` and `.ele` paths of the pair that `path` (either of them) belongs to.
fn pair_paths(path: &Path) -> (PathBuf, PathBuf) {
    (path.with_extension("node"), path.with_extension("ele"))
}

/// Parse a pair from memory; the paths are used in messages only.
pub fn parse(
    node_bytes: &[u8],
    ele_bytes: &[u8],
    node_path: &Path,
    ele_path: &Path,
) -> Result<RawMesh> {
    let mut raw = RawMesh::new(Format::TetGen);
    let ids = parse_nodes(node_bytes, node_path, &mut raw)?;
    parse_elements(ele_bytes, ele_path, &ids, &mut raw)?;
    Ok(raw)
}

/// The white-space separated tokens of a line, without a trailing `# comment`.
fn row_tokens(line: &str) -> Vec<&str> {
    tokens(line.split('#').next().unwrap_or(""))
}

/// The first token of a row ("" if none, which then fails to parse with a clear message).
fn first<'a>(toks: &[&'a str]) -> &'a str {
    toks.first().copied().unwrap_or("")
}

/// The header fields of a file, each a non-negative integer; missing ones are 0 (TetGen allows
/// leaving trailing fields out).
fn header(lines: &mut Lines, what: &str, names: &[&str]) -> Result<Vec<usize>> {
    let line = lines.expect_line(what)?;
    let toks = row_tokens(line);
    if toks.is_empty() {
        return Err(lines.error(None, format!("missing {what}"), "the file is truncated"));
    }
    names
        .iter()
        .enumerate()
        .map(|(i, name)| match toks.get(i) {
            Some(t) => lines.int(t, name, None),
            None => Ok(0),
        })
        .collect()
}

/// Read the `.node` file into `raw.points`; returns the id map.
fn parse_nodes(bytes: &[u8], path: &Path, raw: &mut RawMesh) -> Result<IdMap> {
    let mut lines = Lines::new(path, bytes, Some(b'#'));
    let h = header(
        &mut lines,
        "the .node header",
        &[
            "point count",
            "dimension",
            "attribute count",
            "boundary marker flag",
        ],
    )?;
    let (n, dim, nattr, nmark) = (h[0], h[1], h[2], h[3]);
    if dim != 3 {
        return Err(lines.error(
            None,
            format!("dimension is {dim}; lancet reads 3d meshes only"),
            "mesh the volume in 3d (tetgen writes dimension 3)",
        ));
    }
    if nmark > 1 {
        return Err(lines.error(
            None,
            format!("boundary marker flag is {nmark}, expected 0 or 1"),
            "fix the header",
        ));
    }
    let want = 4 + nattr.min(1 << 16) + nmark;
    let cap = capped(n, bytes.len() - lines.byte_pos(), 8);
    raw.points.reserve(cap);
    raw.point_ids.reserve(cap);
    let mut ids = IdMap::default();
    for k in 0..n {
        let line = lines.next_line().transpose()?.ok_or_else(|| {
            lines.error(
                None,
                format!("the header declares {n} nodes but the file ends after {k}"),
                "the file is truncated or the header count is wrong",
            )
        })?;
        let toks = row_tokens(line);
        let id: i64 = lines.int(first(&toks), "node id", None)?;
        if toks.len() < want {
            return Err(lines.error(
                Some(id),
                format!("node row has {} values, expected {want}", toks.len()),
                "each row needs id, x, y, z and the attributes and marker the header declares",
            ));
        }
        let mut p = [0.0; 3];
        for (c, tok) in p.iter_mut().zip(&toks[1..4]) {
            *c = lines
                .f64(tok, "coordinate", Some(id))
                .map_err(Error::about_node)?;
        }
        let index = u32::try_from(raw.points.len()).map_err(|_| {
            lines
                .error(Some(id), "too many nodes", "split the mesh")
                .about_node()
        })?;
        ids.insert(id, index, path, lines.loc())?;
        if k == 0 {
            raw.notes
                .push(format!("tetgen node numbering starts at {id}"));
        }
        raw.points.push(p);
        raw.point_ids.push(id);
    }
    no_extra_rows(&mut lines, n, "nodes")?;
    Ok(ids)
}

/// Fail if content follows the declared rows: the header count and the rows disagree.
fn no_extra_rows(lines: &mut Lines, n: usize, what: &str) -> Result<()> {
    if lines.next_line().transpose()?.is_some() {
        return Err(lines.error(
            None,
            format!("the header declares {n} {what} but more rows follow"),
            "fix the count in the header or remove the extra rows",
        ));
    }
    Ok(())
}

/// Read the `.ele` file into `raw.tets`.
fn parse_elements(bytes: &[u8], path: &Path, ids: &IdMap, raw: &mut RawMesh) -> Result<()> {
    let mut lines = Lines::new(path, bytes, Some(b'#'));
    let h = header(
        &mut lines,
        "the .ele header",
        &["tet count", "nodes per tet", "region attribute count"],
    )?;
    let (n, npe, nattr) = (h[0], h[1], h[2]);
    if npe != 4 && npe != 10 {
        return Err(lines.error(
            None,
            format!("{npe} nodes per tet; tetgen tets have 4 or 10"),
            "fix the header or export linear tets",
        ));
    }
    let want = 1 + npe + nattr.min(1 << 16);
    raw.tets
        .reserve(capped(n, bytes.len() - lines.byte_pos(), 10));
    let mut fractional = 0usize;
    for k in 0..n {
        let line = lines.next_line().transpose()?.ok_or_else(|| {
            lines.error(
                None,
                format!("the header declares {n} tets but the file ends after {k}"),
                "the file is truncated or the header count is wrong",
            )
        })?;
        let toks = row_tokens(line);
        let id: i64 = lines.int(first(&toks), "tet id", None)?;
        if toks.len() < want {
            return Err(lines.error(
                Some(id),
                format!("tet row has {} values, expected {want}", toks.len()),
                "each row needs id, the node ids and the attributes the header declares",
            ));
        }
        let mut nodes = [0u32; 4];
        for (slot, tok) in nodes.iter_mut().zip(&toks[1..5]) {
            let node: i64 = lines.int(tok, "node id", Some(id))?;
            *slot = ids.get(node, path, lines.loc(), id)?;
        }
        let region = match nattr {
            0 => 0,
            _ => {
                let v = lines.f64(toks[1 + npe], "region attribute", Some(id))?;
                fractional += (v.fract() != 0.0) as usize;
                v.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32
            }
        };
        raw.tets.push(RawTet {
            nodes,
            region,
            id,
            location: lines.loc(),
        });
    }
    no_extra_rows(&mut lines, n, "tets")?;
    notes(raw, npe, nattr, fractional);
    Ok(())
}

/// Record what was assumed about the elements.
fn notes(raw: &mut RawMesh, npe: usize, nattr: usize, fractional: usize) {
    if npe == 10 {
        raw.notes.push(format!(
            "took the 4 corner nodes of {} 10-node (quadratic) tet(s)",
            raw.tets.len()
        ));
    }
    if nattr > 1 {
        raw.notes.push(format!(
            "used the first of {nattr} region attributes as the region tag"
        ));
    }
    if fractional > 0 {
        raw.notes.push(format!(
            "rounded {fractional} non-integer region attribute(s) to the nearest integer"
        ));
    }
}

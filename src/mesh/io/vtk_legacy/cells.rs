//! A legacy VTK file's cells: the classic and the 5.1 offset layouts, the cell types, and
//! each cell kept, ignored or refused.

use super::super::text::capped;
use super::super::vtk_cells::{unsupported_message, CellKind, CellTally, UNSUPPORTED_HINT};
use super::super::{RawTet, RawTriangle};
use super::{clip, Data, Scalar, Vtk};
use crate::error::{Error, Location, Result};

/// The cells as read: flat point lists, their starts, and where each cell was.
#[derive(Default)]
pub(super) struct Cells {
    conn: Vec<i64>,
    pub(super) starts: Vec<usize>,
    locs: Vec<Location>,
    pub(super) types: Vec<(i64, Location)>,
}

impl<'a> Vtk<'a> {
    /// `CELLS`, in the layout of the file's version.
    pub(super) fn cells(&mut self, args: &[&'a str]) -> Result<()> {
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
    pub(super) fn cell_types(&mut self, args: &[&'a str]) -> Result<()> {
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

    /// Convert cell `i`.
    pub(super) fn cell(
        &mut self,
        cells: &Cells,
        i: usize,
        tag: f64,
        tally: &mut CellTally,
    ) -> Result<()> {
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

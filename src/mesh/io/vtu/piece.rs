//! A `.vtu` piece's points and cells added to the mesh: the arrays a piece needs, its
//! regions, and each cell kept, ignored or refused.

use super::super::vtk_cells::{unsupported_message, CellKind, CellTally, UNSUPPORTED_HINT};
use super::super::{RawMesh, RawTet, RawTriangle};
use super::{ArrayDesc, Decoded, Doc, Piece, Positions, Values, REGION_NAMES};
use crate::error::{Location, Result};

impl<'a> Doc<'a> {
    /// Decode an array a piece needs, checking its presence and component count.
    fn array(
        &self,
        desc: Option<&ArrayDesc>,
        what: &str,
        piece: &Piece,
        components: usize,
        max_values: usize,
    ) -> Result<Decoded> {
        let desc = desc.ok_or_else(|| {
            self.err(
                Location::Line(piece.line),
                None,
                format!("the piece has no {what} array"),
                "the file is incomplete; export it again",
            )
        })?;
        if desc.components != components {
            return Err(self.err(
                Location::Line(desc.line),
                None,
                format!(
                    "the {what} array has {} components; it needs {components}",
                    desc.components
                ),
                "fix NumberOfComponents",
            ));
        }
        self.decode(desc, max_values)
    }

    /// Decode an array a piece needs and check that it holds `len` tuples.
    fn required(
        &self,
        desc: Option<&ArrayDesc>,
        what: &str,
        piece: &Piece,
        len: usize,
        components: usize,
    ) -> Result<Decoded> {
        let d = self.array(
            desc,
            what,
            piece,
            components,
            len.saturating_mul(components),
        )?;
        if len.checked_mul(components) != Some(d.values.len()) {
            return Err(self.err(
                d.at.loc,
                None,
                format!(
                    "the {what} array has {} values, but the piece needs {len} x {components}",
                    d.values.len()
                ),
                "the counts in <Piece> and the data disagree; export the file again",
            ));
        }
        Ok(d)
    }

    /// The values of an integer array.
    fn ints(&self, d: Decoded, what: &str) -> Result<(Vec<i64>, Positions)> {
        match d.values {
            Values::Int(v) => Ok((v, d.at)),
            Values::Float(_) => Err(self.err(
                d.at.loc,
                None,
                format!("the {what} array holds floats; it must hold integers"),
                "write cell arrays with an integer type",
            )),
        }
    }

    /// Add a piece's points and cells to `raw`; returns the name of the region array used.
    pub(super) fn add_piece(
        &self,
        piece: &Piece,
        raw: &mut RawMesh,
        counts: &mut CellTally,
    ) -> Result<Option<String>> {
        let base = raw.points.len();
        if base.saturating_add(piece.points) > u32::MAX as usize {
            return Err(self.err(
                Location::Line(piece.line),
                None,
                "the mesh has more points than lancet can index (2^32)".into(),
                "split the mesh",
            ));
        }
        if piece.points > 0 {
            let d = self.required(piece.coords.as_ref(), "Points", piece, piece.points, 3)?;
            let coords: Vec<f64> = match d.values {
                Values::Float(v) => v,
                Values::Int(v) => v.into_iter().map(|x| x as f64).collect(),
            };
            for (i, c) in coords.chunks_exact(3).enumerate() {
                raw.points.push([c[0], c[1], c[2]]);
                raw.point_ids.push((base + i) as i64);
            }
        }
        if piece.cells == 0 {
            return Ok(None);
        }
        let n = piece.cells;
        let offsets = self.required(piece.offsets.as_ref(), "offsets", piece, n, 1)?;
        let (offsets, offsets_d) = self.ints(offsets, "offsets")?;
        // The connectivity length is given by the last offset (checked below), which also
        // bounds what its data may inflate to.
        let conn_len = offsets
            .last()
            .map_or(0, |&o| usize::try_from(o).unwrap_or(0));
        let conn = self.array(
            piece.connectivity.as_ref(),
            "connectivity",
            piece,
            1,
            conn_len,
        )?;
        let (conn, conn_d) = self.ints(conn, "connectivity")?;
        let types = self.required(piece.types.as_ref(), "types", piece, n, 1)?;
        let (types, _) = self.ints(types, "types")?;
        let region = self.regions(piece)?;
        let cell_base = raw.tets.len() + raw.triangles.len();
        let mut prev = 0i64;
        for i in 0..n {
            let id = (cell_base + i) as i64;
            let end = offsets[i];
            if end <= prev || end as u64 > conn.len() as u64 {
                return Err(self.err(
                    offsets_d.loc_of(i),
                    Some(id),
                    format!(
                        "cell offset {end} does not increase from {prev} or lies past the \
                         {} connectivity entries",
                        conn.len()
                    ),
                    "offsets must increase and end at the connectivity length",
                ));
            }
            let start = prev as usize;
            prev = end;
            let cell = Cell {
                id,
                kind: types[i],
                nodes: &conn[start..end as usize],
                loc: conn_d.loc_of(start),
                region: region.as_ref().map_or(0, |(_, r)| r[i]),
            };
            self.add_cell(&cell, base, piece.points, raw, counts)?;
        }
        if prev as u64 != conn.len() as u64 {
            return Err(self.err(
                conn_d.loc,
                None,
                format!(
                    "the connectivity array has {} entries but the offsets end at {prev}",
                    conn.len()
                ),
                "the cell arrays disagree; export the file again",
            ));
        }
        Ok(region.map(|(name, _)| name))
    }

    /// The region tags of a piece's cells, from the first `CellData` array with a region-like
    /// name.
    fn regions(&self, piece: &Piece) -> Result<Option<(String, Vec<i32>)>> {
        let pick = REGION_NAMES.iter().find_map(|key| {
            piece
                .cell_data
                .iter()
                .find(|a| a.components == 1 && a.name.to_ascii_lowercase().contains(key))
        });
        let Some(desc) = pick else {
            return Ok(None);
        };
        let d = self.required(Some(desc), &desc.name, piece, piece.cells, 1)?;
        let as_i32 = |i: usize, v: f64| -> Result<i32> {
            if v.fract() == 0.0 && v >= i32::MIN as f64 && v <= i32::MAX as f64 {
                Ok(v as i32)
            } else {
                Err(self.err(
                    d.at.loc_of(i),
                    Some(i as i64),
                    format!(
                        "region tag {v} in array {:?} is not a 32-bit integer",
                        desc.name
                    ),
                    "region tags must be whole numbers",
                ))
            }
        };
        let tags = match &d.values {
            Values::Int(v) => v
                .iter()
                .enumerate()
                .map(|(i, &x)| as_i32(i, x as f64))
                .collect::<Result<Vec<_>>>()?,
            Values::Float(v) => v
                .iter()
                .enumerate()
                .map(|(i, &x)| as_i32(i, x))
                .collect::<Result<Vec<_>>>()?,
        };
        Ok(Some((desc.name.clone(), tags)))
    }

    /// Add one cell: tets and triangles are kept, vertices, lines and other surface cells are
    /// counted and skipped, other volume cells are an error.
    fn add_cell(
        &self,
        cell: &Cell,
        base: usize,
        points: usize,
        raw: &mut RawMesh,
        counts: &mut CellTally,
    ) -> Result<()> {
        let kind = CellKind::of(cell.kind);
        counts.record(kind);
        match kind {
            CellKind::VertexOrLine | CellKind::OtherSurface => return Ok(()),
            CellKind::Volume(_) | CellKind::Unknown => {
                return Err(self.err(
                    cell.loc,
                    Some(cell.id),
                    unsupported_message(cell.kind),
                    UNSUPPORTED_HINT,
                ))
            }
            _ => {}
        }
        if let Some(msg) = kind.wrong_points(cell.kind, cell.nodes.len()) {
            return Err(self.err(
                cell.loc,
                Some(cell.id),
                msg,
                "fix the offsets or the cell type",
            ));
        }
        if kind.corners() == 3 {
            let nodes = self.nodes::<3>(cell, base, points)?;
            raw.triangles.push(RawTriangle {
                nodes,
                tag: cell.region,
            });
        } else {
            let nodes = self.nodes::<4>(cell, base, points)?;
            raw.tets.push(RawTet {
                nodes,
                region: cell.region,
                id: cell.id,
                location: cell.loc,
            });
        }
        Ok(())
    }

    /// The first `N` point references of a cell, checked against the piece's points and
    /// shifted by the points of earlier pieces.
    fn nodes<const N: usize>(&self, cell: &Cell, base: usize, points: usize) -> Result<[u32; N]> {
        let mut out = [0u32; N];
        for (slot, &v) in out.iter_mut().zip(cell.nodes) {
            if v < 0 || v as u64 >= points as u64 {
                return Err(self.err(
                    cell.loc,
                    Some(cell.id),
                    format!("cell references point {v}, but the piece has {points} points"),
                    "point numbers in the connectivity start at 0 in each piece",
                ));
            }
            *slot = (base + v as usize) as u32;
        }
        Ok(out)
    }
}

/// One cell as read, before it becomes a tet or triangle.
struct Cell<'c> {
    id: i64,
    kind: i64,
    nodes: &'c [i64],
    loc: Location,
    region: i32,
}

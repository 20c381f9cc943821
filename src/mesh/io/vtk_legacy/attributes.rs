//! A legacy VTK file's attribute data: the region array read, everything else skipped with
//! a note.

use super::super::text::capped;
use super::{is_region_name, Scalar, Vtk};
use crate::error::Result;

/// Where attribute data being read belongs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Attached {
    /// Before any `CELL_DATA`/`POINT_DATA` (a dataset-level `FIELD`).
    Dataset,
    Cells(usize),
    Points(usize),
}

impl<'a> Vtk<'a> {
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
    pub(super) fn attribute(&mut self, kw: &str, args: &[&'a str]) -> Result<()> {
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
    pub(super) fn field(&mut self, args: &[&'a str]) -> Result<()> {
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
    pub(super) fn skip_metadata(&mut self) -> Result<()> {
        let lines = self.toks.lines();
        while let Some(l) = lines.next_raw() {
            if l?.trim().is_empty() {
                break;
            }
        }
        Ok(())
    }

    /// Skip a `METADATA` block if one comes next.
    pub(super) fn skip_metadata_if_any(&mut self) -> Result<()> {
        let next = self.toks.lines().peek_line().and_then(|r| r.ok());
        if next.is_some_and(|s| s.eq_ignore_ascii_case("METADATA")) {
            self.toks.lines().next_line();
            self.skip_metadata()?;
        }
        Ok(())
    }
}

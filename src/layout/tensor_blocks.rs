//! The tensor-mass model packed beside a spring layout: one 3x3 block per spring slot (or per
//! edge record), at the slot's own index, so that the layout's tables (rows, continuation rows,
//! valence buckets, the edge records and their incidence) serve the tensors unchanged.
//!
//! A node-centric slot of node `i` pointing at `j` holds `K_ij` (and `C_ij`, Rayleigh's
//! `beta K`, where any tet is damped); an edge record `(a, b)` holds `K_ab` (and `C_ab`). The
//! node tensors `K_ii` are not stored: an element's block rows sum to zero (a translation
//! stores no energy), so `K_ii = -sum_j K_ij` and the force is
//! `f_i = -sum_j K_ij (u_j - u_i) - sum_j C_ij (v_j - v_i)`, on displacement differences as
//! the springs' `e_ij + (u_j - u_i)` is: a large common motion is never rounded against a
//! small strain, and a step reads 48 bytes less per node. The fast engine does the same
//! (`engine::fast::elements`).
//!
//! Each block is three `vec4<f32>` rows (`xyz` used, `w` zero), then three more for `C` when
//! damped: [`TensorBlocks::stride`] vec4s per slot. The blocks are rounded once from the
//! float64 assembly of per-tet shares ([`TensorMass`]).

use super::edges::EdgeLayout;
use super::patch::LayoutArray;
use super::{PackedLayout, Slot};
use crate::physics::{Mat3, TensorMass};

/// One row of a block on the device (`xyz`; `w` is zero).
pub type Row = [f32; 4];

/// The tensor-mass blocks of a layout, by slot (node-centric layouts) or record (edges).
#[derive(Debug, Clone, PartialEq)]
pub struct TensorBlocks {
    /// Whether the damping blocks `C` follow the stiffness blocks.
    pub damped: bool,
    /// [`TensorBlocks::stride`] rows per slot.
    pub rows: Vec<Row>,
}

/// `m` (or `m^T`) as three device rows.
fn rows_of(m: &Mat3, transposed: bool) -> [Row; 3] {
    std::array::from_fn(|r| {
        let e = |c: usize| if transposed { m[c][r] } else { m[r][c] };
        [e(0) as f32, e(1) as f32, e(2) as f32, 0.0]
    })
}

impl TensorBlocks {
    /// Rows per slot: 3 (`K`), 6 (`K` then `C`) when damped.
    pub fn stride(&self) -> usize {
        if self.damped {
            6
        } else {
            3
        }
    }

    /// The layout array the blocks run beside (one block per element of it).
    pub fn beside(layout: &PackedLayout) -> LayoutArray {
        match layout {
            PackedLayout::Edges(_) => LayoutArray::EdgeSprings,
            _ => LayoutArray::Slots,
        }
    }

    /// The plausible end force of the edge records `edges` (which these blocks run beside),
    /// N: the largest `|K_ab|_F * rest` over records, what a record's stiffness block gives
    /// for a difference of displacements as long as the record's rest length (a tet edge
    /// stretched to twice its length). It bounds both ends' forces (`|K du|` and `|K^T du|`
    /// are at most `|K|_F |du|`); the fixed-point accumulation is sized from it
    /// ([`crate::layout::edges::FixedPoint`]).
    pub fn plausible_end_force(&self, edges: &EdgeLayout) -> f64 {
        let stride = self.stride();
        edges
            .springs
            .iter()
            .enumerate()
            .map(|(r, s)| {
                let k = self.rows.get(r * stride..r * stride + 3).unwrap_or(&[]);
                let norm2: f64 = k
                    .iter()
                    .flat_map(|row| &row[..3])
                    .map(|&x| (x as f64) * (x as f64))
                    .sum();
                norm2.sqrt() * s.rest.abs() as f64
            })
            .fold(0.0, f64::max)
    }

    /// Bytes of one slot's blocks.
    pub fn slot_bytes(&self) -> u64 {
        self.stride() as u64 * 16
    }

    /// The blocks of `tm` beside `layout` (node indices of `tm` are the model's: the layout's
    /// order maps them). A slot whose pair of nodes no tet holds gets a zero block.
    pub fn new(layout: &PackedLayout, tm: &TensorMass, damped: bool) -> Self {
        let mut b = TensorBlocks {
            damped,
            rows: Vec::new(),
        };
        let n = match layout {
            PackedLayout::Connectivity(c) => c.slots.len(),
            PackedLayout::Valence(v) => v.slots.len(),
            PackedLayout::Edges(e) => e.springs.len(),
        };
        b.rows = vec![[0.0; 4]; n * b.stride()];
        for (slot, from, to) in slot_pairs(layout) {
            b.write_pair(slot, from, to, tm);
        }
        b
    }

    /// Write slot `slot`'s blocks for the pair `from -> to` (model indices).
    pub fn write_pair(&mut self, slot: usize, from: u32, to: u32, tm: &TensorMass) {
        let stride = self.stride();
        let at = slot * stride;
        let Some(e) = tm.edge_tensor(from, to) else {
            self.rows[at..at + stride].fill([0.0; 4]);
            return;
        };
        // Stored from the lower node to the higher: K_ij, or K_ji^T.
        let t = from > to;
        self.rows[at..at + 3].copy_from_slice(&rows_of(&e.stiffness, t));
        if self.damped {
            self.rows[at + 3..at + 6].copy_from_slice(&rows_of(&e.damping, t));
        }
    }

    /// Bytes of the device buffer holding the blocks.
    pub fn bytes(&self) -> u64 {
        self.rows.len() as u64 * 16
    }
}

/// Every slot in use, with the model indices of its node and of the node it points at:
/// `(slot, from, to)` (see [`slot_walk`]).
pub fn slot_pairs(layout: &PackedLayout) -> Vec<(usize, u32, u32)> {
    let order = &layout.order().order;
    slot_walk(layout)
        .into_iter()
        .map(|(i, slot, j)| (slot, order[i as usize], order[j as usize]))
        .collect()
}

/// Every slot in use as the passes read it: `(node, slot, other)`, node and other in layout
/// order. Each node's slots come in the order its pass sums them: connectivity rows walked
/// through their continuation rows, valence rows left to right; an edge record `(a, b)` is
/// `(a, record, b)`.
pub fn slot_walk(layout: &PackedLayout) -> Vec<(u32, usize, u32)> {
    let order = &layout.order().order;
    let mut out = Vec::new();
    match layout {
        PackedLayout::Connectivity(c) => {
            let k = c.capacity as usize;
            for (i, &o) in order.iter().enumerate().take(c.node_count()) {
                if o == super::NodeOrder::HOLE {
                    continue;
                }
                let mut row = i;
                // A chain is never longer than the table (as the pass bounds it).
                for _ in 0..=c.slots.len() / k.max(1) {
                    let mut next = None;
                    for at in row * k..(row + 1) * k {
                        let s = &c.slots[at];
                        match s.other {
                            Slot::EMPTY => break,
                            Slot::CONTINUE => {
                                next = Some(s.pad as usize);
                                break;
                            }
                            j => out.push((i as u32, at, j)),
                        }
                    }
                    match next {
                        Some(r) => row = r,
                        None => break,
                    }
                }
            }
        }
        PackedLayout::Valence(v) => {
            for b in &v.buckets {
                for local in 0..b.count {
                    let i = b.first + local;
                    if order[i as usize] == super::NodeOrder::HOLE {
                        continue;
                    }
                    let base = (b.offset + local * b.valence) as usize;
                    for at in base..base + b.valence as usize {
                        let s = &v.slots[at];
                        if s.other == Slot::EMPTY {
                            break;
                        }
                        out.push((i, at, s.other));
                    }
                }
            }
        }
        PackedLayout::Edges(e) => {
            for (r, s) in e.springs.iter().enumerate() {
                // A dead record (both ends on one node) holds no edge.
                if s.a != s.b {
                    out.push((s.a, r, s.b));
                }
            }
        }
    }
    out
}

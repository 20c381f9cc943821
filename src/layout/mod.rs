//! Packing the spring model into dense, GPU-ready arrays, in the three memory layouts of the
//! GPU surgical-simulation literature:
//!
//! - [`connectivity`]: every node owns `K` fixed slots (the 2005 "connectivity texture"); a
//!   node-centric gather, padded to the widest node.
//! - [`valence`]: nodes grouped into buckets by valence, each bucket a table exactly as wide as
//!   its valence (the "valence textures"); no padding, nodes permuted.
//! - [`edges`]: one entry per spring; forces are computed once per spring and reach the nodes by
//!   atomics or by a gather through a node-to-spring incidence table.
//!
//! This module is pure CPU: it builds the arrays, reports their memory and patches them after
//! edits. The GPU passes that read them live in `engine::gpu` and `shaders/`.

pub mod connectivity;
pub mod edges;
pub mod patch;
pub mod rcm;
pub mod tensor_blocks;
pub mod tet_pairs;
pub mod tet_table;
pub mod valence;
mod verify;

use bytemuck::{Pod, Zeroable};
use serde::Serialize;

use crate::model::{PackedModel, PackedSpring};

/// Which memory layout a GPU engine packs the springs in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, Default)]
pub enum LayoutKind {
    /// Fixed slots per node, padded to the widest node; node-centric gather.
    #[default]
    Connectivity,
    /// Nodes grouped by valence, no padding.
    Valence,
    /// One record per spring, forces accumulated to nodes.
    Edges,
}

/// One spring as seen from one of its ends: the unit every layout stores.
///
/// Mirrors `struct Slot` in `shaders/common.wgsl` (same field order; `vec3<f32>` has 16-byte
/// alignment and 12-byte size there, so `rest` packs into its fourth word and the struct is 32
/// bytes on both sides).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Slot {
    /// Rest vector from this node to the other, m: computed in float64 and rounded once, so the
    /// rest shape keeps float32 precision of the edge, not of the coordinates.
    pub edge: [f32; 3],
    /// Rest length, m.
    pub rest: f32,
    /// Stiffness, N/m.
    pub k: f32,
    /// Damping along the spring, N s/m.
    pub c: f32,
    /// The other end (index in the layout's node order); [`Slot::EMPTY`] in padding slots.
    pub other: u32,
    /// Padding to 32 bytes; in a [`Slot::CONTINUE`] slot, the row the springs go on in.
    pub pad: u32,
}

const _: () = assert!(std::mem::size_of::<Slot>() == 32);

impl Slot {
    /// Marks an unused slot.
    pub const EMPTY: u32 = u32::MAX;

    /// Marks the last slot of a full connectivity row whose node has more springs: they go on
    /// in the row `pad` names ([`Slot::continuation`]).
    pub const CONTINUE: u32 = u32::MAX - 1;

    /// The slot that continues a connectivity row in row `row` (past the node rows).
    pub fn continuation(row: u32) -> Self {
        Slot {
            other: Slot::CONTINUE,
            pad: row,
            ..Zeroable::zeroed()
        }
    }

    /// An unused slot (zero stiffness, `other = EMPTY`).
    pub fn empty() -> Self {
        Slot {
            other: Slot::EMPTY,
            ..Zeroable::zeroed()
        }
    }

    /// The slot of spring `s` seen from node `from` (one of its ends, model order), pointing at
    /// the other end, whose index in the layout's order is `other`.
    pub fn of(model: &PackedModel, s: &PackedSpring, from: u32, other: u32) -> Self {
        let to = if s.nodes[0] == from {
            s.nodes[1]
        } else {
            s.nodes[0]
        };
        let (a, b) = (model.rest[from as usize], model.rest[to as usize]);
        Slot {
            edge: [
                (b[0] - a[0]) as f32,
                (b[1] - a[1]) as f32,
                (b[2] - a[2]) as f32,
            ],
            rest: s.rest_length as f32,
            k: s.stiffness as f32,
            c: s.damping as f32,
            other,
            pad: 0,
        }
    }
}

/// A renumbering of nodes: `order[new] = old`, `rank[old] = new`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeOrder {
    /// Old (model) index of each new index.
    pub order: Vec<u32>,
    /// New index of each old (model) index.
    pub rank: Vec<u32>,
}

impl NodeOrder {
    /// Marks a layout index that holds no node (room left in a valence bucket).
    pub const HOLE: u32 = u32::MAX;

    /// Build from `order[new] = old`; entries may be [`NodeOrder::HOLE`], and the model nodes
    /// are those that appear.
    pub fn from_order(order: Vec<u32>) -> Self {
        let nodes = order.iter().filter(|&&o| o != Self::HOLE).count();
        let mut rank = vec![0u32; nodes];
        for (new, &old) in order.iter().enumerate() {
            if old != Self::HOLE {
                rank[old as usize] = new as u32;
            }
        }
        NodeOrder { order, rank }
    }

    /// Layout index and model index of every node, skipping holes.
    pub fn pairs(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.order
            .iter()
            .enumerate()
            .filter(|(_, &old)| old != Self::HOLE)
            .map(|(new, &old)| (new, old as usize))
    }

    /// The model's own order.
    pub fn identity(n: usize) -> Self {
        Self::from_order((0..n as u32).collect())
    }

    /// Reverse Cuthill–McKee order of the model's spring graph, for memory locality.
    pub fn locality(model: &PackedModel) -> Self {
        Self::from_order(locality_order(model))
    }
}

/// The spring graph of a model in CSR form (model order): row starts and neighbour indices.
pub fn spring_graph(model: &PackedModel) -> (Vec<u32>, Vec<u32>) {
    let n = model.node_count();
    let mut rows = vec![0u32; n + 1];
    for s in model.springs() {
        rows[s.nodes[0] as usize + 1] += 1;
        rows[s.nodes[1] as usize + 1] += 1;
    }
    for i in 0..n {
        rows[i + 1] += rows[i];
    }
    let mut fill = rows.clone();
    let mut cols = vec![0u32; rows[n] as usize];
    for s in model.springs() {
        let [a, b] = s.nodes;
        cols[fill[a as usize] as usize] = b;
        fill[a as usize] += 1;
        cols[fill[b as usize] as usize] = a;
        fill[b as usize] += 1;
    }
    // Each row in ascending order, whatever the springs' order (a cut leaves them in none):
    // the locality order's start node is the first of least degree it meets.
    for i in 0..n {
        cols[rows[i] as usize..rows[i + 1] as usize].sort_unstable();
    }
    (rows, cols)
}

/// Reverse Cuthill–McKee order (`order[new] = old`) of the model's spring graph.
pub fn locality_order(model: &PackedModel) -> Vec<u32> {
    let (rows, cols) = spring_graph(model);
    rcm::reverse_cuthill_mckee(&rcm::Csr {
        rows: &rows,
        cols: &cols,
    })
}

/// Memory a layout uses on the device.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MemoryStats {
    /// Each buffer by name and its size in bytes.
    pub buffers: Vec<(String, u64)>,
    /// Sum of all buffers, bytes.
    pub total: u64,
    /// Bytes spent on padding (unused slots), included in `total`.
    pub padding: u64,
    /// `total / nodes`.
    pub bytes_per_node: f64,
    /// `total / springs`.
    pub bytes_per_spring: f64,
}

impl MemoryStats {
    /// Stats of the named buffers for a model of `nodes` and `springs`.
    pub fn new(buffers: Vec<(String, u64)>, padding: u64, nodes: usize, springs: usize) -> Self {
        let total = buffers.iter().map(|(_, b)| b).sum();
        MemoryStats {
            buffers,
            total,
            padding,
            bytes_per_node: total as f64 / nodes.max(1) as f64,
            bytes_per_spring: total as f64 / springs.max(1) as f64,
        }
    }

    /// Padding as a percentage of the total.
    pub fn padding_percent(&self) -> f64 {
        100.0 * self.padding as f64 / self.total.max(1) as f64
    }
}

/// A model packed in one of the layouts: what an engine keeps to patch it after edits.
#[derive(Debug, Clone, PartialEq)]
pub enum PackedLayout {
    /// Fixed slots per node.
    Connectivity(connectivity::ConnectivityLayout),
    /// Per-valence tables.
    Valence(valence::ValenceLayout),
    /// Spring records and incidence table.
    Edges(edges::EdgeLayout),
}

impl PackedLayout {
    /// Pack `model` in `kind`, starting from node order `order` (valence regroups it).
    pub fn pack(model: &PackedModel, kind: LayoutKind, order: NodeOrder) -> crate::Result<Self> {
        Ok(match kind {
            LayoutKind::Connectivity => {
                Self::Connectivity(connectivity::ConnectivityLayout::new(model, order, None)?)
            }
            LayoutKind::Valence => Self::Valence(valence::ValenceLayout::new(model, &order)),
            LayoutKind::Edges => Self::Edges(edges::EdgeLayout::new(model, order)),
        })
    }

    /// Keep a quarter of room in every array, so that the patches of local cuts append without
    /// reallocating: the first patch of a fresh packing otherwise moved each array that grew
    /// (the connectivity table of the 100k-tet box is 12 MB) into new pages, a pause of 3-6 ms
    /// on the first cut. Costs a quarter more host memory for the arrays; call it again after
    /// a patch that repacked (the GPU engine does).
    pub fn reserve_room(&mut self) {
        fn room<T>(v: &mut Vec<T>) {
            // Exactly (`reserve` may double); small arrays (the valence buckets) by at least
            // 64 entries.
            v.reserve_exact((v.len() / 4).max(64));
        }
        fn order_room(o: &mut NodeOrder) {
            room(&mut o.order);
            room(&mut o.rank);
        }
        match self {
            Self::Connectivity(c) => {
                order_room(&mut c.order);
                room(&mut c.slots);
                room(&mut c.nodes.inv_mass);
            }
            Self::Valence(v) => {
                order_room(&mut v.order);
                room(&mut v.buckets);
                room(&mut v.room);
                room(&mut v.slots);
                room(&mut v.nodes.inv_mass);
            }
            Self::Edges(e) => {
                order_room(&mut e.order);
                room(&mut e.springs);
                room(&mut e.incidence_rows);
                room(&mut e.incidence);
                room(&mut e.nodes.inv_mass);
            }
        }
    }

    /// Bytes the host holds for the arrays it uploads ([`PackedLayout::array`]), room
    /// included.
    pub fn host_capacity_bytes(&self) -> usize {
        fn held<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        match self {
            Self::Connectivity(c) => held(&c.slots) + held(&c.nodes.inv_mass),
            Self::Valence(v) => held(&v.slots) + held(&v.nodes.inv_mass) + held(&v.buckets),
            Self::Edges(e) => {
                held(&e.springs)
                    + held(&e.incidence_rows)
                    + held(&e.incidence)
                    + held(&e.nodes.inv_mass)
            }
        }
    }

    /// Which layout this is.
    pub fn kind(&self) -> LayoutKind {
        match self {
            Self::Connectivity(_) => LayoutKind::Connectivity,
            Self::Valence(_) => LayoutKind::Valence,
            Self::Edges(_) => LayoutKind::Edges,
        }
    }

    /// The node renumbering.
    pub fn order(&self) -> &NodeOrder {
        match self {
            Self::Connectivity(c) => &c.order,
            Self::Valence(v) => &v.order,
            Self::Edges(e) => &e.order,
        }
    }

    /// Layout indices, holes included: the length of every per-node device array.
    pub fn node_slots(&self) -> usize {
        self.order().order.len()
    }

    /// Apply `diff`, already applied to `model`; see each layout's `patch`.
    pub fn patch(
        &mut self,
        model: &PackedModel,
        diff: &crate::model::ModelDiff,
    ) -> crate::Result<patch::LayoutPatch> {
        match self {
            Self::Connectivity(c) => c.patch(model, diff),
            Self::Valence(v) => v.patch(model, diff),
            Self::Edges(e) => e.patch(model, diff),
        }
    }

    /// The bytes of one of the arrays this layout uploads (empty if it has no such array).
    pub fn array(&self, array: patch::LayoutArray) -> &[u8] {
        use patch::LayoutArray as A;
        match (self, array) {
            (Self::Connectivity(c), A::Slots) => bytemuck::cast_slice(&c.slots),
            (Self::Connectivity(c), A::InvMass) => bytemuck::cast_slice(&c.nodes.inv_mass),
            (Self::Valence(v), A::Slots) => bytemuck::cast_slice(&v.slots),
            (Self::Valence(v), A::InvMass) => bytemuck::cast_slice(&v.nodes.inv_mass),
            (Self::Valence(v), A::Buckets) => bytemuck::cast_slice(&v.buckets),
            (Self::Edges(e), A::EdgeSprings) => bytemuck::cast_slice(&e.springs),
            (Self::Edges(e), A::IncidenceRows) => bytemuck::cast_slice(&e.incidence_rows),
            (Self::Edges(e), A::Incidence) => bytemuck::cast_slice(&e.incidence),
            (Self::Edges(e), A::InvMass) => bytemuck::cast_slice(&e.nodes.inv_mass),
            _ => &[],
        }
    }

    /// Bytes a device upload of the whole layout writes: every array, and the valence bucket
    /// table's header (the base a patch's upload is measured against).
    pub fn upload_bytes(&self) -> u64 {
        let arrays: u64 = patch::LayoutArray::ALL
            .iter()
            .map(|&a| self.array(a).len() as u64)
            .sum();
        match self {
            Self::Valence(_) => arrays + valence::TABLE_HEADER,
            _ => arrays,
        }
    }
}

//! The valence layout (the "valence textures"): nodes are renumbered so that nodes of equal
//! valence are contiguous, and each such bucket has a slot table exactly as wide as its valence,
//! `slots[bucket.offset + local * valence + s]`. No padding; the price is a permutation of the
//! nodes (kept here, invisible to users) and one dispatch per bucket.

use bytemuck::{Pod, Zeroable};

use super::connectivity::{node_update, state_buffers, state_traffic, NodeArrays, StepParams};
use super::{MemoryStats, NodeOrder, Slot};
use crate::engine::Integrator;
use crate::model::PackedModel;

/// One bucket of nodes with the same valence. Mirrors `struct Bucket` in
/// `shaders/springs_valence.wgsl` (16 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Pod, Zeroable)]
pub struct Bucket {
    /// Springs per node in this bucket (the table's width).
    pub valence: u32,
    /// First node of the bucket, layout order.
    pub first: u32,
    /// Nodes in the bucket.
    pub count: u32,
    /// First slot of the bucket's table.
    pub offset: u32,
}

const _: () = assert!(std::mem::size_of::<Bucket>() == 16);

/// Springs packed into per-valence tables.
#[derive(Debug, Clone, PartialEq)]
pub struct ValenceLayout {
    /// Node renumbering: `order.order[layout] = model`, `order.rank[model] = layout`.
    pub order: NodeOrder,
    /// Buckets in increasing valence.
    pub buckets: Vec<Bucket>,
    /// All tables, back to back; exactly two slots per spring.
    pub slots: Vec<Slot>,
    /// Per-node arrays, layout order.
    pub nodes: NodeArrays,
}

impl ValenceLayout {
    /// Pack `model`, grouping nodes by valence and keeping `base` order (for locality) within
    /// each bucket.
    pub fn new(model: &PackedModel, base: &NodeOrder) -> Self {
        let n = model.node_count();
        let mut valence = vec![0u32; n];
        for s in &model.springs {
            valence[s.nodes[0] as usize] += 1;
            valence[s.nodes[1] as usize] += 1;
        }
        // Stable sort of the base order by valence: buckets keep the locality within them.
        let mut order = base.order.clone();
        order.sort_by_key(|&old| valence[old as usize]);
        let order = NodeOrder::from_order(order);
        let mut buckets: Vec<Bucket> = Vec::new();
        let mut offset = 0u32;
        for (new, &old) in order.order.iter().enumerate() {
            let v = valence[old as usize];
            match buckets.last_mut() {
                Some(b) if b.valence == v => b.count += 1,
                _ => buckets.push(Bucket {
                    valence: v,
                    first: new as u32,
                    count: 1,
                    offset,
                }),
            }
            offset += v;
        }
        // A node's table starts at its bucket's offset plus its rank in the bucket times the
        // width, which is also the running sum of valences before it.
        let mut start = vec![0u32; n];
        let mut run = 0u32;
        for (new, &old) in order.order.iter().enumerate() {
            start[new] = run;
            run += valence[old as usize];
        }
        let mut slots = vec![Slot::empty(); run as usize];
        let mut fill = vec![0u32; n];
        for s in &model.springs {
            for (from, to) in [(s.nodes[0], s.nodes[1]), (s.nodes[1], s.nodes[0])] {
                let row = order.rank[from as usize] as usize;
                slots[(start[row] + fill[row]) as usize] =
                    Slot::of(model, s, from, order.rank[to as usize]);
                fill[row] += 1;
            }
        }
        for (new, &old) in order.order.iter().enumerate() {
            let (a, v) = (start[new] as usize, valence[old as usize] as usize);
            slots[a..a + v].sort_by_key(|s| s.other);
        }
        let nodes = NodeArrays::new(model, &order);
        ValenceLayout {
            order,
            buckets,
            slots,
            nodes,
        }
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.inv_mass.len()
    }

    /// Device memory with node state (`uniform_stride`: bytes per bucket in the dynamic-offset
    /// uniform buffer, the device's uniform offset alignment), and the bytes one step moves.
    pub fn memory(&self, integrator: Integrator, uniform_stride: u64) -> (MemoryStats, u64) {
        let n = self.node_count() as u64;
        let slots = self.slots.len() as u64 * 32;
        let table = self.buckets.len() as u64 * uniform_stride;
        let mut buffers = vec![
            ("slots".to_string(), slots),
            ("inverse masses".to_string(), n * 4),
            ("bucket table".to_string(), table),
        ];
        buffers.extend(state_buffers(n, integrator));
        // Only the 16 bytes of each bucket entry are read; the rest is alignment, not padding
        // of the spring data.
        let stats = MemoryStats::new(buffers, 0, n as usize, self.slots.len() / 2);
        let per_step =
            slots + n * 4 + self.buckets.len() as u64 * 16 + state_traffic(n, integrator);
        (stats, per_step)
    }

    /// One step on the CPU exactly as `shaders/springs_valence.wgsl` does it (the GPU pass's
    /// twin); see [`super::connectivity::ConnectivityLayout::step_cpu`] for the arguments.
    pub fn step_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let mut next = vec![[0.0f32; 4]; cur.len()];
        let mut second_next = vec![[0.0f32; 4]; cur.len()];
        for b in &self.buckets {
            for local in 0..b.count {
                let i = (b.first + local) as usize;
                let base = (b.offset + local * b.valence) as usize;
                let row = &self.slots[base..base + b.valence as usize];
                let (u, s) = node_update(p, row, self.nodes.inv_mass[i], cur, second, i);
                next[i] = u;
                second_next[i] = s;
            }
        }
        (next, second_next)
    }
}

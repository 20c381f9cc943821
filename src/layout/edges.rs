//! The edge-centric layout: one record per spring. A first pass computes each spring's force
//! once (half the length computations of a node-centric gather); the forces reach the nodes
//! through a second pass in which every node sums its incident springs' forces from a
//! node-to-spring incidence table and integrates itself.
//!
//! That gather is deterministic (each node sums in a fixed order) and needs no atomics. The
//! alternative, atomic accumulation from the spring pass, measured 2.4x (fixed-point integer
//! atomics) and 3.5x (float atomics) slower than a gather on lavapipe (DESIGN.md section 5), and
//! float atomics sum in a different order every run; it is left for measurement on real GPUs.

use bytemuck::{Pod, Zeroable};

use super::connectivity::{
    integrate, spring_force, state_buffers, state_traffic, velocity, NodeArrays, StepParams,
};
use super::{MemoryStats, NodeOrder};
use crate::engine::Integrator;
use crate::model::PackedModel;

/// One spring. Mirrors `struct EdgeSpring` in `shaders/springs_edges.wgsl` (32 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct EdgeSpring {
    /// Rest vector from `a` to `b`, m (float64 difference rounded once).
    pub edge: [f32; 3],
    /// Rest length, m.
    pub rest: f32,
    /// Stiffness, N/m.
    pub k: f32,
    /// Damping along the spring, N s/m.
    pub c: f32,
    /// First end, layout order.
    pub a: u32,
    /// Second end, layout order.
    pub b: u32,
}

const _: () = assert!(std::mem::size_of::<EdgeSpring>() == 32);

impl EdgeSpring {
    /// The spring seen from its `a` end, for the shared force law.
    pub fn as_slot(&self) -> super::Slot {
        super::Slot {
            edge: self.edge,
            rest: self.rest,
            k: self.k,
            c: self.c,
            other: self.b,
            pad: 0,
        }
    }
}

/// Marks an incidence entry where the node is the spring's `b` end (the force acts reversed).
pub const B_END: u32 = 1 << 31;

/// Springs as records plus the node-to-spring incidence table.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeLayout {
    /// Node renumbering (RCM locality).
    pub order: NodeOrder,
    /// Springs sorted by their layout-order ends.
    pub springs: Vec<EdgeSpring>,
    /// Row starts of the incidence table, `n + 1` entries.
    pub incidence_rows: Vec<u32>,
    /// Spring indices, with [`B_END`] set where the node is the `b` end.
    pub incidence: Vec<u32>,
    /// Per-node arrays.
    pub nodes: NodeArrays,
}

impl EdgeLayout {
    /// Pack `model` in node order `order`.
    pub fn new(model: &PackedModel, order: NodeOrder) -> Self {
        let n = model.node_count();
        let mut springs: Vec<EdgeSpring> = model
            .springs
            .iter()
            .map(|s| {
                let (ra, rb) = (
                    order.rank[s.nodes[0] as usize],
                    order.rank[s.nodes[1] as usize],
                );
                // Store with a < b in layout order so the records stream by their first end.
                let (from, a, b) = if ra < rb {
                    (s.nodes[0], ra, rb)
                } else {
                    (s.nodes[1], rb, ra)
                };
                let slot = super::Slot::of(model, s, from, b);
                EdgeSpring {
                    edge: slot.edge,
                    rest: slot.rest,
                    k: slot.k,
                    c: slot.c,
                    a,
                    b,
                }
            })
            .collect();
        springs.sort_by_key(|s| (s.a, s.b));
        let mut incidence_rows = vec![0u32; n + 1];
        for s in &springs {
            incidence_rows[s.a as usize + 1] += 1;
            incidence_rows[s.b as usize + 1] += 1;
        }
        for i in 0..n {
            incidence_rows[i + 1] += incidence_rows[i];
        }
        let mut fill = incidence_rows.clone();
        let mut incidence = vec![0u32; incidence_rows[n] as usize];
        for (idx, s) in springs.iter().enumerate() {
            for (node, flag) in [(s.a, 0), (s.b, B_END)] {
                incidence[fill[node as usize] as usize] = idx as u32 | flag;
                fill[node as usize] += 1;
            }
        }
        let nodes = NodeArrays::new(model, &order);
        EdgeLayout {
            order,
            springs,
            incidence_rows,
            incidence,
            nodes,
        }
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.inv_mass.len()
    }

    /// Device memory with node state, and the bytes one step moves (the spring pass reads the
    /// records and writes one force per spring; the node pass reads the incidence table and the
    /// forces).
    pub fn memory(&self, integrator: Integrator) -> (MemoryStats, u64) {
        let n = self.node_count() as u64;
        let m = self.springs.len() as u64;
        let records = m * 32;
        let forces = m * 16;
        let table = (self.incidence_rows.len() + self.incidence.len()) as u64 * 4;
        let mut buffers = vec![
            ("springs".to_string(), records),
            ("spring forces".to_string(), forces),
            ("incidence table".to_string(), table),
            ("inverse masses".to_string(), n * 4),
        ];
        buffers.extend(state_buffers(n, integrator));
        let stats = MemoryStats::new(buffers, 0, n as usize, m as usize);
        // Forces are written once and read once.
        let per_step = records + 2 * forces + table + n * 4 + state_traffic(n, integrator);
        (stats, per_step)
    }

    /// The spring pass on the CPU, as `shaders/springs_edges.wgsl` computes it: the force each
    /// spring puts on its `a` end.
    pub fn spring_forces_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> Vec<[f32; 4]> {
        self.springs
            .iter()
            .map(|s| {
                let (a, b) = (s.a as usize, s.b as usize);
                let d = [
                    s.edge[0] + (cur[b][0] - cur[a][0]),
                    s.edge[1] + (cur[b][1] - cur[a][1]),
                    s.edge[2] + (cur[b][2] - cur[a][2]),
                ];
                let dv = if p.damped {
                    let (va, vb) = (
                        velocity(p, cur[a], second[a]),
                        velocity(p, cur[b], second[b]),
                    );
                    [vb[0] - va[0], vb[1] - va[1], vb[2] - va[2]]
                } else {
                    [0.0; 3]
                };
                let f = spring_force(p, &s.as_slot(), d, dv);
                [f[0], f[1], f[2], 0.0]
            })
            .collect()
    }

    /// The node pass on the CPU, as `shaders/gather_edges.wgsl` computes it: each node sums its
    /// incident forces in table order and integrates.
    pub fn gather_cpu(
        &self,
        p: &StepParams,
        forces: &[[f32; 4]],
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let n = cur.len();
        let mut next = vec![[0.0f32; 4]; n];
        let mut second_next = vec![[0.0f32; 4]; n];
        for i in 0..n {
            let m_inv = self.nodes.inv_mass[i];
            if m_inv == 0.0 {
                continue;
            }
            let mut f = [0.0f32; 3];
            let (lo, hi) = (self.incidence_rows[i], self.incidence_rows[i + 1]);
            for &e in &self.incidence[lo as usize..hi as usize] {
                let fs = forces[(e & !B_END) as usize];
                let sign = if e & B_END != 0 { -1.0 } else { 1.0 };
                for c in 0..3 {
                    f[c] += sign * fs[c];
                }
            }
            let vi = velocity(p, cur[i], second[i]);
            (next[i], second_next[i]) = integrate(p, cur[i], second[i], vi, f, m_inv);
        }
        (next, second_next)
    }

    /// Both passes: one step on the CPU.
    pub fn step_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let forces = self.spring_forces_cpu(p, cur, second);
        self.gather_cpu(p, &forces, cur, second)
    }
}

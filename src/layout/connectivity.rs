//! The connectivity layout (the 2005 "connectivity texture"): every node owns `K` fixed slots,
//! `slots[i * K + s]`, filled from the front, the rest marked [`Slot::EMPTY`]. One invocation
//! per node gathers its springs and integrates itself, so no two invocations write the same
//! node. The price is padding: every node pays for the widest one.

use super::{MemoryStats, NodeOrder, Slot};
use crate::engine::Integrator;
use crate::error::{Error, Result};
use crate::model::PackedModel;

/// Per-node data shared by the node-centric layouts, in the layout's node order.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeArrays {
    /// Inverse lumped mass, 1/kg; 0 for fixed nodes (they never move).
    pub inv_mass: Vec<f32>,
}

impl NodeArrays {
    /// The arrays of `model` in `order`.
    pub fn new(model: &PackedModel, order: &NodeOrder) -> Self {
        let inv_mass = order
            .order
            .iter()
            .map(|&old| {
                let old = old as usize;
                if model.fixed[old] {
                    0.0
                } else {
                    (1.0 / model.mass[old]) as f32
                }
            })
            .collect();
        NodeArrays { inv_mass }
    }
}

/// Springs packed into `K` slots per node.
#[derive(Debug, Clone, PartialEq)]
pub struct ConnectivityLayout {
    /// Node renumbering (model index <-> layout index).
    pub order: NodeOrder,
    /// Slots per node.
    pub capacity: u32,
    /// `capacity` slots per node, in layout order.
    pub slots: Vec<Slot>,
    /// Per-node arrays.
    pub nodes: NodeArrays,
}

impl ConnectivityLayout {
    /// Pack `model` in node order `order`, with `capacity` slots per node (default: the largest
    /// valence). A capacity below some node's valence is an error naming that node.
    pub fn new(model: &PackedModel, order: NodeOrder, capacity: Option<u32>) -> Result<Self> {
        let n = model.node_count();
        let mut valence = vec![0u32; n];
        for s in &model.springs {
            valence[s.nodes[0] as usize] += 1;
            valence[s.nodes[1] as usize] += 1;
        }
        let widest = valence.iter().copied().max().unwrap_or(0);
        let k = capacity.unwrap_or(widest).max(1);
        if let Some(node) = valence.iter().position(|&v| v > k) {
            return Err(Error::Model(format!(
                "node {node} has {} springs but the connectivity layout has {k} slots per node; \
                 raise the capacity to at least {widest}",
                valence[node]
            )));
        }
        let total = n
            .checked_mul(k as usize)
            .filter(|&t| t <= u32::MAX as usize)
            .ok_or_else(|| Error::Model("connectivity table too large for u32 indices".into()))?;
        let mut slots = vec![Slot::empty(); total];
        let mut fill = vec![0u32; n];
        // Springs are sorted by their node pair, so each row fills in neighbour order.
        for s in &model.springs {
            for (from, to) in [(s.nodes[0], s.nodes[1]), (s.nodes[1], s.nodes[0])] {
                let row = order.rank[from as usize] as usize;
                let at = row * k as usize + fill[row] as usize;
                slots[at] = Slot::of(model, s, from, order.rank[to as usize]);
                fill[row] += 1;
            }
        }
        // Within a row, put neighbours in ascending layout order so the gather walks memory
        // forwards.
        for row in slots.chunks_mut(k as usize) {
            row.sort_by_key(|s| s.other);
        }
        let nodes = NodeArrays::new(model, &order);
        Ok(ConnectivityLayout {
            order,
            capacity: k,
            slots,
            nodes,
        })
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.inv_mass.len()
    }

    /// Device memory of this layout with its node state (three vec4 displacement buffers, and
    /// two velocity buffers for symplectic Euler), and the bytes one step moves.
    pub fn memory(&self, integrator: Integrator) -> (MemoryStats, u64) {
        let n = self.node_count() as u64;
        let slots = self.slots.len() as u64 * 32;
        let used = self.slots.iter().filter(|s| s.other != Slot::EMPTY).count() as u64;
        let state = state_buffers(n, integrator);
        let mut buffers = vec![
            ("slots".to_string(), slots),
            ("inverse masses".to_string(), n * 4),
        ];
        buffers.extend(state.iter().cloned());
        let springs = (used / 2) as usize;
        let stats = MemoryStats::new(
            buffers,
            (self.slots.len() as u64 - used) * 32,
            n as usize,
            springs,
        );
        // The padded table is streamed whole (empty slots end a row's loop, but they share cache
        // lines with used ones), plus masses and the state read and written once.
        let per_step = slots + n * 4 + state_traffic(n, integrator);
        (stats, per_step)
    }

    /// One step on the CPU, exactly as `shaders/springs_connectivity.wgsl` does it: the twin the
    /// GPU pass is tested against. `second` is the previous displacement (Verlet) or the
    /// velocity (symplectic Euler); returns the next displacement and the next second state.
    pub fn step_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let k = self.capacity as usize;
        let mut next = vec![[0.0f32; 4]; cur.len()];
        let mut second_next = vec![[0.0f32; 4]; cur.len()];
        for i in 0..cur.len() {
            let row = &self.slots[i * k..(i + 1) * k];
            let (u, s) = node_update(p, row, self.nodes.inv_mass[i], cur, second, i);
            next[i] = u;
            second_next[i] = s;
        }
        (next, second_next)
    }
}

/// Constants of one step, as the shaders see them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepParams {
    /// Time step, s.
    pub h: f32,
    /// Gravity, m/s^2.
    pub gravity: [f32; 3],
    /// Mass-proportional damping, 1/s.
    pub alpha: f32,
    /// Integration scheme.
    pub integrator: Integrator,
    /// Whether springs are damped (neighbour velocities are read only then).
    pub damped: bool,
}

/// The update of node `i` from its slots: the arithmetic shared by every node-centric twin,
/// written in the order the WGSL kernels use.
pub(crate) fn node_update(
    p: &StepParams,
    slots: &[Slot],
    inv_mass: f32,
    cur: &[[f32; 4]],
    second: &[[f32; 4]],
    i: usize,
) -> ([f32; 4], [f32; 4]) {
    if inv_mass == 0.0 {
        return ([0.0; 4], [0.0; 4]);
    }
    let ui = cur[i];
    let vi = velocity(p, ui, second[i]);
    let mut f = [0.0f32; 3];
    for s in slots {
        if s.other == Slot::EMPTY {
            break;
        }
        let j = s.other as usize;
        let d = [
            s.edge[0] + (cur[j][0] - ui[0]),
            s.edge[1] + (cur[j][1] - ui[1]),
            s.edge[2] + (cur[j][2] - ui[2]),
        ];
        let dv = if p.damped {
            let vj = velocity(p, cur[j], second[j]);
            [vj[0] - vi[0], vj[1] - vi[1], vj[2] - vi[2]]
        } else {
            [0.0; 3]
        };
        let fs = spring_force(p, s, d, dv);
        for a in 0..3 {
            f[a] += fs[a];
        }
    }
    integrate(p, ui, second[i], vi, f, inv_mass)
}

/// Velocity of a node from its state, as the WGSL `velocity` computes it: backward difference
/// for Verlet (`second` = previous displacement), the stored velocity for symplectic Euler.
pub(crate) fn velocity(p: &StepParams, cur: [f32; 4], second: [f32; 4]) -> [f32; 3] {
    if p.integrator == Integrator::Verlet {
        let inv_h = 1.0 / p.h;
        [
            (cur[0] - second[0]) * inv_h,
            (cur[1] - second[1]) * inv_h,
            (cur[2] - second[2]) * inv_h,
        ]
    } else {
        [second[0], second[1], second[2]]
    }
}

/// Force of spring `s` on the node it is seen from, given the current spring vector `d` and
/// the relative velocity `dv` (other minus self), as the WGSL `slot_force` computes it.
pub(crate) fn spring_force(p: &StepParams, s: &Slot, d: [f32; 3], dv: [f32; 3]) -> [f32; 3] {
    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if l <= 0.0 {
        return [0.0; 3];
    }
    let dir = [d[0] / l, d[1] / l, d[2] / l];
    let mut mag = s.k * (l - s.rest);
    if p.damped {
        mag += s.c * (dv[0] * dir[0] + dv[1] * dir[1] + dv[2] * dir[2]);
    }
    [mag * dir[0], mag * dir[1], mag * dir[2]]
}

/// The next displacement and second state of a free node under spring force `f`, as the WGSL
/// `integrate` computes it.
pub(crate) fn integrate(
    p: &StepParams,
    ui: [f32; 4],
    second_i: [f32; 4],
    vi: [f32; 3],
    f: [f32; 3],
    inv_mass: f32,
) -> ([f32; 4], [f32; 4]) {
    let mut a = [0.0f32; 3];
    for c in 0..3 {
        a[c] = f[c] * inv_mass + p.gravity[c] - p.alpha * vi[c];
    }
    if p.integrator == Integrator::Verlet {
        let mut next = [0.0f32; 4];
        for c in 0..3 {
            next[c] = ui[c] + (ui[c] - second_i[c]) + (p.h * p.h) * a[c];
        }
        (next, [0.0; 4])
    } else {
        let (mut next, mut v) = ([0.0f32; 4], [0.0f32; 4]);
        for c in 0..3 {
            v[c] = vi[c] + p.h * a[c];
            next[c] = ui[c] + p.h * v[c];
        }
        (next, v)
    }
}

/// Node-state buffers of an integrator: three displacement buffers rotate for Verlet; symplectic
/// Euler uses two displacement and two velocity buffers.
pub(crate) fn state_buffers(n: u64, integrator: Integrator) -> Vec<(String, u64)> {
    match integrator {
        Integrator::Verlet => vec![("displacements (3 x vec4)".to_string(), 3 * n * 16)],
        Integrator::SymplecticEuler => vec![
            ("displacements (2 x vec4)".to_string(), 2 * n * 16),
            ("velocities (2 x vec4)".to_string(), 2 * n * 16),
        ],
    }
}

/// Bytes of node state one step reads and writes (each buffer once).
pub(crate) fn state_traffic(n: u64, integrator: Integrator) -> u64 {
    match integrator {
        Integrator::Verlet => 3 * n * 16,
        Integrator::SymplecticEuler => 4 * n * 16,
    }
}

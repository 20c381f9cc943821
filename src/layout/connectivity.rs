//! The connectivity layout (the 2005 "connectivity texture"): every node owns `K` fixed slots,
//! `slots[i * K + s]`, filled from the front, the rest marked [`Slot::EMPTY`]. One invocation
//! per node gathers its springs and integrates itself, so no two invocations write the same
//! node. The price is padding: every node pays for the widest one.

use std::collections::{BTreeMap, BTreeSet};

use super::patch::{row_size_class, LayoutArray, LayoutPatch, StateMove};
use super::{MemoryStats, NodeOrder, Slot};
use crate::engine::Integrator;
use crate::error::{Error, Result};
use crate::model::{ModelDiff, PackedModel};

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
            .map(|&old| inv_mass_of(model, old))
            .collect();
        NodeArrays { inv_mass }
    }
}

/// Inverse mass of model node `node` as the layouts store it: 0 for fixed nodes and for
/// [`NodeOrder::HOLE`] (an unused layout index).
pub(crate) fn inv_mass_of(model: &PackedModel, node: u32) -> f32 {
    if node == NodeOrder::HOLE || model.fixed[node as usize] {
        0.0
    } else {
        (1.0 / model.mass[node as usize]) as f32
    }
}

/// The neighbours (model indices) of every node `diff` touches, in the model after the diff:
/// `current(node)` gives a node's neighbours before it (empty for added nodes).
pub(crate) fn touched_neighbours(
    diff: &ModelDiff,
    nodes_before: usize,
    mut current: impl FnMut(u32) -> Vec<u32>,
) -> BTreeMap<u32, Vec<u32>> {
    let mut removed: BTreeMap<u32, BTreeSet<u32>> = BTreeMap::new();
    for &[a, b] in &diff.removed_springs {
        removed.entry(a).or_default().insert(b);
        removed.entry(b).or_default().insert(a);
    }
    let mut added: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
    for s in &diff.added_springs {
        let [a, b] = s.nodes;
        added.entry(a).or_default().push(b);
        added.entry(b).or_default().push(a);
    }
    diff.touched_nodes(nodes_before)
        .into_iter()
        .map(|t| {
            let mut list = if (t as usize) < nodes_before {
                current(t)
            } else {
                Vec::new()
            };
            if let Some(r) = removed.get(&t) {
                list.retain(|x| !r.contains(x));
            }
            if let Some(a) = added.get(&t) {
                list.extend(a);
            }
            (t, list)
        })
        .collect()
}

/// The slots of model node `node` with neighbours `neighbours` (model indices), pointing at
/// their layout indices `rank`, sorted by layout index as every packing sorts them.
pub(crate) fn row_slots(
    model: &PackedModel,
    node: u32,
    neighbours: &[u32],
    rank: &[u32],
) -> Result<Vec<Slot>> {
    let mut row = neighbours
        .iter()
        .map(|&nb| {
            let s = model.spring_index(node, nb).ok_or_else(|| {
                Error::Model(format!(
                    "the layout joins nodes {node} and {nb} but the model has no such spring; \
                     the diff does not match the model it was applied to"
                ))
            })?;
            Ok(Slot::of(model, &model.springs[s], node, rank[nb as usize]))
        })
        .collect::<Result<Vec<Slot>>>()?;
    row.sort_by_key(|s| s.other);
    Ok(row)
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
    /// Pack `model` in node order `order`, with `capacity` slots per node (default: the next
    /// multiple of 4 above the largest valence, so that every row has a free slot: a cut that
    /// splits a node gives the nodes on its crack front one more neighbour, and without room
    /// the first cut would repack the whole layout). A capacity below some node's valence is an
    /// error naming that node.
    pub fn new(model: &PackedModel, order: NodeOrder, capacity: Option<u32>) -> Result<Self> {
        let n = model.node_count();
        let mut valence = vec![0u32; n];
        for s in &model.springs {
            valence[s.nodes[0] as usize] += 1;
            valence[s.nodes[1] as usize] += 1;
        }
        let widest = valence.iter().copied().max().unwrap_or(0);
        let k = capacity.unwrap_or_else(|| row_size_class(widest));
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

impl ConnectivityLayout {
    /// Apply `diff` (already applied to `model`, the model after the change): added nodes get
    /// the next layout indices and `capacity` empty slots each, the rows of touched nodes are
    /// rewritten. Only when a row outgrows `capacity` is the table repacked, with the capacity
    /// grown to the next size class ([`row_size_class`]). The result equals
    /// `ConnectivityLayout::new(model, self.order.clone(), Some(self.capacity))`.
    pub fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<LayoutPatch> {
        let before = self.node_count();
        super::patch::check_model(before, diff, model)?;
        let k = self.capacity as usize;
        let mut patch = LayoutPatch::default();
        for (i, a) in diff.added_nodes.iter().enumerate() {
            let node = (before + i) as u32;
            self.order.order.push(node);
            self.order.rank.push(node);
            self.slots.extend(std::iter::repeat_n(Slot::empty(), k));
            self.nodes.inv_mass.push(0.0);
            patch.moves.push(StateMove {
                to: node,
                from: a.state_from.map(|s| self.order.rank[s as usize]),
            });
        }
        let (order, slots) = (&self.order, &self.slots);
        let lists = touched_neighbours(diff, before, |t| {
            let row = order.rank[t as usize] as usize;
            slots[row * k..(row + 1) * k]
                .iter()
                .take_while(|s| s.other != Slot::EMPTY)
                .map(|s| order.order[s.other as usize])
                .collect()
        });
        for &t in lists.keys() {
            let row = self.order.rank[t as usize] as usize;
            self.nodes.inv_mass[row] = inv_mass_of(model, t);
        }
        let widest = lists.values().map(|l| l.len() as u32).max().unwrap_or(0);
        if widest > self.capacity {
            let grown = row_size_class(widest);
            *self = ConnectivityLayout::new(model, self.order.clone(), Some(grown))?;
            patch.repacked = true;
            patch.mark_all(LayoutArray::Slots, self.slots.len() as u64 * 32);
            patch.mark_all(LayoutArray::InvMass, self.nodes.inv_mass.len() as u64 * 4);
            patch.rest_fixed(model, diff, &self.order.rank);
            patch.normalize();
            return Ok(patch);
        }
        for (&t, list) in &lists {
            let row = self.order.rank[t as usize] as usize;
            let new = row_slots(model, t, list, &self.order.rank)?;
            let dst = &mut self.slots[row * k..(row + 1) * k];
            dst.fill(Slot::empty());
            dst[..new.len()].copy_from_slice(&new);
        }
        let rows: Vec<u32> = lists.keys().map(|&t| self.order.rank[t as usize]).collect();
        patch.mark(LayoutArray::Slots, rows.iter().copied(), k as u64, 32);
        patch.mark(LayoutArray::InvMass, rows, 1, 4);
        patch.rest_fixed(model, diff, &self.order.rank);
        patch.normalize();
        Ok(patch)
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

//! The tets of a corotational model as the GPU's per-tet pass reads them, in whatever node
//! layout the springs use: the tets are not in the spring layouts, so one table serves the
//! connectivity, valence and edge layouts alike, its corners numbered in the layout's node
//! order. Beside it, each node's list of the (tet, corner) force records it sums, so that the
//! node pass gathers a fixed set in a fixed order (deterministic, no atomics).
//!
//! Per tet, three rows of four floats: the shape-function gradients `b_1, b_2, b_3` of corners
//! 1..3 at rest (corner 0's is minus their sum), with `V lambda`, `2 V mu` and Rayleigh's
//! `beta` in the fourth lanes. The element force of corner `a` is then `-R (V sigma) b_a`,
//! `sigma = 2 mu eps + lambda tr(eps) I` of the rotated strain `eps = sym(R^T F) - I`: the same
//! force as `-R K_e (R^T x - X)` with `K_e` the linear tet's stiffness
//! ([`crate::physics::linear_tet`]), without storing its 144 entries. The pass and its twin are
//! `shaders/corotational_tets.wgsl` and [`crate::twin::corotational`].

use super::patch::rewrite_row;
use crate::model::corner_set;
use crate::physics::TetElement;

/// One row of a tet's shape: three lanes of a gradient and one constant.
pub type ShapeRow = [f32; 4];

/// The identity rotation as a quaternion `(x, y, z, w)`.
pub const IDENTITY: [f32; 4] = [0.0, 0.0, 0.0, 1.0];

/// The tets of a corotational model in a layout's node order, with each node's force records.
#[derive(Debug, Clone, PartialEq)]
pub struct TetTable {
    /// Each tet's corners, layout indices, in the model's tet order.
    pub corners: Vec<[u32; 4]>,
    /// Each tet's three shape rows (see the module documentation).
    pub shape: Vec<[ShapeRow; 3]>,
    /// Each layout node's records, `[start, end)` in `incidence`.
    pub rows: Vec<[u32; 2]>,
    /// Per node, its records `4 tet + corner`, tets ascending.
    pub incidence: Vec<u32>,
    /// Whether any tet has Rayleigh damping (the pass then reads velocities).
    pub damped: bool,
}

impl TetTable {
    /// The table of `elements` (model node indices), corners renumbered by `rank` (model index
    /// to layout index), over `node_slots` layout nodes.
    pub fn new(elements: &[TetElement], rank: &[u32], node_slots: usize) -> Self {
        let corners: Vec<[u32; 4]> = elements
            .iter()
            .map(|e| e.nodes.map(|n| rank[n as usize]))
            .collect();
        let shape = elements.iter().map(shape_of).collect();
        let mut count = vec![0u32; node_slots];
        for c in &corners {
            for &i in c {
                count[i as usize] += 1;
            }
        }
        let mut rows = Vec::with_capacity(node_slots);
        let mut start = 0u32;
        for &n in &count {
            rows.push([start, start]);
            start += n;
        }
        let mut incidence = vec![0u32; start as usize];
        for (t, c) in corners.iter().enumerate() {
            for (a, &i) in c.iter().enumerate() {
                let row = &mut rows[i as usize];
                incidence[row[1] as usize] = 4 * t as u32 + a as u32;
                row[1] += 1;
            }
        }
        TetTable {
            corners,
            shape,
            rows,
            incidence,
            damped: elements.iter().any(|e| e.beta != 0.0),
        }
    }

    /// Tets in the table.
    pub fn len(&self) -> usize {
        self.corners.len()
    }

    /// Whether the table holds no tet.
    pub fn is_empty(&self) -> bool {
        self.corners.is_empty()
    }

    /// Bytes of the table's arrays as uploaded (corners, shape, rows, incidence).
    pub fn bytes(&self) -> u64 {
        (self.corners.len() * 16
            + self.shape.len() * 48
            + self.rows.len() * 8
            + self.incidence.len() * 4) as u64
    }
}

/// Element `e`'s three shape rows (see the module documentation).
fn shape_of(e: &TetElement) -> [ShapeRow; 3] {
    let (lambda, mu) = e.lame;
    let g = |a: usize, w: f64| -> ShapeRow {
        let b = e.gradients[a];
        [b[0] as f32, b[1] as f32, b[2] as f32, w as f32]
    };
    [
        g(1, e.volume * lambda),
        g(2, 2.0 * e.volume * mu),
        g(3, e.beta),
    ]
}

/// What [`TetTable::patch`] changed, for the device copy to follow: nothing else differs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TablePatch {
    /// Rotations to carry over: `(from, to)`, the tet at `from` before the patch now at `to`
    /// (the last tets moved into removed ones' places, as the model moves its tets).
    pub moved: Vec<(u32, u32)>,
    /// Tets whose records (corners and shape) were written, ascending.
    pub tets: Vec<u32>,
    /// Tets at and past this index are new: their rotations start from the identity.
    pub first_new: u32,
    /// Layout nodes whose row (`rows`) was written, ascending.
    pub nodes: Vec<u32>,
    /// Ranges of `incidence` written, ascending.
    pub incidence: Vec<std::ops::Range<u32>>,
}

impl TetTable {
    /// Follow a patch of the model's tets: `removed` (corner sets, model indices) go as the
    /// model removes them (the last tet into each one's place; `at` finds a tet by its corner
    /// set and `keys` lists them in table order, both kept up to date), then the elements of
    /// `elements` past the tets that stay are appended (the model's added tets), their corners
    /// numbered by `rank`, over `node_slots` layout nodes. Old nodes the layout moved (`moved`:
    /// `(before, after)` layout indices, as a valence patch moves a node whose valence changed)
    /// take their record lists to their new index, and the tets holding them get their
    /// corners renumbered. Only the touched nodes' record lists are rewritten (in place where
    /// they do not grow, else at the end of `incidence`), each in ascending order as a rebuild
    /// lists it. `None` if a removed tet is not in the table.
    #[allow(clippy::too_many_arguments)]
    pub fn patch(
        &mut self,
        removed: &[[u32; 4]],
        elements: &[TetElement],
        keys: &mut Vec<[u32; 4]>,
        at: &mut rustc_hash::FxHashMap<[u32; 4], usize>,
        rank: &[u32],
        moved_nodes: &[(u32, u32)],
        node_slots: usize,
    ) -> Option<TablePatch> {
        use std::collections::BTreeMap;
        let mut lists: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
        // Node `n`'s records as the patch has left them so far.
        fn list<'a>(
            lists: &'a mut BTreeMap<u32, Vec<u32>>,
            rows: &[[u32; 2]],
            incidence: &[u32],
            n: u32,
        ) -> &'a mut Vec<u32> {
            lists
                .entry(n)
                .or_insert_with(|| match rows.get(n as usize) {
                    Some(&[s, e]) => incidence[s as usize..e as usize].to_vec(),
                    None => Vec::new(),
                })
        }
        // Where each tet now in a place came from (its index before the patch).
        let mut origin: rustc_hash::FxHashMap<u32, u32> = Default::default();
        let mut written = Vec::new();
        // Moved nodes first: their lists go to their new index (whose list before, if any,
        // left with a node moved from there or stays empty), and the corners that name them
        // follow, so that the removals below find every node where it is now.
        let carried: Vec<(u32, Vec<u32>)> = moved_nodes
            .iter()
            .map(|&(from, to)| {
                let list = list(&mut lists, &self.rows, &self.incidence, from).clone();
                (to, list)
            })
            .collect();
        for &(from, _) in moved_nodes {
            lists.insert(from, Vec::new());
        }
        let renumber: rustc_hash::FxHashMap<u32, u32> = moved_nodes.iter().copied().collect();
        for (to, list) in carried {
            for &r in &list {
                let (t, a) = ((r / 4) as usize, (r % 4) as usize);
                if let Some(&n) = renumber.get(&self.corners[t][a]) {
                    self.corners[t][a] = n;
                    written.push(t as u32);
                }
            }
            lists.insert(to, list);
        }
        for &t in removed {
            let i = at.remove(&corner_set(t))?;
            let last = self.corners.len() - 1;
            for (a, &n) in self.corners[i].iter().enumerate() {
                let record = (4 * i + a) as u32;
                list(&mut lists, &self.rows, &self.incidence, n).retain(|&r| r != record);
            }
            if i != last {
                for (a, &n) in self.corners[last].iter().enumerate() {
                    let (from, to) = ((4 * last + a) as u32, (4 * i + a) as u32);
                    for r in list(&mut lists, &self.rows, &self.incidence, n).iter_mut() {
                        if *r == from {
                            *r = to;
                        }
                    }
                }
                let source = origin.remove(&(last as u32)).unwrap_or(last as u32);
                origin.insert(i as u32, source);
                written.push(i as u32);
            } else {
                origin.remove(&(last as u32));
            }
            self.corners.swap_remove(i);
            self.shape.swap_remove(i);
            keys.swap_remove(i);
            if let Some(&moved) = keys.get(i) {
                at.insert(moved, i);
            }
        }
        let first_new = self.corners.len();
        for (t, e) in elements.iter().enumerate().skip(first_new) {
            let corners = e.nodes.map(|n| rank[n as usize]);
            for (a, &n) in corners.iter().enumerate() {
                list(&mut lists, &self.rows, &self.incidence, n).push((4 * t + a) as u32);
            }
            self.corners.push(corners);
            self.shape.push(shape_of(e));
            keys.push(corner_set(e.nodes));
            at.insert(corner_set(e.nodes), t);
            written.push(t as u32);
        }
        self.damped = elements.iter().any(|e| e.beta != 0.0);
        if self.rows.len() < node_slots {
            // The layout's new node slots (a valence bucket's room among them) get rows too,
            // written like any other: the device's buffer holds nothing there yet.
            let (old, end) = (self.rows.len(), self.incidence.len() as u32);
            self.rows.resize(node_slots, [end, end]);
            for n in old..node_slots {
                lists.entry(n as u32).or_default();
            }
        }
        let mut patch = TablePatch {
            first_new: first_new as u32,
            ..TablePatch::default()
        };
        for (n, mut l) in lists {
            l.sort_unstable();
            let written = rewrite_row(&mut self.rows[n as usize], &mut self.incidence, &l);
            patch.nodes.push(n);
            if !written.is_empty() {
                patch.incidence.push(written);
            }
        }
        patch.incidence.sort_unstable_by_key(|r| r.start);
        // A place written and then removed again (the last place) holds no tet any more.
        written.retain(|&t| (t as usize) < self.corners.len());
        written.sort_unstable();
        written.dedup();
        patch.tets = written;
        let mut moved: Vec<(u32, u32)> = origin
            .into_iter()
            .filter(|&(to, from)| to != from && to < first_new as u32)
            .map(|(to, from)| (from, to))
            .collect();
        moved.sort_unstable();
        patch.moved = moved;
        Some(patch)
    }

    /// Records `incidence` holds that no row points to (left by rows that grew and moved).
    pub fn holes(&self) -> usize {
        self.incidence.len()
            - self
                .rows
                .iter()
                .map(|r| (r[1] - r[0]) as usize)
                .sum::<usize>()
    }

    /// How this table differs from `other` in what the passes read: the tets' corners and
    /// shapes, and each node's records in order (not where in `incidence` they lie).
    pub fn differs_from(&self, other: &TetTable) -> bool {
        fn list(t: &TetTable, n: usize) -> &[u32] {
            let [s, e] = t.rows[n];
            &t.incidence[s as usize..e as usize]
        }
        self.corners != other.corners
            || self.shape != other.shape
            || self.damped != other.damped
            || self.rows.len() != other.rows.len()
            || (0..self.rows.len()).any(|n| list(self, n) != list(other, n))
    }
}

/// Each tet's corners as a set, in table order (to follow a patch's removals).
pub fn corner_sets(elements: &[TetElement]) -> Vec<[u32; 4]> {
    elements.iter().map(|e| corner_set(e.nodes)).collect()
}

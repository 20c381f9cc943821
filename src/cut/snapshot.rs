//! Turning a topology edit into a [`ModelDiff`]: the springs and nodes an edit can touch are
//! recorded before it, compared with what the spring model holds after it, and only the
//! differences are put in the diff (the layouts turn it into dirty byte ranges).

use rustc_hash::FxHashMap;
use slotmap::SecondaryMap;

use crate::mesh::{NodeKey, TetMesh};
use crate::model::{AddedNode, ModelDiff, NodeChange, PackedSpring, SpringModel, StateBlend};

/// Where a node an edit makes starts its state: with a node's state (a copy of it), or with
/// the state at parameter `t` along the edge between two nodes (a node put on that edge), so
/// that nothing jumps when the cut is applied. The nodes existed before the edit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StateSource {
    /// The state of this node.
    Node(NodeKey),
    /// `(1 - t)` times the first node's state plus `t` times the second's.
    Between(NodeKey, NodeKey, f64),
}

/// Rest length, stiffness, damping of a spring.
type SpringParams = (f64, f64, f64);

/// The state of some springs and nodes before an edit. Hashed: the diff sorts what it finds,
/// so the order of these maps never shows.
#[derive(Debug, Default)]
pub struct Snapshot {
    springs: FxHashMap<[NodeKey; 2], Option<SpringParams>>,
    nodes: FxHashMap<NodeKey, (Option<f64>, bool)>,
}

fn edge(a: NodeKey, b: NodeKey) -> [NodeKey; 2] {
    if a < b {
        [a, b]
    } else {
        [b, a]
    }
}

fn params(model: &SpringModel, e: &[NodeKey; 2]) -> Option<SpringParams> {
    model
        .spring_between(e[0], e[1])
        .map(|s| (s.rest_length, s.stiffness, s.damping))
}

impl Snapshot {
    /// Record the edges and corners of the given tets (their current nodes) before an edit.
    pub fn take(model: &SpringModel, tets: &[[NodeKey; 4]]) -> Self {
        // Sized for the tets' edges and corners (each shared by a few tets), so that filling
        // the maps does not rehash them as they grow.
        let mut snap = Snapshot {
            springs: FxHashMap::with_capacity_and_hasher(tets.len() * 2 + 8, Default::default()),
            nodes: FxHashMap::with_capacity_and_hasher(tets.len() + 8, Default::default()),
        };
        snap.extend(model, tets, &|_| true);
        snap
    }

    /// Record more tets, keeping what is already recorded (the first record of a spring or
    /// node is its state before the whole edit).
    /// Springs or nodes involving a node that did not exist before the edit (`existed` false)
    /// are left out: they are new, and the diff adds them.
    pub fn extend(
        &mut self,
        model: &SpringModel,
        tets: &[[NodeKey; 4]],
        existed: &dyn Fn(NodeKey) -> bool,
    ) {
        for t in tets {
            for [a, b] in crate::mesh::TET_EDGES {
                let e = edge(t[a], t[b]);
                if existed(e[0]) && existed(e[1]) {
                    // Looked up in the model only the first time the edge is seen.
                    self.springs.entry(e).or_insert_with(|| params(model, &e));
                }
            }
            for &n in t.iter().filter(|&&n| existed(n)) {
                self.nodes
                    .entry(n)
                    .or_insert_with(|| (model.mass(n), model.is_fixed(n)));
            }
        }
    }

    /// The diff from the recorded state to `model` now. `after` are the touched tets' nodes
    /// after the edit (their new edges are compared too); `added` are the nodes the edit
    /// created, in creation order, with where each starts its state;
    /// `dense` numbers every node, added ones included. A node left without tets keeps its
    /// mass in the packed model and becomes fixed, so that dense indices never change.
    pub fn diff(
        self,
        mesh: &TetMesh,
        model: &SpringModel,
        after: &[[NodeKey; 4]],
        added: &[(NodeKey, StateSource)],
        dense: &SecondaryMap<NodeKey, u32>,
    ) -> ModelDiff {
        let mut springs = self.springs;
        for t in after {
            for [a, b] in crate::mesh::TET_EDGES {
                springs.entry(edge(t[a], t[b])).or_insert(None);
            }
        }
        let mut diff = ModelDiff::default();
        let packed = |e: &[NodeKey; 2], p: SpringParams| {
            let (a, b) = (dense[e[0]], dense[e[1]]);
            PackedSpring {
                nodes: [a.min(b), a.max(b)],
                rest_length: p.0,
                stiffness: p.1,
                damping: p.2,
            }
        };
        for (e, before) in &springs {
            match (before, params(model, e)) {
                (Some(_), None) => {
                    let (a, b) = (dense[e[0]], dense[e[1]]);
                    diff.removed_springs.push([a.min(b), a.max(b)]);
                }
                (None, Some(p)) => diff.added_springs.push(packed(e, p)),
                (Some(p0), Some(p1)) if *p0 != p1 => diff.changed_springs.push(packed(e, p1)),
                _ => {}
            }
        }
        for &(n, source) in added {
            let p = mesh.rest(n);
            let (from, blend) = match source {
                StateSource::Node(a) => (a, None),
                StateSource::Between(a, b, t) => (a, Some(StateBlend { with: dense[b], t })),
            };
            diff.added_nodes.push(AddedNode {
                key: n,
                rest: [p.x, p.y, p.z],
                mass: model.mass(n).unwrap_or(0.0),
                fixed: model.is_fixed(n),
                state_from: Some(dense[from]),
                blend,
            });
        }
        for (n, (mass0, fixed0)) in &self.nodes {
            let (mass1, fixed1) = (model.mass(*n), model.is_fixed(*n));
            match (mass0, mass1) {
                (Some(m0), None) => diff.changed_nodes.push(NodeChange {
                    node: dense[*n],
                    mass: *m0,
                    fixed: true,
                }),
                (Some(m0), Some(m1)) if *m0 != m1 || *fixed0 != fixed1 => {
                    diff.changed_nodes.push(NodeChange {
                        node: dense[*n],
                        mass: m1,
                        fixed: fixed1,
                    })
                }
                _ => {}
            }
        }
        diff.removed_springs.sort_unstable();
        diff.added_springs.sort_by_key(|s| s.nodes);
        diff.changed_springs.sort_by_key(|s| s.nodes);
        diff.changed_nodes.sort_by_key(|c| c.node);
        diff
    }
}

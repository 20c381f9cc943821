//! Turning a topology edit into a [`ModelDiff`]: the spring model notes each spring and node
//! as it was before the edit first changed it ([`SpringModel::record_changes`]); those are
//! compared with what the model holds after the edit, and only the differences are put in the
//! diff (the layouts turn it into dirty byte ranges).

use slotmap::SecondaryMap;

use crate::mesh::{NodeKey, TetMesh};
use crate::model::{
    AddedNode, ModelDiff, ModelJournal, NodeChange, PackedSpring, PackedTet, SpringModel,
    SpringParams, StateBlend,
};

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

/// The diff of an edit: from what the model's journal noted (each changed spring and node as
/// it was, [`SpringModel::record_changes`]) to `model` now. `added` are the nodes the edit
/// created, in creation order, with where each starts its state; `dense` numbers every node,
/// added ones included. A node left without tets keeps its mass in the packed model and
/// becomes fixed, so that dense indices never change.
pub fn diff_of(
    changes: ModelJournal,
    mesh: &TetMesh,
    model: &SpringModel,
    added: &[(NodeKey, StateSource)],
    dense: &SecondaryMap<NodeKey, u32>,
) -> ModelDiff {
    let params = |e: &[NodeKey; 2]| {
        model
            .spring_between(e[0], e[1])
            .map(|s| (s.rest_length, s.stiffness, s.damping))
    };
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
    for (e, before) in &changes.springs {
        match (before, params(e)) {
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
    for (n, (mass0, fixed0)) in &changes.nodes {
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
    for (tk, before) in &changes.tets {
        let after = mesh.tet(*tk);
        if before.as_ref() == after.map(|t| &t.nodes) {
            continue;
        }
        if let Some(b) = before {
            diff.removed_tets.push(b.map(|k| dense[k]));
        }
        if let Some(t) = after {
            diff.added_tets.push(PackedTet {
                nodes: t.nodes.map(|k| dense[k]),
                region: t.region,
                material: *model.config().material_of(t.region),
            });
        }
    }
    diff.removed_tets.sort_unstable();
    diff.added_tets.sort_by_key(|t| t.nodes);
    diff.removed_springs.sort_unstable();
    diff.added_springs.sort_by_key(|s| s.nodes);
    diff.changed_springs.sort_by_key(|s| s.nodes);
    diff.changed_nodes.sort_by_key(|c| c.node);
    diff
}

//! The topology edits of a cut, on the mesh, the spring model and the face index together.

use std::collections::BTreeMap;

use petgraph::unionfind::UnionFind;

use super::changes::{diff_of, StateSource};
use super::{CutOutcome, Cutter};
use crate::error::Result;
use crate::mesh::{NodeKey, TetKey};

impl Cutter {
    /// Carving: delete `tets` (sorted). Nodes left without a tet are retired (fixed, no
    /// springs); crack pairs involving a deleted tet are dropped.
    pub(super) fn remove(&mut self, tets: &[TetKey], outcome: &mut CutOutcome) -> Result<()> {
        let before: Vec<[NodeKey; 4]> = tets
            .iter()
            .map(|&t| self.mesh.tet(t).expect("a tet").nodes)
            .collect();
        self.model.record_changes();
        for &tk in tets {
            outcome.volume_removed += self.mesh.tet_volume(tk);
            self.mass_removed += self.model.share(tk).map_or(0.0, |s| s.mass.iter().sum());
            self.faces.remove(tk);
            self.model.remove_tet(&self.mesh, tk)?;
            self.mesh.remove_tet(tk);
            self.forget_tet(tk);
        }
        self.volume_removed += outcome.volume_removed;
        self.crack
            .retain(|(a, b)| self.mesh.tet(*a).is_some() && self.mesh.tet(*b).is_some());
        let mut retired: Vec<NodeKey> = before.iter().flatten().copied().collect();
        retired.sort();
        retired.dedup();
        outcome.nodes_retired = retired
            .iter()
            .filter(|&&n| self.faces.tets_at(n).is_empty())
            .count();
        outcome.tets_touched = tets.len();
        outcome.tets_removed = tets.len();
        let changes = self.model.take_changes();
        outcome.diff = diff_of(changes, &self.mesh, &self.model, &[], &self.dense);
        Ok(())
    }

    /// Splitting along faces: the pairs in `crossed` (sorted, face neighbours, not yet on the
    /// crack) join the crack; every node of their shared faces is then split into one copy per
    /// group of its tets still joined across faces that are not cut. The group holding the
    /// smallest tet key keeps the original node. Pairs whose face opened leave the crack.
    pub(super) fn separate(
        &mut self,
        crossed: &[(TetKey, TetKey)],
        outcome: &mut CutOutcome,
    ) -> Result<()> {
        outcome.faces_cut = crossed.len();
        let plan = self.plan_split(crossed);
        if plan.copies.is_empty() {
            return Ok(());
        }
        self.model.record_changes();
        let added = self.apply_split(&plan, &StateSource::Node)?;
        outcome.tets_touched = plan.replace.len();
        outcome.nodes_added = added.len();
        let changes = self.model.take_changes();
        outcome.diff = diff_of(changes, &self.mesh, &self.model, &added, &self.dense);
        Ok(())
    }

    /// Put `crossed` on the crack and find, for every node of their shared faces, the groups of
    /// its tets still joined across uncut faces (on the topology before any split, so the order
    /// in which nodes are visited does not matter).
    pub(super) fn plan_split(&mut self, crossed: &[(TetKey, TetKey)]) -> SplitPlan {
        let mut nodes: Vec<NodeKey> = Vec::new();
        for &(a, b) in crossed {
            self.crack.insert((a, b));
            let (ta, tb) = (
                self.mesh.tet(a).expect("a tet"),
                self.mesh.tet(b).expect("a tet"),
            );
            nodes.extend(ta.nodes.iter().filter(|n| tb.nodes.contains(n)));
        }
        nodes.sort();
        nodes.dedup();
        let mut plan = SplitPlan::default();
        for &n in &nodes {
            let around = self.faces.tets_at(n);
            let slot = |t: TetKey| around.binary_search(&t).ok();
            let mut uf = UnionFind::<usize>::new(around.len());
            for (i, &t) in around.iter().enumerate() {
                let tet = self.mesh.tet(t).expect("a tet");
                let at = tet
                    .nodes
                    .iter()
                    .position(|&k| k == n)
                    .expect("n is a corner");
                for local in (0..4).filter(|&l| l != at) {
                    let Some(other) = self.faces.neighbour(t, tet, local) else {
                        continue;
                    };
                    let pair = if t < other { (t, other) } else { (other, t) };
                    if self.crack.contains(&pair) {
                        continue;
                    }
                    if let Some(j) = slot(other) {
                        uf.union(i, j);
                    }
                }
            }
            // Groups in order of their smallest tet (`around` is sorted).
            let mut label: BTreeMap<usize, usize> = BTreeMap::new();
            for (i, &t) in around.iter().enumerate() {
                let root = uf.find(i);
                let next = label.len();
                let g = *label.entry(root).or_insert(next);
                if g > 0 {
                    plan.replace
                        .entry(t)
                        .or_default()
                        .push((n, plan.copies.len() + g - 1));
                }
            }
            for _ in 1..label.len() {
                plan.copies.push(n);
            }
        }
        plan
    }

    /// Make the copies of `plan` and give the tets their new corners (mesh, model and face
    /// index). Returns the copies with the node whose state each starts from
    /// (`state_source` of the node it copies: the node itself for an old one) and the touched tets'
    /// new corners. Pairs whose face opened leave the crack.
    pub(super) fn apply_split(
        &mut self,
        plan: &SplitPlan,
        state_source: &dyn Fn(NodeKey) -> StateSource,
    ) -> Result<Copies> {
        let mut added = Vec::with_capacity(plan.copies.len());
        let mut new_keys = Vec::with_capacity(plan.copies.len());
        for &n in &plan.copies {
            let k = self.add_node(self.mesh.rest(n));
            if self.on_cut.contains(&n) {
                self.on_cut.insert(k);
            }
            added.push((k, state_source(n)));
            new_keys.push(k);
        }
        let before: Vec<[NodeKey; 4]> = plan
            .replace
            .keys()
            .map(|&t| self.mesh.tet(t).expect("a tet").nodes)
            .collect();
        for &t in plan.replace.keys() {
            self.faces.remove(t);
        }
        for ((&t, subs), old) in plan.replace.iter().zip(&before) {
            let mut new = *old;
            for &(n, c) in subs {
                for k in new.iter_mut().filter(|k| **k == n) {
                    *k = new_keys[c];
                }
            }
            self.mesh.set_tet_nodes(t, new)?;
            self.note_tet(t);
            self.model.renode_tet(t, *old, new)?;
        }
        for &t in plan.replace.keys() {
            let tet = *self.mesh.tet(t).expect("a tet");
            self.faces.insert(t, &tet, &self.mesh)?;
        }
        // A pair leaves the crack once its tets no longer share a face.
        let faces = &self.faces;
        let mesh = &self.mesh;
        self.crack.retain(|&(a, b)| {
            let ta = mesh.tet(a).expect("a tet");
            (0..4).any(|l| faces.neighbour(a, ta, l) == Some(b))
        });
        Ok(added)
    }
}

/// Nodes made by a split, each with where it starts its state.
pub(super) type Copies = Vec<(NodeKey, StateSource)>;

/// Which tets get which copies: `replace[t]` lists (node, copy number) pairs, `copies[c]` is
/// the node copy `c` duplicates.
#[derive(Debug, Default)]
pub(super) struct SplitPlan {
    pub replace: BTreeMap<TetKey, Vec<(NodeKey, usize)>>,
    pub copies: Vec<NodeKey>,
}

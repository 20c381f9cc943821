//! Re-making the sub-tets of the parents a cut marks: which families are re-made from their
//! template and which end, and the edit of the mesh, the model and the face index (see
//! `subdivide.rs` and `template.rs`).

use std::collections::{BTreeMap, BTreeSet};

use super::subdivide::edge_key;
use super::template::{self, FamilyKey};
use super::Cutter;
use crate::error::Result;
use crate::mesh::{NodeKey, TetKey, TET_EDGES};

impl Cutter {
    /// The parents whose subdivision splitting `edges` changes: for each tet around a split
    /// edge, its family (re-made from the template with the new marks), else the tet itself.
    ///
    /// A family is re-made only where every tet around the edge is in a family that has it as
    /// a parent edge and whose parent no cut had split, or is a tet no cut has split: a sub-tet
    /// of an ended family (or a family made from one) triangulates its part of a parent face as
    /// it was, and re-making a neighbouring family in the template's order could triangulate that
    /// face another way. Elsewhere every family around the edge
    /// ends ([`Parents::ended`]) and each tet around it is split as a parent of its own, alike on
    /// both sides of every face, until no edge is left with a mix.
    pub(super) fn parents_of(&self, edges: impl Iterator<Item = [NodeKey; 2]> + Clone) -> Parents {
        let mut parents = Parents::default();
        let around: Vec<([NodeKey; 2], Vec<TetKey>)> = edges
            .clone()
            .map(|[a, b]| ([a, b], self.tets_with_edge(a, b)))
            .collect();
        loop {
            let ended = parents.ended.len();
            for ([a, b], tets) in &around {
                let remade = |t: &TetKey| match self.families.of(*t) {
                    Some((f, family)) => {
                        family.whole
                            && !parents.ended.contains(&f)
                            && family.corners.contains(a)
                            && family.corners.contains(b)
                    }
                    None => !self.families.is_loose(*t),
                };
                if !tets.iter().all(remade) {
                    for &t in tets {
                        if let Some((f, _)) = self.families.of(t) {
                            parents.ended.insert(f);
                        }
                    }
                }
            }
            if parents.ended.len() == ended {
                break;
            }
        }
        for [a, b] in edges {
            for t in self.tets_with_edge(a, b) {
                match self.families.of(t) {
                    Some((f, family)) if !parents.ended.contains(&f) => {
                        parents
                            .list
                            .entry(Parent::Family(f))
                            .or_insert_with(|| ParentPlan {
                                corners: family.corners,
                                region: family.region,
                                marks: family.marks.clone(),
                                children: family.children.clone(),
                            });
                    }
                    _ => {
                        let tet = self.mesh.tet(t).expect("a tet");
                        parents.list.entry(Parent::Tet(t)).or_insert(ParentPlan {
                            corners: tet.nodes,
                            region: tet.region,
                            marks: Vec::new(),
                            children: vec![t],
                        });
                    }
                }
            }
        }
        parents
    }

    /// Mark the new nodes `made` (per split edge) on `parents` and replace each parent's
    /// sub-tets with its template's (mesh, model and face index; a sub-tet the template keeps
    /// is left alone). Returns every sub-tet of those parents.
    pub(super) fn subdivide_parents(
        &mut self,
        parents: Parents,
        made: &BTreeMap<[NodeKey; 2], NodeKey>,
    ) -> Result<BTreeSet<TetKey>> {
        for &f in &parents.ended {
            self.families.end(f);
        }
        let mut work: Vec<(FamilyKey, Vec<TetKey>)> = Vec::with_capacity(parents.list.len());
        for (parent, plan) in parents.list {
            let f = match parent {
                Parent::Family(f) => f,
                Parent::Tet(t) => self.families.adopt(t, plan.corners, plan.region),
            };
            for (e, [i, j]) in TET_EDGES.iter().enumerate() {
                if let Some(&k) = made.get(&edge_key(plan.corners[*i], plan.corners[*j])) {
                    self.families.mark(f, e, k);
                }
            }
            work.push((f, plan.children));
        }
        // Each family's new sub-tets; those it already has (same corners) stay as they are.
        let sorted = |mut n: [NodeKey; 4]| {
            n.sort_unstable();
            n
        };
        let mut plans: Vec<Resubdivision> = Vec::with_capacity(work.len());
        for (f, old) in work {
            let family = self.families.get(f);
            let rest = family.corners.map(|n| self.mesh.rest(n));
            let tets =
                template::subdivide(family.corners, &family.marks, &template::edge_order(&rest));
            let had: Vec<[NodeKey; 4]> = old
                .iter()
                .map(|&t| sorted(self.mesh.tet(t).expect("a sub-tet").nodes))
                .collect();
            let wanted: Vec<[NodeKey; 4]> = tets.iter().map(|&n| sorted(n)).collect();
            let (mut kept, mut gone) = (Vec::new(), Vec::new());
            for (&t, h) in old.iter().zip(&had) {
                if wanted.contains(h) {
                    kept.push(t);
                } else {
                    gone.push(t);
                }
            }
            let fresh: Vec<[NodeKey; 4]> = tets
                .into_iter()
                .zip(&wanted)
                .filter(|(_, w)| !had.contains(w))
                .map(|(n, _)| n)
                .collect();
            // All the family's sub-tets carry its parent's mass and `sum k l^2` per volume: the
            // new ones take them, so the gone ones' mass and springs pass to them whatever the
            // region's mass and spring models.
            let density = self.model.split_density(&self.mesh, &old);
            plans.push(Resubdivision {
                family: f,
                kept,
                gone,
                fresh,
                density,
            });
        }
        // Out with every sub-tet that goes first, so that faces between two parents are not
        // matched against a sub-tet about to go.
        for plan in &plans {
            for &t in &plan.gone {
                self.faces.remove(t);
                self.model.remove_tet(&self.mesh, t)?;
            }
        }
        let mut children = BTreeSet::new();
        let mut made = Vec::new();
        for Resubdivision {
            family: f,
            kept,
            gone,
            fresh,
            density,
        } in plans
        {
            let region = self.families.get(f).region;
            // The keys of the sub-tets that go are reused for the new ones.
            let mut keys = kept;
            let count = fresh.len();
            for (i, nodes) in fresh.into_iter().enumerate() {
                let t = match gone.get(i) {
                    Some(&t) => {
                        self.mesh.set_tet_nodes(t, nodes)?;
                        t
                    }
                    None => self.mesh.add_tet(nodes, region)?,
                };
                self.note_tet(t);
                keys.push(t);
                made.push((t, density));
            }
            for &t in gone.iter().skip(count) {
                self.mesh.remove_tet(t);
                self.forget_tet(t);
            }
            children.extend(keys.iter().copied());
            self.families.set_children(f, keys);
        }
        for &(t, density) in &made {
            match density {
                Some(d) => self.model.add_split_tet(&self.mesh, t, d)?,
                None => self.model.add_tet(&self.mesh, t)?,
            }
            let tet = *self.mesh.tet(t).expect("a sub-tet");
            self.faces.insert(t, &tet, &self.mesh)?;
        }
        Ok(children)
    }
}

/// A parent whose subdivision a cut changes: an open family, or a tet in none.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Parent {
    Family(FamilyKey),
    Tet(TetKey),
}

/// A parent's corners, region and marks so far, and its sub-tets now in the mesh.
#[derive(Debug)]
pub(super) struct ParentPlan {
    pub corners: [NodeKey; 4],
    pub region: i32,
    pub marks: Vec<(usize, NodeKey)>,
    pub children: Vec<TetKey>,
}

/// A family's sub-tets before and after a new mark: those the template keeps, those it drops
/// (their keys go to new ones), the new ones' corners, and the family's mass per rest volume
/// (its sub-tets' before the mark), which the new ones take.
struct Resubdivision {
    family: FamilyKey,
    kept: Vec<TetKey>,
    gone: Vec<TetKey>,
    fresh: Vec<[NodeKey; 4]>,
    density: Option<crate::model::SplitDensity>,
}

/// The parents a cut subdivides anew, and the families it ends.
#[derive(Debug, Default)]
pub(super) struct Parents {
    pub list: BTreeMap<Parent, ParentPlan>,
    pub ended: BTreeSet<FamilyKey>,
}

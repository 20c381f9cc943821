//! A change to a packed model: what a cut produces between two steps. Nodes are only ever
//! appended (dense indices of existing nodes never change, so every layout keeps its numbering);
//! springs are removed, added or re-parameterised by their end pair.
//!
//! [`PackedModel::apply`] turns a model into the model after the change; the layouts turn the
//! same diff into dirty byte ranges (`crate::layout`), so the device only receives what changed.
//!
//! Applying a diff costs what the diff holds, not what the model holds: springs are found by
//! end pair through a hash index, a removed spring's place takes the last spring, and added
//! springs are appended. (Kept sorted by end pair, the array moved every spring after the
//! first edit: 65 µs for a cut at the start of a 104,544-tet model's springs, 619 µs at
//! 375,000 tets, at every cut deep in a large mesh.) Every engine and layout orders springs
//! its own way, so none depends on the array's order but for rounding (sums over the springs
//! in their order: the reference engine, the energy bookkeeping).

use std::collections::HashSet;

use rustc_hash::FxHashMap;

use super::tets::corner_set;
use super::{PackedModel, PackedSpring, PackedTet};
use crate::error::{Error, Result};
use crate::mesh::NodeKey;

/// A node appended to the model: it gets the next dense index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AddedNode {
    /// The mesh node behind it (default key where there is no mesh).
    pub key: NodeKey,
    /// Rest position, m.
    pub rest: [f64; 3],
    /// Lumped mass, kg.
    pub mass: f64,
    /// Held at its rest position.
    pub fixed: bool,
    /// An existing node whose current state (displacement and velocity) the new node starts
    /// with: a node split by a cut starts where the original is. `None` starts it at rest.
    pub state_from: Option<u32>,
    /// A second existing node mixed into that state: the new node starts with
    /// `(1 - t) * state_from + t * with`, as a node put on the edge between them at parameter
    /// `t` does (its displacement is then the interpolated one, so nothing jumps). Needs
    /// `state_from`.
    pub blend: Option<StateBlend>,
}

impl AddedNode {
    /// The node's starting value of a quantity that moves with the nodes (displacement,
    /// velocity), given that quantity `of` existing nodes: its source's, mixed with its blend
    /// partner's. `None` without a source: it starts at rest.
    pub fn start_value(&self, of: impl Fn(u32) -> [f64; 3]) -> Option<[f64; 3]> {
        let from = of(self.state_from?);
        Some(match self.blend {
            None => from,
            Some(b) => {
                let with = of(b.with);
                std::array::from_fn(|c| (1.0 - b.t) * from[c] + b.t * with[c])
            }
        })
    }
}

/// The second node of an added node's starting state, see [`AddedNode::blend`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateBlend {
    /// Dense index of an existing node.
    pub with: u32,
    /// Its weight, in [0, 1].
    pub t: f64,
}

/// New mass or fixed flag of an existing node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeChange {
    /// Dense index.
    pub node: u32,
    /// Lumped mass, kg.
    pub mass: f64,
    /// Held at its rest position.
    pub fixed: bool,
}

/// A change to a [`PackedModel`]. Removals are applied before additions, so a spring can be
/// removed and added again (with new parameters) in one diff; `changed_springs` is the direct
/// way to do that.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModelDiff {
    /// Nodes appended, in order: the first gets index `node_count()`.
    pub added_nodes: Vec<AddedNode>,
    /// Mass or fixed-flag changes of existing (or just added) nodes.
    pub changed_nodes: Vec<NodeChange>,
    /// Springs removed, by their end pair (either order).
    pub removed_springs: Vec<[u32; 2]>,
    /// Springs added (ends may be new nodes).
    pub added_springs: Vec<PackedSpring>,
    /// Springs whose rest length, stiffness or damping change, found by their end pair.
    pub changed_springs: Vec<PackedSpring>,
    /// Tets removed (carved, split, or given new corners by a cut), by their corners in any
    /// order: what a finite-element force model subtracts the shares of. Removed before
    /// `added_tets` are added.
    pub removed_tets: Vec<[u32; 4]>,
    /// Tets added (split from a parent, or a tet given new corners), with their material:
    /// what a finite-element force model adds the shares of. Corners may be new nodes.
    pub added_tets: Vec<PackedTet>,
}

impl ModelDiff {
    /// Whether the diff changes nothing.
    pub fn is_empty(&self) -> bool {
        self.added_nodes.is_empty()
            && self.changed_nodes.is_empty()
            && self.removed_springs.is_empty()
            && self.added_springs.is_empty()
            && self.changed_springs.is_empty()
            && self.removed_tets.is_empty()
            && self.added_tets.is_empty()
    }

    /// Every node whose springs, mass or fixed flag change (including added nodes), ascending.
    pub fn touched_nodes(&self, nodes_before: usize) -> Vec<u32> {
        let mut t: Vec<u32> = (0..self.added_nodes.len())
            .map(|i| (nodes_before + i) as u32)
            .chain(self.changed_nodes.iter().map(|c| c.node))
            .chain(self.removed_springs.iter().flatten().copied())
            .chain(self.added_springs.iter().flat_map(|s| s.nodes))
            .chain(self.changed_springs.iter().flat_map(|s| s.nodes))
            .chain(self.removed_tets.iter().flatten().copied())
            .chain(self.added_tets.iter().flat_map(|t| t.nodes))
            .collect();
        t.sort_unstable();
        t.dedup();
        t
    }
}

/// An end pair in canonical (ascending) order.
pub(crate) fn pair(a: u32, b: u32) -> [u32; 2] {
    [a.min(b), a.max(b)]
}

/// Where each spring of a [`PackedModel`] is in its array, by end pair (ascending); stale
/// after [`PackedModel::springs_mut`] until the next [`PackedModel::apply`] or
/// [`PackedModel::reindex`].
#[derive(Clone, Default)]
pub(crate) struct SpringIndex {
    at: FxHashMap<[u32; 2], u32>,
    stale: bool,
}

impl std::fmt::Debug for SpringIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // A map of every spring would drown the model's own fields in a debug print.
        write!(f, "SpringIndex({} springs)", self.at.len())
    }
}

impl PartialEq for SpringIndex {
    /// Always: the index follows from the springs, which the model compares.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl SpringIndex {
    /// The index of `springs` as they lie.
    pub(crate) fn of(springs: &[PackedSpring]) -> Self {
        let mut at = FxHashMap::default();
        at.reserve(springs.len() + crate::model::room::spare(springs.len()));
        // Keyed by the ascending pair even where a hand-built spring lists its ends the other
        // way round, so that every lookup agrees with the scan below.
        at.extend(
            springs
                .iter()
                .enumerate()
                .map(|(i, s)| (pair(s.nodes[0], s.nodes[1]), i as u32)),
        );
        SpringIndex { at, stale: false }
    }
}

impl PackedModel {
    /// The springs: sorted by end pair when packed; a diff moves the last spring into the
    /// place of each it removes and appends those it adds ([`PackedModel::apply`]), so after a
    /// cut they are in no particular order. Find one by its ends with
    /// [`PackedModel::spring_index`].
    pub fn springs(&self) -> &[PackedSpring] {
        &self.springs
    }

    /// The springs, to change in place (tests and tools that build a model by hand). Lookups
    /// scan the array until the next [`PackedModel::apply`] or [`PackedModel::reindex`]
    /// indexes it again.
    pub fn springs_mut(&mut self) -> &mut Vec<PackedSpring> {
        self.index.stale = true;
        &mut self.springs
    }

    /// Index of the spring between `a` and `b` (either order) in [`PackedModel::springs`].
    pub fn spring_index(&self, a: u32, b: u32) -> Option<usize> {
        let key = pair(a, b);
        if self.index.stale {
            return self
                .springs
                .iter()
                .position(|s| pair(s.nodes[0], s.nodes[1]) == key);
        }
        let i = *self.index.at.get(&key)? as usize;
        let s = self.springs[i].nodes;
        debug_assert_eq!(pair(s[0], s[1]), key, "the spring index is behind");
        Some(i)
    }

    /// Index the springs again (after [`PackedModel::springs_mut`]; `apply` does it too).
    pub fn reindex(&mut self) {
        self.index = SpringIndex::of(&self.springs);
    }

    /// Make room for `additional` more springs, in the array and its index, so that a cut
    /// that adds springs does not move or rehash every spring.
    pub fn reserve_springs(&mut self, additional: usize) {
        self.springs.reserve(additional);
        self.index.at.reserve(additional);
    }

    /// Apply `diff`: the removed springs' places take the last springs, in the diff's order,
    /// and the added springs are appended, in theirs, so the same diff on the same model always
    /// gives the same array (see the module's doc). On error (a spring that does not exist, a
    /// duplicate, an index out of range) the model is left unchanged.
    pub fn apply(&mut self, diff: &ModelDiff) -> Result<()> {
        if self.index.stale {
            self.reindex();
        }
        let n = self.node_count() + diff.added_nodes.len();
        let check_node = |i: u32, what: &str| -> Result<()> {
            if (i as usize) < n {
                Ok(())
            } else {
                Err(Error::NodeOutOfRange {
                    node: i as u64,
                    count: n,
                    message: format!(
                        "{what} names node {i}, but the model has {n} nodes after the change"
                    ),
                })
            }
        };
        for a in &diff.added_nodes {
            let sources = a.state_from.into_iter().chain(a.blend.map(|b| b.with));
            for s in sources {
                if s as usize >= self.node_count() {
                    return Err(Error::NodeOutOfRange {
                        node: s as u64,
                        count: self.node_count(),
                        message: format!(
                            "an added node copies the state of node {s}, which does not exist \
                             yet"
                        ),
                    });
                }
            }
            if let Some(b) = a.blend {
                if a.state_from.is_none() || !(0.0..=1.0).contains(&b.t) {
                    return Err(Error::Model(format!(
                        "an added node blends node {}'s state with weight {} and source {:?}; \
                         a blend needs a source node (state_from) and a weight in [0, 1]",
                        b.with, b.t, a.state_from
                    )));
                }
            }
            if !(a.mass > 0.0 && a.mass.is_finite()) {
                return Err(Error::InvalidParameter {
                    name: "the mass of an added node".into(),
                    value: a.mass,
                    requirement: "be finite and positive".into(),
                });
            }
        }
        for c in &diff.changed_nodes {
            check_node(c.node, "a node change")?;
            if !(c.mass > 0.0 && c.mass.is_finite()) {
                return Err(Error::InvalidParameter {
                    name: format!("the new mass of node {}", c.node),
                    value: c.mass,
                    requirement: "be finite and positive".into(),
                });
            }
        }
        let mut removed = HashSet::new();
        for &[a, b] in &diff.removed_springs {
            if self.spring_index(a, b).is_none() || !removed.insert(pair(a, b)) {
                return Err(Error::DiffMismatch(format!(
                    "cannot remove spring {a}-{b}: there is no such spring (or it is removed twice)"
                )));
            }
        }
        let mut added = HashSet::new();
        for s in &diff.added_springs {
            let [a, b] = s.nodes;
            check_node(a, "an added spring")?;
            check_node(b, "an added spring")?;
            let key = pair(a, b);
            let exists = self.spring_index(a, b).is_some() && !removed.contains(&key);
            if a == b || exists || !added.insert(key) {
                return Err(Error::DiffMismatch(format!(
                    "cannot add spring {a}-{b}: its ends must be two distinct nodes not already \
                     joined by a spring"
                )));
            }
        }
        for s in &diff.changed_springs {
            let [a, b] = s.nodes;
            let key = pair(a, b);
            let present = (self.spring_index(a, b).is_some() && !removed.contains(&key))
                || added.contains(&key);
            if !present {
                return Err(Error::DiffMismatch(format!(
                    "cannot change spring {a}-{b}: there is no such spring after the removals"
                )));
            }
        }
        self.tet_index.refresh(&self.tets);
        let mut gone_tets = HashSet::new();
        for &t in &diff.removed_tets {
            if self.tet_index.get(&self.tets, t).is_none() {
                // Edited in place since it was indexed: index again before refusing.
                self.tet_index = super::tets::TetIndex::of(&self.tets);
            }
            if self.tet_index.get(&self.tets, t).is_none() || !gone_tets.insert(corner_set(t)) {
                return Err(Error::DiffMismatch(format!(
                    "cannot remove tet {t:?}: the model has no tet with those corners (or it is \
                     removed twice)"
                )));
            }
        }
        let mut new_tets = HashSet::new();
        for t in &diff.added_tets {
            for &i in &t.nodes {
                check_node(i, "an added tet")?;
            }
            let key = corner_set(t.nodes);
            let distinct = key.windows(2).all(|w| w[0] != w[1]);
            let exists =
                self.tet_index.get(&self.tets, t.nodes).is_some() && !gone_tets.contains(&key);
            if !distinct || exists || !new_tets.insert(key) {
                return Err(Error::DiffMismatch(format!(
                    "cannot add tet {:?}: its corners must be four distinct nodes not already \
                     a tet of the model",
                    t.nodes
                )));
            }
        }
        // Validated: nothing below can fail.
        for a in &diff.added_nodes {
            self.node_keys.push(a.key);
            self.rest.push(a.rest);
            self.mass.push(a.mass);
            self.fixed.push(a.fixed);
        }
        for c in &diff.changed_nodes {
            self.mass[c.node as usize] = c.mass;
            self.fixed[c.node as usize] = c.fixed;
        }
        for &[a, b] in &diff.removed_springs {
            let i = self.index.at.remove(&pair(a, b)).expect("checked above") as usize;
            self.springs.swap_remove(i);
            if let Some(moved) = self.springs.get(i) {
                self.index
                    .at
                    .insert(pair(moved.nodes[0], moved.nodes[1]), i as u32);
            }
        }
        for s in &diff.added_springs {
            let nodes = pair(s.nodes[0], s.nodes[1]);
            self.index.at.insert(nodes, self.springs.len() as u32);
            self.springs.push(PackedSpring { nodes, ..*s });
        }
        for s in &diff.changed_springs {
            let i = self
                .spring_index(s.nodes[0], s.nodes[1])
                .expect("checked above");
            let nodes = self.springs[i].nodes;
            self.springs[i] = PackedSpring { nodes, ..*s };
        }
        for &t in &diff.removed_tets {
            let i = self.tet_index.get(&self.tets, t).expect("checked above");
            self.tet_index.swap_remove(&mut self.tets, i);
        }
        for t in &diff.added_tets {
            self.tet_index.push(&mut self.tets, *t);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeMap;

    proptest! {
        /// Applying a diff gives the springs a rebuild gives (as a set, with their parameters),
        /// removed springs added back and changed ones included, and the index finds every
        /// spring at its place and none that is gone.
        #[test]
        fn applied_springs_equal_a_rebuild_and_are_indexed(
            start in proptest::collection::btree_set((0u32..30, 0u32..30), 1..150),
            remove_mask in proptest::collection::vec(any::<bool>(), 150),
            change_mask in proptest::collection::vec(any::<bool>(), 150),
            add in proptest::collection::btree_set((0u32..30, 0u32..30), 0..60),
        ) {
            let start: Vec<[u32; 2]> =
                start.into_iter().filter(|(a, b)| a < b).map(|(a, b)| [a, b]).collect();
            let rest: Vec<[f64; 3]> = (0..30).map(|i| [i as f64, (i * i % 7) as f64, 0.5]).collect();
            let springs: Vec<([u32; 2], f64, f64)> =
                start.iter().map(|&p| (p, 1.0, 0.0)).collect();
            let mut model = PackedModel::from_springs(rest, vec![1.0; 30], &springs).unwrap();
            let gone: Vec<[u32; 2]> = start
                .iter()
                .zip(&remove_mask)
                .filter(|(_, &r)| r)
                .map(|(p, _)| [p[1], p[0]])
                .collect();
            let mut want: BTreeMap<[u32; 2], PackedSpring> =
                model.springs.iter().map(|s| (s.nodes, *s)).collect();
            for g in &gone {
                want.remove(&pair(g[0], g[1]));
            }
            let mut fresh = HashSet::new();
            let added: Vec<PackedSpring> = add
                .into_iter()
                .filter(|(a, b)| a != b && !want.contains_key(&pair(*a, *b)))
                .filter(|(a, b)| fresh.insert(pair(*a, *b)))
                .map(|(a, b)| PackedSpring { nodes: [b, a], rest_length: 2.0, stiffness: 3.0, damping: 0.1 })
                .collect();
            for s in &added {
                let nodes = pair(s.nodes[0], s.nodes[1]);
                want.insert(nodes, PackedSpring { nodes, ..*s });
            }
            let changed: Vec<PackedSpring> = want
                .values()
                .zip(&change_mask)
                .filter(|(_, &c)| c)
                .map(|(s, _)| PackedSpring { stiffness: 7.0, ..*s })
                .collect();
            for s in &changed {
                want.insert(s.nodes, *s);
            }
            let diff = ModelDiff {
                removed_springs: gone.clone(),
                added_springs: added,
                changed_springs: changed,
                ..Default::default()
            };
            let mut again = model.clone();
            model.apply(&diff).unwrap();
            again.apply(&diff).unwrap();
            prop_assert_eq!(&model.springs, &again.springs);
            let mut got: Vec<PackedSpring> = model.springs.clone();
            got.sort_by_key(|s| s.nodes);
            prop_assert_eq!(got, want.values().copied().collect::<Vec<_>>());
            for (i, s) in model.springs.iter().enumerate() {
                prop_assert_eq!(model.spring_index(s.nodes[1], s.nodes[0]), Some(i));
            }
            for g in &gone {
                let back = want.contains_key(&pair(g[0], g[1]));
                prop_assert_eq!(model.spring_index(g[0], g[1]).is_some(), back);
            }
        }
    }

    /// Springs changed in place through `springs_mut` (removed, pushed, swapped) are found
    /// where they are, before any reindexing, and a diff then removes the spring it names (a
    /// swap that kept the array's length once left the index pointing at the other one).
    #[test]
    fn springs_changed_in_place_are_found_where_they_are() {
        let rest: Vec<[f64; 3]> = (0..4).map(|i| [i as f64, 0.0, 0.0]).collect();
        let springs = [([0, 1], 1.0, 0.0), ([1, 2], 1.0, 0.0), ([2, 3], 1.0, 0.0)];
        let mut model = PackedModel::from_springs(rest, vec![1.0; 4], &springs).unwrap();
        let gone = model.springs_mut().remove(0);
        assert_eq!(model.spring_index(0, 1), None);
        assert_eq!(model.spring_index(2, 1), Some(0));
        model.springs_mut().push(gone);
        model.springs_mut().swap(0, 2);
        assert_eq!(model.spring_index(1, 0), Some(0));
        assert_eq!(model.spring_index(3, 2), Some(1));
        assert_eq!(model.spring_index(1, 2), Some(2));
        model
            .apply(&ModelDiff {
                removed_springs: vec![[0, 1]],
                ..Default::default()
            })
            .unwrap();
        let left: Vec<[u32; 2]> = model.springs().iter().map(|s| s.nodes).collect();
        assert_eq!(left.len(), 2);
        assert!(left.contains(&[1, 2]) && left.contains(&[2, 3]));
        for (i, s) in model.springs().iter().enumerate() {
            assert_eq!(model.spring_index(s.nodes[0], s.nodes[1]), Some(i));
        }
    }

    /// A spring written by hand with its ends the other way round is found by either order,
    /// stale or indexed, and a diff removes it rather than refusing or keeping it.
    #[test]
    fn a_spring_with_its_ends_reversed_is_found() {
        let rest: Vec<[f64; 3]> = (0..4).map(|i| [i as f64, 0.0, 0.0]).collect();
        let springs = [([0, 1], 1.0, 0.0), ([1, 2], 1.0, 0.0), ([2, 3], 1.0, 0.0)];
        let mut model = PackedModel::from_springs(rest, vec![1.0; 4], &springs).unwrap();
        model.springs_mut()[1].nodes = [2, 1];
        assert_eq!(model.spring_index(1, 2), Some(1));
        assert_eq!(model.spring_index(2, 1), Some(1));
        model.reindex();
        assert_eq!(model.spring_index(1, 2), Some(1));
        assert_eq!(model.spring_index(2, 1), Some(1));
        model
            .apply(&ModelDiff {
                removed_springs: vec![[1, 2], [0, 1]],
                ..Default::default()
            })
            .unwrap();
        let left: Vec<[u32; 2]> = model.springs().iter().map(|s| s.nodes).collect();
        assert_eq!(left, vec![[2, 3]]);
    }
}

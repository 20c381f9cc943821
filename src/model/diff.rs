//! A change to a packed model: what a cut produces between two steps. Nodes are only ever
//! appended (dense indices of existing nodes never change, so every layout keeps its numbering);
//! springs are removed, added or re-parameterised by their end pair.
//!
//! [`PackedModel::apply`] turns a model into the model after the change; the layouts turn the
//! same diff into dirty byte ranges (`crate::layout`), so the device only receives what changed.

use std::collections::HashSet;

use super::{PackedModel, PackedSpring};
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
}

impl ModelDiff {
    /// Whether the diff changes nothing.
    pub fn is_empty(&self) -> bool {
        self.added_nodes.is_empty()
            && self.changed_nodes.is_empty()
            && self.removed_springs.is_empty()
            && self.added_springs.is_empty()
            && self.changed_springs.is_empty()
    }

    /// Every node whose springs, mass or fixed flag change (including added nodes), ascending.
    pub fn touched_nodes(&self, nodes_before: usize) -> Vec<u32> {
        let mut t: Vec<u32> = (0..self.added_nodes.len())
            .map(|i| (nodes_before + i) as u32)
            .chain(self.changed_nodes.iter().map(|c| c.node))
            .chain(self.removed_springs.iter().flatten().copied())
            .chain(self.added_springs.iter().flat_map(|s| s.nodes))
            .chain(self.changed_springs.iter().flat_map(|s| s.nodes))
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

impl PackedModel {
    /// Index of the spring between `a` and `b` (either order) in [`PackedModel::springs`],
    /// which is kept sorted by end pair.
    pub fn spring_index(&self, a: u32, b: u32) -> Option<usize> {
        let key = pair(a, b);
        self.springs.binary_search_by_key(&key, |s| s.nodes).ok()
    }

    /// Apply `diff`. Springs stay sorted by end pair, so the result equals a model packed from
    /// scratch with the same content. On error (a spring that does not exist, a duplicate, an
    /// index out of range) the model is left unchanged.
    pub fn apply(&mut self, diff: &ModelDiff) -> Result<()> {
        let n = self.node_count() + diff.added_nodes.len();
        let check_node = |i: u32, what: &str| -> Result<()> {
            if (i as usize) < n {
                Ok(())
            } else {
                Err(Error::Model(format!(
                    "{what} names node {i}, but the model has {n} nodes after the change"
                )))
            }
        };
        for a in &diff.added_nodes {
            let sources = a.state_from.into_iter().chain(a.blend.map(|b| b.with));
            for s in sources {
                if s as usize >= self.node_count() {
                    return Err(Error::Model(format!(
                        "an added node copies the state of node {s}, which does not exist yet"
                    )));
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
                return Err(Error::Model(format!(
                    "an added node has mass {}; give a positive mass",
                    a.mass
                )));
            }
        }
        for c in &diff.changed_nodes {
            check_node(c.node, "a node change")?;
            if !(c.mass > 0.0 && c.mass.is_finite()) {
                return Err(Error::Model(format!(
                    "node {} would get mass {}; give a positive mass",
                    c.node, c.mass
                )));
            }
        }
        let mut removed = HashSet::new();
        for &[a, b] in &diff.removed_springs {
            if self.spring_index(a, b).is_none() || !removed.insert(pair(a, b)) {
                return Err(Error::Model(format!(
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
                return Err(Error::Model(format!(
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
                return Err(Error::Model(format!(
                    "cannot change spring {a}-{b}: there is no such spring after the removals"
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
        let mut added_sorted: Vec<PackedSpring> = diff
            .added_springs
            .iter()
            .map(|s| PackedSpring {
                nodes: pair(s.nodes[0], s.nodes[1]),
                ..*s
            })
            .collect();
        added_sorted.sort_by_key(|s| s.nodes);
        let mut gone: Vec<[u32; 2]> = removed.into_iter().collect();
        gone.sort_unstable();
        edit_sorted(&mut self.springs, &gone, &added_sorted);
        for s in &diff.changed_springs {
            let i = self
                .spring_index(s.nodes[0], s.nodes[1])
                .expect("checked above");
            let nodes = self.springs[i].nodes;
            self.springs[i] = PackedSpring { nodes, ..*s };
        }
        Ok(())
    }
}

/// Remove the springs with end pairs `gone` (sorted, all present) from `springs` (sorted by end
/// pair) and insert `added` (sorted, none present once `gone` is removed), in place. Nothing
/// is allocated beyond the edit's own lists, and each spring moves at most once: a cut edits
/// tens of springs of a model of hundreds of thousands, and moving the tail once for the
/// removals and again for the additions was most of applying its diff.
fn edit_sorted(springs: &mut Vec<PackedSpring>, gone: &[[u32; 2]], added: &[PackedSpring]) {
    let len = springs.len();
    // Where each removed spring is and where each added one goes (before the old spring at
    // that index), by binary searches from the last one found.
    let mut removed_at: Vec<usize> = Vec::with_capacity(gone.len());
    let mut lo = 0;
    for g in gone {
        lo += springs[lo..].partition_point(|s| s.nodes < *g);
        if springs.get(lo).is_some_and(|s| s.nodes == *g) {
            removed_at.push(lo);
            lo += 1;
        }
    }
    let mut insert_at: Vec<usize> = Vec::with_capacity(added.len());
    let mut lo = 0;
    for a in added {
        lo += springs[lo..].partition_point(|s| s.nodes < a.nodes);
        insert_at.push(lo);
    }
    // The old springs between two edits keep their order and all move by the same offset
    // (additions before them less removals): runs (start, end, offset).
    let mut runs: Vec<(usize, usize, isize)> = Vec::new();
    let (mut pos, mut offset, mut r, mut a) = (0usize, 0isize, 0usize, 0usize);
    while pos < len {
        while insert_at.get(a) == Some(&pos) {
            offset += 1;
            a += 1;
        }
        if removed_at.get(r) == Some(&pos) {
            offset -= 1;
            r += 1;
            pos += 1;
            continue;
        }
        let next = [removed_at.get(r), insert_at.get(a)]
            .into_iter()
            .flatten()
            .copied()
            .fold(len, usize::min);
        if offset != 0 {
            runs.push((pos, next, offset));
        }
        pos = next;
    }
    let new_len = len + added.len() - removed_at.len();
    if let Some(first) = added.first() {
        springs.resize(new_len.max(len), *first);
    }
    // A run's destination can only overlap the sources of runs moving the same way: those
    // moving up go from the last, those moving down from the first, so that none is
    // overwritten before it has moved.
    for &(s, e, d) in runs.iter().rev().filter(|r| r.2 > 0) {
        springs.copy_within(s..e, s + d as usize);
    }
    for &(s, e, d) in runs.iter().filter(|r| r.2 < 0) {
        springs.copy_within(s..e, s - (-d) as usize);
    }
    // Each added spring lands after the additions before it and the old springs below its
    // place that stay.
    let mut r = 0;
    for (k, (s, &at)) in added.iter().zip(&insert_at).enumerate() {
        while removed_at.get(r).is_some_and(|&i| i < at) {
            r += 1;
        }
        springs[at + k - r] = *s;
    }
    springs.truncate(new_len);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeSet;

    fn spring(nodes: [u32; 2], tag: f64) -> PackedSpring {
        PackedSpring {
            nodes,
            rest_length: tag,
            stiffness: 1.0,
            damping: 0.0,
        }
    }

    proptest! {
        /// The in-place edit gives the sorted set a rebuild gives, removed springs added back
        /// included.
        #[test]
        fn in_place_edits_equal_a_sorted_rebuild(
            start in proptest::collection::btree_set((0u32..40, 0u32..40), 0..200),
            remove_mask in proptest::collection::vec(any::<bool>(), 200),
            add in proptest::collection::btree_set((0u32..40, 0u32..40), 0..60),
        ) {
            let start: BTreeSet<[u32; 2]> =
                start.into_iter().filter(|(a, b)| a < b).map(|(a, b)| [a, b]).collect();
            let gone: Vec<[u32; 2]> = start
                .iter()
                .zip(&remove_mask)
                .filter(|(_, &r)| r)
                .map(|(p, _)| *p)
                .collect();
            let kept: BTreeSet<[u32; 2]> =
                start.iter().filter(|p| !gone.contains(p)).copied().collect();
            let added: Vec<PackedSpring> = add
                .into_iter()
                .filter(|(a, b)| a < b)
                .map(|(a, b)| [a, b])
                .filter(|p| !kept.contains(p))
                .map(|p| spring(p, 2.0))
                .collect();
            let mut springs: Vec<PackedSpring> = start.iter().map(|&p| spring(p, 1.0)).collect();
            edit_sorted(&mut springs, &gone, &added);
            let mut expected: Vec<PackedSpring> = kept
                .iter()
                .map(|&p| spring(p, 1.0))
                .chain(added.iter().copied())
                .collect();
            expected.sort_by_key(|s| s.nodes);
            prop_assert_eq!(springs, expected);
        }
    }
}

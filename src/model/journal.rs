//! What an edit changed in a [`super::SpringModel`]: each spring's and node's state before its
//! first change since the journal was started.
//!
//! A cut's diff is the difference between the model before and after its edit. Recording the
//! state of everything an edit might touch beforehand (every edge and corner of the tets around
//! the blade) costs a lookup in maps over the whole model for each, cache misses that made up
//! a quarter to a third of a subdividing edit; the model notes each spring and node at the moment it
//! changes instead, when its entry is already at hand, and only those.

use rustc_hash::FxHashMap;

use crate::mesh::{NodeKey, TetKey};

/// Rest length, stiffness and damping of a spring.
pub type SpringParams = (f64, f64, f64);

/// The state before the first change of each spring (by its end pair, in key order) and node
/// changed since the journal was started. Hashed: whoever reads it sorts what it finds.
#[derive(Debug, Clone, Default)]
pub struct ModelJournal {
    /// `None`: the spring did not exist.
    pub springs: FxHashMap<[NodeKey; 2], Option<SpringParams>>,
    /// Lumped mass (`None`: no tet held the node) and fixed flag.
    pub nodes: FxHashMap<NodeKey, (Option<f64>, bool)>,
    /// Each tet's corners before its first change (`None`: the tet did not exist): a
    /// finite-element model follows the tets, not the springs.
    pub tets: FxHashMap<TetKey, Option<[NodeKey; 4]>>,
}

impl ModelJournal {
    /// Note spring `edge` as it is (`before`), unless it changed already.
    pub(super) fn spring(&mut self, edge: [NodeKey; 2], before: Option<SpringParams>) {
        self.springs.entry(edge).or_insert(before);
    }

    /// Note tet `t` as it is (`before`: its corners, `None` if it does not exist yet), unless
    /// it changed already.
    pub(super) fn tet(&mut self, t: TetKey, before: Option<[NodeKey; 4]>) {
        self.tets.entry(t).or_insert(before);
    }

    /// Note node `n` as it is, unless it changed already.
    pub(super) fn node(&mut self, n: NodeKey, mass: Option<f64>, fixed: bool) {
        self.nodes.entry(n).or_insert((mass, fixed));
    }
}

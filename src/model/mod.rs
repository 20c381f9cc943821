//! The mass-spring model: springs on the unique tet edges, lumped node masses, damping, gravity
//! and fixed nodes.
//!
//! [`SpringModel`] is keyed by the mesh's stable node and tet keys and keeps, for every tet, the
//! exact share of stiffness, damping and mass it contributed, so that a cut can subtract
//! precisely what a removed or split tet gave ([`SpringModel::remove_tet`]). Engines run on the
//! dense [`PackedModel`] made by [`SpringModel::pack`].

pub mod constraints;
pub mod diff;
pub mod journal;
pub mod material;
mod packed;
pub(crate) mod room;
pub mod stability;
mod tets;

use std::collections::BTreeMap;

use rustc_hash::FxHashMap;

use serde::{Deserialize, Serialize};
use slotmap::{new_key_type, SecondaryMap, SlotMap};

use crate::error::{Error, Result};
use crate::mesh::{NodeKey, TetKey, TetMesh, TET_EDGES};

pub use constraints::FixedSelector;
pub use diff::{AddedNode, ModelDiff, NodeChange, StateBlend};
pub use journal::{ModelJournal, SpringParams};
pub use material::{Mass, Material, SpringDamping, Stiffness, StiffnessRule};
pub use packed::{PackedModel, PackedSpring};
pub use stability::{stable_time_step, stable_time_step_from_rows, BoundUndo, StabilityBound};
pub use tets::{corner_set, PackedTet};

new_key_type! {
    /// Stable identity of a spring.
    pub struct SpringKey;
}

/// Everything needed to turn a mesh into a spring model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelConfig {
    /// Material of tets whose region has no entry in `regions`.
    pub material: Material,
    /// Materials by region tag.
    #[serde(default)]
    pub regions: BTreeMap<i32, Material>,
    /// Gravity, m/s^2.
    #[serde(default)]
    pub gravity: [f64; 3],
    /// Global mass-proportional damping `alpha`, 1/s: force `-alpha m v` on every node.
    #[serde(default)]
    pub mass_damping: f64,
    /// Nodes held at their rest positions (union of the selectors).
    #[serde(default)]
    pub fixed: Vec<FixedSelector>,
}

impl ModelConfig {
    /// One material everywhere, no gravity, no damping, nothing fixed.
    pub fn new(material: Material) -> Self {
        ModelConfig {
            material,
            regions: BTreeMap::new(),
            gravity: [0.0; 3],
            mass_damping: 0.0,
            fixed: Vec::new(),
        }
    }

    /// The material of a region.
    pub fn material_of(&self, region: i32) -> &Material {
        self.regions.get(&region).unwrap_or(&self.material)
    }
}

/// A spring between two nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spring {
    /// The two nodes, in key order.
    pub nodes: [NodeKey; 2],
    /// Rest length, m.
    pub rest_length: f64,
    /// Stiffness, N/m: the sum of the shares of the tets holding the edge.
    pub stiffness: f64,
    /// Damping along the spring, N s/m.
    pub damping: f64,
    /// How many tets hold this edge; the spring is deleted when the last one goes.
    pub tets: u32,
}

/// What one tet contributed to the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetShare {
    /// The springs of its six edges, in [`TET_EDGES`] order.
    pub springs: [SpringKey; 6],
    /// Its stiffness share of each.
    pub stiffness: [f64; 6],
    /// Its damping share of each.
    pub damping: [f64; 6],
    /// Its mass share of each of its four nodes.
    pub mass: [f64; 4],
}

/// What the tets a cut splits held per unit of their rest volume, which the sub-tets that
/// replace them take ([`SpringModel::split_density`], [`SpringModel::add_split_tet`]): the
/// sub-tets of a parent then carry exactly its mass, and exactly its springs' `sum k l^2` (the
/// energy a uniform stretch stores in them), whatever the region's mass and spring models.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitDensity {
    /// Mass per rest volume, kg/m^3: `mass V / 4` to each corner of a sub-tet.
    pub mass: f64,
    /// `sum k l^2 / (6 V)` over the parents' edge shares, N/m^2: a sub-tet's edge of rest
    /// length `l` takes `stiffness V / l^2` where its region gives stiffness per spring
    /// ([`Stiffness::Spring`]); a material stiffness keeps its own rule, which is this one.
    pub stiffness: f64,
    /// The same for damping given per spring ([`SpringDamping::Absolute`]), N s/m^2.
    pub damping: f64,
}

/// The mass-spring model of a mesh, keyed by stable identities.
#[derive(Debug, Clone)]
pub struct SpringModel {
    springs: SlotMap<SpringKey, Spring>,
    /// Never iterated (its order is not deterministic), so a fast hash suits it.
    by_edge: FxHashMap<[NodeKey; 2], SpringKey>,
    mass: SecondaryMap<NodeKey, f64>,
    tets_at_node: SecondaryMap<NodeKey, u32>,
    fixed: SecondaryMap<NodeKey, ()>,
    shares: SecondaryMap<TetKey, TetShare>,
    config: ModelConfig,
    /// What changed since [`SpringModel::record_changes`], while recording.
    journal: Option<ModelJournal>,
}

fn edge_key(a: NodeKey, b: NodeKey) -> [NodeKey; 2] {
    if a < b {
        [a, b]
    } else {
        [b, a]
    }
}

impl SpringModel {
    /// Build the model of `mesh` under `config`.
    pub fn build(mesh: &TetMesh, config: &ModelConfig) -> Result<Self> {
        config.material.validate()?;
        for (r, m) in &config.regions {
            m.validate().map_err(|e| match e {
                Error::InvalidParameter {
                    name,
                    value,
                    requirement,
                } => Error::InvalidParameter {
                    name: format!("region {r}: {name}"),
                    value,
                    requirement,
                },
                e => Error::Model(format!("region {r}: {e}")),
            })?;
        }
        if let Some(c) = config.gravity.iter().position(|g| !g.is_finite()) {
            return Err(Error::InvalidParameter {
                name: format!("component {c} of gravity {:?}", config.gravity),
                value: config.gravity[c],
                requirement: "be finite".into(),
            });
        }
        if !(config.mass_damping.is_finite() && config.mass_damping >= 0.0) {
            return Err(Error::InvalidParameter {
                name: "mass damping".into(),
                value: config.mass_damping,
                requirement: "be finite and not negative".into(),
            });
        }
        let mut model = SpringModel {
            springs: SlotMap::with_key(),
            by_edge: FxHashMap::default(),
            mass: SecondaryMap::new(),
            tets_at_node: SecondaryMap::new(),
            fixed: SecondaryMap::new(),
            shares: SecondaryMap::new(),
            config: config.clone(),
            journal: None,
        };
        // Per-node and per-edge incidence counts, needed only by the "per node" and "per
        // spring" parameterisations, which split a given value equally among tets.
        let mut tets_at_node: SecondaryMap<NodeKey, u32> = SecondaryMap::new();
        let mut tets_at_edge: FxHashMap<[NodeKey; 2], u32> = FxHashMap::default();
        for (_, t) in mesh.tets() {
            for &n in &t.nodes {
                if let Some(e) = tets_at_node.entry(n) {
                    *e.or_insert(0) += 1;
                }
            }
            for [a, b] in TET_EDGES {
                *tets_at_edge
                    .entry(edge_key(t.nodes[a], t.nodes[b]))
                    .or_insert(0) += 1;
            }
        }
        for (tk, t) in mesh.tets() {
            let at_node = t.nodes.map(|n| tets_at_node.get(n).copied().unwrap_or(1));
            let at_edge = TET_EDGES.map(|[a, b]| tets_at_edge[&edge_key(t.nodes[a], t.nodes[b])]);
            let share = model.tet_share(mesh, tk, at_node, at_edge, None)?;
            model.apply_share(mesh, tk, share, 1.0);
        }
        for sel in &config.fixed {
            sel.select(mesh, &mut model.fixed)?;
        }
        Ok(model)
    }

    /// Start noting what changes (the state of each spring and node before its first
    /// change), until [`SpringModel::take_changes`]; anything noted before is forgotten.
    pub fn record_changes(&mut self) {
        self.journal = Some(ModelJournal::default());
    }

    /// What changed since [`SpringModel::record_changes`] (empty if it was not called); stops
    /// recording.
    pub fn take_changes(&mut self) -> ModelJournal {
        self.journal.take().unwrap_or_default()
    }

    /// Note spring `sk` before it changes, while recording.
    fn note_spring(&mut self, sk: SpringKey) {
        if let (Some(j), Some(s)) = (&mut self.journal, self.springs.get(sk)) {
            j.spring(s.nodes, Some((s.rest_length, s.stiffness, s.damping)));
        }
    }

    /// Note node `n` before its mass or fixed flag changes, while recording.
    fn note_node(&mut self, n: NodeKey) {
        if let Some(j) = &mut self.journal {
            j.node(n, self.mass.get(n).copied(), self.fixed.contains_key(n));
        }
    }

    /// Insert a spring on `key` with rest length `rest_length` and nothing of any tet yet.
    fn new_spring(&mut self, key: [NodeKey; 2], rest_length: f64) -> SpringKey {
        if let Some(j) = &mut self.journal {
            j.spring(key, None);
        }
        let s = self.springs.insert(Spring {
            nodes: key,
            rest_length,
            stiffness: 0.0,
            damping: 0.0,
            tets: 0,
        });
        self.by_edge.insert(key, s);
        s
    }

    /// Compute what tet `tk` contributes (springs are created if missing), given how many tets
    /// hold each of its corners (`at_node`, in corner order) and each of its edges (`at_edge`,
    /// in [`TET_EDGES`] order), counting this one: the "per node" and "per spring" values are
    /// split equally among them. Arrays rather than maps, because adding one tet to a large
    /// model must not cost a map sized to the model. With `parent` (a tet split from parents
    /// of these densities), a "per node" region's tet gives `parent.mass V / 4` to each corner
    /// and a "per spring" region's tet `parent.stiffness V / l^2` to each edge instead, so that
    /// splitting conserves mass and `sum k l^2`.
    fn tet_share(
        &mut self,
        mesh: &TetMesh,
        tk: TetKey,
        at_node: [u32; 4],
        at_edge: [u32; 6],
        parent: Option<SplitDensity>,
    ) -> Result<TetShare> {
        let t = *mesh
            .tet(tk)
            .ok_or_else(|| Error::Model("tet is not in the mesh".into()))?;
        let mat = *self.config.material_of(t.region);
        let p = mesh.tet_points(&t);
        let volume = mesh.tet_volume(tk);
        let mut share = TetShare {
            springs: [SpringKey::default(); 6],
            stiffness: [0.0; 6],
            damping: [0.0; 6],
            mass: [0.0; 4],
        };
        for (e, [a, b]) in TET_EDGES.iter().enumerate() {
            let key = edge_key(t.nodes[*a], t.nodes[*b]);
            let l = (p[*a] - p[*b]).norm();
            let n_e = at_edge[e].max(1) as f64;
            let k = match (mat.stiffness, mat.stiffness_constant(), parent) {
                (Stiffness::Spring(_), _, Some(p)) => p.stiffness * volume / (l * l),
                (Stiffness::Spring(k), _, None) => k / n_e,
                (_, Some(c), _) => c * volume / (l * l),
                _ => 0.0,
            };
            let c = match (mat.damping, parent) {
                (SpringDamping::None, _) => 0.0,
                (SpringDamping::Absolute(_), Some(p)) => p.damping * volume / (l * l),
                (SpringDamping::Absolute(c), None) => c / n_e,
                (SpringDamping::StiffnessProportional(beta), _) => beta * k,
            };
            let sk = match self.by_edge.get(&key) {
                Some(&s) => s,
                None => self.new_spring(key, l),
            };
            share.springs[e] = sk;
            share.stiffness[e] = k;
            share.damping[e] = c;
        }
        for (i, held) in at_node.iter().enumerate() {
            share.mass[i] = match (mat.mass, parent) {
                (Mass::Density(rho), _) => rho * volume / 4.0,
                (Mass::PerNode(_), Some(p)) => p.mass * volume / 4.0,
                (Mass::PerNode(m), None) => m / (*held).max(1) as f64,
            };
        }
        Ok(share)
    }

    /// Add (`sign = 1`) or subtract (`sign = -1`) a tet's share.
    fn apply_share(&mut self, mesh: &TetMesh, tk: TetKey, share: TetShare, sign: f64) {
        let count = |c: u32| {
            if sign > 0.0 {
                c + 1
            } else {
                c.saturating_sub(1)
            }
        };
        for e in 0..6 {
            self.note_spring(share.springs[e]);
            if let Some(s) = self.springs.get_mut(share.springs[e]) {
                s.stiffness += sign * share.stiffness[e];
                s.damping += sign * share.damping[e];
                s.tets = count(s.tets);
            }
        }
        if let Some(t) = mesh.tet(tk) {
            for (i, n) in t.nodes.iter().enumerate() {
                self.note_node(*n);
                if let Some(m) = self.mass.entry(*n) {
                    *m.or_insert(0.0) += sign * share.mass[i];
                }
                if let Some(c) = self.tets_at_node.entry(*n) {
                    let c = c.or_insert(0);
                    *c = count(*c);
                }
            }
        }
        if sign > 0.0 {
            self.shares.insert(tk, share);
        }
    }

    /// Remove what tet `tk` contributed, before the tet is removed from `mesh`. Springs left
    /// with no tet are deleted; nodes left with no tet lose their mass entry. Returns the
    /// springs that were deleted.
    pub fn remove_tet(&mut self, mesh: &TetMesh, tk: TetKey) -> Result<Vec<SpringKey>> {
        let share = self
            .shares
            .remove(tk)
            .ok_or_else(|| Error::Model("tet has no share in the model".into()))?;
        self.apply_share(mesh, tk, share, -1.0);
        let t = *mesh
            .tet(tk)
            .ok_or_else(|| Error::Model("tet is not in the mesh".into()))?;
        if let Some(j) = &mut self.journal {
            j.tet(tk, Some(t.nodes));
        }
        // A spring survives while another tet still holds its edge; likewise a node's mass.
        let mut removed = Vec::new();
        for &s in &share.springs {
            if self.springs.get(s).is_some_and(|sp| sp.tets == 0) {
                if let Some(spring) = self.springs.remove(s) {
                    self.by_edge.remove(&spring.nodes);
                    removed.push(s);
                }
            }
        }
        for n in t.nodes {
            if self.tets_at_node.get(n).is_some_and(|&c| c == 0) {
                self.mass.remove(n);
                self.tets_at_node.remove(n);
            }
        }
        Ok(removed)
    }

    /// Move tet `tk`'s share from its old corner nodes `old` to `new` (the same tet with some
    /// corners replaced by copies at the same rest positions, as a cut that separates tets
    /// does). Each spring and node loses exactly what the tet gave and the new ones receive it,
    /// so masses and stiffnesses are divided by each tet's share whatever the parameterisation.
    /// Springs left with no tet are deleted, springs on new edges are created (with the old
    /// edge's rest length), nodes left with no tet lose their mass entry, and new nodes take
    /// the fixed flag of the node they replace. Returns the deleted springs.
    pub fn renode_tet(
        &mut self,
        tk: TetKey,
        old: [NodeKey; 4],
        new: [NodeKey; 4],
    ) -> Result<Vec<SpringKey>> {
        let mut share = *self
            .shares
            .get(tk)
            .ok_or_else(|| Error::Model("tet has no share in the model".into()))?;
        if let Some(j) = &mut self.journal {
            j.tet(tk, Some(old));
        }
        for (i, (&o, &n)) in old.iter().zip(&new).enumerate() {
            if o == n {
                continue;
            }
            self.note_node(o);
            self.note_node(n);
            if let Some(m) = self.mass.get_mut(o) {
                *m -= share.mass[i];
            }
            if let Some(c) = self.tets_at_node.get_mut(o) {
                *c = c.saturating_sub(1);
            }
            if let Some(e) = self.mass.entry(n) {
                *e.or_insert(0.0) += share.mass[i];
            }
            if let Some(e) = self.tets_at_node.entry(n) {
                *e.or_insert(0) += 1;
            }
            if self.fixed.contains_key(o) {
                self.fixed.insert(n, ());
            }
        }
        let mut removed = Vec::new();
        for (e, [a, b]) in TET_EDGES.iter().enumerate() {
            let (oa, ob, na, nb) = (old[*a], old[*b], new[*a], new[*b]);
            if oa == na && ob == nb {
                continue;
            }
            let old_key = share.springs[e];
            let rest_length = self.springs.get(old_key).map_or(0.0, |s| s.rest_length);
            self.note_spring(old_key);
            if let Some(s) = self.springs.get_mut(old_key) {
                s.stiffness -= share.stiffness[e];
                s.damping -= share.damping[e];
                s.tets = s.tets.saturating_sub(1);
                if s.tets == 0 {
                    let nodes = s.nodes;
                    self.springs.remove(old_key);
                    self.by_edge.remove(&nodes);
                    removed.push(old_key);
                }
            }
            let key = edge_key(na, nb);
            let sk = match self.by_edge.get(&key) {
                Some(&s) => s,
                None => self.new_spring(key, rest_length),
            };
            self.note_spring(sk);
            let s = &mut self.springs[sk];
            s.stiffness += share.stiffness[e];
            s.damping += share.damping[e];
            s.tets += 1;
            share.springs[e] = sk;
        }
        for o in old {
            if self.tets_at_node.get(o).is_some_and(|&c| c == 0) {
                self.mass.remove(o);
                self.tets_at_node.remove(o);
            }
        }
        self.shares.insert(tk, share);
        Ok(removed)
    }

    /// Add what a new tet `tk` of `mesh` contributes. Material stiffness and density shares
    /// depend only on the tet's geometry, so they are exact; the "per spring" and "per node"
    /// parameterisations split their value among the tets holding an edge or node counted now,
    /// this one included (earlier tets keep their shares). A tet split from a parent takes
    /// [`SpringModel::add_split_tet`] instead, which conserves the parent's mass and springs.
    pub fn add_tet(&mut self, mesh: &TetMesh, tk: TetKey) -> Result<()> {
        self.add_tet_with(mesh, tk, None)
    }

    /// Add a tet `tk` that a cut split from parent tets of densities `parent`
    /// ([`SpringModel::split_density`] of the tets it replaces): `parent.mass V / 4` to each
    /// corner, and where the region gives stiffness or damping per spring, `parent.stiffness V
    /// / l^2` and `parent.damping V / l^2` to each edge, so that the sub-tets of a parent carry
    /// exactly its mass and its springs' `sum k l^2`. Material stiffness and [`Mass::Density`]
    /// keep their own rules, which are these already.
    pub fn add_split_tet(
        &mut self,
        mesh: &TetMesh,
        tk: TetKey,
        parent: SplitDensity,
    ) -> Result<()> {
        for (name, value, positive) in [
            ("mass", parent.mass, true),
            ("stiffness", parent.stiffness, false),
            ("damping", parent.damping, false),
        ] {
            if !(value.is_finite() && (value > 0.0 || (!positive && value == 0.0))) {
                return Err(Error::InvalidParameter {
                    name: format!("a split tet's parent {name} density"),
                    value,
                    requirement: if positive {
                        "be finite and positive".into()
                    } else {
                        "be finite and not negative".into()
                    },
                });
            }
        }
        self.add_tet_with(mesh, tk, Some(parent))
    }

    fn add_tet_with(
        &mut self,
        mesh: &TetMesh,
        tk: TetKey,
        parent: Option<SplitDensity>,
    ) -> Result<()> {
        let t = *mesh
            .tet(tk)
            .ok_or_else(|| Error::Model("tet is not in the mesh".into()))?;
        if let Some(j) = &mut self.journal {
            j.tet(tk, None);
        }
        let at_node = t.nodes.map(|n| self.tets_at_node(n) + 1);
        let at_edge = TET_EDGES.map(|[a, b]| {
            let key = edge_key(t.nodes[a], t.nodes[b]);
            self.by_edge.get(&key).map_or(0, |s| self.springs[*s].tets) + 1
        });
        let share = self.tet_share(mesh, tk, at_node, at_edge, parent)?;
        self.apply_share(mesh, tk, share, 1.0);
        Ok(())
    }

    /// What the tets `tets` of `mesh` hold per unit of their rest volume: the mass they give
    /// their nodes, and `sum k l^2 / 6` and `sum c l^2 / 6` over their edge shares (`l` the
    /// rest length): what their sub-tets take when a cut splits them
    /// ([`SpringModel::add_split_tet`]). `None` when they hold no volume or have no share.
    pub fn split_density(&self, mesh: &TetMesh, tets: &[TetKey]) -> Option<SplitDensity> {
        let (mut mass, mut kl2, mut cl2, mut volume) = (0.0, 0.0, 0.0, 0.0);
        for &tk in tets {
            let share = self.shares.get(tk)?;
            mass += share.mass.iter().sum::<f64>();
            for e in 0..6 {
                let l = self.springs.get(share.springs[e])?.rest_length;
                kl2 += share.stiffness[e] * l * l;
                cl2 += share.damping[e] * l * l;
            }
            volume += mesh.tet_volume(tk);
        }
        (volume > 0.0 && mass > 0.0).then(|| SplitDensity {
            mass: mass / volume,
            stiffness: kl2 / (6.0 * volume),
            damping: cl2 / (6.0 * volume),
        })
    }

    /// Number of tets holding node `n`.
    pub fn tets_at_node(&self, n: NodeKey) -> u32 {
        self.tets_at_node.get(n).copied().unwrap_or(0)
    }

    /// The configuration the model was built with.
    pub fn config(&self) -> &ModelConfig {
        &self.config
    }

    /// All springs.
    pub fn springs(&self) -> impl Iterator<Item = (SpringKey, &Spring)> + '_ {
        self.springs.iter()
    }

    /// Number of springs.
    pub fn spring_count(&self) -> usize {
        self.springs.len()
    }

    /// The spring on edge `a b`, if any.
    pub fn spring_between(&self, a: NodeKey, b: NodeKey) -> Option<&Spring> {
        self.by_edge.get(&edge_key(a, b)).map(|s| &self.springs[*s])
    }

    /// Lumped mass of a node, kg.
    pub fn mass(&self, n: NodeKey) -> Option<f64> {
        self.mass.get(n).copied()
    }

    /// Total mass, kg.
    pub fn total_mass(&self) -> f64 {
        self.mass.values().sum()
    }

    /// Whether a node is fixed.
    pub fn is_fixed(&self, n: NodeKey) -> bool {
        self.fixed.contains_key(n)
    }

    /// Number of fixed nodes.
    pub fn fixed_count(&self) -> usize {
        self.fixed.len()
    }

    /// The share a tet contributed.
    pub fn share(&self, tk: TetKey) -> Option<&TetShare> {
        self.shares.get(tk)
    }

    /// Dense arrays for the engines, nodes in the mesh's storage order, springs sorted by their
    /// dense node pair.
    pub fn pack(&self, mesh: &TetMesh) -> Result<PackedModel> {
        let dense = mesh.dense_nodes();
        let n = dense.keys.len();
        let mut rest = Vec::with_capacity(n);
        let mut mass = Vec::with_capacity(n);
        let mut fixed = Vec::with_capacity(n);
        for &k in &dense.keys {
            let p = mesh.rest(k);
            rest.push([p.x, p.y, p.z]);
            let m = self.mass.get(k).copied().unwrap_or(0.0);
            if !(m > 0.0 && m.is_finite()) {
                return Err(Error::InvalidParameter {
                    name: format!("the mass of node {}", dense.index[k]),
                    value: m,
                    requirement: "be positive: every node needs a mass (remove nodes that no \
                                  tet uses)"
                        .into(),
                });
            }
            mass.push(m);
            fixed.push(self.fixed.contains_key(k));
        }
        let mut springs: Vec<PackedSpring> = self
            .springs
            .values()
            .map(|s| {
                let (a, b) = (dense.index[s.nodes[0]], dense.index[s.nodes[1]]);
                PackedSpring {
                    nodes: [a.min(b), a.max(b)],
                    rest_length: s.rest_length,
                    stiffness: s.stiffness,
                    damping: s.damping,
                }
            })
            .collect();
        springs.sort_by_key(|s| s.nodes);
        let tets: Vec<PackedTet> = mesh
            .tets()
            .map(|(_, t)| PackedTet {
                nodes: t.nodes.map(|k| dense.index[k]),
                region: t.region,
                material: *self.config.material_of(t.region),
            })
            .collect();
        Ok(PackedModel {
            tet_index: tets::TetIndex::of(&tets),
            tets,
            node_keys: dense.keys,
            rest,
            mass,
            fixed,
            index: diff::SpringIndex::of(&springs),
            springs,
            gravity: self.config.gravity,
            mass_damping: self.config.mass_damping,
        })
    }
}

//! Unstructured tetrahedral meshes with stable node and tet identities.
//!
//! A [`TetMesh`] stores rest positions in float64 and tets as four node keys plus a region tag.
//! Keys come from slotmaps, so they stay valid while other nodes and tets are added or removed
//! (what a cut does); dense `u32` indices are made only when a layout is packed
//! ([`TetMesh::dense_nodes`]).

pub mod generate;
#[cfg(feature = "formats")]
pub mod io;
pub mod quality;
pub mod topology;

use nalgebra::{Point3, Vector3};
use slotmap::{new_key_type, DenseSlotMap, SecondaryMap};

use crate::error::{Error, Result};

pub use quality::{QualityStats, TetQuality};
pub use topology::{BoundaryFace, Topology};

new_key_type! {
    /// Stable identity of a mesh node.
    pub struct NodeKey;
    /// Stable identity of a tetrahedron.
    pub struct TetKey;
}

/// A mesh node: its rest (material-space) position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Rest position, metres (or whatever unit the mesh file uses).
    pub rest: Point3<f64>,
}

/// A tetrahedron: four nodes, positively oriented (`det[b-a, c-a, d-a] > 0`), and a region tag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tet {
    /// The four corners, positively oriented.
    pub nodes: [NodeKey; 4],
    /// Region (material, physical group) tag; 0 when the source has none.
    pub region: i32,
}

/// Local node pairs of the six edges of a tet.
pub const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

/// Local node triples of the four faces of a positively oriented tet, each ordered so that its
/// normal (right-hand rule) points out of the tet. Face `i` is opposite node `i`.
pub const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// A tetrahedral mesh with stable keys.
#[derive(Debug, Clone, Default)]
pub struct TetMesh {
    nodes: DenseSlotMap<NodeKey, Node>,
    tets: DenseSlotMap<TetKey, Tet>,
}

/// Dense `0..n` numbering of the nodes of a mesh, made when packing.
#[derive(Debug, Clone)]
pub struct DenseNodes {
    /// `keys[i]` is the node with dense index `i`.
    pub keys: Vec<NodeKey>,
    /// Dense index of each node.
    pub index: SecondaryMap<NodeKey, u32>,
}

/// Six times the signed volume of the tet `a b c d`: `det[b-a, c-a, d-a]`.
pub fn signed_volume6(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>, d: &Point3<f64>) -> f64 {
    (b - a).cross(&(c - a)).dot(&(d - a))
}

impl TetMesh {
    /// An empty mesh.
    pub fn new() -> Self {
        Self::default()
    }

    /// Build a mesh from flat arrays: `points[i]` and tets as indices into `points`.
    ///
    /// Tets must reference existing, distinct points and have non-zero volume; negatively
    /// oriented tets are reoriented (the count is returned beside the mesh).
    pub fn from_arrays(
        points: &[[f64; 3]],
        tets: &[[u32; 4]],
        regions: Option<&[i32]>,
    ) -> Result<(Self, usize)> {
        if let Some(r) = regions {
            if r.len() != tets.len() {
                return Err(Error::Mesh(format!(
                    "{} region tags given for {} tets; give one per tet",
                    r.len(),
                    tets.len()
                )));
            }
        }
        let mut mesh = TetMesh::new();
        let keys: Vec<NodeKey> = points
            .iter()
            .map(|p| mesh.add_node(Point3::new(p[0], p[1], p[2])))
            .collect();
        let mut reoriented = 0;
        for (t, tet) in tets.iter().enumerate() {
            let mut k = [NodeKey::default(); 4];
            for (slot, &i) in k.iter_mut().zip(tet) {
                *slot = *keys.get(i as usize).ok_or_else(|| {
                    Error::Mesh(format!(
                        "tet {t} references node {i} but there are {} nodes",
                        keys.len()
                    ))
                })?;
            }
            let region = regions.map_or(0, |r| r[t]);
            let (_, flipped) = mesh
                .add_tet_reorienting(k, region)
                .map_err(|e| Error::Mesh(format!("tet {t}: {e}")))?;
            reoriented += flipped as usize;
        }
        Ok((mesh, reoriented))
    }

    /// Add a node at rest position `p`.
    pub fn add_node(&mut self, p: Point3<f64>) -> NodeKey {
        self.nodes.insert(Node { rest: p })
    }

    /// Add a positively oriented tet. Fails if a key is unknown, repeated, or the tet is
    /// degenerate or inverted.
    pub fn add_tet(&mut self, nodes: [NodeKey; 4], region: i32) -> Result<TetKey> {
        let v6 = self.check_tet(&nodes)?;
        if v6 < 0.0 {
            return Err(Error::Mesh(
                "tet is inverted (negative signed volume); swap two of its nodes".into(),
            ));
        }
        Ok(self.tets.insert(Tet { nodes, region }))
    }

    /// Add a tet, swapping its last two nodes if it is negatively oriented. Returns the key and
    /// whether it was reoriented.
    pub fn add_tet_reorienting(
        &mut self,
        mut nodes: [NodeKey; 4],
        region: i32,
    ) -> Result<(TetKey, bool)> {
        let v6 = self.check_tet(&nodes)?;
        let flipped = v6 < 0.0;
        if flipped {
            nodes.swap(2, 3);
        }
        Ok((self.tets.insert(Tet { nodes, region }), flipped))
    }

    /// Validate keys and distinctness, and return six times the signed volume, which must not
    /// be zero relative to the tet's size.
    fn check_tet(&self, nodes: &[NodeKey; 4]) -> Result<f64> {
        let mut p = [Point3::origin(); 4];
        for (i, k) in nodes.iter().enumerate() {
            p[i] = self
                .nodes
                .get(*k)
                .ok_or_else(|| Error::Mesh("tet references a node that does not exist".into()))?
                .rest;
            if nodes[..i].contains(k) {
                return Err(Error::Mesh(
                    "tet uses the same node twice; each tet needs four distinct nodes".into(),
                ));
            }
        }
        let v6 = signed_volume6(&p[0], &p[1], &p[2], &p[3]);
        if is_degenerate(v6, &p) {
            return Err(Error::Mesh(format!(
                "tet has zero volume (6V = {v6:e}); remove it or fix its nodes"
            )));
        }
        Ok(v6)
    }

    /// Remove a tet. Its nodes stay (remove unused nodes with [`TetMesh::remove_unused_nodes`]).
    pub fn remove_tet(&mut self, key: TetKey) -> Option<Tet> {
        self.tets.remove(key)
    }

    /// Remove a node. Fails if a tet still uses it.
    pub fn remove_node(&mut self, key: NodeKey) -> Result<Option<Node>> {
        if self.tets.values().any(|t| t.nodes.contains(&key)) {
            return Err(Error::Mesh(
                "node is still used by a tet; remove the tets first".into(),
            ));
        }
        Ok(self.nodes.remove(key))
    }

    /// Remove every node that no tet uses; returns how many were removed.
    pub fn remove_unused_nodes(&mut self) -> usize {
        let mut used: SecondaryMap<NodeKey, ()> = SecondaryMap::new();
        for t in self.tets.values() {
            for &n in &t.nodes {
                used.insert(n, ());
            }
        }
        let before = self.nodes.len();
        self.nodes.retain(|k, _| used.contains_key(k));
        before - self.nodes.len()
    }

    /// Replace the corners of tet `key` (a cut giving a tet copies of its nodes). The new
    /// corners must exist, be distinct and keep the tet positively oriented; on error the tet is
    /// unchanged.
    pub fn set_tet_nodes(&mut self, key: TetKey, nodes: [NodeKey; 4]) -> Result<()> {
        let v6 = self.check_tet(&nodes)?;
        if v6 < 0.0 {
            return Err(Error::Mesh(
                "new corners would invert the tet; swap two of them".into(),
            ));
        }
        let t = self
            .tets
            .get_mut(key)
            .ok_or_else(|| Error::Mesh("tet does not exist".into()))?;
        t.nodes = nodes;
        Ok(())
    }

    /// Add every node and tet of `other` (as a separate piece; nothing is merged).
    pub fn append(&mut self, other: &TetMesh) -> Result<()> {
        let mut map: SecondaryMap<NodeKey, NodeKey> = SecondaryMap::new();
        for (k, n) in other.nodes() {
            map.insert(k, self.add_node(n.rest));
        }
        for (_, t) in other.tets() {
            self.add_tet(t.nodes.map(|k| map[k]), t.region)?;
        }
        Ok(())
    }

    /// Move a node's rest position (used by cuts that snap nodes). Does not re-check tets.
    pub fn set_rest(&mut self, key: NodeKey, p: Point3<f64>) -> Option<()> {
        self.nodes.get_mut(key).map(|n| n.rest = p)
    }

    /// Set the region tag of a tet.
    pub fn set_region(&mut self, key: TetKey, region: i32) -> Option<()> {
        self.tets.get_mut(key).map(|t| t.region = region)
    }

    /// Set the region of every tet whose centroid satisfies `pred`.
    pub fn set_region_where(&mut self, region: i32, mut pred: impl FnMut(&Point3<f64>) -> bool) {
        let nodes = &self.nodes;
        for t in self.tets.values_mut() {
            let c = t
                .nodes
                .iter()
                .fold(Vector3::zeros(), |acc, k| acc + nodes[*k].rest.coords)
                / 4.0;
            if pred(&Point3::from(c)) {
                t.region = region;
            }
        }
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Number of tets.
    pub fn tet_count(&self) -> usize {
        self.tets.len()
    }

    /// A node by key.
    pub fn node(&self, key: NodeKey) -> Option<&Node> {
        self.nodes.get(key)
    }

    /// A tet by key.
    pub fn tet(&self, key: TetKey) -> Option<&Tet> {
        self.tets.get(key)
    }

    /// Rest position of a node. Panics on a key not in this mesh (a programming error).
    pub fn rest(&self, key: NodeKey) -> Point3<f64> {
        self.nodes[key].rest
    }

    /// All nodes, in storage order (deterministic for a given history of edits).
    pub fn nodes(&self) -> impl ExactSizeIterator<Item = (NodeKey, &Node)> + '_ {
        self.nodes.iter()
    }

    /// All tets, in storage order.
    pub fn tets(&self) -> impl ExactSizeIterator<Item = (TetKey, &Tet)> + '_ {
        self.tets.iter()
    }

    /// The four rest positions of a tet.
    pub fn tet_points(&self, tet: &Tet) -> [Point3<f64>; 4] {
        tet.nodes.map(|k| self.nodes[k].rest)
    }

    /// Signed rest volume of a tet (positive for every tet of a valid mesh).
    pub fn tet_volume(&self, key: TetKey) -> f64 {
        let p = self.tet_points(&self.tets[key]);
        signed_volume6(&p[0], &p[1], &p[2], &p[3]) / 6.0
    }

    /// Total rest volume.
    pub fn volume(&self) -> f64 {
        self.tets.keys().map(|k| self.tet_volume(k)).sum()
    }

    /// Axis-aligned bounds of the rest positions, `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        let mut it = self.nodes.values();
        let first = it.next()?.rest;
        Some(it.fold((first, first), |(lo, hi), n| {
            (lo.inf(&n.rest), hi.sup(&n.rest))
        }))
    }

    /// Region tags and how many tets carry each, sorted by tag.
    pub fn regions(&self) -> Vec<(i32, usize)> {
        let mut m = std::collections::BTreeMap::new();
        for t in self.tets.values() {
            *m.entry(t.region).or_insert(0usize) += 1;
        }
        m.into_iter().collect()
    }

    /// Dense numbering of the nodes in storage order.
    pub fn dense_nodes(&self) -> DenseNodes {
        let keys: Vec<NodeKey> = self.nodes.keys().collect();
        let mut index = SecondaryMap::with_capacity(keys.len());
        for (i, k) in keys.iter().enumerate() {
            index.insert(*k, i as u32);
        }
        DenseNodes { keys, index }
    }

    /// Unique edges (one per pair of nodes sharing a tet), each as `[lo, hi]` dense indices of
    /// [`TetMesh::dense_nodes`], sorted. These are the springs of the mass-spring model.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        topology::unique_edges(self, &self.dense_nodes())
    }
}

/// Whether a tet is degenerate: its volume is negligible next to the cube of its longest edge.
/// The threshold (1e-12 relative) keeps real slivers, whose relative volume is ~1e-4 or more,
/// and rejects only tets that are flat to rounding.
fn is_degenerate(v6: f64, p: &[Point3<f64>; 4]) -> bool {
    let mut l2max: f64 = 0.0;
    for [a, b] in TET_EDGES {
        l2max = l2max.max((p[a] - p[b]).norm_squared());
    }
    !v6.is_finite() || v6.abs() <= 1e-12 * l2max * l2max.sqrt()
}

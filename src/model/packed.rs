//! The model as dense arrays, what engines consume: springs, masses and tets indexed by dense
//! node numbers, and the energies of a state.

use super::{corner_set, diff, tets, PackedTet};
use crate::error::{Error, Result};
use crate::mesh::NodeKey;

/// A spring in dense form.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackedSpring {
    /// Dense node indices, `nodes[0] < nodes[1]`.
    pub nodes: [u32; 2],
    /// Rest length, m.
    pub rest_length: f64,
    /// Stiffness, N/m.
    pub stiffness: f64,
    /// Damping along the spring, N s/m.
    pub damping: f64,
}

/// The model as dense arrays, what engines consume.
#[derive(Debug, Clone, PartialEq)]
pub struct PackedModel {
    /// The mesh node behind each dense index.
    pub node_keys: Vec<NodeKey>,
    /// Rest positions, m.
    pub rest: Vec<[f64; 3]>,
    /// Lumped masses, kg.
    pub mass: Vec<f64>,
    /// Whether each node is held at its rest position.
    pub fixed: Vec<bool>,
    /// The springs ([`PackedModel::springs`]).
    pub(super) springs: Vec<PackedSpring>,
    /// Gravity, m/s^2.
    pub gravity: [f64; 3],
    /// Mass-proportional damping, 1/s.
    pub mass_damping: f64,
    /// Where each spring is in `springs`, by end pair.
    pub(super) index: diff::SpringIndex,
    /// The tets with their region's material, in the mesh's storage order when packed: what
    /// the finite-element force models are built from. A diff ([`PackedModel::apply`]) moves the
    /// last tet into the place of each it removes and appends those it adds, as for springs.
    /// Empty for a model made from springs alone ([`PackedModel::from_springs`]).
    pub tets: Vec<PackedTet>,
    /// Where each tet is in `tets`, by its corners.
    pub(super) tet_index: tets::TetIndex,
}

impl PackedModel {
    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.rest.len()
    }

    /// Build a model directly from arrays (for tests and programs without a mesh): springs get
    /// rest lengths from `rest`.
    pub fn from_springs(
        rest: Vec<[f64; 3]>,
        mass: Vec<f64>,
        springs: &[([u32; 2], f64, f64)],
    ) -> Result<Self> {
        let n = rest.len();
        if mass.len() != n {
            return Err(Error::LengthMismatch {
                given: mass.len(),
                expected: n,
                message: format!("{} masses for {n} nodes; give one per node", mass.len()),
            });
        }
        let mut packed = Vec::with_capacity(springs.len());
        for &([a, b], k, c) in springs {
            if a as usize >= n || b as usize >= n {
                return Err(Error::NodeOutOfRange {
                    node: a.max(b) as u64,
                    count: n,
                    message: format!("spring {a}-{b} needs two distinct nodes below {n}"),
                });
            }
            if a == b {
                return Err(Error::Model(format!(
                    "spring {a}-{b} needs two distinct nodes below {n}"
                )));
            }
            let d: f64 = (0..3)
                .map(|i| (rest[a as usize][i] - rest[b as usize][i]).powi(2))
                .sum::<f64>()
                .sqrt();
            packed.push(PackedSpring {
                nodes: [a.min(b), a.max(b)],
                rest_length: d,
                stiffness: k,
                damping: c,
            });
        }
        // Sorted by end pair, as `SpringModel::pack` gives them (and to find duplicates).
        packed.sort_by_key(|s| s.nodes);
        if let Some(w) = packed.windows(2).find(|w| w[0].nodes == w[1].nodes) {
            let [a, b] = w[0].nodes;
            return Err(Error::Model(format!(
                "spring {a}-{b} is given twice; give each spring once"
            )));
        }
        Ok(PackedModel {
            tets: Vec::new(),
            tet_index: tets::TetIndex::default(),
            node_keys: vec![NodeKey::default(); n],
            fixed: vec![false; n],
            rest,
            mass,
            index: diff::SpringIndex::of(&packed),
            springs: packed,
            gravity: [0.0; 3],
            mass_damping: 0.0,
        })
    }

    /// The tet with corners `nodes` (in any order), if the model holds it.
    pub fn tet(&self, nodes: [u32; 4]) -> Option<&PackedTet> {
        match self.tet_index.get(&self.tets, nodes) {
            Some(i) => Some(&self.tets[i]),
            // The index is behind an edit in place of the public array: look it up by a scan.
            None => {
                let key = corner_set(nodes);
                self.tets.iter().find(|t| corner_set(t.nodes) == key)
            }
        }
    }

    /// Elastic energy stored in the springs at positions `x`, J.
    pub fn elastic_energy(&self, x: &[[f64; 3]]) -> f64 {
        self.springs
            .iter()
            .map(|s| {
                let (a, b) = (x[s.nodes[0] as usize], x[s.nodes[1] as usize]);
                let l =
                    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt();
                0.5 * s.stiffness * (l - s.rest_length).powi(2)
            })
            .sum()
    }

    /// Gravitational potential energy at positions `x`, J (zero at the rest positions).
    pub fn gravity_energy(&self, x: &[[f64; 3]]) -> f64 {
        let g = self.gravity;
        x.iter()
            .zip(&self.rest)
            .zip(&self.mass)
            .map(|((p, r), m)| {
                -m * ((p[0] - r[0]) * g[0] + (p[1] - r[1]) * g[1] + (p[2] - r[2]) * g[2])
            })
            .sum()
    }

    /// Kinetic energy of velocities `v`, J.
    pub fn kinetic_energy(&self, v: &[[f64; 3]]) -> f64 {
        v.iter()
            .zip(&self.mass)
            .map(|(v, m)| 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
            .sum()
    }
}

//! The tets of a corotational model as the GPU's per-tet pass reads them, in whatever node
//! layout the springs use: the tets are not in the spring layouts, so one table serves the
//! connectivity, valence and edge layouts alike, its corners numbered in the layout's node
//! order. Beside it, each node's list of the (tet, corner) force records it sums, so that the
//! node pass gathers a fixed set in a fixed order (deterministic, no atomics).
//!
//! Per tet, three rows of four floats: the shape-function gradients `b_1, b_2, b_3` of corners
//! 1..3 at rest (corner 0's is minus their sum), with `V lambda`, `2 V mu` and Rayleigh's
//! `beta` in the fourth lanes. The element force of corner `a` is then `-R (V sigma) b_a`,
//! `sigma = 2 mu eps + lambda tr(eps) I` of the rotated strain `eps = sym(R^T F) - I`: the same
//! force as `-R K_e (R^T x - X)` with `K_e` the linear tet's stiffness
//! ([`crate::physics::linear_tet`]), without storing its 144 entries. The pass and its twin are
//! `shaders/corotational_tets.wgsl` and [`crate::twin::corotational`].

use crate::model::corner_set;
use crate::physics::TetElement;

/// One row of a tet's shape: three lanes of a gradient and one constant.
pub type ShapeRow = [f32; 4];

/// The identity rotation as a quaternion `(x, y, z, w)`.
pub const IDENTITY: [f32; 4] = [0.0, 0.0, 0.0, 1.0];

/// The tets of a corotational model in a layout's node order, with each node's force records.
#[derive(Debug, Clone, PartialEq)]
pub struct TetTable {
    /// Each tet's corners, layout indices, in the model's tet order.
    pub corners: Vec<[u32; 4]>,
    /// Each tet's three shape rows (see the module documentation).
    pub shape: Vec<[ShapeRow; 3]>,
    /// Each layout node's records, `[start, end)` in `incidence`.
    pub rows: Vec<[u32; 2]>,
    /// Per node, its records `4 tet + corner`, tets ascending.
    pub incidence: Vec<u32>,
    /// Whether any tet has Rayleigh damping (the pass then reads velocities).
    pub damped: bool,
}

impl TetTable {
    /// The table of `elements` (model node indices), corners renumbered by `rank` (model index
    /// to layout index), over `node_slots` layout nodes.
    pub fn new(elements: &[TetElement], rank: &[u32], node_slots: usize) -> Self {
        let corners: Vec<[u32; 4]> = elements
            .iter()
            .map(|e| e.nodes.map(|n| rank[n as usize]))
            .collect();
        let shape = elements
            .iter()
            .map(|e| {
                let (lambda, mu) = e.lame;
                let g = |a: usize, w: f64| -> ShapeRow {
                    let b = e.gradients[a];
                    [b[0] as f32, b[1] as f32, b[2] as f32, w as f32]
                };
                [
                    g(1, e.volume * lambda),
                    g(2, 2.0 * e.volume * mu),
                    g(3, e.beta),
                ]
            })
            .collect();
        let mut count = vec![0u32; node_slots];
        for c in &corners {
            for &i in c {
                count[i as usize] += 1;
            }
        }
        let mut rows = Vec::with_capacity(node_slots);
        let mut start = 0u32;
        for &n in &count {
            rows.push([start, start]);
            start += n;
        }
        let mut incidence = vec![0u32; start as usize];
        for (t, c) in corners.iter().enumerate() {
            for (a, &i) in c.iter().enumerate() {
                let row = &mut rows[i as usize];
                incidence[row[1] as usize] = 4 * t as u32 + a as u32;
                row[1] += 1;
            }
        }
        TetTable {
            corners,
            shape,
            rows,
            incidence,
            damped: elements.iter().any(|e| e.beta != 0.0),
        }
    }

    /// Tets in the table.
    pub fn len(&self) -> usize {
        self.corners.len()
    }

    /// Whether the table holds no tet.
    pub fn is_empty(&self) -> bool {
        self.corners.is_empty()
    }

    /// Bytes of the table's arrays as uploaded (corners, shape, rows, incidence).
    pub fn bytes(&self) -> u64 {
        (self.corners.len() * 16
            + self.shape.len() * 48
            + self.rows.len() * 8
            + self.incidence.len() * 4) as u64
    }
}

/// Each tet's corners as a set, in table order (to follow a patch's removals).
pub fn corner_sets(elements: &[TetElement]) -> Vec<[u32; 4]> {
    elements.iter().map(|e| corner_set(e.nodes)).collect()
}

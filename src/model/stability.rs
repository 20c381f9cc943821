//! The stable time step of explicit integration, per node.
//!
//! Verlet (position form) and symplectic Euler are the same recurrence for a damped oscillator
//! `x'' = -w^2 x - c x'` with the velocity taken as a backward difference:
//! `x+ - 2x + x- = -w^2 h^2 x - c h (x - x-)`. Its characteristic polynomial
//! `z^2 - (2 - w^2 h^2 - c h) z + (1 - c h)` has both roots in the unit disc (Jury's test) iff
//! `w^2 h^2 + 2 c h < 4`, that is
//!
//! ```text
//! h < h(w, c) = (sqrt(c^2 + 4 w^2) - c) / w^2 = (2 / w) (sqrt(1 + xi^2) - xi),  xi = c / (2 w)
//! ```
//!
//! the central-difference bound with its damping correction (Belytschko, Liu, Moran,
//! "Nonlinear Finite Elements for Continua and Structures", 2000, section 6.2).
//!
//! For the whole model, the largest eigenvalue of `M^-1 K` is bounded by block Gershgorin
//! discs: at rest each spring contributes `k u u^T` (norm `k`) to the diagonal block of both
//! its nodes and `-k u u^T` off the diagonal, so `lambda_max <= max_i 2 sum_j k_ij / m_i`.
//! Damping `M^-1 C` is bounded the same way (`2 sum_j c_ij / m_i + alpha`). Each free node
//! gets `h_i = h(w_i, c_i)`; the bound is the smallest. Fixed nodes do not move and are left
//! out (their springs still count at their neighbours). It holds at rest and for any state
//! where no spring is compressed below half its rest length (the geometric stiffness
//! `k (1 - L/l)` stays below `k` there).

use super::PackedModel;

/// The stable time step of a model and where it comes from.
#[derive(Debug, Clone, PartialEq)]
pub struct StabilityBound {
    /// The largest stable step, s (`f64::INFINITY` if nothing can oscillate).
    pub dt: f64,
    /// The node with the smallest per-node bound.
    pub node: usize,
    /// Gershgorin bound on the highest angular frequency, rad/s.
    pub omega_max: f64,
    /// The bound of each node, s (`INFINITY` for fixed nodes).
    pub per_node: Vec<f64>,
    /// Sum of the stiffnesses of each node's springs, N/m (for a finite-element model, half
    /// its Gershgorin row sum: see [`stable_time_step_from_rows`]).
    pub k_sum: Vec<f64>,
    /// Sum of the dampings of each node's springs, N s/m.
    pub c_sum: Vec<f64>,
    /// The smallest of each block of [`BLOCK`] per-node bounds and its node, so that an update
    /// finds the smallest bound from the blocks it touched, not from every node.
    blocks: Vec<(f64, usize)>,
}

/// Nodes per block of [`StabilityBound`]'s minima.
const BLOCK: usize = 256;

/// The smallest bound of block `b` of `per_node` and its node (the first of equals).
fn block_min(per_node: &[f64], b: usize) -> (f64, usize) {
    let start = b * BLOCK;
    let (h, i) = smallest(&per_node[start..per_node.len().min(start + BLOCK)]);
    (h, start + i)
}

/// The smallest of the block minima (the first of equals, as [`smallest`] over every node).
fn smallest_block(blocks: &[(f64, usize)]) -> (f64, usize) {
    let mut best = (f64::INFINITY, 0);
    for &(h, i) in blocks {
        if h < best.0 {
            best = (h, i);
        }
    }
    best
}

/// `h(w, c)` from the module documentation.
pub fn damped_bound(omega: f64, c: f64) -> f64 {
    if omega > 0.0 {
        ((c * c + 4.0 * omega * omega).sqrt() - c) / (omega * omega)
    } else if c > 0.0 {
        2.0 / c
    } else {
        f64::INFINITY
    }
}

/// The per-node Gershgorin bound on the stable time step of `model`.
pub fn stable_time_step(model: &PackedModel) -> StabilityBound {
    let n = model.node_count();
    let mut k_sum = vec![0.0f64; n];
    let mut c_sum = vec![0.0f64; n];
    for s in &model.springs {
        for &i in &s.nodes {
            k_sum[i as usize] += s.stiffness;
            c_sum[i as usize] += s.damping;
        }
    }
    bound_from_sums(k_sum, c_sum, &model.mass, &model.fixed, model.mass_damping)
}

/// The bound of every free node from its half row sums `k_sum` (N/m) and `c_sum` (N s/m), its
/// mass and the mass damping `alpha` (1/s), with room for the nodes cuts append.
fn bound_from_sums(
    k_sum: Vec<f64>,
    c_sum: Vec<f64>,
    mass: &[f64],
    fixed: &[bool],
    mass_damping: f64,
) -> StabilityBound {
    let n = mass.len();
    let mut per_node = vec![f64::INFINITY; n];
    let mut omega_max = 0.0f64;
    for i in (0..n).filter(|&i| !fixed[i]) {
        let (h, omega) = node_bound(k_sum[i], c_sum[i], mass[i], mass_damping);
        per_node[i] = h;
        omega_max = omega_max.max(omega);
    }
    let blocks: Vec<(f64, usize)> = (0..n.div_ceil(BLOCK))
        .map(|b| block_min(&per_node, b))
        .collect();
    let (dt, node) = smallest_block(&blocks);
    // Cuts append nodes: room made now, not by moving every node's entry at the first.
    use super::room::with_room;
    StabilityBound {
        dt,
        node,
        omega_max,
        per_node: with_room(per_node),
        k_sum: with_room(k_sum),
        c_sum: with_room(c_sum),
        blocks: with_room(blocks),
    }
}

/// The per-node block-Gershgorin bound of a model whose stiffness and damping are given as
/// row sums: `stiffness_rows[i]` bounds `sum_j |K_ij|` over node `i`'s block row (N/m) and
/// `damping_rows[i]` the same for the damping matrix (N s/m), so that `M^-1 K` has no
/// eigenvalue above `max_i stiffness_rows[i] / m_i`. For springs at rest the row sum is
/// `2 sum_j k_ij` (what [`stable_time_step`] uses); the finite-element models give theirs
/// from their element blocks (`crate::physics::linear_tet::gershgorin_rows`). `k_sum` and
/// `c_sum` of the result hold half the row sums, as they would for springs. Fixed nodes are
/// left out; `mass_damping` is the model's `alpha`, 1/s.
pub fn stable_time_step_from_rows(
    stiffness_rows: &[f64],
    damping_rows: &[f64],
    mass: &[f64],
    fixed: &[bool],
    mass_damping: f64,
) -> StabilityBound {
    let k_sum = stiffness_rows.iter().map(|r| 0.5 * r).collect();
    let c_sum = damping_rows.iter().map(|r| 0.5 * r).collect();
    bound_from_sums(k_sum, c_sum, mass, fixed, mass_damping)
}

/// The bound of one free node and its Gershgorin frequency.
fn node_bound(k_sum: f64, c_sum: f64, mass: f64, alpha: f64) -> (f64, f64) {
    let omega = (2.0 * k_sum / mass).sqrt();
    let c = 2.0 * c_sum / mass + alpha;
    (damped_bound(omega, c), omega)
}

/// The smallest per-node bound and its node (the first of equals).
fn smallest(per_node: &[f64]) -> (f64, usize) {
    let (mut dt, mut node) = (f64::INFINITY, 0);
    for (i, &h) in per_node.iter().enumerate() {
        if h < dt {
            dt = h;
            node = i;
        }
    }
    (dt, node)
}

impl StabilityBound {
    /// The bound after `diff` is applied to `before` (the model this bound is of), updating
    /// only the nodes the diff touches: the same result as [`stable_time_step`] of the changed
    /// model, without going over every spring. Springs the diff names that do not exist are
    /// ignored here (applying such a diff fails anyway).
    pub fn after(&self, before: &PackedModel, diff: &super::ModelDiff) -> StabilityBound {
        let mut b = self.clone();
        b.update(before, diff);
        b
    }

    /// [`StabilityBound::after`] in place, touching only the diff's nodes (and one pass over
    /// the per-node bounds for the smallest). Returns what [`StabilityBound::undo`] needs to
    /// put the bound back, for a change that is then refused.
    pub fn update(&mut self, before: &PackedModel, diff: &super::ModelDiff) -> BoundUndo {
        self.update_with(before, diff, |k_sum, c_sum| {
            let mut add = |s: &super::PackedSpring, sign: f64| {
                for &i in &s.nodes {
                    if let (Some(k), Some(c)) =
                        (k_sum.get_mut(i as usize), c_sum.get_mut(i as usize))
                    {
                        *k += sign * s.stiffness;
                        *c += sign * s.damping;
                    }
                }
            };
            for &[a, c] in &diff.removed_springs {
                if let Some(i) = before.spring_index(a, c) {
                    add(&before.springs[i], -1.0);
                }
            }
            for s in &diff.changed_springs {
                if let Some(i) = before.spring_index(s.nodes[0], s.nodes[1]) {
                    add(&before.springs[i], -1.0);
                }
                add(s, 1.0);
            }
            for s in &diff.added_springs {
                add(s, 1.0);
            }
        })
    }

    /// [`StabilityBound::update`] with the change of the per-node stiffness and damping sums
    /// made by `change` (given the sums, already grown to the node count after the diff): how
    /// a finite-element model, whose sums come from its elements' rows, updates the bound. The
    /// diff gives the nodes touched and their new masses and fixed flags.
    pub fn update_with(
        &mut self,
        before: &PackedModel,
        diff: &super::ModelDiff,
        change: impl FnOnce(&mut [f64], &mut [f64]),
    ) -> BoundUndo {
        let n0 = before.node_count();
        let n = n0 + diff.added_nodes.len();
        let touched = diff.touched_nodes(n0);
        let undo = BoundUndo {
            len: self.per_node.len(),
            dt: self.dt,
            node: self.node,
            omega_max: self.omega_max,
            saved: touched
                .iter()
                .filter(|&&i| (i as usize) < self.per_node.len())
                .map(|&i| {
                    let i = i as usize;
                    (i, self.per_node[i], self.k_sum[i], self.c_sum[i])
                })
                .collect(),
        };
        self.per_node.resize(n, f64::INFINITY);
        self.k_sum.resize(n, 0.0);
        self.c_sum.resize(n, 0.0);
        change(&mut self.k_sum, &mut self.c_sum);
        let mut mass: std::collections::HashMap<u32, (f64, bool)> = diff
            .added_nodes
            .iter()
            .enumerate()
            .map(|(k, a)| ((n0 + k) as u32, (a.mass, a.fixed)))
            .collect();
        for c in &diff.changed_nodes {
            mass.insert(c.node, (c.mass, c.fixed));
        }
        for &i in &touched {
            let i = i as usize;
            if i >= n {
                // Out of range: applying such a diff fails, and the bound is put back.
                continue;
            }
            let (m, fixed) = mass
                .get(&(i as u32))
                .copied()
                .unwrap_or_else(|| (before.mass[i], before.fixed[i]));
            self.per_node[i] = if fixed {
                f64::INFINITY
            } else {
                let (h, omega) = node_bound(self.k_sum[i], self.c_sum[i], m, before.mass_damping);
                self.omega_max = self.omega_max.max(omega);
                h
            };
        }
        self.refresh_blocks(touched.iter().map(|&i| i as usize), undo.len);
        (self.dt, self.node) = smallest_block(&self.blocks);
        undo
    }

    /// Bring the block minima up to date after the bounds of the nodes `changed` changed and
    /// the per-node bounds, `before` long until then, took their present length.
    fn refresh_blocks(&mut self, changed: impl Iterator<Item = usize>, before: usize) {
        let n = self.per_node.len();
        let count = n.div_ceil(BLOCK);
        self.blocks.truncate(count);
        // Blocks that grew or shrank, and new ones, from the last block that was full.
        let first_partial = (before / BLOCK).min(count);
        self.blocks.resize(count, (f64::INFINITY, 0));
        let mut dirty: Vec<usize> = changed
            .filter(|&i| i < n)
            .map(|i| i / BLOCK)
            .chain(first_partial..count)
            .collect();
        dirty.sort_unstable();
        dirty.dedup();
        for b in dirty {
            self.blocks[b] = block_min(&self.per_node, b);
        }
    }

    /// Put the bound back as it was before the [`StabilityBound::update`] that gave `undo`.
    pub fn undo(&mut self, undo: BoundUndo) {
        for &(i, h, k, c) in &undo.saved {
            self.per_node[i] = h;
            self.k_sum[i] = k;
            self.c_sum[i] = c;
        }
        let grown = self.per_node.len();
        self.per_node.truncate(undo.len);
        self.k_sum.truncate(undo.len);
        self.c_sum.truncate(undo.len);
        self.refresh_blocks(undo.saved.iter().map(|s| s.0), grown.min(undo.len));
        (self.dt, self.node, self.omega_max) = (undo.dt, undo.node, undo.omega_max);
    }
}

/// What [`StabilityBound::undo`] restores: the bound's scalars, its length and the touched
/// nodes' entries.
#[derive(Debug, Clone)]
pub struct BoundUndo {
    len: usize,
    dt: f64,
    node: usize,
    omega_max: f64,
    saved: Vec<(usize, f64, f64, f64)>,
}

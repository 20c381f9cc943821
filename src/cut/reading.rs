//! The current positions a cut reads. A cut only looks at the tissue near the blade, so it asks
//! its [`PositionSource`] for the nodes in a box around the sweep (on the GPU, one pass over the
//! nodes and a readback of just those) instead of every node's position, then for the few
//! nodes around its candidates that the box missed (tissue stretched further than the box
//! allowed for). What it read sits in a [`ReadPositions`]: an array over every node, valid only where
//! this cut read, which is all the cut and [`crate::Simulation::apply_at`] look at.

use nalgebra::Point3;

pub use crate::engine::reading::{float32_box, inside, sort_by_node, AllPositions, PositionSource};
use crate::error::{Error, Result};
/// The positions one cut read: `at` has an entry per node (dense order, as many as the mesh
/// had when the cut began), valid where `known` carries the cut's stamp.
#[derive(Debug, Clone, Default)]
pub struct ReadPositions {
    at: Vec<[f64; 3]>,
    /// Where the cut classifies each node read: its position, or its rest position when it is
    /// within the snap distance of it (see [`super::SNAP_RELATIVE`]); worked out once per node
    /// read, not at every corner of every tet looked at.
    class: Vec<Point3<f64>>,
    /// Every node read, in the order read (the box, then what the box missed).
    read: Vec<u32>,
    /// How many of `read` have their classification position.
    settled: usize,
    known: Vec<u32>,
    stamp: u32,
    /// How many of `read` came from the box around the sweep (the first ones).
    near: usize,
    /// Bounds of the classification displacements (classification position less rest) of the
    /// nodes settled: see [`ReadPositions::displacement_spread`].
    moved_lo: [f64; 3],
    moved_hi: [f64; 3],
}

impl ReadPositions {
    /// Arrays for a mesh of `nodes` nodes, with room for the nodes cuts add
    /// ([`crate::model::room::spare`]), written once: made with the cutter, so that its first
    /// cut does not pay for them (the kernel's first touch of every page: milliseconds on a
    /// mesh of a few hundred thousand nodes), nor an early cut for moving them all when the
    /// mesh grows past them.
    pub(super) fn for_nodes(nodes: usize) -> Self {
        let room = nodes + crate::model::room::spare(nodes);
        let mut r = ReadPositions {
            at: Vec::with_capacity(room),
            class: Vec::with_capacity(room),
            known: Vec::with_capacity(room),
            ..Default::default()
        };
        r.begin(nodes);
        r
    }

    /// Start a new cut over `nodes` nodes: nothing is known.
    pub(super) fn begin(&mut self, nodes: usize) {
        // What the last cut read is forgotten, not left stale: a node this cut did not read
        // holds NaN, so a use of it shows (a non-finite energy, a failed comparison) instead of
        // giving a plausible wrong answer.
        let nan = Point3::new(f64::NAN, f64::NAN, f64::NAN);
        for &i in &self.read {
            self.at[i as usize] = [f64::NAN; 3];
            self.class[i as usize] = nan;
        }
        self.at.resize(nodes, [f64::NAN; 3]);
        self.at.truncate(nodes);
        self.class.resize(nodes, nan);
        self.class.truncate(nodes);
        self.read.clear();
        self.settled = 0;
        self.known.resize(nodes, 0);
        self.known.truncate(nodes);
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            // Wrapped: old stamps could equal the new one.
            self.known.fill(0);
            self.stamp = 1;
        }
        self.near = 0;
        self.moved_lo = [f64::INFINITY; 3];
        self.moved_hi = [f64::NEG_INFINITY; 3];
    }

    /// Take what the source gave for the box.
    pub(super) fn take_near(&mut self, read: Vec<(u32, [f64; 3])>) -> Result<()> {
        for (i, p) in read {
            self.set(i, p)?;
        }
        self.near = self.read.len();
        Ok(())
    }

    /// Read the nodes of `needed` not known yet from `source`.
    pub(super) fn complete(
        &mut self,
        needed: impl IntoIterator<Item = u32>,
        source: &mut dyn PositionSource,
    ) -> Result<()> {
        let mut missing: Vec<u32> = needed.into_iter().filter(|&i| !self.knows(i)).collect();
        if missing.is_empty() {
            return Ok(());
        }
        missing.sort_unstable();
        missing.dedup();
        let got = source.of(&missing)?;
        if got.len() != missing.len() {
            return Err(Error::LengthMismatch {
                given: got.len(),
                expected: missing.len(),
                message: format!("{} positions read for {} nodes", got.len(), missing.len()),
            });
        }
        for (&i, p) in missing.iter().zip(got) {
            self.set(i, p)?;
        }
        Ok(())
    }

    fn set(&mut self, i: u32, p: [f64; 3]) -> Result<()> {
        let n = self.at.len();
        let (Some(slot), Some(k)) = (self.at.get_mut(i as usize), self.known.get_mut(i as usize))
        else {
            return Err(Error::NodeOutOfRange {
                node: i as u64,
                count: n,
                message: format!("a position was read for node {i} of a mesh of {n} nodes"),
            });
        };
        // A node given twice (a source may) is read once: the cut counts what it read.
        if *k != self.stamp {
            *slot = p;
            *k = self.stamp;
            self.read.push(i);
        }
        Ok(())
    }

    /// Work out the classification position of every node read since the last call: its
    /// position, or `rest(i)` where that lies within `sqrt(snap2)` of it.
    pub(super) fn settle(&mut self, rest: impl Fn(u32) -> Point3<f64>, snap2: f64) {
        for &i in &self.read[self.settled..] {
            let (x, r) = (Point3::from(self.at[i as usize]), rest(i));
            let class = if (x - r).norm_squared() <= snap2 {
                r
            } else {
                x
            };
            self.class[i as usize] = class;
            for c in 0..3 {
                let u = class[c] - r[c];
                self.moved_lo[c] = self.moved_lo[c].min(u);
                self.moved_hi[c] = self.moved_hi[c].max(u);
            }
        }
        self.settled = self.read.len();
    }

    /// How far apart the classification displacements (classification position less rest) of
    /// the nodes settled so far can be: the diagonal of their bounds (0 before any). An edge
    /// between two of them is at most this much longer at its classification positions than
    /// at rest, so a tet whose corners were all read is at most its rest diameter plus this
    /// across: how near the blade the cut must look for the tets it meets.
    pub(super) fn displacement_spread(&self) -> f64 {
        (0..3)
            .map(|c| (self.moved_hi[c] - self.moved_lo[c]).max(0.0).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// The bounds, per axis, of the classification displacements of the nodes settled so far
    /// (`None` before any).
    pub(super) fn displacement_bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        (self.settled > 0).then_some((self.moved_lo, self.moved_hi))
    }

    /// The classification position of node `i` (read and settled by this cut).
    pub(super) fn class(&self, i: u32) -> Point3<f64> {
        debug_assert!(self.knows(i), "node {i} was not read");
        self.class[i as usize]
    }

    /// The nodes read in the box around the sweep.
    pub fn near(&self) -> &[u32] {
        &self.read[..self.near]
    }

    /// Every node read so far, in the order read.
    pub fn all(&self) -> &[u32] {
        &self.read
    }

    /// How many nodes were read afterwards because the box missed them.
    pub fn fetched(&self) -> usize {
        self.read.len() - self.near
    }

    /// Whether this cut read node `i`.
    pub fn knows(&self, i: u32) -> bool {
        self.known.get(i as usize) == Some(&self.stamp)
    }

    /// Positions of every node the mesh had when the cut began, valid only at the nodes this
    /// cut read (the others hold NaN): what the cut classified with, to hand to
    /// [`crate::Simulation::apply_at`].
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.at
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_positions_lists_the_nodes_in_the_box_and_refuses_unknown_ones() {
        let x = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.5, 0.5]];
        let mut s = AllPositions(&x);
        let mut near = s.near([0.4, -1.0, -1.0], [1.0, 1.0, 1.0]).unwrap();
        near.sort_by_key(|e| e.0);
        assert_eq!(near, vec![(1, x[1]), (2, x[2])]);
        assert!(s.of(&[3]).is_err());
    }

    #[test]
    fn nodes_found_are_sorted_by_node_with_their_positions() {
        let mut found: Vec<(u32, [f64; 3])> = [7u32, 3, 9, 0, 5]
            .iter()
            .map(|&i| (i, [i as f64, -(i as f64), 0.5 * i as f64]))
            .collect();
        sort_by_node(&mut found);
        let nodes: Vec<u32> = found.iter().map(|e| e.0).collect();
        assert_eq!(nodes, vec![0, 3, 5, 7, 9]);
        assert!(found
            .iter()
            .all(|(i, p)| *p == [*i as f64, -(*i as f64), 0.5 * *i as f64]));
    }

    #[test]
    fn a_new_cut_forgets_what_the_last_one_read() {
        let x = [[0.0; 3], [1.0; 3]];
        let mut r = ReadPositions::default();
        r.begin(2);
        r.take_near(vec![(0, x[0])]).unwrap();
        r.complete([0, 1], &mut AllPositions(&x)).unwrap();
        assert!(r.knows(0) && r.knows(1));
        assert_eq!(r.fetched(), 1);
        r.begin(3);
        assert!(!r.knows(0) && !r.knows(1) && !r.knows(2));
        assert!(r.take_near(vec![(3, x[0])]).is_err());
    }

    /// A node a source gives twice is read once (with its first position): the cut counts
    /// the nodes it read in a region (`Cutter::pulled_out`), and a repeat would stand in for
    /// a node it did not read.
    #[test]
    fn a_node_given_twice_is_read_once() {
        let mut r = ReadPositions::default();
        r.begin(3);
        r.take_near(vec![(1, [1.0; 3]), (2, [2.0; 3]), (1, [9.0; 3])])
            .unwrap();
        assert_eq!(r.all(), &[1, 2]);
        assert_eq!(r.near(), &[1, 2]);
        assert_eq!(r.positions()[1], [1.0; 3]);
        r.complete(
            [0, 1, 0],
            &mut AllPositions(&[[0.5; 3], [7.0; 3], [8.0; 3]]),
        )
        .unwrap();
        assert_eq!(r.all(), &[1, 2, 0]);
        assert_eq!(r.fetched(), 1);
    }

    /// The spread is the diagonal of the bounds of the classification displacements of the
    /// nodes settled: a node within the snap distance of rest counts as not displaced, and a
    /// new cut starts from nothing.
    #[test]
    fn the_displacement_spread_bounds_the_classified_displacements() {
        let rest = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        // Displaced by (0.3, 0, 0), (0, -0.4, 0) and, within the snap distance, (1e-4, 0, 0).
        let x = [[0.3, 0.0, 0.0], [1.0, -0.4, 0.0], [1e-4, 1.0, 0.0]];
        let at_rest = |i: u32| Point3::from(rest[i as usize]);
        let mut r = ReadPositions::default();
        r.begin(3);
        assert_eq!(r.displacement_spread(), 0.0);
        r.take_near(vec![(0, x[0]), (2, x[2])]).unwrap();
        r.settle(at_rest, 1e-6);
        // (0.3, 0, 0) and the snapped (0, 0, 0).
        assert!((r.displacement_spread() - 0.3).abs() < 1e-12);
        r.complete([1], &mut AllPositions(&x)).unwrap();
        r.settle(at_rest, 1e-6);
        let want = (0.3f64.powi(2) + 0.4f64.powi(2)).sqrt();
        assert!((r.displacement_spread() - want).abs() < 1e-12);
        r.begin(3);
        assert_eq!(r.displacement_spread(), 0.0);
    }
}

//! The nodes by rest position: what a cut asks to find tissue pulled out of the box it read.
//!
//! The box a cut reads around its sweep holds every node whose *current* position lies in it.
//! A node whose rest position lies well inside the box, and which was not read, was moved
//! further than the tissue read near it (a grasper pulling one node out of otherwise quiet
//! tissue): its tets may stretch across the sweep from outside the box, and the cut reads it.
//! Finding those nodes is a box query over rest positions, which never change, at every cut:
//! a uniform grid of cells about a rest edge wide answers it by visiting the few hundred nodes
//! in the box, in cell order. (An R-tree, `rstar`, which the narrow phase already pulls in,
//! took ten times as long for these queries, a tenth of a cut.) Nodes a cut adds go to a
//! small map per cell.

use rustc_hash::FxHashMap;

use nalgebra::Point3;

/// A node in the grid: its dense index and rest position.
type Entry = (u32, [f64; 3]);

/// Dense node indices by rest position.
#[derive(Debug, Clone, Default)]
pub struct RestIndex {
    origin: [f64; 3],
    /// Cell width, m (positive where there are nodes).
    cell: f64,
    dims: [usize; 3],
    /// The nodes present when the index was made, by cell (x fastest): cell `c` holds
    /// `entries[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    entries: Vec<Entry>,
    /// Nodes added since, by cell.
    added: FxHashMap<usize, Vec<Entry>>,
}

impl RestIndex {
    /// The index of `rest` (dense order: node `i` at `rest[i]`), with cells about `width`
    /// wide (the mesh's longest rest edge; wider where that would make more cells than four
    /// per node).
    pub fn of(rest: &[Point3<f64>], width: f64) -> Self {
        let Some(first) = rest.first() else {
            return RestIndex::default();
        };
        let (lo, hi) = rest
            .iter()
            .fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        let extent = hi - lo;
        let most = 4.0 * rest.len() as f64 + 64.0;
        let mut cell = if width.is_finite() && width > 0.0 {
            width
        } else {
            extent.max().max(1e-9)
        };
        let count = |cell: f64| extent.map(|e| (e / cell).floor() + 1.0).product();
        while count(cell) > most {
            cell *= 1.25;
        }
        let dims = [0, 1, 2].map(|c| (extent[c] / cell) as usize + 1);
        let mut index = RestIndex {
            origin: [lo.x, lo.y, lo.z],
            cell,
            dims,
            ..Default::default()
        };
        let cells: Vec<usize> = rest
            .iter()
            .map(|p| index.cell_of(&[p.x, p.y, p.z]))
            .collect();
        let mut start = vec![0u32; dims.iter().product::<usize>() + 1];
        for &c in &cells {
            start[c + 1] += 1;
        }
        for c in 1..start.len() {
            start[c] += start[c - 1];
        }
        let mut fill = start.clone();
        let mut entries = vec![(0, [0.0; 3]); rest.len()];
        for (i, (&c, p)) in cells.iter().zip(rest).enumerate() {
            entries[fill[c] as usize] = (i as u32, [p.x, p.y, p.z]);
            fill[c] += 1;
        }
        index.start = start;
        index.entries = entries;
        index
    }

    /// The cell holding `p`, clamped to the grid (nodes a cut adds lie within the mesh's
    /// bounds, on its edges or at its nodes; one outside would sit in a border cell, which a
    /// query reaching past the grid visits, and the exact test decides).
    fn cell_of(&self, p: &[f64; 3]) -> usize {
        let at = |c: usize| self.axis(c, p[c]);
        at(0) + self.dims[0] * (at(1) + self.dims[1] * at(2))
    }

    /// The cell column along axis `c` holding coordinate `v`, clamped to the grid.
    fn axis(&self, c: usize, v: f64) -> usize {
        let k = ((v - self.origin[c]) / self.cell).floor();
        if k.is_nan() || k < 0.0 {
            0
        } else {
            (k as usize).min(self.dims[c] - 1)
        }
    }

    /// Add node `i` at rest position `p`.
    pub fn insert(&mut self, i: u32, p: Point3<f64>) {
        if self.start.is_empty() {
            // An index of no nodes: the first one makes the grid.
            *self = RestIndex::of(&[p], self.cell);
            self.entries[0].0 = i;
            return;
        }
        let q = [p.x, p.y, p.z];
        let c = self.cell_of(&q);
        self.added.entry(c).or_default().push((i, q));
    }

    /// How many nodes have their rest position in the box `lo..=hi`: with a count of the nodes
    /// a cut read there, whether it read them all, without looking each up.
    pub fn count_within(&self, lo: [f64; 3], hi: [f64; 3]) -> usize {
        let mut n = 0;
        self.visit(lo, hi, |_| n += 1);
        n
    }

    /// Every node whose rest position lies in the box `lo..=hi`, in no order (none where the
    /// box is empty), for which `keep` holds.
    pub fn within(
        &self,
        lo: [f64; 3],
        hi: [f64; 3],
        mut keep: impl FnMut(u32) -> bool,
    ) -> Vec<u32> {
        let mut out = Vec::new();
        self.visit(lo, hi, |i| {
            if keep(i) {
                out.push(i);
            }
        });
        out
    }

    /// Call `f` with every node whose rest position lies in the box `lo..=hi`.
    fn visit(&self, lo: [f64; 3], hi: [f64; 3], mut f: impl FnMut(u32)) {
        if self.start.is_empty() || !(0..3).all(|c| lo[c] <= hi[c]) {
            return;
        }
        let a = [0, 1, 2].map(|c| self.axis(c, lo[c]));
        let b = [0, 1, 2].map(|c| self.axis(c, hi[c]));
        let inside = |p: &[f64; 3]| (0..3).all(|c| p[c] >= lo[c] && p[c] <= hi[c]);
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                let row = self.dims[0] * (y + self.dims[1] * z);
                // A row of cells along x is one run of entries.
                let run = self.start[row + a[0]] as usize..self.start[row + b[0] + 1] as usize;
                for &(i, p) in &self.entries[run] {
                    if inside(&p) {
                        f(i);
                    }
                }
                if self.added.is_empty() {
                    continue;
                }
                for x in a[0]..=b[0] {
                    for &(i, p) in self.added.get(&(row + x)).into_iter().flatten() {
                        if inside(&p) {
                            f(i);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(all: &[Point3<f64>], lo: [f64; 3], hi: [f64; 3]) -> Vec<u32> {
        all.iter()
            .enumerate()
            .filter(|(_, p)| (0..3).all(|c| p[c] >= lo[c] && p[c] <= hi[c]))
            .map(|(i, _)| i as u32)
            .collect()
    }

    /// Random boxes over scattered nodes, added ones included, against a scan of every node.
    #[test]
    fn finds_exactly_the_nodes_at_rest_in_a_box_including_added_ones() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut all: Vec<Point3<f64>> = (0..2000)
            .map(|_| Point3::new(next() * 0.1, next() * 0.05, next() * 0.02))
            .collect();
        let mut index = RestIndex::of(&all, 0.004);
        for _ in 0..300 {
            let p = Point3::new(next() * 0.1, next() * 0.05, next() * 0.02);
            index.insert(all.len() as u32, p);
            all.push(p);
        }
        let mut found = 0;
        for _ in 0..200 {
            let c = [
                next() * 0.12 - 0.01,
                next() * 0.06 - 0.005,
                next() * 0.03 - 0.005,
            ];
            let r = [next() * 0.02, next() * 0.02, next() * 0.01];
            let (lo, hi) = (
                [0, 1, 2].map(|k| c[k] - r[k]),
                [0, 1, 2].map(|k| c[k] + r[k]),
            );
            let mut got = index.within(lo, hi, |_| true);
            got.sort_unstable();
            assert_eq!(got, brute(&all, lo, hi));
            found += got.len();
            // `keep` filters.
            let odd = index.within(lo, hi, |i| i % 2 == 1);
            assert_eq!(odd.len(), got.iter().filter(|&&i| i % 2 == 1).count());
            assert_eq!(index.count_within(lo, hi), got.len());
        }
        assert!(found > 1000, "the boxes held only {found} nodes");
        assert!(index
            .within([0.05, 0.0, 0.0], [0.04, 1.0, 1.0], |_| true)
            .is_empty());
    }

    #[test]
    fn an_index_of_no_nodes_takes_added_ones() {
        let mut index = RestIndex::of(&[], 0.01);
        assert!(index.within([-1.0; 3], [1.0; 3], |_| true).is_empty());
        index.insert(7, Point3::new(0.1, 0.2, 0.3));
        index.insert(8, Point3::new(0.1, 0.2, 0.3));
        let mut got = index.within([0.0; 3], [1.0; 3], |_| true);
        got.sort_unstable();
        assert_eq!(got, vec![7, 8]);
    }
}

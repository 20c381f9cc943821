//! A uniform grid over axis-aligned boxes (tets, boundary faces), so that binding a surface
//! vertex tests the few items near it instead of every item: O(V + T) to embed, not O(V T).
//! Cells are about the size of a mean item, so an item lies in a handful of cells.

/// Items (by index) bucketed by the grid cells their boxes overlap.
#[derive(Debug, Clone)]
pub struct Grid {
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// `items[start[c]..start[c + 1]]` overlap cell `c`.
    start: Vec<u32>,
    items: Vec<u32>,
}

/// Cells at most, per item: a grid of tiny items spread far apart stays bounded.
const CELLS_PER_ITEM: usize = 8;

impl Grid {
    /// A grid over `boxes` (`lo`, `hi` each), cells about the mean box's largest side.
    pub fn new(boxes: &[([f64; 3], [f64; 3])]) -> Self {
        let Some(first) = boxes.first() else {
            return Grid {
                lo: [0.0; 3],
                cell: 1.0,
                dims: [1; 3],
                start: vec![0, 0],
                items: Vec::new(),
            };
        };
        let (mut lo, mut hi) = *first;
        let mut side = 0.0;
        for (a, b) in boxes {
            for c in 0..3 {
                lo[c] = lo[c].min(a[c]);
                hi[c] = hi[c].max(b[c]);
            }
            side += (0..3).map(|c| b[c] - a[c]).fold(0.0, f64::max);
        }
        let extent = (0..3).map(|c| hi[c] - lo[c]).fold(0.0, f64::max);
        let mut cell = (side / boxes.len() as f64)
            .max(extent * 1e-6)
            .max(f64::MIN_POSITIVE);
        let dims_for = |cell: f64| [0, 1, 2].map(|c| ((hi[c] - lo[c]) / cell) as usize + 1);
        let mut dims = dims_for(cell);
        while dims.iter().product::<usize>() > CELLS_PER_ITEM * boxes.len() + 64 {
            cell *= 1.5;
            dims = dims_for(cell);
        }
        let mut grid = Grid {
            lo,
            cell,
            dims,
            start: Vec::new(),
            items: Vec::new(),
        };
        // Count, then fill (a compressed row per cell).
        let mut count = vec![0u32; dims.iter().product::<usize>() + 1];
        for b in boxes {
            grid.for_cells(b.0, b.1, |c| count[c + 1] += 1);
        }
        for c in 1..count.len() {
            count[c] += count[c - 1];
        }
        let mut fill = count.clone();
        grid.items = vec![0; *count.last().unwrap_or(&0) as usize];
        for (i, b) in boxes.iter().enumerate() {
            let (lo_c, hi_c) = (grid.clamped(b.0), grid.clamped(b.1));
            let items = &mut grid.items;
            for z in lo_c[2]..=hi_c[2] {
                for y in lo_c[1]..=hi_c[1] {
                    for x in lo_c[0]..=hi_c[0] {
                        let c = x + dims[0] * (y + dims[1] * z);
                        items[fill[c] as usize] = i as u32;
                        fill[c] += 1;
                    }
                }
            }
        }
        grid.start = count;
        grid
    }

    /// The cell holding `p`, clamped into the grid.
    fn clamped(&self, p: [f64; 3]) -> [usize; 3] {
        [0, 1, 2].map(|c| {
            let k = ((p[c] - self.lo[c]) / self.cell).floor();
            (k.max(0.0) as usize).min(self.dims[c] - 1)
        })
    }

    /// Call `f` with every cell index overlapping the box `lo..=hi` (clamped into the grid).
    fn for_cells(&self, lo: [f64; 3], hi: [f64; 3], mut f: impl FnMut(usize)) {
        let (a, b) = (self.clamped(lo), self.clamped(hi));
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    f(x + self.dims[0] * (y + self.dims[1] * z));
                }
            }
        }
    }

    /// Items whose boxes overlap the cell holding `p` (a point outside the grid gets the
    /// nearest cell's: a superset of the items that can hold it, which is none).
    pub fn at(&self, p: [f64; 3]) -> &[u32] {
        let c = self.clamped(p);
        let i = c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2]);
        &self.items[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// The item nearest `p` by `distance` (any distance that is at least the distance from `p`
    /// to the item's box), with that distance; `None` without items. Searches boxes of growing
    /// radius around `p` until the nearest item found lies within the radius searched.
    pub fn nearest(&self, p: [f64; 3], mut distance: impl FnMut(u32) -> f64) -> Option<(u32, f64)> {
        if self.items.is_empty() {
            return None;
        }
        // Far enough to cover the whole grid from p.
        let span = (0..3)
            .map(|c| {
                let far = self.lo[c] + self.cell * self.dims[c] as f64;
                (p[c] - self.lo[c]).abs().max((far - p[c]).abs())
            })
            .fold(0.0, f64::max);
        let mut r = self.cell;
        let mut seen = Vec::new();
        loop {
            seen.clear();
            self.for_cells(p.map(|v| v - r), p.map(|v| v + r), |c| {
                seen.extend_from_slice(
                    &self.items[self.start[c] as usize..self.start[c + 1] as usize],
                )
            });
            seen.sort_unstable();
            seen.dedup();
            let best = seen
                .iter()
                .map(|&i| (i, distance(i)))
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            match best {
                // Every item within r of p overlaps the searched box, so none is nearer.
                Some(b) if b.1 <= r || r > span => return Some(b),
                _ if r > span => return None,
                _ => r *= 2.0,
            }
        }
    }
}

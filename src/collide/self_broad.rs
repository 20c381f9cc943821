//! Broad phase, tissue against itself: pairs of boundary triangles whose margin-widened boxes
//! overlap and that share no node (a cut that opens and closes, a fold). A spatial hash of a
//! uniform grid: every triangle is counted into the buckets of the cells its box overlaps, the
//! counts are prefix-summed into bucket offsets, the triangles scattered into an entry list,
//! and each triangle tests the later triangles in its buckets. A pair is reported only from the
//! cell holding the lower corner of the two boxes' intersection, so once. The GPU passes are
//! `shaders/self_*.wgsl` and `shaders/scan_*.wgsl` (`engine::gpu::broad_self`);
//! `twin::broad_self::self_pairs_cpu` is their twin and [`self_pairs_exact`] the brute-force float64 answer.

use bytemuck::{Pod, Zeroable};

/// Cells a box may span per axis; a box spanning more makes the pass report that the cell is
/// too small (the host then doubles it).
pub const MAX_SPAN: i32 = 2;

/// Grid and output parameters. Mirrors `struct GridParams` in `shaders/self_grid.wgsl`
/// (32 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct GridParams {
    /// Triangles in the surface.
    pub triangles: u32,
    /// Hash buckets, a power of two (a multiple of 256).
    pub table: u32,
    /// `1 / cell size`, 1/m.
    pub inv_cell: f32,
    /// Each triangle's box is widened by this on every side, m.
    pub half_margin: f32,
    /// Pairs the output buffer holds.
    pub capacity: u32,
    /// Invocations per dispatch row.
    pub row: u32,
    /// `table / 256`.
    pub blocks: u32,
    /// Padding to 32 bytes.
    pub pad: u32,
}

const _: () = assert!(std::mem::size_of::<GridParams>() == 32);

impl GridParams {
    /// A grid for `triangles` at rest positions `rest` (float64, indexed by the triangles'
    /// nodes) reporting pairs within `margin` (m) of each other box-wise: cells 1.5 times the
    /// largest widened box at rest (so that a box spans at most two cells per axis until the
    /// tissue stretches by half), a table of twice as many buckets as triangles. The half margin
    /// is widened by four float32 epsilons of the largest coordinate so that the float32 boxes
    /// contain the float64 ones.
    pub fn for_surface(rest: &[[f64; 3]], triangles: &[[u32; 3]], margin: f64) -> Self {
        let mut extent: f64 = 0.0;
        let mut magnitude: f64 = 0.0;
        for t in triangles {
            let [a, b, c] = t.map(|i| rest[i as usize]);
            for ((a, b), c) in a.iter().zip(&b).zip(&c) {
                let (lo, hi) = (a.min(*b).min(*c), a.max(*b).max(*c));
                extent = extent.max(hi - lo);
                magnitude = magnitude.max(lo.abs()).max(hi.abs());
            }
        }
        let half_margin = 0.5 * margin + 4.0 * f32::EPSILON as f64 * magnitude;
        let cell = (1.5 * (extent + 2.0 * half_margin)).max(1e-9);
        let table = (2 * triangles.len()).next_power_of_two().max(256) as u32;
        GridParams {
            triangles: triangles.len() as u32,
            table,
            inv_cell: (1.0 / cell) as f32,
            half_margin: half_margin as f32,
            capacity: 0,
            row: 0,
            blocks: table / 256,
            pad: 0,
        }
    }
}

/// Whether two triangles share a corner node (such pairs are never reported).
pub fn shares_node(a: [u32; 3], b: [u32; 3]) -> bool {
    a.iter().any(|x| b.contains(x))
}

/// Every pair of triangles sharing no node whose float64 boxes, widened by `margin / 2` on
/// every side, overlap: the brute-force answer (quadratic; for tests).
pub fn self_pairs_exact(
    positions: &[[f64; 3]],
    triangles: &[[u32; 3]],
    margin: f64,
) -> Vec<[u32; 2]> {
    let m = 0.5 * margin;
    let boxes: Vec<_> = triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| positions[i as usize]);
            (
                [0, 1, 2].map(|k| p[0][k].min(p[1][k]).min(p[2][k]) - m),
                [0, 1, 2].map(|k| p[0][k].max(p[1][k]).max(p[2][k]) + m),
            )
        })
        .collect();
    let mut out = Vec::new();
    for t in 0..triangles.len() {
        for u in t + 1..triangles.len() {
            if shares_node(triangles[t], triangles[u]) {
                continue;
            }
            let ((lo, hi), (lo2, hi2)) = (boxes[t], boxes[u]);
            if (0..3).all(|k| lo[k] <= hi2[k] && lo2[k] <= hi[k]) {
                out.push([t as u32, u as u32]);
            }
        }
    }
    out
}

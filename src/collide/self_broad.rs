//! Broad phase, tissue against itself: pairs of boundary triangles whose margin-widened boxes
//! overlap and that share no node (a cut that opens and closes, a fold). A spatial hash of a
//! uniform grid: every triangle is counted into the buckets of the cells its box overlaps, the
//! counts are prefix-summed into bucket offsets, the triangles scattered into an entry list,
//! and each triangle tests the later triangles in its buckets. A pair is reported only from the
//! cell holding the lower corner of the two boxes' intersection, so once. The GPU passes are
//! `shaders/self_*.wgsl` and `shaders/scan_*.wgsl` (`engine::gpu::broad_self`);
//! [`self_pairs_cpu`] is their twin and [`self_pairs_exact`] the brute-force float64 answer.

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

/// Float32 widened box of triangle `t` at `rest + disp`, as the passes compute it.
fn widened_box(rest: &[[f32; 4]], disp: &[[f32; 4]], t: [u32; 3], m: f32) -> ([f32; 3], [f32; 3]) {
    let p = t.map(|i| {
        let (r, u) = (rest[i as usize], disp[i as usize]);
        [r[0] + u[0], r[1] + u[1], r[2] + u[2]]
    });
    let lo = [0, 1, 2].map(|k| p[0][k].min(p[1][k]).min(p[2][k]) - m);
    let hi = [0, 1, 2].map(|k| p[0][k].max(p[1][k]).max(p[2][k]) + m);
    (lo, hi)
}

/// The grid cell of a point, as `cell_of` in the shader.
fn cell_of(p: [f32; 3], inv_cell: f32) -> [i32; 3] {
    p.map(|x| (x * inv_cell).floor() as i32)
}

/// The hash bucket of a cell, as `hash_cell` in the shader.
pub fn hash_cell(c: [i32; 3], table: u32) -> u32 {
    let h = c[0].wrapping_mul(73856093) ^ c[1].wrapping_mul(19349663) ^ c[2].wrapping_mul(83492791);
    (h as u32) & (table - 1)
}

/// The cells (inclusive ranges) a widened box overlaps, or `None` when it spans more than
/// [`MAX_SPAN`] per axis.
fn cell_range(lo: [f32; 3], hi: [f32; 3], inv_cell: f32) -> Option<([i32; 3], [i32; 3])> {
    let (c0, c1) = (cell_of(lo, inv_cell), cell_of(hi, inv_cell));
    (0..3).all(|k| c1[k] - c0[k] < MAX_SPAN).then_some((c0, c1))
}

fn cells(c0: [i32; 3], c1: [i32; 3]) -> impl Iterator<Item = [i32; 3]> {
    (c0[2]..=c1[2]).flat_map(move |z| {
        (c0[1]..=c1[1]).flat_map(move |y| (c0[0]..=c1[0]).map(move |x| [x, y, z]))
    })
}

/// The pairs (t < u) the GPU passes report, sorted; `None` when a box spans more than
/// [`MAX_SPAN`] cells per axis (the cell is too small for the deformed surface). `rest` and
/// `disp` are float32 positions indexed by the triangles' nodes.
pub fn self_pairs_cpu(
    grid: &GridParams,
    rest: &[[f32; 4]],
    disp: &[[f32; 4]],
    triangles: &[[u32; 3]],
) -> Option<Vec<[u32; 2]>> {
    let boxes: Vec<_> = triangles
        .iter()
        .map(|&t| widened_box(rest, disp, t, grid.half_margin))
        .collect();
    let ranges: Vec<_> = boxes
        .iter()
        .map(|&(lo, hi)| cell_range(lo, hi, grid.inv_cell))
        .collect::<Option<_>>()?;
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); grid.table as usize];
    for (t, &(c0, c1)) in ranges.iter().enumerate() {
        for c in cells(c0, c1) {
            buckets[hash_cell(c, grid.table) as usize].push(t as u32);
        }
    }
    let mut out = Vec::new();
    for (t, &(c0, c1)) in ranges.iter().enumerate() {
        let (lo, hi) = boxes[t];
        for c in cells(c0, c1) {
            for &u in &buckets[hash_cell(c, grid.table) as usize] {
                if u as usize <= t || shares_node(triangles[t], triangles[u as usize]) {
                    continue;
                }
                let (lo2, hi2) = boxes[u as usize];
                if (0..3).any(|k| hi[k] < lo2[k] || hi2[k] < lo[k]) {
                    continue;
                }
                let corner = [0, 1, 2].map(|k| lo[k].max(lo2[k]));
                if cell_of(corner, grid.inv_cell) == c {
                    out.push([t as u32, u]);
                }
            }
        }
    }
    out.sort_unstable();
    Some(out)
}

fn shares_node(a: [u32; 3], b: [u32; 3]) -> bool {
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

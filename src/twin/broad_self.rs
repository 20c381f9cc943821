//! Twin of the self-contact broad phase (pass `engine::gpu::broad_self`: `shaders/self_count`,
//! `scan_blocks`, `scan_top`, `scan_apply`, `self_scatter` and `self_pairs.wgsl`, sharing
//! `self_grid.wgsl`): the spatial hash that finds pairs of surface triangles near each other,
//! as one function over its final output (the prefix sum and the scatter only arrange the
//! buckets, whose contents the twin keeps as lists). Also the self-contact broad phase of the
//! CPU engines (`Simulation::cull_self`).

use crate::collide::self_broad::{shares_node, GridParams, MAX_SPAN};

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

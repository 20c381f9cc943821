//! Which elements a sweep cuts, from the tissue's current (deformed) positions: tets the sweep
//! meets (carving) and inside faces whose two tets it separates (splitting along faces).
//!
//! Classification is done where the blade is, in the deformed state; what it decides is
//! topological (which tets go, which faces open), so applying it to the rest mesh cuts the
//! material the blade actually passed through.

use nalgebra::Point3;

use super::exact::{segment_crosses_triangle, triangle_meets_tet};
use super::faces::FaceIndex;
use super::sweep::Sweep;
use crate::collide::tool::Aabb;
use crate::mesh::{NodeKey, TetKey, TetMesh};

/// Current corner positions of a tet.
pub type Corners = [Point3<f64>; 4];

/// The tets at the `nodes` (with their current positions; others may come too) within `reach`
/// of the sweep's bounds, each once, in no order: where the candidates of the exact tests are
/// looked for ([`overlapping`] keeps them). A tet meeting the sweep has a corner within its
/// longest edge of it, so `reach` must be at least the longest current edge near the blade;
/// the cutter bounds it, for the tets whose corners it read, by the longest rest edge and how
/// far apart the displacements it read are. Scanning nodes rather than tets reads one position
/// per node; `first_visit` (true the first time it is asked about a tet in this
/// scan) lists each tet once.
pub fn tets_near(
    faces: &FaceIndex,
    nodes: impl Iterator<Item = (NodeKey, [f64; 3])>,
    reach: f64,
    sweep: &Sweep,
    mut first_visit: impl FnMut(TetKey) -> bool,
) -> Vec<TetKey> {
    let Some(b) = sweep.aabb() else {
        return Vec::new();
    };
    let (lo, hi) = (
        b.min.coords.add_scalar(-reach),
        b.max.coords.add_scalar(reach),
    );
    let mut out: Vec<TetKey> = Vec::new();
    for (k, p) in nodes {
        if !(0..3).all(|c| p[c] >= lo[c] && p[c] <= hi[c]) {
            continue;
        }
        for &tk in faces.tets_at(k) {
            if first_visit(tk) {
                out.push(tk);
            }
        }
    }
    out
}

/// The candidates of the exact tests, in key order: the `tets` whose bounds, at their
/// classification `corners` grown by `margin`, overlap the sweep's.
pub fn overlapping(
    mut tets: Vec<TetKey>,
    corners: &impl Fn(TetKey) -> Corners,
    sweep: &Sweep,
    margin: f64,
) -> Vec<TetKey> {
    let Some(b) = sweep.aabb() else {
        return Vec::new();
    };
    tets.retain(|&tk| bounds_overlap(&corners(tk), &b, margin));
    tets.sort();
    tets
}

/// Whether the bounds of a tet at `p`, grown by `margin`, overlap `b`.
pub fn bounds_overlap(p: &Corners, b: &Aabb, margin: f64) -> bool {
    (0..3).all(|c| {
        let lo = p.iter().map(|q| q[c]).fold(f64::INFINITY, f64::min);
        let hi = p.iter().map(|q| q[c]).fold(f64::NEG_INFINITY, f64::max);
        lo <= b.max[c] + margin && hi >= b.min[c] - margin
    })
}

/// The candidate tets that the sweep meets (exact test), in key order.
pub fn tets_met(
    candidates: &[TetKey],
    corners: &impl Fn(TetKey) -> Corners,
    sweep: &Sweep,
) -> Vec<TetKey> {
    candidates
        .iter()
        .copied()
        .filter(|&tk| {
            let p = corners(tk);
            sweep.triangles.iter().any(|s| triangle_meets_tet(s, &p))
        })
        .collect()
}

/// Inside faces the sweep crosses: pairs of face-neighbours (smaller key first) whose centroids
/// the sweep separates (the segment between them crosses a sweep triangle), sorted. The crossing
/// lies in one of the two tets, so one of them is always among `candidates`.
pub fn faces_crossed(
    mesh: &TetMesh,
    faces: &FaceIndex,
    candidates: &[TetKey],
    corners: &impl Fn(TetKey) -> Corners,
    sweep: &Sweep,
) -> Vec<(TetKey, TetKey)> {
    let centroid = |tk: TetKey| {
        let p = corners(tk);
        Point3::from((p[0].coords + p[1].coords + p[2].coords + p[3].coords) * 0.25)
    };
    let mut out = Vec::new();
    for &tk in candidates {
        let Some(tet) = mesh.tet(tk) else { continue };
        for local in 0..4 {
            let Some(other) = faces.neighbour(tk, tet, local) else {
                continue;
            };
            let pair = if tk < other { (tk, other) } else { (other, tk) };
            // Always from the smaller key's centroid, so the tie rule of `exact` is applied the
            // same way whichever tet the pair was reached from.
            let (c, d) = (centroid(pair.0), centroid(pair.1));
            if sweep
                .triangles
                .iter()
                .any(|s| segment_crosses_triangle(&c, &d, s))
            {
                out.push(pair);
            }
        }
    }
    out.sort();
    out.dedup();
    out
}

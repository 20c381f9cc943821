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
use crate::mesh::{TetKey, TetMesh};

/// Current corner positions of a tet.
pub type Corners = [Point3<f64>; 4];

fn overlaps(a: &Aabb, lo: &Point3<f64>, hi: &Point3<f64>) -> bool {
    (0..3).all(|k| lo[k] <= a.max[k] && hi[k] >= a.min[k])
}

/// Tets whose current bounds overlap the sweep's bounds, in key order (the candidates of the
/// exact tests below).
pub fn candidates(
    mesh: &TetMesh,
    corners: &impl Fn(TetKey) -> Corners,
    sweep: &Sweep,
) -> Vec<TetKey> {
    let Some(b) = sweep.aabb() else {
        return Vec::new();
    };
    let mut out: Vec<TetKey> = mesh
        .tets()
        .filter_map(|(tk, _)| {
            let p = corners(tk);
            let lo = p[1..].iter().fold(p[0], |a, q| a.inf(q));
            let hi = p[1..].iter().fold(p[0], |a, q| a.sup(q));
            overlaps(&b, &lo, &hi).then_some(tk)
        })
        .collect();
    out.sort();
    out
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

//! Binding render vertices to a tet on their own side of a blade's sweep: the vertices a cut
//! appends (crossings, slit ends), and the surface's own vertices between the sweep and the
//! faces a separating cut opened ([`rebind_band`]). Used by [`super::cap`].

use nalgebra::Point3;

use super::cap_sweep::SweepIndex;
use super::embed::{barycentric, bounds, closest_on_triangle, INSIDE_TOLERANCE};
use super::grid::Grid;
use super::rebind::side_of;
use super::{Binding, Embedding};
use crate::cut::Sweep;
use crate::mesh::{TetKey, TetMesh, TET_FACES};

/// Bind again, on their own side, the surface's vertices (below `first_new`) over the sweep
/// and within a tet's reach of it that are bound to a tet whose centroid lies on the other
/// side. Separating opens the faces between tets whose centroids the sweep parts, up to a cell
/// from the blade, so that a vertex between the sweep and the faces opened lies in a tet of the
/// other piece: bound there, it would go with that piece, stretching its triangles (which lie
/// on its side of the sweep, where the surface is split) across the opening.
pub(super) fn rebind_band(
    e: &mut Embedding,
    binder: &SideBinder,
    index: &SweepIndex,
    sweep: &Sweep,
    first_new: u32,
) {
    let reach = binder.reach;
    let (lo, hi) = (index.lo.map(|c| c - reach), index.hi.map(|c| c + reach));
    for v in 0..first_new as usize {
        let p = Point3::from(e.rest[v]);
        if e.dropped[v] || (0..3).any(|k| p[k] < lo[k] || p[k] > hi[k]) {
            continue;
        }
        // Over the sweep (its nearest point inside a triangle, not on the sweep's boundary)
        // and off it: a vertex on it has its copies.
        let Some((t, d)) = index.nearest(&p) else {
            continue;
        };
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        let Some(n) = n.try_normalize(0.0) else {
            continue;
        };
        let height = n.dot(&(p - t[0]));
        if d > reach || d <= index.tolerance || d > height.abs() + index.tolerance {
            continue;
        }
        let side = height >= 0.0;
        if !binder.holds(e, v, side, sweep) {
            binder.bind(e, v, Some(side), sweep);
        }
    }
}

/// Appends vertices to an embedding, each bound to a tet on its side of the sweep.
pub(super) struct SideBinder<'a> {
    mesh: &'a TetMesh,
    tets: Vec<(TetKey, [Point3<f64>; 4])>,
    grid: Grid,
    dense: crate::mesh::DenseNodes,
    /// The largest extent of a tet, m: how far from the sweep a vertex can lie in a tet on
    /// its other side.
    reach: f64,
}

impl<'a> SideBinder<'a> {
    pub(super) fn new(mesh: &'a TetMesh) -> Self {
        let tets: Vec<(TetKey, [Point3<f64>; 4])> =
            mesh.tets().map(|(k, t)| (k, mesh.tet_points(t))).collect();
        let grid = Grid::new(&tets.iter().map(|(_, p)| bounds(p)).collect::<Vec<_>>());
        let reach = tets
            .iter()
            .map(|(_, p)| {
                let (lo, hi) = bounds(p);
                (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        SideBinder {
            mesh,
            tets,
            grid,
            dense: mesh.dense_nodes(),
            reach,
        }
    }

    /// Bind vertex `v` of `e` (at its rest position) to the nearest tet whose centroid lies on
    /// `side` of `sweep` (any tet for `None`); dropped when there is none.
    pub(super) fn bind(&self, e: &mut Embedding, v: usize, side: Option<bool>, sweep: &Sweep) {
        let p = Point3::from(e.rest[v]);
        let found = self.grid.nearest(e.rest[v], |i| {
            let (_, t) = &self.tets[i as usize];
            if let Some(s) = side {
                let c = Point3::from((t[0].coords + t[1].coords + t[2].coords + t[3].coords) / 4.0);
                if side_of(sweep, &c) != s {
                    return f64::INFINITY;
                }
            }
            let w = barycentric(t, &p);
            if w.iter().all(|&w| w >= -INSIDE_TOLERANCE) {
                return 0.0;
            }
            TET_FACES
                .iter()
                .map(|f| (closest_on_triangle(&p, &t[f[0]], &t[f[1]], &t[f[2]]) - p).norm())
                .fold(f64::INFINITY, f64::min)
        });
        let Some((i, d)) = found.filter(|(_, d)| d.is_finite()) else {
            e.dropped[v] = true;
            e.weights[v] = [0.0; 4];
            return;
        };
        let (key, points) = &self.tets[i as usize];
        let w = barycentric(points, &p);
        let tet = self.mesh.tet(*key).expect("a tet of the mesh");
        e.nodes[v] = tet.nodes.map(|k| self.dense.index[k]);
        e.weights[v] = w;
        e.dropped[v] = false;
        e.bindings[v] = if d == 0.0 {
            Binding::Inside(*key)
        } else {
            // The face beyond which it lies: the corner opposite it has the lowest weight.
            let face = (0..4).min_by(|&a, &b| w[a].total_cmp(&w[b])).unwrap_or(0) as u8;
            Binding::Outside {
                tet: *key,
                face,
                distance: d,
            }
        };
    }

    /// Whether vertex `v` is bound to a tet of the mesh by its nodes now, on `side` of `sweep`
    /// (a vertex bound here at an earlier cut is not in the rebinder's index, and its tet may
    /// have been given new corners since).
    pub(super) fn holds(&self, e: &Embedding, v: usize, side: bool, sweep: &Sweep) -> bool {
        let Some(t) = self.mesh.tet(e.bindings[v].tet()) else {
            return false;
        };
        let p = self.mesh.tet_points(t);
        let c = Point3::from((p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0);
        t.nodes.map(|k| self.dense.index[k]) == e.nodes[v] && side_of(sweep, &c) == side
    }
}

//! How far a render surface lies from the simulation mesh's boundary: for each drawn vertex at
//! its deformed position, the distance to the nearest boundary triangle at the nodes' deformed
//! positions. A surface modelled on the organ stays within its modelling offset of the
//! simulated boundary; a vertex left on the wrong side of a cut, or dragged across an opening,
//! shows as a large gap.

use nalgebra::Point3;
use serde::Serialize;

use super::embed::{bounds, closest_on_triangle};
use super::grid::Grid;
use super::Embedding;
use crate::mesh::{TetMesh, Topology};

/// Distances from the drawn render vertices to the simulation boundary, m.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Gap {
    /// Mean over the drawn vertices.
    pub mean: f64,
    /// Largest.
    pub max: f64,
    /// Vertices measured (those drawn).
    pub vertices: usize,
}

/// The gap between `embedding`'s drawn vertices and `mesh`'s boundary, both at the node
/// positions `x` (dense order, the mesh's storage order).
pub fn boundary_gap(embedding: &Embedding, mesh: &TetMesh, x: &[[f64; 3]]) -> Gap {
    let dense = mesh.dense_nodes();
    let faces: Vec<[Point3<f64>; 3]> = Topology::of(mesh)
        .boundary
        .iter()
        .map(|f| f.nodes.map(|k| Point3::from(x[dense.index[k] as usize])))
        .collect();
    let grid = Grid::new(&faces.iter().map(|f| bounds(f)).collect::<Vec<_>>());
    let at = embedding.evaluate(x);
    let mut gap = Gap::default();
    for (v, p) in at.iter().enumerate() {
        if embedding.dropped[v] {
            continue;
        }
        let q = Point3::from(*p);
        let Some((_, d)) = grid.nearest(*p, |f| {
            let [a, b, c] = &faces[f as usize];
            (closest_on_triangle(&q, a, b, c) - q).norm()
        }) else {
            continue;
        };
        gap.mean += d;
        gap.max = gap.max.max(d);
        gap.vertices += 1;
    }
    gap.mean /= gap.vertices.max(1) as f64;
    gap
}

//! The small incision the single-cut tests make: a 3 cm box of 1 cm cells and a blade pushed
//! into it along its own axis, each drawn from one random sequence.

use crate::models::Rng;
use lancet::collide::ToolShape;
use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::TetMesh;
use nalgebra::{Isometry3, Vector3};

/// A 3 cm box of 1 cm cells, split five or six tets a cell at random.
pub fn small_box(rng: &mut Rng) -> TetMesh {
    let split = if rng.next() < 0.5 {
        TetSplit::Five
    } else {
        TetSplit::Six
    };
    BoxGrid {
        cells: [3, 3, 3],
        size: [0.03; 3],
        origin: [0.0; 3],
        split,
    }
    .build()
    .unwrap()
}

/// A blade 2 cm wide, turned at random, and its poses pushed along its own axis from outside
/// the box to a random depth around a random point of it: before and after.
pub fn blade_push(rng: &mut Rng) -> (ToolShape, Isometry3<f64>, Isometry3<f64>) {
    let blade = ToolShape::Blade {
        width: 0.02,
        length: 0.2,
        thickness: 1e-4,
    };
    let axis = Vector3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5);
    let rotation = axis.normalize() * (rng.next() * 3.0);
    let centre = Vector3::new(rng.next(), rng.next(), rng.next()) * 0.03;
    let z = Isometry3::new(Vector3::zeros(), rotation) * Vector3::z();
    let from = Isometry3::new(centre + z * 0.06, rotation);
    let to = Isometry3::new(centre - z * 0.06 * (rng.next() - 0.5), rotation);
    (blade, from, to)
}

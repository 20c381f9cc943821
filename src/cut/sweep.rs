//! The surface a blade cuts in one step, as float64 triangles in the scene frame.
//!
//! A blade is a thin cutting quad ([`ToolShape::blade_quad`]). It cuts with its leading sides:
//! the sides that move outwards within the blade's plane (the edge when the blade is pushed in,
//! the front side when it is drawn along). Each leading side cuts the band it sweeps between the
//! two poses; tissue that crosses the flat of a blade standing still, or a side that trails,
//! is not cut (a scalpel held still in stretching tissue does not go on cutting). For a straight
//! motion the bands of many small steps tile the band of one large step, so a fast blade that
//! crosses several elements in one step cuts the same as a slow one along the same path, and a
//! blade moved back along a cut sweeps only what is already cut.

use nalgebra::{Isometry3, Point3};

use crate::collide::tool::{Aabb, ToolShape};

/// The surface a blade cuts over one step: triangles, scene frame, their normals on the
/// blade's +y side.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// The triangles. Degenerate ones (a side moving along itself) are left out.
    pub triangles: Vec<[Point3<f64>; 3]>,
}

impl Sweep {
    /// The surface `shape` (a blade) cuts moving from `from` to `to`; `None` for other shapes.
    pub fn of_blade(shape: &ToolShape, from: &Isometry3<f64>, to: &Isometry3<f64>) -> Option<Self> {
        let q0 = shape.blade_quad(from)?;
        let q1 = shape.blade_quad(to)?;
        let normal = from * nalgebra::Vector3::y();
        let centre =
            Point3::from((q0[0].coords + q0[1].coords + q0[2].coords + q0[3].coords) / 4.0);
        let mut triangles = Vec::with_capacity(8);
        for k in 0..4 {
            let (a0, b0) = (q0[k], q0[(k + 1) % 4]);
            let (a1, b1) = (q1[k], q1[(k + 1) % 4]);
            // The side's outward direction within the blade's plane, and how its middle moved.
            let mut out = (b0 - a0).cross(&normal);
            if out.dot(&(nalgebra::center(&a0, &b0) - centre)) < 0.0 {
                out = -out;
            }
            let moved = nalgebra::center(&a1, &b1) - nalgebra::center(&a0, &b0);
            // A side moving along itself (a blade pushed in or pulled out along its axis) does
            // not lead, though rounding can leave it a motion of 1e-17 m outwards; that would
            // make triangles the length of the blade and no width, which still meet tets.
            // Leading takes an outward motion above a billionth of the side.
            let side = (b0 - a0).norm();
            if moved.dot(&out) <= 1e-9 * side * side {
                continue;
            }
            triangles.push([a0, b0, b1]);
            triangles.push([a0, b1, a1]);
        }
        triangles.retain(|t| (t[1] - t[0]).cross(&(t[2] - t[0])).norm_squared() > 0.0);
        // One orientation for every piece: normals on the side of the blade's +y face (at the
        // start pose), so that the tie rule of `exact` (a point on the plane counts as on the
        // positive side) puts a node exactly on the blade's plane on the same side for every
        // triangle of the sweep.
        for t in &mut triangles {
            if (t[1] - t[0]).cross(&(t[2] - t[0])).dot(&normal) < 0.0 {
                t.swap(1, 2);
            }
        }
        Some(Sweep { triangles })
    }

    /// Sweep made directly of triangles (for programs that define their own cutting surface).
    pub fn from_triangles(triangles: Vec<[Point3<f64>; 3]>) -> Self {
        Sweep { triangles }
    }

    /// Whether there is nothing to cut with.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Bounds of the swept surface, `None` when empty.
    pub fn aabb(&self) -> Option<Aabb> {
        let mut it = self.triangles.iter().flatten();
        let first = *it.next()?;
        let (min, max) = it.fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        Some(Aabb { min, max })
    }
}

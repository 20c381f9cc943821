//! The surface a blade sweeps in one step, as float64 triangles in the scene frame.
//!
//! A blade is a thin cutting quad ([`ToolShape::blade_quad`]). Everything the quad passes
//! through between two poses is cut: for a motion in the blade's own plane (how a scalpel is
//! drawn or pushed) that region is the quad at both poses plus the band each of its four sides
//! sweeps, which is exactly the Minkowski sum of the quad with the path for a straight
//! translation. So a fast blade that crosses several elements in one step sweeps the same
//! surface as a slow one along the same path in many steps.

use nalgebra::{Isometry3, Point3};

use crate::collide::tool::{Aabb, ToolShape};

/// The surface swept by a blade over one step: triangles, scene frame, their normals on the
/// blade's +y side.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// The triangles. Degenerate ones (a side moving along itself) are left out.
    pub triangles: Vec<[Point3<f64>; 3]>,
}

impl Sweep {
    /// The surface `shape` (a blade) sweeps from `from` to `to`; `None` for other shapes.
    pub fn of_blade(shape: &ToolShape, from: &Isometry3<f64>, to: &Isometry3<f64>) -> Option<Self> {
        let q0 = shape.blade_quad(from)?;
        let q1 = shape.blade_quad(to)?;
        let mut triangles = Vec::with_capacity(12);
        for q in [&q0, &q1] {
            triangles.push([q[0], q[1], q[2]]);
            triangles.push([q[0], q[2], q[3]]);
        }
        if q0 != q1 {
            for k in 0..4 {
                let (a0, b0) = (q0[k], q0[(k + 1) % 4]);
                let (a1, b1) = (q1[k], q1[(k + 1) % 4]);
                triangles.push([a0, b0, b1]);
                triangles.push([a0, b1, a1]);
            }
        }
        triangles.retain(|t| (t[1] - t[0]).cross(&(t[2] - t[0])).norm_squared() > 0.0);
        // One orientation for every piece: normals on the side of the blade's +y face (at the
        // start pose), so that the tie rule of `exact` (a point on the plane counts as on the
        // positive side) puts a node exactly on the blade's plane on the same side for every
        // triangle of the sweep.
        let normal = from * nalgebra::Vector3::y();
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

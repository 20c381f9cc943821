//! Triangle meshes of the tool shapes, for pictures and per-frame output: each convex part of
//! a shape ([`ToolShape::parts`]) as a closed, outward-oriented triangle surface (a box as 12
//! triangles, a ball as a latitude–longitude sphere, a capsule as that sphere split at its
//! equator and stretched over the axis), placed at the tool's pose.
//!
//! The meshes only show where a tool is; contact uses the exact shapes, not these.

use nalgebra::{Isometry3, Point3, Rotation3, Vector3};

use super::tool::{ToolPart, ToolShape};
use crate::surface::RenderSurface;

/// Rings of latitude between the poles of a ball or capsule (an even number, so that a
/// capsule splits on a ring).
const LATITUDES: usize = 12;
/// Vertices around each ring.
const LONGITUDES: usize = 24;

impl ToolShape {
    /// The shape as a closed triangle surface placed at `pose` (scene frame): every part's
    /// surface, counter-clockwise seen from outside.
    pub fn mesh(&self, pose: &Isometry3<f64>) -> RenderSurface {
        let mut out = RenderSurface::default();
        for part in self.parts() {
            part.append_mesh(pose, &mut out);
        }
        out
    }
}

impl ToolPart {
    /// Append the part's surface at `pose` to `out`.
    fn append_mesh(&self, pose: &Isometry3<f64>, out: &mut RenderSurface) {
        let first = out.positions.len() as u32;
        let (local, triangles) = match *self {
            ToolPart::Ball { centre, radius } => round(centre, centre, radius),
            ToolPart::Capsule { a, b, radius } => round(a, b, radius),
            ToolPart::Box {
                centre,
                half_extents,
            } => cuboid(centre, half_extents),
        };
        out.positions.extend(
            local
                .iter()
                .map(|p| -> [f64; 3] { (pose * p).coords.into() }),
        );
        out.triangles
            .extend(triangles.iter().map(|t| t.map(|v| v + first)));
    }
}

/// A capsule from `a` to `b` (a ball when they coincide): the lower hemisphere about `a`, the
/// upper about `b`, joined by the cylinder between their equators.
fn round(a: Point3<f64>, b: Point3<f64>, radius: f64) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    // The axis from `a` to `b` becomes the local z axis of the sphere's parametrisation.
    let axis = b - a;
    let rotation = Rotation3::rotation_between(&Vector3::z(), &axis)
        .or_else(|| {
            (axis.norm() > 0.0)
                .then(|| Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI))
        })
        .unwrap_or_else(Rotation3::identity);
    let point = |centre: Point3<f64>, theta: f64, phi: f64| {
        let d = Vector3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            -theta.cos(),
        );
        centre + rotation * (radius * d)
    };
    let mut positions = vec![point(a, 0.0, 0.0)];
    // Rings from the bottom pole up; the equator appears twice, once about each end.
    let mut rings = Vec::new();
    for i in 1..LATITUDES {
        let centre = if 2 * i <= LATITUDES { a } else { b };
        rings.push((centre, i));
        if 2 * i == LATITUDES {
            rings.push((b, i));
        }
    }
    for &(centre, i) in &rings {
        let theta = std::f64::consts::PI * i as f64 / LATITUDES as f64;
        for j in 0..LONGITUDES {
            let phi = std::f64::consts::TAU * j as f64 / LONGITUDES as f64;
            positions.push(point(centre, theta, phi));
        }
    }
    let top = positions.len() as u32;
    positions.push(point(b, std::f64::consts::PI, 0.0));
    let n = LONGITUDES as u32;
    let at = |ring: usize, j: u32| 1 + ring as u32 * n + j % n;
    let mut triangles = Vec::new();
    for j in 0..n {
        triangles.push([0, at(0, j + 1), at(0, j)]);
    }
    for r in 0..rings.len() - 1 {
        for j in 0..n {
            triangles.push([at(r, j), at(r, j + 1), at(r + 1, j + 1)]);
            triangles.push([at(r, j), at(r + 1, j + 1), at(r + 1, j)]);
        }
    }
    let last = rings.len() - 1;
    for j in 0..n {
        triangles.push([at(last, j), at(last, j + 1), top]);
    }
    (positions, triangles)
}

/// A box with the given centre and half-extents, axis-aligned in its frame.
fn cuboid(centre: Point3<f64>, h: Vector3<f64>) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    // Corner k has x, y, z signs from its bits 0, 1, 2.
    let positions = (0..8)
        .map(|k| {
            let s = |bit: u32| if k & (1 << bit) != 0 { 1.0 } else { -1.0 };
            centre + Vector3::new(s(0) * h.x, s(1) * h.y, s(2) * h.z)
        })
        .collect();
    // Each face as a quad counter-clockwise seen from outside.
    let faces = [
        [0, 4, 6, 2], // -x
        [1, 3, 7, 5], // +x
        [0, 1, 5, 4], // -y
        [2, 6, 7, 3], // +y
        [0, 2, 3, 1], // -z
        [4, 5, 7, 6], // +z
    ];
    let triangles = faces
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (positions, triangles)
}

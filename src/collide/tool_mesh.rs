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

#[cfg(test)]
mod tests {
    use super::*;

    /// Volume enclosed by a closed triangle surface (divergence theorem): positive only when
    /// every triangle faces outwards.
    fn enclosed_volume(s: &RenderSurface) -> f64 {
        s.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| Vector3::from(s.positions[v as usize]));
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Every edge used by exactly two triangles, once in each direction: closed and
    /// consistently oriented.
    fn assert_closed(s: &RenderSurface) {
        let mut edges = std::collections::HashMap::new();
        for t in &s.triangles {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a}-{b} used {n} times the same way");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
        }
    }

    #[test]
    fn shapes_are_closed_outward_and_near_their_volume() {
        let pose = Isometry3::new(Vector3::new(0.3, -0.2, 0.1), Vector3::new(0.4, 0.9, -0.3));
        let r: f64 = 0.01;
        let pi = std::f64::consts::PI;
        let cases = [
            (ToolShape::Sphere { radius: r }, 4.0 / 3.0 * pi * r.powi(3)),
            (
                ToolShape::Probe {
                    radius: r,
                    length: 0.05,
                },
                4.0 / 3.0 * pi * r.powi(3) + pi * r * r * 0.05,
            ),
            (
                ToolShape::Blade {
                    width: 0.02,
                    length: 0.03,
                    thickness: 0.001,
                },
                0.02 * 0.03 * 0.001,
            ),
            (
                ToolShape::Grasper {
                    jaw: [0.002, 0.003, 0.01],
                    opening: 0.004,
                },
                2.0 * 8.0 * 0.002 * 0.003 * 0.01,
            ),
        ];
        for (shape, volume) in cases {
            let m = shape.mesh(&pose);
            let parts = shape.parts().len();
            let per_part = m.triangles.len() / parts;
            for p in 0..parts {
                let part = RenderSurface {
                    positions: m.positions.clone(),
                    triangles: m.triangles[p * per_part..(p + 1) * per_part].to_vec(),
                };
                assert_closed(&part);
            }
            // A polygonal sphere is inside the true one: a few percent less volume.
            let v = enclosed_volume(&m);
            assert!(
                v > 0.95 * volume && v <= volume * (1.0 + 1e-9),
                "{shape:?}: {v} against {volume}"
            );
            // Every vertex lies on the shape's surface: its distance to the shape's axis or
            // centre as the shape says.
            let centre = pose * shape.bounding_sphere().0;
            let reach = shape.bounding_sphere().1;
            for p in &m.positions {
                assert!((Point3::from(*p) - centre).norm() <= reach * (1.0 + 1e-9));
            }
        }
    }
}

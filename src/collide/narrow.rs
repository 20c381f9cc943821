//! Narrow phase: contact between a tool and a triangle or a tetrahedron, through parry3d.
//!
//! parry3d computes in float32. A millimetre tool in a scene measured in metres is a poor fit
//! for float32 as is: positions around 0.5 m carry a rounding step of 60 nm, and parry's
//! absolute tolerances (GJK treats anything closer than about 1.2e-6 as touching) are sized for
//! shapes near unit size. So each query is made in a local frame:
//!
//! 1. in float64, the triangle or tetrahedron is taken into the tool frame (the inverse of the
//!    tool's pose), moved so that the tool part's bounding-sphere centre is the origin, and
//!    scaled by the inverse of that sphere's radius, which makes the tool part unit size;
//! 2. parry runs there, in float32, both shapes at the identity pose;
//! 3. its answer is mapped back in float64: distances divided by the scale, points and normals
//!    through the tool's pose.
//!
//! `tests/contact/collide_narrow.rs` checks the answers against an exact float64 computation on
//! thousands of random near-contact configurations and measures the direct float32 query for
//! comparison.
//!
//! Vectors cross between nalgebra and parry's glam types through glamx's `nalgebra` feature.

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d::math::{Pose, Vector};
use parry3d::query::{self, Contact};
use parry3d::shape::{Ball, ConvexPolyhedron, Cuboid, Segment, Shape, Triangle};

use super::tool::{ToolPart, ToolShape};
use crate::error::{Error, Result};

/// A contact (or near contact) between a tool and a piece of tissue, in the scene frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolContact {
    /// Signed distance, m: the gap between the surfaces when positive, minus the penetration
    /// depth (the shortest move that separates them) when negative.
    pub distance: f64,
    /// Unit normal pointing from the tool toward the tissue element: moving the element along
    /// it by `-distance` separates a penetrating pair.
    pub normal: Vector3<f64>,
    /// The point of the tool nearest the element (deepest into it when penetrating), m.
    pub point_on_tool: Point3<f64>,
    /// The point of the element nearest the tool (deepest into it when penetrating), m.
    pub point_on_element: Point3<f64>,
    /// Which convex part of the tool made the contact (index into [`ToolShape::parts`]: the jaw
    /// for a grasper, 0 otherwise).
    pub part: usize,
}

/// The frame a query runs in: scene point `p` maps to `(pose⁻¹ p - centre) * scale`.
struct LocalFrame<'a> {
    pose: &'a Isometry3<f64>,
    centre: Point3<f64>,
    scale: f64,
}

impl LocalFrame<'_> {
    fn to_local(&self, p: &Point3<f64>) -> Vector {
        let q = (self.pose.inverse_transform_point(p) - self.centre) * self.scale;
        Vector::from(q.cast::<f32>())
    }

    fn point_to_scene(&self, v: Vector) -> Point3<f64> {
        let q = nalgebra::Vector3::<f32>::from(v).cast::<f64>();
        self.pose * (self.centre + q / self.scale)
    }

    fn normal_to_scene(&self, v: Vector) -> Vector3<f64> {
        let n = nalgebra::Vector3::<f32>::from(v).cast::<f64>();
        let n = self.pose.rotation * n;
        n.try_normalize(0.0).unwrap_or(n)
    }

    fn contact_to_scene(&self, c: &Contact, part: usize) -> ToolContact {
        ToolContact {
            distance: f64::from(c.dist) / self.scale,
            normal: self.normal_to_scene(c.normal1),
            point_on_tool: self.point_to_scene(c.point1),
            point_on_element: self.point_to_scene(c.point2),
            part,
        }
    }
}

/// The part as a parry shape in its own local frame (centred, scaled by `scale`), and the
/// radius by which that shape is to be grown.
///
/// A capsule is queried as its axis segment, grown afterwards: GJK between two polytopes ends
/// on an exact simplex, while on a round support map it stops at a relative tolerance (with
/// parry's float32 settings, errors up to 5% of the gap were measured on a capsule against a
/// tetrahedron). Growing a contact by `r` adds `r` to the depth and moves the tool's point by
/// `r` along the normal, exactly.
fn local_part(part: &ToolPart, scale: f64) -> (Box<dyn Shape>, f32) {
    let centre = part.centre();
    let v = |p: Vector3<f64>| Vector::from((p * scale).cast::<f32>());
    match *part {
        ToolPart::Capsule { a, b, radius } => (
            Box::new(Segment::new(v(a - centre), v(b - centre))),
            (radius * scale) as f32,
        ),
        // parry answers a ball against a convex shape by projecting its centre, exactly.
        ToolPart::Ball { radius, .. } => (Box::new(Ball::new((radius * scale) as f32)), 0.0),
        ToolPart::Box { half_extents, .. } => (Box::new(Cuboid::new(v(half_extents))), 0.0),
    }
}

/// Query every part of `shape` at `pose` against the element built by `element` in each
/// part's local frame; keep the deepest contact within `margin`.
fn query_parts(
    shape: &ToolShape,
    pose: &Isometry3<f64>,
    margin: f64,
    mut element: impl FnMut(&LocalFrame) -> Result<Box<dyn Shape>>,
) -> Result<Option<ToolContact>> {
    if !(margin.is_finite() && margin >= 0.0) {
        return Err(Error::Options(format!(
            "contact margin must be zero or positive and finite, got {margin} m"
        )));
    }
    shape.validate()?;
    let mut best: Option<ToolContact> = None;
    for (i, part) in shape.parts().iter().enumerate() {
        let frame = LocalFrame {
            pose,
            centre: part.centre(),
            scale: 1.0 / part.bounding_radius(),
        };
        let (tool, grow) = local_part(part, frame.scale);
        let other = element(&frame)?;
        let prediction = (margin * frame.scale) as f32 + grow;
        let found = query::contact(
            &Pose::IDENTITY,
            tool.as_ref(),
            &Pose::IDENTITY,
            other.as_ref(),
            prediction,
        )
        .map_err(|_| {
            Error::Unsupported(format!(
                "parry3d has no contact query between tool part {part:?} and this element"
            ))
        })?;
        if let Some(mut c) = found {
            c.dist -= grow;
            c.point1 += c.normal1 * grow;
            let c = frame.contact_to_scene(&c, i);
            if best.is_none_or(|b| c.distance < b.distance) {
                best = Some(c);
            }
        }
    }
    Ok(best)
}

/// Contact between a tool at `pose` and the triangle `triangle` (scene frame, m), if their
/// signed distance is at most `margin` (m). For a grasper the deeper jaw is reported.
///
/// A triangle has no inside: a penetration depth is the shortest move that separates the tool
/// from the triangle, which may be toward either side of it.
pub fn tool_triangle(
    shape: &ToolShape,
    pose: &Isometry3<f64>,
    triangle: &[Point3<f64>; 3],
    margin: f64,
) -> Result<Option<ToolContact>> {
    query_parts(shape, pose, margin, |frame| {
        let [a, b, c] = triangle.map(|p| frame.to_local(&p));
        Ok(Box::new(Triangle::new(a, b, c)))
    })
}

/// Contact between a tool at `pose` and the solid tetrahedron `tet` (scene frame, m, either
/// orientation), if their signed distance is at most `margin` (m). A tool inside the
/// tetrahedron has a negative distance.
///
/// parry's `Tetrahedron` lacks the full query set, so the tetrahedron becomes a
/// `ConvexPolyhedron` with its four faces turned outward. A flat tetrahedron (no volume at
/// float32 resolution in the local frame) is refused.
pub fn tool_tetrahedron(
    shape: &ToolShape,
    pose: &Isometry3<f64>,
    tet: &[Point3<f64>; 4],
    margin: f64,
) -> Result<Option<ToolContact>> {
    // Faces of a positively oriented tet (d on the side of (b - a) x (c - a)), turned outward.
    const FACES: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
    let positive = (tet[1] - tet[0])
        .cross(&(tet[2] - tet[0]))
        .dot(&(tet[3] - tet[0]))
        > 0.0;
    let ordered = if positive {
        *tet
    } else {
        [tet[0], tet[2], tet[1], tet[3]]
    };
    query_parts(shape, pose, margin, |frame| {
        let points: Vec<Vector> = ordered.iter().map(|p| frame.to_local(p)).collect();
        ConvexPolyhedron::from_convex_mesh(points, &FACES)
            .map(|p| Box::new(p) as Box<dyn Shape>)
            .ok_or_else(|| {
                Error::Mesh(format!(
                    "tetrahedron {tet:?} is flat (no volume at float32 resolution); remove or \
                     repair it before querying contact"
                ))
            })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_above_a_triangle_far_from_the_origin_reports_the_gap() {
        let o = Point3::new(0.3, -0.2, 0.5);
        let tri = [
            o + Vector3::new(-0.002, -0.002, 0.0),
            o + Vector3::new(0.003, -0.001, 0.0),
            o + Vector3::new(0.0, 0.003, 0.0),
        ];
        let shape = ToolShape::Sphere { radius: 0.001 };
        let pose = Isometry3::translation(o.x, o.y, o.z + 0.00125);
        let c = tool_triangle(&shape, &pose, &tri, 0.001).unwrap().unwrap();
        assert!((c.distance - 0.00025).abs() < 1e-9, "{c:?}");
        assert!((c.normal - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-6);
        assert!((c.point_on_element - o).norm() < 1e-9);
        // Beyond the margin: nothing.
        assert!(tool_triangle(&shape, &pose, &tri, 0.0001)
            .unwrap()
            .is_none());
    }

    #[test]
    fn sphere_inside_a_tetrahedron_has_negative_distance() {
        let o = Point3::new(0.3, -0.2, 0.5);
        let s = 0.004;
        let tet = [
            o,
            o + Vector3::new(s, 0.0, 0.0),
            o + Vector3::new(0.0, 0.0, s),
            o + Vector3::new(0.0, s, 0.0),
        ];
        let shape = ToolShape::Sphere { radius: 0.0002 };
        let pose = Isometry3::translation(o.x + 0.0005, o.y + 0.0005, o.z + 0.0005);
        let c = tool_tetrahedron(&shape, &pose, &tet, 0.0).unwrap().unwrap();
        // The nearest faces are the three coordinate planes, 0.5 mm away (the slanted face is
        // 1.44 mm away): depth 0.5 + 0.2 mm.
        assert!((c.distance + 0.0007).abs() < 1e-8, "{c:?}");
    }
}

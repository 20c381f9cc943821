//! Narrow phase, tissue against itself: two surface triangles.
//!
//! [`triangle_triangle`] asks parry3d for the contact between two triangles (signed distance,
//! normal, both points) in a local frame, as [`super::narrow`] does for tools: in float64 the
//! six corners are moved so that the centre of their bounding box is the origin and scaled so
//! that the farthest corner is at distance 1, then parry runs in float32 and its answer is
//! mapped back in float64. `tests/contact/collide_self_narrow.rs` checks it against an exact float64
//! computation at millimetre scale half a metre from the origin.
//!
//! The float64 proximity primitives ([`closest_on_triangle`], [`closest_segment_segment`],
//! [`point_triangle`], [`edge_edge`]) are what the self-contact response
//! (`crate::contact::self_response`) is built on instead of the triangle–triangle depth: see there why.

use nalgebra::{Point3, Vector3};
use parry3d::math::{Pose, Vector};
use parry3d::query;
use parry3d::shape::Triangle;

use crate::error::{Error, Result};

type P = Point3<f64>;
type V = Vector3<f64>;

/// A contact (or near contact) between two surface triangles `a` and `b`, scene frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleContact {
    /// Signed distance, m: the gap when positive, minus the penetration depth (the shortest
    /// translation of one triangle that separates them) when negative.
    pub distance: f64,
    /// Unit normal from `a` toward `b`: translating `b` along it by `-distance` separates a
    /// penetrating pair.
    pub normal: V,
    /// The point of `a` nearest `b` (deepest into it when penetrating), m.
    pub point_on_a: P,
    /// The point of `b` nearest `a`, m.
    pub point_on_b: P,
}

/// Contact between triangles `a` and `b` (scene frame, m) if their signed distance is at most
/// `margin` (m), from parry3d's GJK (separated) or EPA (penetrating) in a local unit frame.
///
/// Measured against float64 on millimetre triangles half a metre from the origin
/// (`tests/contact/collide_self_narrow.rs`): within 0.3 nm on generic near-contact pairs, separated or
/// intersecting (EPA), and within 1 µm on nearly coplanar overlapping pairs; parry's float32
/// query in scene coordinates is off by up to 2.7 mm and misses two thirds of the separated
/// contacts within a 1 mm margin. For
/// intersecting pairs the answer is the depth of the Minkowski difference of two triangles:
/// right as such, but not what a response needs (see `crate::contact::self_response`).
pub fn triangle_triangle(a: &[P; 3], b: &[P; 3], margin: f64) -> Result<Option<TriangleContact>> {
    if !(margin.is_finite() && margin >= 0.0) {
        return Err(Error::Options(format!(
            "contact margin must be zero or positive and finite, got {margin} m"
        )));
    }
    let (mut lo, mut hi) = (a[0], a[0]);
    for p in a.iter().chain(b) {
        if !p.iter().all(|c| c.is_finite()) {
            return Err(Error::Model(format!("triangle corner {p:?} is not finite")));
        }
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let centre = nalgebra::center(&lo, &hi);
    let radius = a
        .iter()
        .chain(b)
        .map(|p| (p - centre).norm())
        .fold(0.0, f64::max);
    if radius == 0.0 {
        return Ok(Some(TriangleContact {
            distance: 0.0,
            normal: V::z(),
            point_on_a: centre,
            point_on_b: centre,
        }));
    }
    let scale = 1.0 / radius;
    let local = |p: &P| Vector::from(((p - centre) * scale).cast::<f32>());
    let back = |v: Vector| centre + nalgebra::Vector3::<f32>::from(v).cast::<f64>() / scale;
    let ta = Triangle::new(local(&a[0]), local(&a[1]), local(&a[2]));
    let tb = Triangle::new(local(&b[0]), local(&b[1]), local(&b[2]));
    let found = query::contact(
        &Pose::IDENTITY,
        &ta,
        &Pose::IDENTITY,
        &tb,
        (margin * scale) as f32,
    )
    .map_err(|_| Error::Unsupported("parry3d has no triangle-triangle contact query".into()))?;
    Ok(found.map(|c| {
        let n = nalgebra::Vector3::<f32>::from(c.normal1).cast::<f64>();
        TriangleContact {
            distance: f64::from(c.dist) / scale,
            normal: n.try_normalize(0.0).unwrap_or(n),
            point_on_a: back(c.point1),
            point_on_b: back(c.point2),
        }
    }))
}

/// Closest point of triangle `abc` to `p` and its barycentric weights (Ericson, Real-Time
/// Collision Detection, 5.1.5, by Voronoi regions), float64.
pub fn closest_on_triangle(p: &P, a: &P, b: &P, c: &P) -> (P, [f64; 3]) {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, [0.0, 1.0 - w, w]);
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (a + ab * v + ac * w, [1.0 - v - w, v, w])
}

/// Closest points of segments `p1 q1` and `p2 q2` and their parameters `(s, t)` along them
/// (Ericson 5.1.9), float64.
pub fn closest_segment_segment(p1: &P, q1: &P, p2: &P, q2: &P) -> (P, P, f64, f64) {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let tiny = 1e-300;
    let (s, t) = if a <= tiny && e <= tiny {
        (0.0, 0.0)
    } else if a <= tiny {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= tiny {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    (p1 + d1 * s, p2 + d2 * t, s, t)
}

/// A point facing a triangle: where its projection on the triangle's plane falls, and how far
/// in front of the plane it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointFace {
    /// Signed distance of the point from the triangle's plane along the triangle's unit normal
    /// (right-handed from its corner order), m: negative behind it.
    pub height: f64,
    /// Barycentric weights of the projection (they sum to 1; all in `[0, 1]` when the
    /// projection falls inside the triangle).
    pub weights: [f64; 3],
    /// The triangle's unit normal.
    pub normal: V,
}

/// The point `p` against the plane of triangle `t`, float64; `None` for a degenerate triangle.
pub fn point_triangle(p: &P, t: &[P; 3]) -> Option<PointFace> {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let n = e1.cross(&e2);
    let area2 = n.norm();
    if area2.is_nan() || area2 <= 0.0 {
        return None;
    }
    let normal = n / area2;
    let height = normal.dot(&(p - t[0]));
    let q = p - normal * height;
    // Sub-triangle areas against the whole, signed by the normal.
    let w1 = normal.dot(&(q - t[0]).cross(&e2)) / area2;
    let w2 = normal.dot(&e1.cross(&(q - t[0]))) / area2;
    Some(PointFace {
        height,
        weights: [1.0 - w1 - w2, w1, w2],
        normal,
    })
}

/// Two edges near each other: the closest points of their lines, when both fall strictly
/// inside the edges, and the unit direction normal to both edges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeEdge {
    /// Parameter of the closest point along the first edge, in `(0, 1)`.
    pub s: f64,
    /// Parameter along the second edge, in `(0, 1)`.
    pub t: f64,
    /// Unit vector normal to both edges (sign: the cross product of the first edge with the
    /// second).
    pub direction: V,
    /// Component along `direction` of the first closest point minus the second, m.
    pub gap: f64,
}

/// Edges `p1 q1` and `p2 q2` against each other, float64; `None` when they are nearly
/// parallel (within `1e-6` rad, where vertex–triangle tests take over) or when the closest
/// points of their lines fall outside either edge.
pub fn edge_edge(p1: &P, q1: &P, p2: &P, q2: &P) -> Option<EdgeEdge> {
    let (d1, d2) = (q1 - p1, q2 - p2);
    let c = d1.cross(&d2);
    let norm = c.norm();
    let least = 1e-6 * d1.norm() * d2.norm();
    if norm.is_nan() || norm <= least {
        return None;
    }
    let direction = c / norm;
    let r = p1 - p2;
    let (a, b, e) = (d1.dot(&d1), d1.dot(&d2), d2.dot(&d2));
    let (cc, f) = (d1.dot(&r), d2.dot(&r));
    let denom = a * e - b * b;
    let s = (b * f - cc * e) / denom;
    let t = (a * f - b * cc) / denom;
    if !(s > 0.0 && s < 1.0 && t > 0.0 && t < 1.0) {
        return None;
    }
    Some(EdgeEdge {
        s,
        t,
        direction,
        gap: direction.dot(&r),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_edges_have_a_gap_along_their_common_normal() {
        let o = P::new(0.3, -0.2, 0.5);
        let e = edge_edge(
            &(o + V::new(-1e-3, 0.0, 2e-4)),
            &(o + V::new(1e-3, 0.0, 2e-4)),
            &(o + V::new(0.0, -1e-3, 0.0)),
            &(o + V::new(0.0, 1e-3, 0.0)),
        )
        .unwrap();
        assert!((e.s - 0.5).abs() < 1e-9 && (e.t - 0.5).abs() < 1e-9);
        assert!((e.direction - V::z()).norm() < 1e-12);
        assert!((e.gap - 2e-4).abs() < 1e-12, "{e:?}");
    }

    #[test]
    fn a_point_behind_a_triangle_has_negative_height_and_inside_weights() {
        let o = P::new(0.3, -0.2, 0.5);
        let t = [o, o + V::new(2e-3, 0.0, 0.0), o + V::new(0.0, 2e-3, 0.0)];
        let f = point_triangle(&(o + V::new(5e-4, 5e-4, -1e-4)), &t).unwrap();
        assert!((f.height + 1e-4).abs() < 1e-12);
        assert!((f.weights[0] - 0.5).abs() < 1e-9 && (f.weights[1] - 0.25).abs() < 1e-9);
        assert!((f.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
}

//! Exact float64 predicates for the cut tests, on Shewchuk's adaptive orientation test (the
//! `robust` crate): a sweep that passes exactly through a node, along an edge or in the plane of
//! a face must give the same answer every time, which rounded arithmetic cannot promise.
//!
//! Ties are broken by one rule everywhere: a point exactly on a sweep triangle's plane counts as
//! being on its positive side (as if the sweep were pushed an infinitesimal distance against its
//! normal). So a cut exactly through grid nodes separates them into one side, never both or
//! neither.

use nalgebra::Point3;
use robust::{orient3d, Coord3D};

fn c(p: &Point3<f64>) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// The exact sign of `det[b - a, c - a, d - a]` (six times the signed volume of `a b c d`):
/// positive when `d` lies on the side `(b - a) x (c - a)` points to.
pub fn orient(a: &Point3<f64>, b: &Point3<f64>, c_: &Point3<f64>, d: &Point3<f64>) -> f64 {
    // Shewchuk's orient3d is positive when `d` lies below the plane in which `a b c` turn
    // counter-clockwise, the opposite convention.
    let o = -orient3d(c(a), c(b), c(c_), c(d));
    if o > 0.0 {
        1.0
    } else if o < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// The side of the plane of triangle `t` that `p` is on, with points on the plane counted on the
/// positive side (the tie rule of this module): `true` for positive.
pub fn side(t: &[Point3<f64>; 3], p: &Point3<f64>) -> bool {
    orient(&t[0], &t[1], &t[2], p) >= 0.0
}

/// Whether the segment `p q` crosses triangle `t`: its ends lie on different sides of the
/// triangle's plane (by [`side`]) and the line through them meets the closed triangle. A segment
/// lying in the plane never crosses; a crossing on the triangle's edge or corner counts.
pub fn segment_crosses_triangle(p: &Point3<f64>, q: &Point3<f64>, t: &[Point3<f64>; 3]) -> bool {
    if side(t, p) == side(t, q) {
        return false;
    }
    let s = [
        orient(p, q, &t[0], &t[1]),
        orient(p, q, &t[1], &t[2]),
        orient(p, q, &t[2], &t[0]),
    ];
    let all_pos = s.iter().all(|&x| x >= 0.0);
    let all_neg = s.iter().all(|&x| x <= 0.0);
    // All three zero: the segment lies in a plane with the triangle's edges only if the triangle
    // is degenerate; such a triangle cuts nothing.
    (all_pos || all_neg) && s.iter().any(|&x| x != 0.0)
}

/// Whether the open segment `p q` passes through the open triangle `t`: strictly, so touching
/// at a corner, along an edge or in the plane does not count.
pub fn segment_pierces_triangle(p: &Point3<f64>, q: &Point3<f64>, t: &[Point3<f64>; 3]) -> bool {
    let (sp, sq) = (
        orient(&t[0], &t[1], &t[2], p),
        orient(&t[0], &t[1], &t[2], q),
    );
    if sp * sq >= 0.0 {
        return false;
    }
    let s = [
        orient(p, q, &t[0], &t[1]),
        orient(p, q, &t[1], &t[2]),
        orient(p, q, &t[2], &t[0]),
    ];
    s.iter().all(|&x| x > 0.0) || s.iter().all(|&x| x < 0.0)
}

/// Whether point `p` lies strictly inside the positively oriented tet `t`.
pub fn inside_tet(t: &[Point3<f64>; 4], p: &Point3<f64>) -> bool {
    crate::mesh::TET_FACES.iter().all(|f| {
        // Faces are ordered with outward normals: inside is the negative side.
        orient(&t[f[0]], &t[f[1]], &t[f[2]], p) < 0.0
    })
}

/// Whether triangle `s` (a piece of the sweep) meets tet `t` (positively oriented): one of the
/// tet's edges crosses the triangle (with the tie rule, so a tet with corners on both sides of
/// the blade's plane is met), one of the triangle's edges pierces a face of the tet (strictly:
/// a sweep whose edge slides along the tet's boundary does not carve it), or the triangle
/// starts inside the tet.
pub fn triangle_meets_tet(s: &[Point3<f64>; 3], t: &[Point3<f64>; 4]) -> bool {
    for [a, b] in crate::mesh::TET_EDGES {
        if segment_crosses_triangle(&t[a], &t[b], s) {
            return true;
        }
    }
    for f in crate::mesh::TET_FACES {
        let face = [t[f[0]], t[f[1]], t[f[2]]];
        for k in 0..3 {
            if segment_pierces_triangle(&s[k], &s[(k + 1) % 3], &face) {
                return true;
            }
        }
    }
    inside_tet(t, &s[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new(x, y, z)
    }

    #[test]
    fn orientation_follows_the_right_hand_rule() {
        let (a, b, c) = (p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.));
        assert_eq!(orient(&a, &b, &c, &p(0.2, 0.2, 1.0)), 1.0);
        assert_eq!(orient(&a, &b, &c, &p(0.2, 0.2, -1.0)), -1.0);
        assert_eq!(orient(&a, &b, &c, &p(5.0, -3.0, 0.0)), 0.0);
    }

    #[test]
    fn a_segment_through_a_corner_crosses_and_one_beside_does_not() {
        let t = [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)];
        assert!(segment_crosses_triangle(
            &p(0.2, 0.2, -1.),
            &p(0.2, 0.2, 1.),
            &t
        ));
        assert!(segment_crosses_triangle(
            &p(0., 0., -1.),
            &p(0., 0., 1.),
            &t
        ));
        assert!(segment_crosses_triangle(
            &p(0.5, 0.5, -1.),
            &p(0.5, 0.5, 1.),
            &t
        ));
        assert!(!segment_crosses_triangle(
            &p(0.6, 0.6, -1.),
            &p(0.6, 0.6, 1.),
            &t
        ));
        // Ending on the plane counts as the positive side: from below it crosses, from above not.
        assert!(segment_crosses_triangle(
            &p(0.2, 0.2, -1.),
            &p(0.2, 0.2, 0.),
            &t
        ));
        assert!(!segment_crosses_triangle(
            &p(0.2, 0.2, 1.),
            &p(0.2, 0.2, 0.),
            &t
        ));
        // In the plane: never.
        assert!(!segment_crosses_triangle(
            &p(-1., 0.2, 0.),
            &p(2., 0.2, 0.),
            &t
        ));
    }

    #[test]
    fn a_small_triangle_inside_a_tet_meets_it() {
        let t = [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.), p(0., 0., 1.)];
        let s = [p(0.1, 0.1, 0.1), p(0.2, 0.1, 0.1), p(0.1, 0.2, 0.1)];
        assert!(inside_tet(&t, &s[0]));
        assert!(triangle_meets_tet(&s, &t));
        let far = s.map(|q| q + nalgebra::Vector3::new(3.0, 0.0, 0.0));
        assert!(!triangle_meets_tet(&far, &t));
    }
}

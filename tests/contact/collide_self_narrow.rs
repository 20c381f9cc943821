//! Triangle against triangle (self-contact narrow phase) agrees with an exact float64
//! computation at surgical scale: two triangles with 2 to 5 mm edges, up to 1 mm apart or
//! through each other, half a metre from the origin of a scene measured in metres. The float64
//! proximity primitives the response is built on are checked against dense sampling.
//!
//! Run with `cargo test --test collide_self_narrow -- --nocapture` to see the measured errors.

#![cfg(feature = "collide")]

use crate::splitmix;
use lancet::collide::self_narrow::{
    closest_on_triangle, closest_segment_segment, edge_edge, point_triangle, triangle_triangle,
};
use nalgebra::{Point3, Vector3};

type P = Point3<f64>;
type V = Vector3<f64>;

/// Answers must agree with float64 to this, m (1 µm). Measured at worst: 0.2 nm on generic
/// near-contact pairs, separated or intersecting; 0.45 µm separated and 0.9 µm intersecting on
/// nearly coplanar overlapping pairs.
const TOLERANCE: f64 = 1e-6;

use splitmix::{random_triangle, Rng, ORIGIN};

fn at(t: &[P; 3], w: [f64; 3]) -> P {
    P::from(t[0].coords * w[0] + t[1].coords * w[1] + t[2].coords * w[2])
}

/// A second triangle placed so that a random point of it is `sep` (-1 to 1 mm) from a random
/// point of `a` along a random direction: near contact, separated or through `a`.
fn near_pair(rng: &mut Rng) -> ([P; 3], [P; 3]) {
    let a = random_triangle(rng);
    let b = random_triangle(rng);
    let target = at(&a, rng.barycentric()) + rng.unit() * rng.range(-0.001, 0.001);
    let shift = target - at(&b, rng.barycentric());
    (a, b.map(|p| p + shift))
}

// ---------------------------------------------------------------------------------------------
// Float64 reference.
// ---------------------------------------------------------------------------------------------

fn edges(t: &[P; 3]) -> [(P, P); 3] {
    [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]
}

/// Directions that contain every facet normal of the Minkowski difference of two triangles
/// (both triangle normals, the nine edge-edge cross products) and, for coplanar pairs, the
/// in-plane edge normals; unit, both signs.
fn axes(a: &[P; 3], b: &[P; 3]) -> Vec<V> {
    let na = (a[1] - a[0]).cross(&(a[2] - a[0]));
    let nb = (b[1] - b[0]).cross(&(b[2] - b[0]));
    let mut out = vec![na, nb];
    for (p, q) in edges(a) {
        out.push(na.cross(&(q - p)));
        for (r, s) in edges(b) {
            out.push((q - p).cross(&(s - r)));
        }
    }
    for (r, s) in edges(b) {
        out.push(nb.cross(&(s - r)));
    }
    out.into_iter()
        .filter_map(|v| v.try_normalize(1e-300))
        .flat_map(|v| [v, -v])
        .collect()
}

/// Support of the Minkowski difference `b - a` along `u`.
fn support(a: &[P; 3], b: &[P; 3], u: &V) -> f64 {
    let hb = b.iter().map(|p| u.dot(&p.coords)).fold(f64::MIN, f64::max);
    let la = a.iter().map(|p| u.dot(&p.coords)).fold(f64::MAX, f64::min);
    hb - la
}

/// Exact signed distance between triangles `a` and `b`: separated (some axis separates them),
/// the least of the six node-triangle and nine edge-edge distances; intersecting, minus the
/// penetration depth, the least support of the Minkowski difference over its facet normals
/// (a superset of them does no harm: every direction's support bounds the depth from above).
fn signed_distance(a: &[P; 3], b: &[P; 3]) -> f64 {
    let dirs = axes(a, b);
    // `b - a` contains the origin iff no axis has all of `b - a` strictly on one side.
    let separated = dirs.iter().any(|u| support(a, b, &-u) < 0.0);
    if separated {
        let mut d = f64::INFINITY;
        for (s, t) in [(a, b), (b, a)] {
            for p in s {
                d = d.min((p - closest_on_triangle(p, &t[0], &t[1], &t[2]).0).norm());
            }
        }
        for (p, q) in edges(a) {
            for (r, s) in edges(b) {
                let (x, y, _, _) = closest_segment_segment(&p, &q, &r, &s);
                d = d.min((x - y).norm());
            }
        }
        d
    } else {
        -dirs
            .iter()
            .map(|u| support(a, b, u))
            .fold(f64::INFINITY, f64::min)
    }
}

// ---------------------------------------------------------------------------------------------
// The measurements.
// ---------------------------------------------------------------------------------------------

#[derive(Default, Debug)]
struct Stats {
    separated: usize,
    intersecting: usize,
    /// Worst |distance error| over separated pairs, m.
    separated_max: f64,
    /// Separated pairs within the margin that parry did not report.
    separated_missed: usize,
    /// Worst |depth error| over intersecting pairs parry answered, m.
    intersecting_max: f64,
    /// Intersecting pairs with no answer (EPA failed) or an answer more than 1 µm off.
    intersecting_bad: usize,
    /// Intersecting pairs parry answered with a non-negative distance.
    intersecting_positive: usize,
    /// The same query in float32 scene coordinates: worst separated error and misses.
    naive_max: f64,
    naive_missed: usize,
}

fn naive_f32(a: &[P; 3], b: &[P; 3], margin: f64) -> Option<f64> {
    use parry3d::math::{Pose, Vector};
    use parry3d::shape::Triangle;
    let t = |t: &[P; 3]| {
        let [p, q, r] = t.map(|p| Vector::from(p.coords.cast::<f32>()));
        Triangle::new(p, q, r)
    };
    parry3d::query::contact(
        &Pose::IDENTITY,
        &t(a),
        &Pose::IDENTITY,
        &t(b),
        margin as f32,
    )
    .unwrap()
    .map(|c| c.dist as f64)
}

/// A pair through each other, the second nearly in the plane of the first (tilted by up to
/// `tilt` rad and moved up to `offset` m off it), overlapping: the Minkowski difference is
/// nearly flat, the hard case for EPA.
fn coplanar_pair(rng: &mut Rng, tilt: f64, offset: f64) -> ([P; 3], [P; 3]) {
    let a = random_triangle(rng);
    let n = (a[1] - a[0]).cross(&(a[2] - a[0])).normalize();
    let c = at(&a, [1.0 / 3.0; 3]);
    let b = a.map(|p| {
        let r = nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(n),
            rng.range(0.0, 6.3),
        );
        c + r * (p - c) * rng.range(0.6, 1.2)
    });
    let axis = nalgebra::Unit::new_normalize(n.cross(&rng.unit()));
    let tilt = nalgebra::Rotation3::from_axis_angle(&axis, rng.range(-tilt, tilt));
    let shift = at(&a, rng.barycentric()) - c + n * rng.range(-offset, offset);
    (a, b.map(|p| c + tilt * (p - c) + shift * 0.3))
}

fn run(seed: u64, samples: usize) -> Stats {
    run_pairs(seed, samples, near_pair)
}

fn run_pairs(seed: u64, samples: usize, pair: impl Fn(&mut Rng) -> ([P; 3], [P; 3])) -> Stats {
    let margin = 0.001;
    let mut rng = Rng(seed);
    let mut s = Stats::default();
    for _ in 0..samples {
        let (a, b) = pair(&mut rng);
        let exact = signed_distance(&a, &b);
        let found = triangle_triangle(&a, &b, margin).unwrap();
        if exact > 0.0 {
            s.separated += 1;
            match found {
                Some(c) => {
                    let err = (c.distance - exact).abs();
                    s.separated_max = s.separated_max.max(err);
                    // The points are on their triangles and as far apart as the distance.
                    assert!(((c.point_on_b - c.point_on_a).norm() - exact).abs() < 2.0 * TOLERANCE);
                    assert!((c.normal.norm() - 1.0).abs() < 1e-6);
                }
                None if exact <= margin - TOLERANCE => s.separated_missed += 1,
                None => {}
            }
            match naive_f32(&a, &b, margin) {
                Some(d) => s.naive_max = s.naive_max.max((d - exact).abs()),
                None if exact <= margin - TOLERANCE => s.naive_missed += 1,
                None => {}
            }
        } else {
            s.intersecting += 1;
            match found {
                Some(c) => {
                    let err = (c.distance - exact).abs();
                    s.intersecting_max = s.intersecting_max.max(err);
                    if c.distance >= 0.0 {
                        s.intersecting_positive += 1;
                    }
                    if err > TOLERANCE {
                        s.intersecting_bad += 1;
                    }
                }
                None => s.intersecting_bad += 1,
            }
        }
    }
    s
}

#[test]
fn triangle_pairs_match_float64_at_millimetre_scale_in_a_metre_scene() {
    let s = run(7, 4000);
    eprintln!("triangle-triangle, 4000 pairs (2-5 mm edges, -1..1 mm, 0.6 m from the origin):");
    eprintln!(
        "  separated: {} pairs, max |error| {:.3e} m, {} missed within the 1 mm margin; \
         float32 in scene coordinates: max |error| {:.3e} m, {} missed",
        s.separated, s.separated_max, s.separated_missed, s.naive_max, s.naive_missed
    );
    eprintln!(
        "  intersecting: {} pairs, max |depth error| {:.3e} m over the answered ones, {} \
         unanswered or more than 1 um off, {} with a non-negative distance",
        s.intersecting, s.intersecting_max, s.intersecting_bad, s.intersecting_positive
    );
    assert!(s.separated > 500 && s.intersecting > 500, "{s:?}");
    assert_eq!(s.intersecting_bad, 0, "{s:?}");
    assert!(s.separated_max < TOLERANCE, "{s:?}");
    assert_eq!(s.separated_missed, 0, "{s:?}");
    // The frame is what makes separated answers right: scene-coordinate float32 is far off.
    assert!(s.naive_max > 10.0 * s.separated_max, "{s:?}");
}

#[test]
fn nearly_coplanar_overlapping_triangles_match_float64() {
    for (tilt, offset) in [(1e-2, 1e-4), (1e-4, 1e-6), (0.0, 0.0)] {
        let s = run_pairs(13, 2000, |rng| coplanar_pair(rng, tilt, offset));
        eprintln!(
            "nearly coplanar (tilt up to {tilt:.0e} rad, offset up to {offset:.0e} m), 2000 \
             pairs: {} intersecting, max |depth error| {:.3e} m, {} unanswered or more than 1 \
             um off, {} with a non-negative distance; {} separated, max |error| {:.3e} m",
            s.intersecting,
            s.intersecting_max,
            s.intersecting_bad,
            s.intersecting_positive,
            s.separated,
            s.separated_max
        );
        // Measured: at most 0.45 um (separated) and 0.9 um (intersecting, 10 mrad tilt).
        assert!(
            s.separated_max < TOLERANCE && s.intersecting_bad == 0,
            "{s:?}"
        );
    }
}

#[test]
fn reference_signed_distance_of_hand_made_pairs() {
    let o = P::from(ORIGIN);
    let a = [o, o + V::new(0.004, 0.0, 0.0), o + V::new(0.0, 0.004, 0.0)];
    // Parallel, 0.3 mm above.
    let b = a.map(|p| p + V::new(0.0, 0.0, 3e-4));
    assert!((signed_distance(&a, &b) - 3e-4).abs() < 1e-12);
    // A vertical triangle pushed 0.4 mm through `a` from above: the depth is 0.4 mm.
    let c = [
        o + V::new(0.001, 0.001, -4e-4),
        o + V::new(0.002, 0.001, 0.003),
        o + V::new(0.001, 0.002, 0.003),
    ];
    assert!(
        (signed_distance(&a, &c) + 4e-4).abs() < 1e-12,
        "{}",
        signed_distance(&a, &c)
    );
    let found = triangle_triangle(&a, &c, 0.0).unwrap().unwrap();
    eprintln!("vertical triangle 0.4 mm through a flat one: parry {found:?}");
}

/// Least distance between a point and a triangle by sampling the triangle densely.
fn sampled_point_triangle(p: &P, t: &[P; 3], n: usize) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..=n {
        for j in 0..=n - i {
            let w = [i as f64 / n as f64, j as f64 / n as f64];
            let q = at(t, [1.0 - w[0] - w[1], w[0], w[1]]);
            best = best.min((p - q).norm());
        }
    }
    best
}

#[test]
fn float64_primitives_agree_with_dense_sampling() {
    let mut rng = Rng(11);
    let n = 200;
    for _ in 0..200 {
        let (a, b) = near_pair(&mut rng);
        // Node against triangle: the closest point is never beaten by a sample, and a sample
        // comes within the sampling step of it.
        let p = b[0];
        let (q, w) = closest_on_triangle(&p, &a[0], &a[1], &a[2]);
        let d = (p - q).norm();
        let sampled = sampled_point_triangle(&p, &a, n);
        assert!(
            d <= sampled + 1e-12 && sampled - d < 0.005 / n as f64,
            "{d} {sampled}"
        );
        assert!((at(&a, w) - q).norm() < 1e-12);
        // The plane projection's weights and height reproduce the point.
        let f = point_triangle(&p, &a).unwrap();
        let back = at(&a, f.weights) + f.normal * f.height;
        assert!((back - p).norm() < 1e-12, "{f:?}");
        // Segments.
        let (x, y, s, t) = closest_segment_segment(&a[0], &a[1], &b[0], &b[1]);
        let mut sampled = f64::INFINITY;
        for i in 0..=n {
            for j in 0..=n {
                let u = a[0] + (a[1] - a[0]) * (i as f64 / n as f64);
                let v = b[0] + (b[1] - b[0]) * (j as f64 / n as f64);
                sampled = sampled.min((u - v).norm());
            }
        }
        let d = (x - y).norm();
        assert!(
            d <= sampled + 1e-12 && sampled - d < 0.005 / n as f64,
            "{d} {sampled}"
        );
        // Inside both edges, the line closest points are the segment closest points.
        if let Some(e) = edge_edge(&a[0], &a[1], &b[0], &b[1]) {
            assert!(
                (e.s - s).abs() < 1e-9 && (e.t - t).abs() < 1e-9,
                "{e:?} {s} {t}"
            );
            assert!((e.gap.abs() - d).abs() < 1e-12);
        }
    }
}

//! The narrow phase agrees with an exact float64 computation at surgical scale: millimetre tools
//! near millimetre triangles, in a scene measured in metres, half a metre from the origin.
//!
//! Run with `cargo test --test collide_narrow -- --nocapture` to see the measured errors.

#![cfg(feature = "collide")]

use crate::splitmix;
use lancet::collide::narrow::{tool_tetrahedron, tool_triangle, ToolContact};
use lancet::collide::ToolShape;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

type P = Point3<f64>;
type V = Vector3<f64>;

/// The wrapper's answers must agree with float64 to this, m (1 µm). Measured at worst: 57 nm
/// (probes near triangles); about 1 nm in every other test here, penetrating ones included.
const TOLERANCE: f64 = 1e-6;

// ---------------------------------------------------------------------------------------------
// Float64 reference: closest points between a segment and a triangle (Ericson, Real-Time
// Collision Detection, 5.1.5 closest point on a triangle, 5.1.9 closest points of two segments),
// and the penetration depth of a segment through a triangle from their Minkowski difference.
// ---------------------------------------------------------------------------------------------

/// Closest point of triangle `abc` to `p` (Ericson 5.1.5, by Voronoi regions).
fn closest_on_triangle(p: &P, a: &P, b: &P, c: &P) -> P {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Closest points of segments `p1 q1` and `p2 q2` (Ericson 5.1.9).
fn closest_segment_segment(p1: &P, q1: &P, p2: &P, q2: &P) -> (P, P) {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let eps = 1e-30;
    let (s, t);
    if a <= eps && e <= eps {
        return (*p1, *p2);
    }
    if a <= eps {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    (p1 + d1 * s, p2 + d2 * t)
}

/// Whether segment `pq` meets triangle `abc` (crosses or touches its plane inside it).
fn segment_hits_triangle(p: &P, q: &P, tri: &[P; 3]) -> bool {
    let [a, b, c] = tri;
    let n = (b - a).cross(&(c - a));
    let (dp, dq) = (n.dot(&(p - a)), n.dot(&(q - a)));
    if dp * dq > 0.0 || dp == dq {
        // Both on one side, or parallel to the plane: the edge and endpoint distances decide.
        return false;
    }
    let x = p + (q - p) * (dp / (dp - dq));
    let inside = |u: &P, v: &P| n.dot(&(v - u).cross(&(x - u))) >= 0.0;
    inside(a, b) && inside(b, c) && inside(c, a)
}

/// Distance between segment `pq` (possibly a point) and triangle `abc`, with the closest
/// points (on the segment, on the triangle).
fn segment_triangle(p: &P, q: &P, tri: &[P; 3]) -> (f64, P, P) {
    if segment_hits_triangle(p, q, tri) {
        let [a, b, c] = tri;
        let n = (b - a).cross(&(c - a));
        let (dp, dq) = (n.dot(&(p - a)), n.dot(&(q - a)));
        let x = p + (q - p) * (dp / (dp - dq));
        return (0.0, x, x);
    }
    let mut best = (f64::INFINITY, *p, *p);
    let mut consider = |s: P, t: P| {
        let d = (s - t).norm();
        if d < best.0 {
            best = (d, s, t);
        }
    };
    for e in [p, q] {
        consider(*e, closest_on_triangle(e, &tri[0], &tri[1], &tri[2]));
    }
    for i in 0..3 {
        let (s, t) = closest_segment_segment(p, q, &tri[i], &tri[(i + 1) % 3]);
        consider(s, t);
    }
    best
}

/// Exact signed distance between the capsule (segment `pq`, radius `r`; a ball when `p == q`)
/// and triangle `tri`: the gap, or minus the penetration depth.
///
/// The capsule is the segment grown by `r`, so the Minkowski difference of capsule and
/// triangle is `K` grown by `r`, with `K` = segment minus triangle (a prism: its facets are
/// normal to the triangle's normal and to each triangle edge crossed with the segment). When
/// the segment misses the triangle the origin lies outside `K` and the signed distance is
/// `d(segment, triangle) - r`; otherwise the depth is `r` plus the origin's depth in `K`, which
/// is the least support of `K` over its facet normals.
fn capsule_triangle_signed(p: &P, q: &P, r: f64, tri: &[P; 3]) -> (f64, P, P) {
    let (d, s, t) = segment_triangle(p, q, tri);
    if d > 0.0 {
        return (d - r, s, t);
    }
    let [a, b, c] = tri;
    let mut normals = vec![(b - a).cross(&(c - a))];
    let axis = q - p;
    for (u, v) in [(a, b), (b, c), (c, a)] {
        normals.push((v - u).cross(&axis));
    }
    let mut depth = f64::INFINITY;
    for n in normals {
        let Some(n) = n.try_normalize(1e-300) else {
            continue;
        };
        for n in [n, -n] {
            let support = n.dot(&p.coords).max(n.dot(&q.coords))
                - tri
                    .iter()
                    .map(|v| n.dot(&v.coords))
                    .fold(f64::INFINITY, f64::min);
            depth = depth.min(support);
        }
    }
    (-(r + depth), s, t)
}

/// Signed distance from `p` to the solid tetrahedron `tet`: positive outside, minus the depth
/// inside.
fn point_tet_signed(p: &P, tet: &[P; 4]) -> f64 {
    let faces = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
    let mut outside = f64::INFINITY;
    let mut inside = true;
    let mut depth = f64::INFINITY;
    for f in &faces {
        let opposite = tet[6 - f.iter().sum::<usize>()];
        let [a, b, c] = f.map(|i| tet[i]);
        let mut n = (b - a).cross(&(c - a)).normalize();
        if n.dot(&(opposite - a)) > 0.0 {
            n = -n;
        }
        let h = n.dot(&(p - a));
        if h > 0.0 {
            inside = false;
        }
        depth = depth.min(-h);
        outside = outside.min((p - closest_on_triangle(p, &a, &b, &c)).norm());
    }
    if inside {
        -depth
    } else {
        outside
    }
}

// ---------------------------------------------------------------------------------------------
// Random near-contact configurations.
// ---------------------------------------------------------------------------------------------

use splitmix::{random_triangle, Rng, ORIGIN};

/// A probe (or sphere when `length == 0`) of radius 1 to 3 mm placed so that its surface is
/// about `sep` from a random point of the triangle; the exact distance is computed separately.
struct Placed {
    shape: ToolShape,
    pose: Isometry3<f64>,
    /// Axis segment ends in the scene frame.
    a: P,
    b: P,
    radius: f64,
}

fn place_tool(rng: &mut Rng, tri: &[P; 3], sphere: bool) -> Placed {
    place_tool_at(rng, tri, sphere, (-0.001, 0.001))
}

/// As [`place_tool`], with the intended separation drawn from `seps` (m).
fn place_tool_at(rng: &mut Rng, tri: &[P; 3], sphere: bool, seps: (f64, f64)) -> Placed {
    let radius = rng.range(0.001, 0.003);
    let length = if sphere { 0.0 } else { rng.range(0.002, 0.02) };
    let (u, v) = (rng.next(), rng.next());
    let (u, v) = if u + v > 1.0 {
        (1.0 - u, 1.0 - v)
    } else {
        (u, v)
    };
    let on_tri = tri[0] + (tri[1] - tri[0]) * u + (tri[2] - tri[0]) * v;
    let sep = rng.range(seps.0, seps.1);
    let near = on_tri + rng.unit() * (radius + sep);
    let axis = rng.unit();
    let spin = UnitQuaternion::from_axis_angle(
        &nalgebra::Unit::new_normalize(axis),
        rng.range(0.0, std::f64::consts::TAU),
    );
    let rotation = spin
        * UnitQuaternion::rotation_between(&V::z(), &axis).unwrap_or_else(UnitQuaternion::identity);
    let tau = rng.next();
    let origin = near - axis * (tau * length);
    let pose = Isometry3::from_parts(Translation3::from(origin.coords), rotation);
    let shape = if sphere {
        ToolShape::Sphere { radius }
    } else {
        ToolShape::Probe { radius, length }
    };
    Placed {
        shape,
        pose,
        a: pose * P::origin(),
        b: pose * P::new(0.0, 0.0, length),
        radius,
    }
}

/// The direct query: parry in float32 with the scene coordinates as they are (the tool's pose
/// converted to float32 through glamx, the triangle's vertices cast to float32).
///
/// With `core`, a probe is queried as its axis segment and grown by its radius afterwards, as
/// the wrapper does, so that only the frame differs from the wrapper.
fn naive_f32(placed: &Placed, tri: &[P; 3], margin: f64, core: bool) -> Option<f64> {
    use parry3d::math::{Pose, Vector};
    use parry3d::shape::{Ball, Capsule, Segment, Shape, Triangle};
    let pose = Pose::from(placed.pose.cast::<f32>());
    let mut grow = 0.0;
    let shape: Box<dyn Shape> = match placed.shape {
        ToolShape::Sphere { radius } => Box::new(Ball::new(radius as f32)),
        ToolShape::Probe { radius, length } => {
            let (a, b) = (Vector::ZERO, Vector::new(0.0, 0.0, length as f32));
            if core {
                grow = radius as f32;
                Box::new(Segment::new(a, b))
            } else {
                Box::new(Capsule::new(a, b, radius as f32))
            }
        }
        _ => unreachable!("only probes and spheres are placed"),
    };
    let [a, b, c] = tri.map(|p| Vector::from(p.coords.cast::<f32>()));
    let tri = Triangle::new(a, b, c);
    parry3d::query::contact(
        &pose,
        shape.as_ref(),
        &Pose::IDENTITY,
        &tri,
        margin as f32 + grow,
    )
    .ok()
    .flatten()
    .map(|c| f64::from(c.dist - grow))
}

/// The distance from `x` to the segment `ab`.
fn dist_to_segment(x: &P, a: &P, b: &P) -> f64 {
    (x - closest_segment_segment(x, x, a, b).1).norm()
}

/// Check a wrapper contact against the reference; return the distance error.
fn check_contact(c: &ToolContact, placed: &Placed, tri: &[P; 3], exact: f64) -> f64 {
    let err = (c.distance - exact).abs();
    // The reported points lie on the surfaces and the normal joins them.
    let on_tool = (dist_to_segment(&c.point_on_tool, &placed.a, &placed.b) - placed.radius).abs();
    let on_tri = (c.point_on_element
        - closest_on_triangle(&c.point_on_element, &tri[0], &tri[1], &tri[2]))
    .norm();
    let along = (c.normal.dot(&(c.point_on_element - c.point_on_tool)) - c.distance).abs();
    assert!(
        on_tool < TOLERANCE && on_tri < TOLERANCE && along < TOLERANCE,
        "inconsistent contact {c:?}: off the tool by {on_tool:e}, off the triangle by {on_tri:e}, \
         normal gap mismatch {along:e}"
    );
    assert!((c.normal.norm() - 1.0).abs() < 1e-6);
    err
}

struct Stats {
    wrapper_max: f64,
    /// Direct float32 query of the shape as it is (capsule or ball), scene coordinates.
    naive_max: f64,
    naive_missed: usize,
    /// Direct float32 query of the axis segment grown by the radius, scene coordinates.
    naive_core_max: f64,
    naive_core_missed: usize,
    samples: usize,
}

fn run(sphere: bool, seed: u64, samples: usize) -> Stats {
    let mut rng = Rng(seed);
    let margin = 0.002;
    let mut stats = Stats {
        wrapper_max: 0.0,
        naive_max: 0.0,
        naive_missed: 0,
        naive_core_max: 0.0,
        naive_core_missed: 0,
        samples: 0,
    };
    while stats.samples < samples {
        let tri = random_triangle(&mut rng);
        let placed = place_tool(&mut rng, &tri, sphere);
        let (exact, _, _) = capsule_triangle_signed(&placed.a, &placed.b, placed.radius, &tri);
        if !(-0.001..=0.001).contains(&exact) {
            continue;
        }
        stats.samples += 1;
        let c = tool_triangle(&placed.shape, &placed.pose, &tri, margin)
            .expect("query runs")
            .unwrap_or_else(|| panic!("missed contact at exact distance {exact:e}"));
        stats.wrapper_max = stats
            .wrapper_max
            .max(check_contact(&c, &placed, &tri, exact));
        match naive_f32(&placed, &tri, margin, false) {
            Some(d) => stats.naive_max = stats.naive_max.max((d - exact).abs()),
            None => stats.naive_missed += 1,
        }
        match naive_f32(&placed, &tri, margin, true) {
            Some(d) => stats.naive_core_max = stats.naive_core_max.max((d - exact).abs()),
            None => stats.naive_core_missed += 1,
        }
    }
    stats
}

fn report(what: &str, s: &Stats) {
    eprintln!(
        "{what}: {} configurations, max |error| vs float64: local frame {:.3e} m; direct float32 \
         {:.3e} m ({} found no contact); direct float32 on the axis segment {:.3e} m ({} found \
         no contact)",
        s.samples,
        s.wrapper_max,
        s.naive_max,
        s.naive_missed,
        s.naive_core_max,
        s.naive_core_missed
    );
}

#[test]
fn narrow_phase_matches_float64_for_probes_near_triangles_at_millimetre_scale() {
    let s = run(false, 1, 4000);
    report("probe-triangle", &s);
    assert!(s.wrapper_max < TOLERANCE, "max error {:e} m", s.wrapper_max);
    // Measured: the direct float32 query is off by millimetres and misses about one contact in
    // nine, with the capsule as it is or as a grown segment: the local frame is what matters.
    assert!(s.naive_max > 100.0 * s.wrapper_max && s.naive_core_max > 100.0 * s.wrapper_max);
}

#[test]
fn narrow_phase_matches_float64_for_spheres_near_triangles_at_millimetre_scale() {
    let s = run(true, 2, 4000);
    report("sphere-triangle", &s);
    assert!(s.wrapper_max < TOLERANCE, "max error {:e} m", s.wrapper_max);
    // Measured: the direct float32 query is within 0.3 µm here (parry projects the centre), but
    // still hundreds of times worse than the local frame.
    assert!(s.naive_max > 10.0 * s.wrapper_max);
}

#[test]
fn reference_penetration_depth_of_a_probe_through_a_triangle() {
    // A vertical probe through the middle of a large horizontal triangle: the shortest way out
    // is up or down through the plane, by the nearer end plus the radius.
    let tri = [
        P::new(-1.0, -1.0, 0.0),
        P::new(2.0, -1.0, 0.0),
        P::new(-1.0, 2.0, 0.0),
    ];
    let (d, _, _) =
        capsule_triangle_signed(&P::new(0.0, 0.0, -0.3), &P::new(0.0, 0.0, 1.0), 0.1, &tri);
    assert!((d + 0.4).abs() < 1e-12, "{d}");
    // A sphere resting on it.
    let (d, _, _) =
        capsule_triangle_signed(&P::new(0.0, 0.0, 0.25), &P::new(0.0, 0.0, 0.25), 0.1, &tri);
    assert!((d - 0.15).abs() < 1e-12, "{d}");
}

#[test]
fn sphere_against_tetrahedron_matches_float64() {
    let mut rng = Rng(3);
    let mut worst: f64 = 0.0;
    let mut n = 0;
    while n < 1000 {
        let centre = P::from(ORIGIN) + rng.unit() * rng.range(0.0, 0.01);
        let tet = [0; 4].map(|_| centre + rng.unit() * rng.range(0.001, 0.003));
        let vol = (tet[1] - tet[0])
            .cross(&(tet[2] - tet[0]))
            .dot(&(tet[3] - tet[0]))
            .abs()
            / 6.0;
        if vol < 5e-10 {
            continue;
        }
        let radius = rng.range(0.0005, 0.002);
        let c = centre + rng.unit() * rng.range(0.0, 0.004);
        let exact = point_tet_signed(&c, &tet) - radius;
        if !(-0.001..=0.001).contains(&exact) {
            continue;
        }
        n += 1;
        let shape = ToolShape::Sphere { radius };
        let pose = Isometry3::translation(c.x, c.y, c.z);
        let got = tool_tetrahedron(&shape, &pose, &tet, 0.002)
            .expect("query runs")
            .unwrap_or_else(|| panic!("missed contact at {exact:e}"));
        worst = worst.max((got.distance - exact).abs());
    }
    eprintln!("sphere-tetrahedron: 1000 configurations, max |error| vs float64 {worst:.3e} m");
    assert!(worst < TOLERANCE, "{worst:e}");
}

/// Exact signed distance between the capsule (segment `pq`, radius `r`) and the solid
/// tetrahedron `tet`. As for a triangle: outside, the least distance from the segment to the
/// faces, minus `r`; when the segment meets the solid, minus `r` plus the origin's depth in the
/// Minkowski difference of segment and tetrahedron, whose facets are normal to the four faces
/// and to each of the six edges crossed with the segment.
fn capsule_tet_signed(p: &P, q: &P, r: f64, tet: &[P; 4]) -> f64 {
    let faces = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]].map(|f| f.map(|i| tet[i]));
    let meets = [p, q].iter().any(|x| point_tet_signed(x, tet) <= 0.0)
        || faces.iter().any(|f| segment_hits_triangle(p, q, f));
    if !meets {
        let d = faces
            .iter()
            .map(|f| segment_triangle(p, q, f).0)
            .fold(f64::INFINITY, f64::min);
        return d - r;
    }
    let axis = q - p;
    let mut normals: Vec<V> = faces
        .iter()
        .map(|[a, b, c]| (b - a).cross(&(c - a)))
        .collect();
    for i in 0..4 {
        for j in i + 1..4 {
            normals.push((tet[j] - tet[i]).cross(&axis));
        }
    }
    let mut depth = f64::INFINITY;
    for n in normals {
        let Some(n) = n.try_normalize(1e-300) else {
            continue;
        };
        for n in [n, -n] {
            let lowest = tet
                .iter()
                .map(|v| n.dot(&v.coords))
                .fold(f64::INFINITY, f64::min);
            depth = depth.min(n.dot(&p.coords).max(n.dot(&q.coords)) - lowest);
        }
    }
    -(r + depth)
}

#[test]
fn probe_through_a_triangle_matches_float64() {
    // The axis crosses the triangle: parry's answer comes from EPA on the segment.
    let mut rng = Rng(5);
    let (mut worst, mut n): (f64, usize) = (0.0, 0);
    while n < 1000 {
        let tri = random_triangle(&mut rng);
        let placed = place_tool_at(&mut rng, &tri, false, (-0.004, -0.001));
        let (d, _, _) = segment_triangle(&placed.a, &placed.b, &tri);
        if d > 0.0 {
            continue;
        }
        let (exact, _, _) = capsule_triangle_signed(&placed.a, &placed.b, placed.radius, &tri);
        n += 1;
        let got = tool_triangle(&placed.shape, &placed.pose, &tri, 0.0)
            .expect("query runs")
            .unwrap_or_else(|| panic!("missed contact at {exact:e}"));
        worst = worst.max(check_contact(&got, &placed, &tri, exact));
    }
    eprintln!("probe through triangle: 1000 configurations, max |error| vs float64 {worst:.3e} m");
    assert!(worst < TOLERANCE, "{worst:e}");
}

#[test]
fn probe_deep_in_a_tetrahedron_matches_float64() {
    let mut rng = Rng(6);
    let (mut worst, mut n): (f64, usize) = (0.0, 0);
    while n < 1000 {
        let centre = P::from(ORIGIN) + rng.unit() * rng.range(0.0, 0.01);
        let tet = [0; 4].map(|_| centre + rng.unit() * rng.range(0.002, 0.004));
        let vol = (tet[1] - tet[0])
            .cross(&(tet[2] - tet[0]))
            .dot(&(tet[3] - tet[0]))
            .abs()
            / 6.0;
        if vol < 1e-9 {
            continue;
        }
        let face = [tet[0], tet[1], tet[2]];
        let placed = place_tool_at(&mut rng, &face, false, (-0.004, -0.001));
        let exact = capsule_tet_signed(&placed.a, &placed.b, placed.radius, &tet);
        if exact >= -placed.radius {
            continue;
        }
        n += 1;
        let got = tool_tetrahedron(&placed.shape, &placed.pose, &tet, 0.0)
            .expect("query runs")
            .unwrap_or_else(|| panic!("missed contact at {exact:e}"));
        worst = worst.max((got.distance - exact).abs());
    }
    eprintln!(
        "probe axis inside tetrahedron: 1000 configurations, max |error| vs float64 {worst:.3e} m"
    );
    assert!(worst < TOLERANCE, "{worst:e}");
}

#[test]
fn probe_against_tetrahedron_matches_float64() {
    let mut rng = Rng(4);
    let (mut worst, mut n): (f64, usize) = (0.0, 0);
    while n < 2000 {
        let centre = P::from(ORIGIN) + rng.unit() * rng.range(0.0, 0.01);
        let tet = [0; 4].map(|_| centre + rng.unit() * rng.range(0.001, 0.003));
        let vol = (tet[1] - tet[0])
            .cross(&(tet[2] - tet[0]))
            .dot(&(tet[3] - tet[0]))
            .abs()
            / 6.0;
        if vol < 5e-10 {
            continue;
        }
        let face = [tet[0], tet[1], tet[2]];
        let placed = place_tool(&mut rng, &face, false);
        let exact = capsule_tet_signed(&placed.a, &placed.b, placed.radius, &tet);
        if !(-0.001..=0.001).contains(&exact) {
            continue;
        }
        n += 1;
        let got = tool_tetrahedron(&placed.shape, &placed.pose, &tet, 0.002)
            .expect("query runs")
            .unwrap_or_else(|| panic!("missed contact at {exact:e}"));
        worst = worst.max((got.distance - exact).abs());
    }
    eprintln!("probe-tetrahedron: 2000 configurations, max |error| vs float64 {worst:.3e} m");
    assert!(worst < TOLERANCE, "{worst:e}");
}

#[test]
fn probe_pressed_into_a_tetrahedron_reports_penetration() {
    let o = P::from(ORIGIN);
    let tet = [
        o,
        o + V::new(0.004, 0.0, 0.0),
        o + V::new(0.0, 0.004, 0.0),
        o + V::new(0.0, 0.0, 0.004),
    ];
    // A probe inside the corner of the tet, axis from (0.8, 0.8, 0.8) mm up to (0.8, 0.8, 1.8)
    // mm, radius 0.3 mm: the shortest way out is through the face x = 0 (or y = 0), by
    // 0.8 + 0.3 = 1.1 mm (the slanted face needs 1.22 mm, the base 2.1 mm).
    let shape = ToolShape::Probe {
        radius: 0.0003,
        length: 0.001,
    };
    let pose = Isometry3::translation(o.x + 0.0008, o.y + 0.0008, o.z + 0.0008);
    let c = tool_tetrahedron(&shape, &pose, &tet, 0.0).unwrap().unwrap();
    assert!((c.distance + 0.0011).abs() < 1e-7, "{c:?}");
}

#[test]
fn grasper_reports_the_jaw_in_contact() {
    let o = P::from(ORIGIN);
    let shape = ToolShape::Grasper {
        jaw: [0.001, 0.002, 0.005],
        opening: 0.004,
    };
    let pose = Isometry3::translation(o.x, o.y, o.z);
    // A vertical triangle just outside the +x jaw's outer face (x = 2 + 2 = 4 mm).
    let x = 0.0041;
    let tri = [
        o + V::new(x, -0.001, 0.001),
        o + V::new(x, 0.001, 0.001),
        o + V::new(x, 0.0, 0.004),
    ];
    let c = tool_triangle(&shape, &pose, &tri, 0.001).unwrap().unwrap();
    assert_eq!(c.part, 1);
    assert!((c.distance - 0.0001).abs() < 1e-9, "{c:?}");
    assert!((c.normal - V::x()).norm() < 1e-5);
}

#[test]
fn blade_edge_touching_a_triangle() {
    let o = P::from(ORIGIN);
    let shape = ToolShape::Blade {
        width: 0.01,
        length: 0.02,
        thickness: 0.0005,
    };
    // Edge down at 0.2 mm above a horizontal triangle.
    let pose = Isometry3::translation(o.x, o.y, o.z + 0.0002);
    let tri = [
        o + V::new(-0.002, -0.002, 0.0),
        o + V::new(0.003, -0.001, 0.0),
        o + V::new(0.0, 0.003, 0.0),
    ];
    let c = tool_triangle(&shape, &pose, &tri, 0.001).unwrap().unwrap();
    assert!((c.distance - 0.0002).abs() < 1e-9, "{c:?}");
    let pose = Isometry3::translation(o.x, o.y, o.z - 0.0003);
    let c = tool_triangle(&shape, &pose, &tri, 0.001).unwrap().unwrap();
    assert!((c.distance + 0.0003).abs() < 1e-9, "{c:?}");
}

#[test]
fn bad_margin_is_refused() {
    let shape = ToolShape::Sphere { radius: 0.001 };
    let tri = [P::origin(), P::new(1.0, 0.0, 0.0), P::new(0.0, 1.0, 0.0)];
    let e = tool_triangle(&shape, &Isometry3::identity(), &tri, f64::NAN).unwrap_err();
    assert!(e.to_string().contains("margin"), "{e}");
}

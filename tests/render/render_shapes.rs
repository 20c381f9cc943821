//! The pieces the pictures and frames are made of, through the public API: tool meshes (closed,
//! outward, on their shapes' surfaces, near their volumes), the camera fitted to a box (every
//! corner in the picture, up is up) and the colour map (its ends, clamping, monotone
//! lightness).

use lancet::collide::ToolShape;
use lancet::render::{Camera, View};
use lancet::surface::colour::{displacement_colour, viridis};
use lancet::surface::RenderSurface;
use nalgebra::{Isometry3, Point3, Vector3};

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

/// The box's eight corners all land inside the picture, and the target in its middle.
#[test]
fn a_fitted_box_is_inside_the_picture() {
    let (lo, hi) = ([0.0, -0.01, -0.01], [0.05, 0.01, 0.01]);
    for (az, el, up) in [
        (-60.0, 25.0, Vector3::z()),
        (30.0, -40.0, -Vector3::y()),
        (170.0, 80.0, Vector3::x()),
    ] {
        let view = View {
            azimuth: az,
            elevation: el,
            ..View::default()
        };
        let cam = Camera::fit(lo, hi, up, &view, 4.0 / 3.0);
        let (c, _) = cam.project([0.025, 0.0, 0.0], 400, 300).unwrap();
        assert!((c[0] - 200.0).abs() < 1e-6 && (c[1] - 150.0).abs() < 1e-6);
        for k in 0..8 {
            let p = [0, 1, 2].map(|i| if k & (1 << i) != 0 { hi[i] } else { lo[i] });
            let (q, z) = cam.project(p, 400, 300).unwrap();
            assert!((0.0..=400.0).contains(&q[0]) && (0.0..=300.0).contains(&q[1]));
            assert!((0.0..=1.0).contains(&z), "depth {z}");
        }
    }
}

/// Up in the scene is up in the picture: a point above the target lands above its middle.
#[test]
fn up_is_up() {
    let cam = Camera::fit([-1.0; 3], [1.0; 3], -Vector3::y(), &View::default(), 1.0);
    let (q, _) = cam.project([0.0, -0.5, 0.0], 100, 100).unwrap();
    assert!(q[1] < 50.0, "{q:?}");
}

#[test]
fn ends_and_clamping() {
    assert_eq!(viridis(0.0), [0.267, 0.005, 0.329]);
    assert_eq!(viridis(1.0), [0.993, 0.906, 0.144]);
    assert_eq!(viridis(-3.0), [0.267, 0.005, 0.329]);
    assert_eq!(viridis(7.0), [0.993, 0.906, 0.144]);
    assert_eq!(viridis(f64::NAN), [0.267, 0.005, 0.329]);
    assert_eq!(displacement_colour(1.0, 0.0), [0.267, 0.005, 0.329]);
    // Half-way between two stops is their mean.
    let m = viridis(0.05);
    for c in 0..3 {
        assert!((m[c] - 0.5 * ([0.267, 0.005, 0.329][c] + [0.283, 0.141, 0.458][c])).abs() < 1e-6);
    }
    // Viridis brightens monotonically (its defining property for reading in grey).
    let luma = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    for k in 0..100 {
        assert!(luma(viridis(k as f64 / 100.0)) < luma(viridis((k + 1) as f64 / 100.0)));
    }
}

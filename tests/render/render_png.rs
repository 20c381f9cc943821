//! Pictures of a scene run (on a real device; skipped without one unless
//! `LANCET_REQUIRE_GPU=1`): a beam at rest covers the outline its box projects to, and a beam
//! sagging under gravity is the low colour at its clamped end and the high colour at its free
//! end, as its displacements say.

use std::path::Path;

use lancet::render::frames::{PictureOptions, PngFrames};
use lancet::render::png_out::read_png;
use lancet::render::{Camera, BACKGROUND};
use lancet::scene::{run_scene_with, Frame, FrameSink, RunOptions, Scene};
use lancet::surface::colour::viridis;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;

/// A 50 x 20 x 20 mm beam clamped at x = 0, with Young's modulus `e` and `gravity` along -z.
fn beam(e: f64, gravity: f64, steps: u64) -> Scene {
    let text = format!(
        r#"Scene(
    name: "beam picture",
    mesh: Beam(length: 0.05, width: 0.02, height: 0.02, cells_along: 10, cells_across: 4),
    material: (
        stiffness: Material(youngs_modulus: {e:e}, poisson_ratio: 0.25),
        mass: Density(1000.0),
    ),
    gravity: (0.0, 0.0, {gravity:e}),
    mass_damping: 60.0,
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: 1e-9)],
    dt: BoundFraction(0.9),
    steps: {steps},
    engine: Fast,
)"#
    );
    Scene::from_ron(&text, Path::new("beam.ron")).unwrap()
}

/// Run `scene` drawing one picture at its end; the picture, its file, the camera and the
/// last frame.
fn picture(scene: &Scene, dir: &Path) -> Option<(lancet::render::Image, Camera, Frame)> {
    let ctx = crate::common::gpu()?;
    let options = PictureOptions {
        width: WIDTH,
        height: HEIGHT,
        legend: false,
        ..Default::default()
    };
    let mut png = PngFrames::new(&ctx, scene, dir, "beam", options).unwrap();
    let mut last = None;
    {
        let mut sink = |f: &Frame| {
            png.frame(f)?;
            last = Some(f.clone());
            Ok(())
        };
        let opts = RunOptions {
            frame_every: Some(scene.steps),
            no_output: true,
            ..Default::default()
        };
        let sink: &mut dyn FrameSink = &mut sink;
        run_scene_with(scene, Path::new("beam.ron"), &opts, |_, _| {}, Some(sink)).unwrap();
    }
    assert_eq!(png.pictures.len(), 1, "one picture, at the end");
    let image = read_png(&png.pictures[0].path).unwrap();
    assert_eq!((image.width, image.height), (WIDTH, HEIGHT));
    Some((image, *png.camera().unwrap(), last.unwrap()))
}

fn is_background(p: [u8; 4]) -> bool {
    let bg = BACKGROUND.map(|c| (c * 255.0).round() as u8);
    p[..3] == bg[..3]
}

/// Area of the convex hull of `points` (Andrew's monotone chain).
fn hull_area(mut points: Vec<[f64; 2]>) -> f64 {
    points.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    let n = hull.len();
    0.5 * (0..n)
        .map(|i| {
            let (a, b) = (hull[i], hull[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        .abs()
}

/// A stiff beam without gravity stays at rest: a box, whose picture is the convex hull of its
/// eight projected corners. The pixels not of the background cover that hull's area (to the
/// edge pixels multisampling blends, under 3%), and the picture is not empty or full.
#[test]
fn a_box_covers_its_projected_outline() {
    let dir = tempfile::tempdir().unwrap();
    let scene = beam(1e9, 0.0, 2);
    let Some((image, camera, _)) = picture(&scene, dir.path()) else {
        return;
    };
    let (lo, hi) = ([0.0, 0.0, 0.0], [0.05, 0.02, 0.02]);
    let corners: Vec<[f64; 2]> = (0..8)
        .map(|k| {
            let p = [0, 1, 2].map(|i| if k & (1 << i) != 0 { hi[i] } else { lo[i] });
            camera.project(p, WIDTH, HEIGHT).unwrap().0
        })
        .collect();
    let expected = hull_area(corners) / (WIDTH * HEIGHT) as f64;
    let covered = image
        .rgba
        .chunks_exact(4)
        .filter(|p| !is_background([p[0], p[1], p[2], p[3]]))
        .count() as f64
        / (WIDTH * HEIGHT) as f64;
    assert!(
        expected > 0.1 && expected < 0.9,
        "the fitted box should fill part of the picture: {expected}"
    );
    assert!(
        (covered / expected - 1.0).abs() < 0.03,
        "covered {covered}, projected outline {expected}"
    );
}

/// The chromaticity (share of each channel) of the mean colour of the 3 x 3 pixels about
/// `at`: the shading scales all three channels alike, so this is the colour map's, unshaded.
fn chromaticity(image: &lancet::render::Image, at: [f64; 2]) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for dy in -1..=1 {
        for dx in -1..=1 {
            let p = image.pixel((at[0] as i64 + dx) as u32, (at[1] as i64 + dy) as u32);
            assert!(!is_background(p), "pixel at {at:?} is background");
            for c in 0..3 {
                sum[c] += p[c] as f64;
            }
        }
    }
    let total: f64 = sum.iter().sum();
    sum.map(|s| s / total)
}

/// A soft beam sags under gravity: on its top face, the triangle nearest the clamp shows the
/// colour of its small displacement (the low, blue-violet end of viridis), the one at the
/// free end the colour of the largest (yellow-green); each agrees with the colour map at the
/// frame's own displacements.
#[test]
fn the_clamped_end_is_the_low_colour_and_the_free_end_the_high() {
    let dir = tempfile::tempdir().unwrap();
    let scene = beam(50e3, -9.81, 400);
    let Some((image, camera, frame)) = picture(&scene, dir.path()) else {
        return;
    };
    let s = &frame.tissue.surface;
    let top_of_range = frame.max_displacement();
    // The colour at a triangle's centroid is the mean of its corners' colours (colours are
    // interpolated across a triangle, not displacements).
    let top: Vec<(f64, [f64; 3], f64, [f32; 3])> = s
        .triangles
        .iter()
        .filter_map(|t| {
            let [a, b, c] = t.map(|v| nalgebra::Vector3::from(s.positions[v as usize]));
            let n = (b - a).cross(&(c - a)).normalize();
            let centroid = (a + b + c) / 3.0;
            let d = t.map(|v| frame.tissue.displacement[v as usize]);
            let colours = d.map(|d| viridis(d / top_of_range));
            let mean = [0, 1, 2].map(|k| colours.iter().map(|c| c[k]).sum::<f32>() / 3.0);
            (n.z > 0.9).then_some((
                centroid.x,
                centroid.into(),
                (d[0] + d[1] + d[2]) / 3.0,
                mean,
            ))
        })
        .collect();
    type Top = (f64, [f64; 3], f64, [f32; 3]);
    let by_x = |a: &&Top, b: &&Top| a.0.partial_cmp(&b.0).unwrap();
    let clamped = top.iter().min_by(by_x).unwrap();
    let free = top.iter().max_by(by_x).unwrap();
    assert!(
        free.2 > 0.8 * top_of_range,
        "the free end moves most: {} of {top_of_range}",
        free.2
    );
    assert!(clamped.2 < 0.2 * top_of_range);
    let mut shares = Vec::new();
    for (_, centroid, d, c) in [clamped, free] {
        let (at, _) = camera.project(*centroid, WIDTH, HEIGHT).unwrap();
        let got = chromaticity(&image, at);
        let total = (c[0] + c[1] + c[2]) as f64;
        let want = c.map(|x| x as f64 / total);
        for k in 0..3 {
            assert!(
                (got[k] - want[k]).abs() < 0.06,
                "at {centroid:?} (displacement {d:e} of {top_of_range:e}): {got:?} against {want:?}"
            );
        }
        shares.push(got);
    }
    // Blue dominates at the clamp, red and green at the free end.
    assert!(shares[0][2] > 0.4 && shares[1][2] < 0.2, "{shares:?}");
}

//! The render surface follows every stroke of a blade, not only those that changed the mesh:
//! separating `surface_cut_box.ron` changes the mesh at a dozen steps whose strips of sweep
//! cross no render edge, yet at the end the drawn surface is opened where the mesh is (the
//! piece that falls takes its side of the surface with it, the one that hangs keeps the
//! other), closed and outward.

use std::path::Path;

use lancet::cut::CutMethod;
use lancet::scene::{run_scene_with, Frame, FrameSink, RunOptions, Scene};
use rstest::rstest;

use crate::cut_box::{enclosed_volume, not_closed};

/// The first and last frames of `surface_cut_box.ron` cut by `method`.
fn first_and_last(method: CutMethod) -> (Frame, Frame) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/surface_cut_box.ron");
    let scene = Scene::read(&path).unwrap();
    let opts = RunOptions {
        cut_method: Some(method),
        no_output: true,
        ..Default::default()
    };
    let mut frames: Vec<Frame> = Vec::new();
    let mut sink = |f: &Frame| {
        if frames.is_empty() {
            frames.push(f.clone());
        } else {
            frames.truncate(1);
            frames.push(f.clone());
        }
        Ok(())
    };
    let sink: &mut dyn FrameSink = &mut sink;
    let summary = run_scene_with(&scene, &path, &opts, |_, _| {}, Some(sink)).unwrap();
    assert!(
        summary.expectations_passed,
        "{method}: {:#?}",
        summary.expectations
    );
    let s = summary.surface.unwrap();
    assert_eq!(s.open_rims, 0, "{method}: {s:#?}");
    assert!(s.cap_triangles > 0, "{method}: nothing capped: {s:#?}");
    let last = frames.pop().unwrap();
    (frames.pop().unwrap(), last)
}

#[rstest]
fn the_surface_opens_where_the_mesh_does(
    #[values(CutMethod::Separate, CutMethod::Remove)] method: CutMethod,
) {
    let (first, last) = first_and_last(method);
    let (rest, end) = (&first.tissue.surface, &last.tissue.surface);
    if let Some(why) = not_closed(&end.triangles) {
        panic!("{method}: the drawn surface is open: {why}");
    }
    // Each piece closed and outward, moved without being squashed: what they enclose is about
    // the box's volume, and positive. (The caps lie on the sweep, and a carved layer's surface
    // goes with the faces left on its side: the drawn pieces keep the layer a carving took.)
    let box_volume = enclosed_volume(&rest.positions, &rest.triangles);
    let v = enclosed_volume(&end.positions, &end.triangles);
    assert!(
        (v / box_volume - 1.0).abs() < 0.05,
        "{method}: {v} m3 enclosed, the box {box_volume} m3"
    );
    // The free piece falls more than its own size (the scene's expectations: 11 to 18 cm), the
    // piece held at y = 0 moves far less than a cell: every drawn vertex moved with one of
    // them, and no triangle joins the two (it would be stretched across the opening).
    let u = &last.tissue.displacement;
    let falls = |v: u32| u[v as usize] > 0.05;
    for (v, &d) in u.iter().enumerate() {
        assert!(
            !(0.005..=0.05).contains(&d),
            "{method}: vertex {v} moved {d} m: with neither piece"
        );
    }
    let joined: Vec<_> = end
        .triangles
        .iter()
        .filter(|t| t.iter().any(|&v| falls(v)) && !t.iter().all(|&v| falls(v)))
        .collect();
    assert!(
        joined.is_empty(),
        "{method}: {} triangles join the pieces, e.g. {:?}",
        joined.len(),
        &joined[..joined.len().min(4)]
    );
    // Both pieces have their side: the surface as read above and below the sweep (y = 0.017).
    let above = (0..rest.positions.len()).filter(|&v| rest.positions[v][1] > 0.017);
    assert!(above.clone().all(|v| falls(v as u32)), "{method}");
    assert!(
        (0..rest.positions.len())
            .filter(|&v| rest.positions[v][1] < 0.017)
            .all(|v| !falls(v as u32)),
        "{method}"
    );
}

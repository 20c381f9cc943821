//! A blade still moving inside the tissue when the run ends: the strokes after its last cut
//! (separating opens a tet only once the blade is through it, so its strokes inside the last
//! layer of cells change none) are applied when the run ends, so that the drawn surface's slit
//! reaches the blade's last position, closed and outward.

use std::path::Path;

use lancet::scene::{run_scene_with, Frame, FrameSink, RunOptions, Scene};

use crate::cut_box::{enclosed_volume, not_closed};

/// Where the blade's edge starts and where its keyframes would take it, m (it goes down at a
/// constant speed; the run ends long before it gets there).
const TOP: f64 = 0.05;
const BOTTOM: f64 = -0.01;
/// The keyframes' duration, s.
const DURATION: f64 = 0.05;

/// `surface_cut_box.ron` without gravity, the blade going down at a constant speed until the
/// run ends at `steps` steps (inside the box), cut by separating.
fn scene(steps: u64) -> (Scene, std::path::PathBuf) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/surface_cut_box.ron");
    let text = format!(
        r#"Scene(
    name: "a blade still inside at the end",
    mesh: Box((cells: (4, 4, 4), size: (0.04, 0.04, 0.04))),
    surface: File("../surfaces/box_fine.obj"),
    material: (
        stiffness: Material(youngs_modulus: 2e4, poisson_ratio: 0.3),
        mass: Density(1000.0),
    ),
    gravity: (0.0, 0.0, 0.0),
    dt: BoundFraction(0.8),
    steps: {steps},
    engine: Reference,
    tools: [(
        name: "scalpel",
        shape: Blade(width: 0.1, length: 0.1, thickness: 2e-4),
        trajectory: Keyframes([
            (time: 0.0, translation: (0.02, 0.017, {TOP})),
            (time: {DURATION}, translation: (0.02, 0.017, {BOTTOM})),
        ]),
    )],
    cut: Some((methods: [Separate])),
)"#
    );
    (Scene::from_ron(&text, &path).unwrap(), path)
}

#[test]
fn strokes_after_the_last_cut_are_applied_when_the_run_ends() {
    let steps = 35;
    let (scene, path) = scene(steps);
    let opts = RunOptions {
        no_output: true,
        ..Default::default()
    };
    let mut last: Option<Frame> = None;
    let mut sink = |f: &Frame| {
        last = Some(f.clone());
        Ok(())
    };
    let sink: &mut dyn FrameSink = &mut sink;
    let summary = run_scene_with(&scene, &path, &opts, |_, _| {}, Some(sink)).unwrap();
    let last = last.unwrap();
    assert_eq!(last.step, steps, "the last frame is the run's end");
    // Where the blade's edge is at the end: inside the box's third layer of cells, below the
    // last node layer it went through, not on a row of render vertices (3.3 mm apart).
    let edge = TOP + (BOTTOM - TOP) * last.time / DURATION;
    assert!(
        edge > 0.011 && edge < 0.0195,
        "the blade ends at z = {edge}: change the steps"
    );
    let cuts = summary.cuts.as_ref().unwrap();
    assert!(cuts.cuts > 0, "it cut: {cuts:#?}");
    // The blade's last cut came more than a render row (3.3 mm) above where it ends: a surface
    // split only along the strokes up to a cut would end its slit there, not at the blade.
    let last_cut = cuts.events.last().unwrap().step;
    let at_last_cut = TOP + (BOTTOM - TOP) * last_cut as f64 * summary.dt_final / DURATION;
    assert!(
        at_last_cut - edge > 0.004,
        "the last cut at step {last_cut} (z = {at_last_cut}), the blade ends at z = {edge}"
    );
    let s = summary.surface.as_ref().unwrap();
    assert_eq!(s.open_rims, 0, "{s:#?}");
    let drawn = &last.tissue.surface;
    if let Some(why) = not_closed(&drawn.triangles) {
        panic!("the drawn surface is open: {why}");
    }
    // No force moved the tissue: at rest, what it encloses is the box's volume.
    let v = enclosed_volume(&drawn.positions, &drawn.triangles);
    assert!((v - 0.04f64.powi(3)).abs() < 1e-9 * 0.04f64.powi(3), "{v}");
    // The slit runs down to the blade's edge at the end: it ends there, on the box's two
    // sides the blade's plane crosses (x = 0 and x = 0.04), one vertex both sides share each.
    let ends: Vec<_> = drawn
        .positions
        .iter()
        .filter(|p| (p[2] - edge).abs() < 1e-9 && (p[1] - 0.017).abs() < 1e-9)
        .collect();
    assert_eq!(ends.len(), 2, "slit ends at z = {edge}: {ends:?}");
    for x in [0.0, 0.04] {
        assert!(
            ends.iter().any(|p| (p[0] - x).abs() < 1e-9),
            "no slit end on the side x = {x}: {ends:?}"
        );
    }
}

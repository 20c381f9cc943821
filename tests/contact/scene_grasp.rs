//! Graspers in scenes: grasp windows parse and bad ones are refused saying what to fix; the
//! grasp-lift fixture closes, lifts, opens and lets the flap spring back on the GPU as on the
//! CPU (the CPU engines run it with the other fixtures in `tests/scenes.rs`).

use crate::common;
use std::path::{Path, PathBuf};

use lancet::engine::EngineKind;
use lancet::scene::{run_scene, RunOptions, Scene};

const BASE: &str = r#"Scene(
    name: "grasp",
    mesh: Box((cells: (2, 2, 2), size: (0.02, 0.02, 0.02))),
    material: (stiffness: Material(youngs_modulus: 1e4, poisson_ratio: 0.25), mass: Density(1000.0)),
    dt: BoundFraction(0.5),
    steps: 10,
    tools: [(name: "g", shape: SHAPE, trajectory: Keyframes([(time: 0.0)]), GRASP)],
)"#;

fn parse(shape: &str, grasp: &str) -> lancet::Result<Scene> {
    let text = BASE.replace("SHAPE", shape).replace("GRASP", grasp);
    Scene::from_ron(&text, Path::new("grasp.ron"))
}

const JAWS: &str = "Grasper(jaw: (0.001, 0.006, 0.003), opening: 0.002)";

fn error_of(shape: &str, grasp: &str) -> String {
    parse(shape, grasp).unwrap_err().to_string()
}

#[test]
fn grasp_windows_parse_and_say_when_the_grasper_holds() {
    let scene = parse(
        JAWS,
        "grasp: [(close: 0.1, open: 0.2), (close: 0.3, open: 0.5, reach: Some(5e-4))]",
    )
    .unwrap();
    let tool = &scene.tools[0];
    assert_eq!(tool.grasp.len(), 2);
    assert_eq!(tool.grasp[1].reach, Some(5e-4));
    let holding = |t: f64| tool.grasp_at(t).is_some();
    assert!(!holding(0.05) && holding(0.1) && holding(0.199) && !holding(0.2));
    assert!(!holding(0.25) && holding(0.3) && !holding(0.5));
    // Without `grasp` a tool never holds.
    let plain = parse(JAWS, "").unwrap();
    assert!(plain.tools[0].grasp.is_empty() && plain.tools[0].grasp_at(0.0).is_none());
}

#[test]
fn bad_grasp_windows_are_refused_saying_what_to_fix() {
    let e = error_of("Sphere(radius: 0.001)", "grasp: [(close: 0.1, open: 0.2)]");
    assert!(
        e.starts_with("grasp.ron: tool 0 (\"g\"): only a grasper can grasp")
            && e.contains("remove `grasp` or make the shape a Grasper"),
        "{e}"
    );
    let e = error_of(JAWS, "grasp: [(close: 0.2, open: 0.1)]");
    assert!(
        e.contains("grasp window 0: opens at 0.1 s, not after it closes at 0.2 s"),
        "{e}"
    );
    let e = error_of(
        JAWS,
        "grasp: [(close: 0.1, open: 0.3), (close: 0.2, open: 0.4)]",
    );
    assert!(
        e.contains("grasp window 1 closes at 0.2 s, before window 0 opens at 0.3 s")
            && e.contains("without overlap"),
        "{e}"
    );
    let e = error_of(JAWS, "grasp: [(close: 0.1, open: 0.3, reach: Some(-1e-3))]");
    assert!(e.contains("reach must be zero or positive"), "{e}");
    // A window without its opening time is a parse error naming the field, with its line.
    let e = error_of(JAWS, "grasp: [(close: 0.1)]");
    assert!(
        e.contains("grasp.ron: line") && e.contains("missing field named `open`"),
        "{e}"
    );
}

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/grasp_lift.ron")
}

#[test]
fn the_grasp_lift_scene_lifts_and_releases_the_flap_on_the_gpu_as_on_the_cpu() {
    let path = fixture();
    let scene = Scene::read(&path).unwrap();
    let run = |engine| {
        let opts = RunOptions {
            engine: Some(engine),
            no_output: true,
            ..Default::default()
        };
        run_scene(&scene, &path, &opts, |_, _| {}).unwrap()
    };
    let cpu = run(EngineKind::Fast);
    assert!(cpu.expectations_passed, "{:#?}", cpu.expectations);
    // The top and bottom nodes of the three columns under the jaws, six across the width.
    assert_eq!(cpu.tools[0].max_held, 36, "{:?}", cpu.tools[0]);
    if common::gpu().is_none() {
        return;
    }
    let gpu = run(EngineKind::Gpu);
    assert!(gpu.expectations_passed, "{:#?}", gpu.expectations);
    assert_eq!(gpu.tools[0].max_held, cpu.tools[0].max_held);
}

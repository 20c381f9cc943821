//! Scene fixtures run and meet their expectations on every CPU engine; the embedded default
//! scene is valid.

use std::path::{Path, PathBuf};

use lancet::engine::EngineKind;
use lancet::scene::{run_scene, RunOptions, Scene};
use rstest::rstest;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/scenes")
        .join(name)
}

#[rstest]
fn fixture_scene_meets_its_expectations(
    #[values(
        "default.ron",
        "stiffness_contrast.ron",
        "refused_time_step.ron",
        "forced_unstable.ron",
        "probe_press.ron",
        "grasp_lift.ron"
    )]
    file: &str,
    #[values(EngineKind::Reference, EngineKind::Fast)] engine: EngineKind,
) {
    let path = fixture(file);
    let scene = Scene::read(&path).unwrap();
    let opts = RunOptions {
        engine: Some(engine),
        no_output: true,
        ..Default::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    assert!(
        summary.expectations_passed,
        "{file} on {engine}: {:#?}",
        summary.expectations
    );
    assert!(!summary.expectations.is_empty());
}

/// The probe scene on the GPU engine feels what it feels on the CPU (its broad phase then
/// runs on the device), and the force on the probe points up, away from the tissue below it.
#[test]
fn the_probe_scene_feels_the_same_force_on_the_gpu_and_it_points_away_from_the_tissue() {
    let path = fixture("probe_press.ron");
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
    let t = &cpu.tools[0];
    assert!(t.final_force[2] > 0.9 * t.max_force, "{t:?}");
    assert!(t.contact_steps > 1000, "{t:?}");
    if lancet::engine::gpu::GpuContext::new().is_err() {
        assert!(
            std::env::var("LANCET_REQUIRE_GPU").is_err(),
            "LANCET_REQUIRE_GPU=1 but no adapter"
        );
        eprintln!("skipped the GPU half: no adapter");
        return;
    }
    let gpu = run(EngineKind::Gpu);
    assert!(gpu.expectations_passed, "{:#?}", gpu.expectations);
    let (a, b) = (cpu.tools[0].max_force, gpu.tools[0].max_force);
    assert!((a - b).abs() < 0.02 * a, "cpu {a} N, gpu {b} N");
}

#[test]
fn embedded_default_scene_is_the_default_fixture() {
    let from_file = Scene::read(&fixture("default.ron")).unwrap();
    assert_eq!(Scene::default_scene(), from_file);
}

#[test]
fn forced_divergence_is_reported_with_step_and_node() {
    let path = fixture("forced_unstable.ron");
    let scene = Scene::read(&path).unwrap();
    let summary = run_scene(&scene, &path, &RunOptions::default(), |_, _| {}).unwrap();
    assert!(summary.diverged);
    // Reported promptly (the run asked for 2000 steps), with the step and a node.
    assert!(
        summary.steps < 200,
        "detected only at step {}",
        summary.steps
    );
    let msg = summary.message.unwrap();
    assert!(
        msg.contains(&format!("step {}", summary.steps)) && msg.contains("node"),
        "{msg}"
    );
}

#[test]
fn refused_time_step_states_the_bound() {
    let path = fixture("refused_time_step.ron");
    let scene = Scene::read(&path).unwrap();
    let summary = run_scene(&scene, &path, &RunOptions::default(), |_, _| {}).unwrap();
    assert!(summary.refused);
    assert_eq!(summary.steps, 0);
    let msg = summary.message.unwrap();
    assert!(msg.contains(&format!("{:e}", summary.dt_bound)), "{msg}");
}

//! Tets turned inside out during a run are found (by the simulation's checks, at most
//! `INVERSION_CHECK_EVERY` apart, and placed at the first step with one) and reported like a
//! divergence, unless the scene allows them.

use std::path::Path;

use lancet::engine::EngineKind;
use lancet::scene::runner::INVERSION_CHECK_EVERY;
use lancet::scene::{run_scene, RunOptions, Scene};

/// A 10 mm cube standing on its fixed base under gravity, of Young's modulus `e` Pa.
fn cube(e: f64, extra: &str) -> Scene {
    let text = format!(
        r#"Scene(
    name: "cube",
    mesh: Box((cells: (2, 2, 2), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: {e:?}, poisson_ratio: 0.25), mass: Density(1000.0)),
    gravity: (0.0, 0.0, -9.81),
    mass_damping: 5.0,
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (0.0, 0.0, 1.0), tolerance: 1e-9)],
    dt: BoundFraction(0.5),
    steps: 3000,
    expect: [MaxDisplacement(max: Some(1.0))],
    {extra}
)"#
    );
    Scene::from_ron(&text, Path::new("cube.ron")).unwrap()
}

fn run(scene: &Scene, engine: EngineKind) -> lancet::scene::RunSummary {
    let opts = RunOptions {
        engine: Some(engine),
        no_output: true,
        ..Default::default()
    };
    run_scene(scene, Path::new("cube.ron"), &opts, |_, _| {}).unwrap()
}

/// With E = 1 Pa the cube's weight (rho g h = 98 Pa at its base, about a hundred times E)
/// crushes it through its base: tets turn over, which once ended "pass" with a negative volume
/// ratio. The run stops at the first step with one (found by a later check), fails, and names
/// the step and a tet.
#[test]
fn a_cube_crushed_by_its_weight_is_reported_with_the_step_and_a_tet() {
    // The GPU engine reads its state back at the check's cadence to look at the tets.
    let gpu = crate::common::gpu().map(|_| EngineKind::Gpu);
    let engines = [EngineKind::Reference, EngineKind::Fast]
        .into_iter()
        .chain(gpu);
    for engine in engines {
        let s = run(&cube(1.0, ""), engine);
        assert!(s.diverged, "{engine}: {s:#?}");
        assert!(!s.expectations_passed, "{engine}");
        let msg = s.message.clone().unwrap();
        assert!(msg.contains("inverted at step"), "{engine}: {msg}");
        assert!(msg.contains(" tet "), "{engine}: {msg}");
        assert!(s.steps < 3000, "{engine}: stopped at {}", s.steps);
        assert!(
            msg.contains(&format!("inverted at step {} ", s.steps)),
            "{engine}: {msg}"
        );
        // The check that found them ran on the cadence, after the first bad step.
        let at = msg.split("the check at step ").nth(1).unwrap();
        let found_at: u64 = at.split(' ').next().unwrap().parse().unwrap();
        assert!(
            found_at >= s.steps && found_at.is_multiple_of(INVERSION_CHECK_EVERY),
            "{msg}"
        );
    }
}

/// `allow_inverted: true` runs on to the end, and the inversion shows in the volume ratio; a
/// cube stiff enough to carry its weight (E = 50 kPa: strain about 2e-3) is not reported.
#[test]
fn allowed_inversions_run_on_and_a_stiff_cube_is_not_reported() {
    let allowed = run(&cube(1.0, "allow_inverted: true,"), EngineKind::Fast);
    assert!(!allowed.diverged, "{allowed:#?}");
    assert_eq!(allowed.steps, 3000);
    assert!(allowed.volume_ratio < 1.0, "{}", allowed.volume_ratio);
    let stiff = run(&cube(50e3, ""), EngineKind::Fast);
    assert!(!stiff.diverged, "{stiff:#?}");
    assert!(stiff.expectations_passed);
    assert!(
        (stiff.volume_ratio - 1.0).abs() < 0.01,
        "{}",
        stiff.volume_ratio
    );
}

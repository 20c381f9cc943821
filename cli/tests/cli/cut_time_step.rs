//! What a scene does when a cut lowers the stable time step below the one in use, under each
//! policy of its `cut` section: `Warn` goes on at the same step and says so, `Stop` ends the run
//! naming the step and the policies that would go on, and `Substep` goes on at the scene's
//! fraction of the lowered bound, writing only the step parameters (counted in the upload), with
//! the simulated time summed over the steps taken at each time step.
//!
//! The scene: a 4 x 4 x 4 cm box, hanging from its y = 0 face, that a blade sweeps down through
//! (as in `fixtures/scenes/cut_box_through.ron`) and subdivides. Splitting an edge at a
//! crossing near one of its ends makes a node with a small mass and stiff short springs, so the
//! first cut lowers the stable bound to about 0.4 of the uncut mesh's, well below the 0.8 of it
//! the scene steps at.

use crate::common;
use std::path::Path;
use std::process::{Command, Output};

use lancet::engine::EngineKind;
use lancet::model::stable_time_step;
use lancet::scene::cuts::CutEvent;
use lancet::scene::driver::SceneDriver;
use lancet::scene::{RunOptions, Scene};
use lancet::world::World;

/// The scene's time step as a fraction of the stable bound (`dt: BoundFraction(..)`), which
/// `Substep` also lowers the step to.
const FRACTION: f64 = 0.8;

fn scene_text(policy: &str, steps: u64) -> String {
    format!(
        r#"Scene(
    name: "subdivide lowers the bound",
    mesh: Box((cells: (4, 4, 4), size: (0.04, 0.04, 0.04))),
    material: (
        stiffness: Material(youngs_modulus: 2e4, poisson_ratio: 0.3),
        mass: Density(1000.0),
        damping: StiffnessProportional(2e-3),
    ),
    gravity: (0.0, 9.81, 0.0),
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (0.0, 1.0, 0.0), tolerance: 1e-9)],
    dt: BoundFraction({FRACTION}),
    steps: {steps},
    engine: Fast,
    tools: [(
        name: "scalpel",
        shape: Blade(width: 0.1, length: 0.1, thickness: 2e-4),
        trajectory: Keyframes([
            (time: 0.0, translation: (0.02, 0.017, 0.05)),
            (time: 0.03, translation: (0.02, 0.017, -0.01)),
        ]),
    )],
    cut: Some((methods: [Subdivide], time_step: {policy})),
)"#
    )
}

/// The scene under `policy`, ready to step on `engine` as `lancet run` steps it.
fn start(policy: &str, engine: EngineKind) -> (World, SceneDriver) {
    let path = Path::new("policy.ron");
    let scene = Scene::from_ron(&scene_text(policy, 1000), path).unwrap();
    let opts = RunOptions {
        engine: Some(engine),
        ..RunOptions::default()
    };
    let world = World::from_scene(&scene, path, &opts).unwrap();
    let dt = FRACTION * stable_time_step(world.model()).dt;
    assert_eq!(world.sim().config().dt, dt);
    (world, SceneDriver::new(&scene))
}

/// Step once; the cut made after the step, if any.
fn step(world: &mut World, driver: &mut SceneDriver) -> Option<CutEvent> {
    driver.step(world).unwrap().cuts.into_iter().last()
}

#[test]
fn warn_goes_on_at_the_same_step_and_names_the_lowered_bound() {
    let (mut world, mut driver) = start("Warn", EngineKind::Fast);
    let dt = world.sim().config().dt;
    // Up to the first cut that lowers the bound below dt.
    let event = loop {
        if let Some(e) = step(&mut world, &mut driver) {
            if e.time_step.is_some() {
                break e;
            }
        }
        assert!(
            world.sim().steps() < 1000,
            "no cut lowered the bound below dt"
        );
    };
    let change = event.time_step.unwrap();
    // The bound named is the cut model's, recomputed from scratch, and below the step.
    let bound = stable_time_step(world.sim().model());
    assert_eq!((change.bound, change.node), (bound.dt, bound.node));
    assert!(change.bound < dt, "{} >= {dt}", change.bound);
    assert_eq!((change.dt_before, change.dt_after), (dt, dt));
    assert_eq!(event.time_step_bytes, 0);
    let warning = world.cutting().unwrap().report.time_step_events.last();
    let warning = warning.expect("a time-step event is listed").clone();
    assert!(
        warning.contains(&format!("step {}", event.step))
            && warning.contains(&format!("{:.4e} s", bound.dt))
            && warning.contains(&format!("node {}", bound.node)),
        "{warning}"
    );
    // The run goes on at the same step: a few more steps (above the bound it must diverge in
    // the end, so not many), each of dt.
    let (steps, time) = (world.sim().steps(), world.sim().time());
    for _ in 0..3 {
        driver.step(&mut world).unwrap();
    }
    assert_eq!(world.sim().config().dt, dt);
    assert_eq!(world.sim().steps(), steps + 3);
    assert!((world.sim().time() - (time + 3.0 * dt)).abs() < 1e-12 * time);
}

/// `Substep` on `engine`: at every cut that lowers the bound below the step, the new step is
/// the scene's fraction of the bound recomputed from the cut model, the engine now runs it,
/// and the cut's upload counts the step parameters besides the patch, never the whole engine.
/// The simulated time is the sum of the steps taken at each step size.
fn substep_lowers_the_step_to_the_fraction_of_the_new_bound(engine: EngineKind) {
    let (mut world, mut driver) = start("Substep", engine);
    let mut time = 0.0;
    let mut changes = 0;
    for _ in 0..300 {
        time += world.sim().config().dt;
        let Some(event) = step(&mut world, &mut driver) else {
            continue;
        };
        let Some(change) = event.time_step else {
            assert_eq!(event.time_step_bytes, 0);
            assert!(event.bytes_uploaded <= event.layout_bytes);
            continue;
        };
        changes += 1;
        let bound = stable_time_step(world.sim().model());
        assert_eq!((change.bound, change.node), (bound.dt, bound.node));
        assert!(change.bound < change.dt_before);
        assert_eq!(change.dt_after, FRACTION * bound.dt);
        assert_eq!(world.sim().config().dt, change.dt_after);
        // The new step wrote the engine's step parameters and nothing else (a rebuild wrote
        // all of the engine's memory), besides the patch, which is part of a layout and not
        // empty: the cut changed springs.
        let params = event.time_step_bytes;
        assert!(
            params > 0 && params <= 64,
            "{params} bytes of step parameters"
        );
        if engine == EngineKind::Gpu {
            let uniform = std::mem::size_of::<lancet::engine::gpu::StepUniform>() as u64;
            assert_eq!(params, uniform);
        }
        let patch = event.bytes_uploaded - params;
        assert!(
            patch > 0 && event.bytes_uploaded <= event.layout_bytes,
            "{patch} + {params} of {}",
            event.layout_bytes
        );
    }
    assert!(changes > 0, "no cut lowered the bound below dt");
    assert!(
        (world.sim().time() - time).abs() < 1e-12 * time,
        "{} {time}",
        world.sim().time()
    );
    let report = &world.cutting().unwrap().report;
    let params: u64 = report.events.iter().map(|e| e.time_step_bytes).sum();
    assert_eq!(report.bytes_time_step, params);
    assert_eq!(
        report.bytes_uploaded,
        report.events.iter().map(|e| e.bytes_uploaded).sum::<u64>()
    );
    assert_eq!(report.time_step_events.len(), changes);
}

#[test]
fn substep_lowers_the_step_to_the_fraction_of_the_new_bound_on_the_cpu() {
    substep_lowers_the_step_to_the_fraction_of_the_new_bound(EngineKind::Fast);
}

#[test]
fn substep_lowers_the_step_to_the_fraction_of_the_new_bound_on_the_gpu() {
    if common::gpu().is_none() {
        return;
    }
    substep_lowers_the_step_to_the_fraction_of_the_new_bound(EngineKind::Gpu);
}

fn lancet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lancet"))
        .args(args)
        .output()
        .expect("the lancet binary runs")
}

/// `lancet run` on the scene under `policy` for `steps` steps, with `extra` arguments.
fn run(policy: &str, steps: u64, extra: &[&str]) -> Output {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("policy.ron");
    std::fs::write(&scene, scene_text(policy, steps)).unwrap();
    let mut args = vec!["run", scene.to_str().unwrap(), "--no-output"];
    args.extend_from_slice(extra);
    lancet(&args)
}

fn json(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}):\n{}\nstderr:\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

fn f(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn stop_exits_non_zero_naming_the_step_and_the_policy_that_goes_on() {
    let v = json(&run("Stop", 1000, &["--json"]));
    assert_eq!(v["stopped"], true);
    // The run ended at the cut that lowered the bound: the last one, after the last step.
    let events = v["cuts"]["events"].as_array().unwrap();
    let last = events.last().unwrap();
    let step = last["step"].as_u64().unwrap();
    assert_eq!(v["steps"].as_u64().unwrap(), step);
    assert!(step < 1000);
    let bound = f(&last["time_step"]["bound"]);
    assert!(bound < f(&v["dt"]));
    assert_eq!(f(&v["dt_bound_final"]), bound);

    let out = run("Stop", 1000, &[]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("stopped after a cut:"))
        .unwrap_or_else(|| panic!("no stop line in:\n{text}"));
    assert!(line.contains(&format!("the cut at step {step} ")), "{line}");
    assert!(line.contains(&format!("{bound:e} s")), "{line}");
    assert!(
        line.contains("`time_step: Substep`") && line.contains("`cut` section"),
        "{line}"
    );
    // The scene's `allow_unstable` does not let a cut through: the message must not send the
    // user there.
    assert!(!line.contains("allow_unstable"), "{line}");
}

#[test]
fn warn_runs_to_the_end_at_the_scene_step_and_reports_the_lowered_bound() {
    // The blade reaches the tissue after 5 ms, about 27 steps: 30 steps take a few past the
    // first cut, and stop well before running above the bound diverges.
    let steps = 30;
    let out = run("Warn", steps, &["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let v = json(&out);
    assert_eq!(v["stopped"], false);
    assert_eq!(v["diverged"], false);
    assert_eq!(v["steps"].as_u64().unwrap(), steps);
    let dt = f(&v["dt"]);
    assert_eq!(dt, FRACTION * f(&v["dt_bound"]));
    assert_eq!(f(&v["dt_final"]), dt);
    let time = f(&v["simulated_s"]);
    assert!((time - steps as f64 * dt).abs() < 1e-12 * time, "{time}");
    let events = v["cuts"]["events"].as_array().unwrap();
    let changed: Vec<_> = events
        .iter()
        .filter(|e| !e["time_step"].is_null())
        .collect();
    assert_eq!(changed.len(), 1, "{events:#?}");
    let change = &changed[0]["time_step"];
    let bound = f(&change["bound"]);
    assert!(bound < dt);
    assert_eq!((f(&change["dt_before"]), f(&change["dt_after"])), (dt, dt));
    // The bound at the end is the one the cut lowered it to (nothing cut after it).
    assert_eq!(f(&v["dt_bound_final"]), bound);
    let warnings = v["cuts"]["time_step_events"].as_array().unwrap();
    assert_eq!(warnings.len(), 1);
    let w = warnings[0].as_str().unwrap();
    assert!(w.contains(&format!("{bound:.4e} s")), "{w}");

    let text = String::from_utf8_lossy(&run("Warn", steps, &[]).stdout).into_owned();
    assert!(text.contains(&format!("  {w}")), "{text}");
    assert!(
        text.contains(&format!("ran {steps} steps ({:.4} s simulated)", time)),
        "{text}"
    );
}

#[test]
fn substep_reports_the_final_step_and_the_time_summed_over_the_steps_taken() {
    let out = run("Substep", 300, &["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let v = json(&out);
    assert_eq!(v["stopped"], false);
    assert_eq!(v["steps"].as_u64().unwrap(), 300);
    let dt = f(&v["dt"]);
    assert_eq!(dt, FRACTION * f(&v["dt_bound"]));
    // The time steps the run went through: after each change, the steps up to the next one
    // (or the end) are taken at the new step.
    let events = v["cuts"]["events"].as_array().unwrap();
    let (mut time, mut at, mut current) = (0.0, 0, dt);
    let mut changes = 0;
    for e in events {
        let c = &e["time_step"];
        if c.is_null() {
            assert_eq!(e["time_step_bytes"].as_u64().unwrap(), 0);
            continue;
        }
        changes += 1;
        let step = e["step"].as_u64().unwrap();
        assert_eq!(f(&c["dt_before"]), current);
        assert_eq!(f(&c["dt_after"]), FRACTION * f(&c["bound"]));
        time += (step - at) as f64 * current;
        (at, current) = (step, f(&c["dt_after"]));
        // Counted: the patch (not empty, at most a layout) and the step parameters (a few
        // dozen bytes, not a rebuilt engine).
        let (uploaded, layout, params) = (
            e["bytes_uploaded"].as_u64().unwrap(),
            e["layout_bytes"].as_u64().unwrap(),
            e["time_step_bytes"].as_u64().unwrap(),
        );
        assert!(params > 0 && params <= 64 && uploaded > params, "{e}");
        assert!(uploaded <= layout, "{e}");
    }
    assert!(changes > 0, "{events:#?}");
    time += (300 - at) as f64 * current;
    let simulated = f(&v["simulated_s"]);
    assert!(
        (simulated - time).abs() < 1e-12 * time,
        "{simulated} {time}"
    );
    assert!(simulated < 300.0 * dt);
    assert_eq!(f(&v["dt_final"]), current);
    assert!(f(&v["dt_final"]) <= f(&v["dt_bound_final"]));
    let c = &v["cuts"];
    let params: u64 = events
        .iter()
        .map(|e| e["time_step_bytes"].as_u64().unwrap())
        .sum();
    assert_eq!(c["bytes_time_step"].as_u64().unwrap(), params);
    let uploaded: u64 = events
        .iter()
        .map(|e| e["bytes_uploaded"].as_u64().unwrap())
        .sum();
    assert_eq!(c["bytes_uploaded"].as_u64().unwrap(), uploaded);

    let text = String::from_utf8_lossy(&run("Substep", 300, &[]).stdout).into_owned();
    assert!(
        text.contains(&format!(
            "dt changed from {dt:.3e} s to {current:.3e} s during the run"
        )),
        "{text}"
    );
    assert!(
        text.contains(&format!("ran 300 steps ({simulated:.4} s simulated)")),
        "{text}"
    );
}

//! `lancet report accuracy`: exit codes, the table, JSON and the plot files.

use std::path::Path;
use std::process::{Command, Output};

fn lancet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lancet"))
        .args(args)
        .output()
        .expect("the lancet binary runs")
}

/// A 36-node box scene, 400 steps: the whole report runs in well under a second.
const TINY: &str = r#"Scene(
    name: "tiny box",
    mesh: Box((cells: (3, 2, 2), size: (0.03, 0.02, 0.02))),
    material: (stiffness: Material(youngs_modulus: 10e3, poisson_ratio: 0.25), mass: Density(1000.0)),
    gravity: (0.0, 0.0, -9.81),
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: 1e-9)],
    dt: BoundFraction(0.9),
    steps: 400,
)"#;

fn tiny_scene(dir: &Path) -> String {
    let p = dir.join("tiny.ron");
    std::fs::write(&p, TINY).unwrap();
    p.to_str().unwrap().to_string()
}

#[test]
fn accuracy_json_has_a_row_per_engine_and_dt_and_writes_both_plots() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let plots = dir.path().join("plots");
    let out = lancet(&[
        "report",
        "accuracy",
        &scene,
        "--engine",
        "reference,fast",
        "--ladder",
        "1,0.5,0.25",
        "--no-implicit",
        "--json",
        "--plot",
        plots.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON only ({e}):\n{}",
            String::from_utf8_lossy(&out.stdout)
        )
    });
    let rows = v["report"]["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    for r in rows {
        assert!(r["wall_s_per_sim_s"].as_f64().unwrap() > 0.0);
        assert_eq!(r["errors"].as_array().unwrap().len(), 3, "{r}");
    }
    assert_eq!(v["report"]["sample_times"].as_array().unwrap().len(), 3);
    assert!(v["report"]["reference"]["self_error"][0]["relative_l2"]
        .as_f64()
        .is_some());
    let svg = std::fs::read_to_string(plots.join("accuracy.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("cpu-fast-f32"));
    let png = std::fs::read(plots.join("accuracy.png")).unwrap();
    assert_eq!(png[..4], [0x89, b'P', b'N', b'G']);
}

#[test]
fn accuracy_prints_a_table_naming_each_series_at_the_given_time() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let out = lancet(&[
        "report",
        "accuracy",
        &scene,
        "--engine",
        "reference,cpu",
        "--ladder",
        "0.5,0.25",
        "--time",
        "0.05",
        "--no-implicit",
        "--no-plot",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("sample times (s): 5.0000e-2"), "{stdout}");
    assert!(stdout.contains("reference self-check"), "{stdout}");
    for s in ["cpu-reference-f64", "cpu-fast-f32"] {
        assert_eq!(
            stdout.lines().filter(|l| l.starts_with(s)).count(),
            2,
            "{stdout}"
        );
    }
    assert!(stdout.contains("relL2@t1") && !stdout.contains("relL2@t2"));
    assert!(!dir.path().join("accuracy.svg").exists());
}

#[test]
fn accuracy_on_a_missing_scene_exits_2_naming_the_path() {
    let out = lancet(&["report", "accuracy", "/nonexistent/scene.ron", "--no-plot"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("/nonexistent/scene.ron"), "{stderr}");
}

#[test]
fn accuracy_refuses_a_step_above_the_bound_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let out = lancet(&["report", "accuracy", &scene, "--ladder", "2", "--no-plot"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("fraction 2") && stderr.contains("bound"),
        "{stderr}"
    );
    let out = lancet(&["report", "accuracy", &scene, "--ladder", "abc"]);
    assert_eq!(out.status.code(), Some(2));
}

/// The implicit series stand beside the explicit ones, above the bound, and the summary says
/// what each series needs to reach the target error.
#[test]
fn accuracy_puts_backward_euler_above_the_bound_beside_the_explicit_series() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let out = lancet(&[
        "report",
        "accuracy",
        &scene,
        "--engine",
        "reference",
        "--ladder",
        "1,0.5",
        "--implicit-ladder",
        "2,8",
        "--target-error",
        "10",
        "--no-plot",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let implicit: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("cpu-reference-f64-backward-euler "))
        .collect();
    assert_eq!(implicit.len(), 2, "{stdout}");
    // dt/bound of each implicit row: at or just below 2 and 8 (steps divide the sample times).
    let over: Vec<f64> = implicit
        .iter()
        .map(|l| l.split_whitespace().nth(1).unwrap().parse().unwrap())
        .collect();
    assert!(
        over[0] > 1.0 && over[0] <= 2.0 && over[1] > 4.0 && over[1] <= 8.0,
        "{over:?}"
    );
    // A target every row meets: each series has a time, and the comparison line is printed.
    assert!(stdout.contains("time to relL2 <= 1e1"), "{stdout}");
    assert!(
        stdout.contains("best implicit (cpu-reference-f64-backward-euler)"),
        "{stdout}"
    );
}

/// `--model-error` on the cantilever fixture: one row per force model against Timoshenko's
/// tip deflection in the JSON; a scene without an analytic answer exits with the reason.
#[test]
fn model_error_json_names_each_force_model_against_the_analytic_tip() {
    let fixture = &format!("{}/fixtures/scenes/fem_cantilever.ron", crate::REPO);
    let out = lancet(&[
        "report",
        "accuracy",
        fixture,
        "--model-error",
        "--model-error-only",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let m = &v["model_error"];
    assert!(m["analytic_tip_m"].as_f64().unwrap() < 0.0);
    let models: Vec<&str> = m["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["force_model"].as_str().unwrap())
        .collect();
    assert_eq!(models, ["springs", "tensor-mass", "corotational"]);
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let out = lancet(&[
        "report",
        "accuracy",
        &scene,
        "--model-error",
        "--model-error-only",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("Beam"));
}

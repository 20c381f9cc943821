//! The `lancet` command line: exit codes, JSON fields, errors that name the file and line.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub(crate) fn lancet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lancet"))
        .args(args)
        .output()
        .expect("the lancet binary runs")
}

pub(crate) fn json_of(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}):\n{}\nstderr:\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// The JSON a successful run printed (the run's stderr in the message otherwise).
pub(crate) fn ok_json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    json_of(out)
}

pub(crate) fn fixtures() -> PathBuf {
    Path::new(crate::REPO).join("fixtures/scenes")
}

#[test]
fn run_without_arguments_runs_the_embedded_scene_and_reports_json() {
    let out = lancet(&["run", "--json", "--no-output"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json_of(&out);
    for key in [
        "steps",
        "simulated_s",
        "dt",
        "dt_bound",
        "dt_final",
        "dt_bound_final",
        "engine",
        "wall_s",
        "max_displacement",
        "diverged",
        "expectations_passed",
    ] {
        assert!(v.get(key).is_some(), "missing {key} in {v}");
    }
    assert_eq!(v["diverged"], false);
    assert_eq!(v["expectations_passed"], true);
    assert!(v["dt"].as_f64().unwrap() <= v["dt_bound"].as_f64().unwrap());
    assert!(v["steps"].as_u64().unwrap() > 0);
    // Nothing cuts: the step and its bound stay, and the time is the steps at that step.
    assert_eq!(v["dt_final"], v["dt"]);
    assert_eq!(v["dt_bound_final"], v["dt_bound"]);
    let (dt, time) = (
        v["dt"].as_f64().unwrap(),
        v["simulated_s"].as_f64().unwrap(),
    );
    let expected = v["steps"].as_u64().unwrap() as f64 * dt;
    assert!(
        (time - expected).abs() < 1e-12 * expected,
        "{time} {expected}"
    );
    assert!(v["max_displacement"].as_f64().unwrap() > 0.0);
}

#[test]
fn run_on_a_folder_runs_every_scene_and_prints_a_table() {
    let out = lancet(&["run", fixtures().to_str().unwrap(), "--no-output"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A scene that cuts runs once per method it names.
    let scenes: Vec<usize> = std::fs::read_dir(fixtures())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "ron"))
        .map(|p| lancet::scene::Scene::read(&p).unwrap())
        // Scenes on real meshes are skipped when LANCET_MESH_DIR is not set.
        .filter(|s| {
            std::env::var_os("LANCET_MESH_DIR").is_some()
                || !matches!(&s.mesh, lancet::scene::MeshSource::File(f) if f.starts_with("$LANCET_MESH_DIR/"))
        })
        .map(|s| s.cut.map_or(1, |c| c.methods.len()))
        .collect::<Vec<_>>();
    let (runs, scenes) = (scenes.iter().sum::<usize>(), scenes.len());
    assert!(
        stdout.contains(&format!("{runs} runs ({scenes} scenes), 0 failed")),
        "{stdout}"
    );
    // The columns say what they hold: expectations met of those listed, nodes before and
    // after cutting.
    let header = stdout
        .lines()
        .find(|l| l.starts_with("scene "))
        .unwrap_or_else(|| panic!("no table header:\n{stdout}"));
    for column in ["nodes", "after cut", "expect", "result"] {
        assert!(header.contains(column), "{header}");
    }
    assert!(!header.contains("checks"), "{header}");
    // A scene that cuts and adds nodes shows more after the cut than before.
    // Counted from the right, past a scene name that may hold spaces: nodes, after cut, steps,
    // dt, wall, expect, result.
    let grew = stdout
        .lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l.split_whitespace().collect();
            let n = cells.len().checked_sub(7)?;
            Some((
                cells[n].parse::<usize>().ok()?,
                cells[n + 1].parse::<usize>().ok()?,
            ))
        })
        .any(|(before, after)| after > before);
    assert!(grew, "{stdout}");
}

#[test]
fn failing_expectation_exits_with_code_1() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("sags.ron");
    // Under gravity the free block must move: a bound of 1 nm on its displacement fails.
    std::fs::write(
        &scene,
        r#"Scene(
    name: "must fail",
    mesh: Box((cells: (2, 2, 2), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    gravity: (0.0, 0.0, -9.81),
    dt: BoundFraction(0.5),
    steps: 200,
    expect: [MaxDisplacement(max: Some(1e-9))],
)"#,
    )
    .unwrap();
    let out = lancet(&["run", scene.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("FAIL"));
}

#[test]
fn malformed_scene_exits_with_code_2_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("broken.ron");
    std::fs::write(
        &scene,
        "Scene(\n    name: \"x\",\n    mesh: Sphere(1.0),\n)",
    )
    .unwrap();
    let out = lancet(&["run", scene.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("broken.ron") && err.contains("line 3"),
        "{err}"
    );
}

#[test]
fn missing_mesh_file_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("missing.ron");
    std::fs::write(
        &scene,
        r#"Scene(name: "m", mesh: File("nowhere.msh"),
    material: (stiffness: Spring(10.0), mass: PerNode(0.01)), dt: Seconds(1e-4), steps: 1)"#,
    )
    .unwrap();
    let out = lancet(&["run", scene.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nowhere.msh"));
}

#[test]
fn info_reports_counts_volume_and_regions_as_json() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("two.mesh");
    // Two tets sharing a face, regions 1 and 7; total volume 1/6 + 1/6.
    std::fs::write(
        &mesh,
        "MeshVersionFormatted 1\nDimension 3\nVertices\n5\n0 0 0 0\n1 0 0 0\n0 1 0 0\n\
         0 0 1 0\n0 0 -1 0\nTetrahedra\n2\n1 2 3 4 1\n1 3 2 5 7\nEnd\n",
    )
    .unwrap();
    let out = lancet(&["info", mesh.to_str().unwrap(), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json_of(&out);
    assert_eq!(v["nodes"], 5);
    assert_eq!(v["tets"], 2);
    assert_eq!(v["edges"], 9);
    assert_eq!(v["boundary_faces"], 6);
    assert_eq!(v["components"], 1);
    assert_eq!(v["inverted"], 0);
    assert!((v["volume"].as_f64().unwrap() - 1.0 / 3.0).abs() < 1e-12);
    assert_eq!(v["regions"]["1"], 1);
    assert_eq!(v["regions"]["7"], 1);
    assert!(v["min_quality"].as_f64().unwrap() > 0.0);
    // The box of the five nodes: x and y in [0, 1], z in [-1, 1].
    assert_eq!(v["bounds"]["min"], serde_json::json!([0.0, 0.0, -1.0]));
    assert_eq!(v["bounds"]["max"], serde_json::json!([1.0, 1.0, 1.0]));
    assert_eq!(v["bounds"]["size"], serde_json::json!([1.0, 1.0, 2.0]));
    let text =
        String::from_utf8_lossy(&lancet(&["info", mesh.to_str().unwrap()]).stdout).into_owned();
    assert!(
        text.contains("size (1.000000e0, 1.000000e0, 2.000000e0)"),
        "{text}"
    );
}

#[test]
fn info_on_real_meshes_matches_their_readme() {
    let Some(dir) = std::env::var_os("LANCET_MESH_DIR") else {
        eprintln!("skipped: LANCET_MESH_DIR is not set");
        return;
    };
    let dir = PathBuf::from(dir);
    // (file, nodes, tets, edges, boundary faces, volume), from the meshes' README.
    let cases = [
        (
            "polyfem-data/cubes_v41.msh",
            7714,
            32981,
            44499,
            7610,
            2.09790,
        ),
        (
            "positionbaseddynamics/armadillo_4k.node",
            1180,
            3717,
            5947,
            2102,
            1.8596,
        ),
    ];
    for (file, nodes, tets, edges, faces, volume) in cases {
        let out = lancet(&["info", dir.join(file).to_str().unwrap(), "--json"]);
        assert!(
            out.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v = json_of(&out);
        assert_eq!(v["nodes"], nodes, "{file}");
        assert_eq!(v["tets"], tets, "{file}");
        assert_eq!(v["edges"], edges, "{file}");
        assert_eq!(v["boundary_faces"], faces, "{file}");
        let vol = v["volume"].as_f64().unwrap();
        assert!((vol / volume - 1.0).abs() < 1e-4, "{file}: volume {vol}");
    }
}

#[test]
fn info_on_a_bad_file_exits_2_with_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("nan.mesh");
    std::fs::write(
        &mesh,
        "MeshVersionFormatted 1\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\nnan 1 0 0\n\
         0 0 1 0\nTetrahedra\n1\n1 2 3 4 1\nEnd\n",
    )
    .unwrap();
    let out = lancet(&["info", mesh.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("nan.mesh") && err.contains("line 7"), "{err}");
}

#[test]
fn run_with_output_writes_a_pvd_series_of_frames_that_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let out = lancet(&["run", "--output", dir.path().to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let pvd = std::fs::read_to_string(dir.path().join("default_hanging_beam.pvd")).unwrap();
    let frames: Vec<&str> = pvd
        .split("file=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap())
        .collect();
    // The first state, then every tenth of the run.
    assert_eq!(frames.len(), 11, "{pvd}");
    let first = lancet::mesh::io::read(dir.path().join(frames[0])).unwrap();
    let last = lancet::mesh::io::read(dir.path().join(frames[10])).unwrap();
    assert_eq!(first.mesh.node_count(), 1701);
    assert_eq!(last.mesh.tet_count(), first.mesh.tet_count());
    // The beam sags under gravity: the last frame's lowest point is below the first's.
    let lowest = |m: &lancet::TetMesh| m.nodes().map(|(_, n)| n.rest.z).fold(f64::MAX, f64::min);
    assert!(lowest(&last.mesh) < lowest(&first.mesh) - 1e-5);
}

/// `--method` and `--check` act on cuts: on a scene without a `cut` section they are noted on
/// stderr as having no effect, and the run goes on.
#[test]
fn run_notes_that_cut_options_do_nothing_on_a_scene_that_does_not_cut() {
    let out = lancet(&[
        "run",
        "--no-output",
        "--steps",
        "10",
        "--method",
        "remove",
        "--check",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    // Ten steps are too few for the default scene's expectations (exit code 1); the point is
    // that it ran them.
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("ran 10 steps"),
        "{err}"
    );
    assert!(
        err.contains("--method and --check have no effect: the scene does not cut"),
        "{err}"
    );
    let plain = lancet(&["run", "--no-output", "--steps", "10"]);
    assert!(!String::from_utf8_lossy(&plain.stderr).contains("no effect"));
}

/// A scene with a `cut` section and no blade runs (a scene may check that other tools do not
/// cut) with a warning that nothing will cut.
#[test]
fn run_warns_about_a_cut_section_without_a_blade() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bladeless.ron");
    std::fs::write(
        &scene,
        r#"Scene(
    name: "cut without a blade",
    mesh: Box((cells: (2, 2, 2), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    dt: BoundFraction(0.5),
    steps: 10,
    cut: Some((methods: [Separate])),
)"#,
    )
    .unwrap();
    let out = lancet(&["run", scene.to_str().unwrap(), "--no-output"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning:") && err.contains("bladeless.ron") && err.contains("no blade"),
        "{err}"
    );
}

/// A 3 cm box, hanging from its y = 0 face, that a blade cuts through at y = 1.7 cm by
/// separating (two pieces), with checks off and the expectations `expect`, written in `dir`.
fn separated_box_scene(dir: &Path, expect: &str) -> PathBuf {
    let scene = dir.join("separated_box.ron");
    std::fs::write(
        &scene,
        format!(
            r#"Scene(
    name: "cut, checks off",
    mesh: Box((cells: (3, 3, 3), size: (0.03, 0.03, 0.03))),
    material: (stiffness: Material(youngs_modulus: 2e4, poisson_ratio: 0.3), mass: Density(1000.0)),
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (0.0, 1.0, 0.0), tolerance: 1e-9)],
    dt: BoundFraction(0.8),
    steps: 100,
    engine: Fast,
    tools: [(
        name: "scalpel",
        shape: Blade(width: 0.1, length: 0.1, thickness: 2e-4),
        trajectory: Keyframes([
            (time: 0.0, translation: (0.015, 0.017, 0.04)),
            (time: 0.01, translation: (0.015, 0.017, -0.01)),
        ]),
    )],
    cut: Some((methods: [Separate], check: false)),
    expect: [{expect}],
)"#
        ),
    )
    .unwrap();
    scene
}

/// `--check` turns the invariant checks on for a scene that leaves them off (no `check: true`,
/// no `InvariantsHold`): without it no cut is checked, with it every cut is; and the run's
/// per-cut latencies are ordered (p50 <= p99 <= max).
#[test]
fn run_check_turns_the_invariant_checks_on() {
    let dir = tempfile::tempdir().unwrap();
    let scene = separated_box_scene(dir.path(), "Fragments(min: Some(2), max: Some(2))");
    let path = scene.to_str().unwrap();
    let cuts = |extra: &[&str]| {
        let mut args = vec!["run", "--no-output", "--json"];
        args.extend_from_slice(extra);
        args.push(path);
        ok_json(&lancet(&args))["cuts"].clone()
    };
    let (off, on) = (cuts(&[]), cuts(&["--check"]));
    let n = |c: &serde_json::Value, k: &str| c[k].as_u64().unwrap();
    assert!(n(&off, "cuts") > 0, "{off:#}");
    assert_eq!(n(&off, "checks"), 0, "{off:#}");
    assert_eq!(n(&on, "checks"), n(&on, "cuts"), "{on:#}");
    assert!(on["violations"].as_array().unwrap().is_empty(), "{on:#}");
    let f = |k: &str| on[k].as_f64().unwrap();
    assert!(
        f("p50_ms") <= f("p99_ms") && f("p99_ms") <= f("max_ms"),
        "{on:#}"
    );
}

/// A local incision touches about as much of a larger mesh as of a smaller one: the bytes a cut
/// event writes stay flat while the layout grows over four times (3,000 to 24,000 tets), on the
/// fast CPU engine and, where there is an adapter, the GPU valence and edge layouts; and each
/// row's latencies are ordered (p50 <= p99 <= max).
#[test]
fn bench_cut_bytes_per_cut_stay_flat_as_the_mesh_grows() {
    let out = lancet(&[
        "bench",
        "cut",
        "--cube",
        "10,20",
        "--engine",
        "fast,gpu",
        "--layout",
        "valence,edges",
        "--method",
        "separate,subdivide,remove",
        "--json",
    ]);
    let rows = ok_json(&out).as_array().unwrap().clone();
    let f = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap();
    let s = |r: &serde_json::Value, k: &str| r[k].as_str().unwrap().to_string();
    let mut pairs = 0;
    for small in rows.iter().filter(|r| r["tets"].as_u64() == Some(3_000)) {
        let large = rows
            .iter()
            .find(|r| {
                r["tets"].as_u64() == Some(24_000)
                    && s(r, "engine") == s(small, "engine")
                    && s(r, "method") == s(small, "method")
            })
            .unwrap_or_else(|| panic!("no 20-cell row for {small:#}"));
        assert!(
            f(large, "layout_bytes") > 4.0 * f(small, "layout_bytes"),
            "{small:#} {large:#}"
        );
        assert!(
            f(large, "bytes_per_cut") < 2.0 * f(small, "bytes_per_cut"),
            "{small:#} {large:#}"
        );
        pairs += 1;
    }
    assert!(pairs >= 3, "every method on the fast engine: {rows:#?}");
    for r in &rows {
        assert!(
            f(r, "p50_ms") <= f(r, "p99_ms") && f(r, "p99_ms") <= f(r, "max_ms"),
            "{r:#}"
        );
    }
}

/// A cut expectation that fails (two pieces where three are expected) fails the run with exit
/// code 1, naming it.
#[test]
fn a_failing_cut_expectation_exits_with_code_1() {
    let dir = tempfile::tempdir().unwrap();
    let scene = separated_box_scene(dir.path(), "Fragments(min: Some(3))");
    let out = lancet(&["run", "--no-output", scene.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains("FAIL  fragments"), "{stdout}");
}

/// `lancet run --json | head`: a reader that closes the pipe before the summary is printed ends
/// the process as it ends other Unix tools (by SIGPIPE), not with a panic and exit code 101.
#[cfg(unix)]
#[test]
fn a_closed_pipe_ends_the_run_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_lancet"))
        .args(["run", "--json", "--engine", "fast", "--no-output"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the lancet binary runs");
    // Closed before the run ends, so the summary is written to a pipe nobody reads.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), None, "{:?}: {stderr}", out.status);
    assert_eq!(
        out.status.signal(),
        Some(libc_sigpipe()),
        "{:?}",
        out.status
    );
}

/// SIGPIPE's number on Linux and the BSDs (and macOS).
#[cfg(unix)]
fn libc_sigpipe() -> i32 {
    13
}

/// Under `--json` an error is a JSON object on stdout that a program can parse (exit code 2),
/// for every command; without it, a line on stderr.
#[test]
fn errors_under_json_are_a_json_object() {
    for args in [
        &["run", "no/such/scene.ron", "--json"][..],
        &["info", "no/such/mesh.msh", "--json"][..],
    ] {
        let out = lancet(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let v = json_of(&out);
        let message = v["error"].as_str().expect("an error message");
        assert!(message.contains("no/such/"), "{args:?}: {message}");
    }
    let out = lancet(&["info", "no/such/mesh.msh"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
    assert!(String::from_utf8_lossy(&out.stderr).starts_with("error: "));
}

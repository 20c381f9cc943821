//! The `lancet` command line: exit codes, JSON fields, errors that name the file and line.

use crate::common;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn lancet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lancet"))
        .args(args)
        .output()
        .expect("the lancet binary runs")
}

fn json_of(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}):\n{}\nstderr:\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// The JSON a successful run printed (the run's stderr in the message otherwise).
fn ok_json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    json_of(out)
}

fn fixtures() -> PathBuf {
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

/// `--integrator backward-euler` benchmarks the implicit step at 1 ms on every engine: each
/// row gives the conjugate-gradient iterations per step and the time of one, the fast engine
/// the bytes one moves too (its bandwidth columns are then per iteration); the GPU gives its
/// row, or is skipped with the reason where no adapter is usable.
#[test]
fn bench_with_backward_euler_reports_time_and_bytes_per_cg_iteration() {
    let has_gpu = common::gpu().is_some();
    let out = lancet(&[
        "bench",
        "--cube",
        "4",
        "--steps",
        "20",
        "--engine",
        "reference,fast,gpu",
        "--layout",
        "connectivity",
        "--integrator",
        "backward-euler",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json_of(&out);
    let rows = v["rows"].as_array().unwrap();
    // Reference and fast, and the GPU's connectivity layout where an adapter is usable.
    assert_eq!(rows.len(), if has_gpu { 3 } else { 2 }, "{v}");
    for r in rows {
        let iterations = r["cg_iterations_per_step"].as_f64().unwrap();
        let per_iteration = r["ms_per_cg_iteration"].as_f64().unwrap();
        let per_step = r["ms_per_step"].as_f64().unwrap();
        assert!(iterations >= 1.0, "{r}");
        assert!(
            (per_iteration * iterations - per_step).abs() <= 1e-9 * per_step,
            "{r}"
        );
    }
    let fast = rows
        .iter()
        .find(|r| r["engine"].as_str().unwrap().starts_with("cpu-fast"))
        .unwrap();
    let bytes = fast["bytes_per_cg_iteration"].as_u64().unwrap();
    // At least the spring blocks: 28 bytes for each end of each spring.
    let springs = fast["springs"].as_u64().unwrap();
    assert!(bytes >= 2 * springs * 28, "{fast}");
    let achieved = fast["achieved_bytes_per_s"].as_f64().unwrap();
    let seconds = fast["ms_per_cg_iteration"].as_f64().unwrap() * 1e-3;
    assert!(
        (achieved - bytes as f64 / seconds).abs() <= 1e-6 * achieved,
        "{fast}"
    );
    let skipped = v["skipped"].as_array().unwrap();
    assert!(
        has_gpu
            || skipped
                .iter()
                .any(|s| s.as_str().unwrap().starts_with("gpu rows skipped")),
        "{v}"
    );
}

#[test]
fn bench_reports_every_engine_and_layout_with_bandwidth_and_error() {
    let has_gpu = common::gpu().is_some();
    let engines = if has_gpu { "fast,gpu" } else { "fast" };
    let out = lancet(&[
        "bench", "--cube", "4", "--steps", "40", "--engine", engines, "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json_of(&out);
    assert!(v["bandwidth"]["bytes_per_s"].as_f64().unwrap() > 1e8);
    // The device's copy is measured whenever a GPU engine is benchmarked: a buffer of at least
    // 16 MiB (past the caches), copied at a plausible rate (over 100 MB/s, under 100 TB/s).
    if has_gpu {
        let d = &v["device_bandwidth"];
        assert!(d["bytes"].as_u64().unwrap() >= 16 << 20, "{d}");
        let b = d["bytes_per_s"].as_f64().unwrap();
        assert!(b > 1e8 && b < 1e14, "{d}");
        assert!(["compute pass", "buffer copy"].contains(&d["method"].as_str().unwrap()));
    } else {
        assert!(v["device_bandwidth"].is_null());
    }
    let rows = v["rows"].as_array().unwrap();
    // The CPU engine once, the GPU engine in each of the three layouts (when there is a GPU).
    let gpu_rows = rows
        .iter()
        .filter(|r| r["engine"].as_str().unwrap().starts_with("gpu-"))
        .count();
    assert!(
        gpu_rows == 3
            || (gpu_rows == 0 && std::env::var("LANCET_REQUIRE_GPU").as_deref() != Ok("1"))
    );
    for r in rows {
        let ms = r["ms_per_step"].as_f64().unwrap();
        let bytes = r["bytes_per_step"].as_u64().unwrap();
        assert!(ms > 0.0 && bytes > 0, "{r}");
        // Achieved bandwidth is bytes over time, and the floor ratio is its share of the triad.
        let achieved = r["achieved_bytes_per_s"].as_f64().unwrap();
        assert!((achieved - bytes as f64 / (ms * 1e-3)).abs() <= 1e-6 * achieved);
        assert!(r["floor_ratio"].as_f64().unwrap() > 0.0);
        // GPU rows against the device's copy bandwidth, CPU rows against the host's triad.
        let on_gpu = r["engine"].as_str().unwrap().starts_with("gpu-");
        let floor = if on_gpu {
            &v["device_bandwidth"]["bytes_per_s"]
        } else {
            &v["bandwidth"]["bytes_per_s"]
        };
        assert_eq!(r["bandwidth_bytes_per_s"].as_f64(), floor.as_f64(), "{r}");
        let ratio = r["floor_ratio"].as_f64().unwrap();
        assert!(
            (ratio - achieved / floor.as_f64().unwrap()).abs() <= 1e-9 * ratio,
            "{r}"
        );
        assert!(r["error_vs_reference"].as_f64().unwrap() < 1e-2, "{r}");
        // Timestamp queries time the GPU engine only.
        if !r["engine"].as_str().unwrap().starts_with("gpu-") {
            assert!(r["gpu_ms_per_step"].is_null(), "{r}");
        }
    }
}

/// `bench cut` gives a row per method, and per quality floor for subdividing: a floor keeps the
/// lowest tet quality at or above it and the stable step at least as long as without; each cut
/// uploads a part of the layout, not all of it.
#[test]
fn bench_cut_reports_each_quality_floor_of_subdividing() {
    let out = lancet(&[
        "bench",
        "cut",
        "--cube",
        "8",
        "--engine",
        "fast",
        "--method",
        "separate,subdivide",
        "--quality-floor",
        "0,0.3",
        "--json",
    ]);
    let v = ok_json(&out);
    let rows = v.as_array().unwrap();
    let of = |method: &str, floor: f64| {
        rows.iter()
            .find(|r| r["method"] == method && r["quality_floor"].as_f64() == Some(floor))
            .unwrap_or_else(|| panic!("no {method} row at floor {floor}: {v:#}"))
    };
    assert_eq!(rows.len(), 3, "{v:#}");
    let (without, with) = (of("subdivide", 0.0), of("subdivide", 0.3));
    let q = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap();
    assert!(q(with, "min_quality") >= 0.3, "{with:#}");
    assert!(q(without, "min_quality") < 0.3, "{without:#}");
    assert!(q(with, "dt_after") >= q(without, "dt_after"));
    assert!(q(without, "dt_after") < q(without, "dt_before"));
    for r in rows {
        assert!(r["cuts"].as_u64().unwrap() > 0, "{r:#}");
        assert!(q(r, "bytes_per_cut") < r["layout_bytes"].as_u64().unwrap() as f64);
    }
    // Separating makes no tets: the mesh keeps its quality.
    let separate = &rows.iter().find(|r| r["method"] == "separate").unwrap();
    assert!(q(separate, "min_quality") > 0.6, "{separate:#}");
}

/// Whether the preferred adapter has float32 atomics (the `atomic-float` accumulation).
fn has_float_atomics(ctx: &lancet::engine::gpu::GpuContext) -> bool {
    ctx.device
        .features()
        .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC)
}

#[test]
fn bench_gives_one_edges_row_per_accumulation_variant() {
    let Some(ctx) = common::gpu() else { return };
    let float_ok = has_float_atomics(&ctx);
    let timestamps = ctx
        .device
        .features()
        .contains(wgpu::Features::TIMESTAMP_QUERY);
    drop(ctx);
    let out = lancet(&[
        "bench",
        "--cube",
        "4",
        "--steps",
        "40",
        "--engine",
        "gpu",
        "--layout",
        "edges",
        "--accumulation",
        "gather,atomic-fixed,atomic-float",
        "--json",
    ]);
    let v = ok_json(&out);
    let rows = v["rows"].as_array().unwrap();
    let skipped = v["skipped"].as_array().unwrap();
    for (variant, name) in [
        ("gather", "gpu-edges on"),
        ("atomic-fixed", "gpu-edges-atomicfixed on"),
        ("atomic-float", "gpu-edges-atomicfloat on"),
    ] {
        let matching: Vec<_> = rows
            .iter()
            .filter(|r| r["accumulation"] == variant)
            .collect();
        if variant == "atomic-float" && !float_ok {
            // No row, and a note that says why.
            assert!(matching.is_empty(), "{v}");
            assert!(
                skipped
                    .iter()
                    .any(|s| s.as_str().unwrap().contains("SHADER_FLOAT32_ATOMIC")),
                "{v}"
            );
            continue;
        }
        assert_eq!(matching.len(), 1, "{variant}: {v}");
        let r = matching[0];
        assert_eq!(r["layout"], "edges");
        assert!(r["engine"].as_str().unwrap().starts_with(name), "{r}");
        assert!(r["ms_per_step"].as_f64().unwrap() > 0.0);
        assert!(r["error_vs_reference"].as_f64().unwrap() < 1e-2, "{r}");
        // Device time per chunk is inside the chunk's wall time (which adds submission and
        // the wait), so its median cannot exceed the wall-time median; 5% for clock skew.
        if timestamps {
            let gpu = r["gpu_ms_per_step"].as_f64().unwrap();
            let wall = r["ms_per_step"].as_f64().unwrap();
            assert!(gpu > 0.0 && gpu <= 1.05 * wall, "{r}");
        } else {
            assert!(r["gpu_ms_per_step"].is_null(), "{r}");
        }
    }
    assert_eq!(rows.len() + skipped.len(), 3, "{v}");
}

#[test]
fn run_with_each_accumulation_agrees_with_gather_on_the_default_scene() {
    let Some(ctx) = common::gpu() else { return };
    let float_ok = has_float_atomics(&ctx);
    drop(ctx);
    let run = |accumulation: &str| {
        lancet(&[
            "run",
            "--engine",
            "gpu",
            "--layout",
            "edges",
            "--accumulation",
            accumulation,
            "--json",
            "--no-output",
        ])
    };
    let gather = run("gather");
    assert!(
        gather.status.success(),
        "{}",
        String::from_utf8_lossy(&gather.stderr)
    );
    let g = json_of(&gather);
    for variant in ["atomic-fixed", "atomic-float"] {
        let out = run(variant);
        if variant == "atomic-float" && !float_ok {
            assert_eq!(out.status.code(), Some(2));
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(err.contains("float32 atomics"), "{err}");
            continue;
        }
        assert!(
            out.status.success(),
            "{variant}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v = json_of(&out);
        let tag = variant.replace('-', "");
        assert!(
            v["engine"]
                .as_str()
                .unwrap()
                .contains(&format!("-{tag} on")),
            "{v}"
        );
        // The same physics in float32 after 6000 steps: the fixed-point rounding (a force
        // quantum of 2^-scale N per spring and step) moves the tip by about 1e-4 of its sag,
        // float atomics by their summation order only; 1e-3 leaves room for both.
        // The volume change, not the ratio near 1, is what the tolerance is relative to.
        for (key, offset) in [("max_displacement", 0.0), ("volume_ratio", 1.0)] {
            let a = v[key].as_f64().unwrap() - offset;
            let b = g[key].as_f64().unwrap() - offset;
            assert!(
                (a - b).abs() <= 1e-3 * b.abs(),
                "{variant} {key}: {a} against gather {b}"
            );
        }
    }
}

/// `lancet` with the GPU hidden: only the Vulkan backend searched (so that wgpu's OpenGL
/// fallback on llvmpipe is not picked up), and the Vulkan loader pointed at no driver.
fn lancet_without_gpu(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lancet"))
        .args(args)
        .env("WGPU_BACKEND", "vulkan")
        .env("VK_ICD_FILENAMES", "/nonexistent")
        .env("VK_DRIVER_FILES", "/nonexistent")
        .output()
        .expect("the lancet binary runs")
}

/// `lancet bench --engine fast,gpu` without an adapter measures the CPU rows and lists the GPU
/// rows as skipped with the reason, as `lancet report accuracy` does (it exited 2 and dropped
/// the CPU rows).
#[test]
fn without_a_gpu_bench_runs_the_cpu_rows_and_skips_the_gpu_ones() {
    let out = lancet_without_gpu(&[
        "bench", "--cube", "4", "--engine", "fast,gpu", "--steps", "20", "--json",
    ]);
    let v = ok_json(&out);
    let rows = v["rows"].as_array().unwrap();
    assert!(!rows.is_empty());
    assert!(
        rows.iter()
            .all(|r| r["engine"].as_str().unwrap().contains("fast")),
        "{rows:?}"
    );
    let skipped: Vec<&str> = v["skipped"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap())
        .collect();
    assert_eq!(skipped.len(), 1, "{skipped:?}");
    assert!(skipped[0].starts_with("gpu rows skipped: "), "{skipped:?}");
}

/// `lancet bench` without `--engine` once benchmarked the CPU engines only, the GPU layouts
/// only when asked for; it measures every GPU layout when an adapter exists, and without one
/// runs the CPU rows and lists the GPU rows as skipped with the reason.
#[test]
fn bench_includes_the_gpu_layouts_by_default() {
    let args = ["bench", "--cube", "3", "--steps", "10", "--json"];
    let engines = |v: &serde_json::Value| -> Vec<String> {
        v["rows"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["engine"].as_str().unwrap().to_string())
            .collect()
    };
    if common::gpu().is_some() {
        let v = ok_json(&lancet(&args));
        let rows = engines(&v);
        for layout in ["connectivity", "valence", "edges"] {
            assert!(
                rows.iter()
                    .any(|e| e.starts_with("gpu-") && e.contains(layout)),
                "no {layout} row in {rows:?}"
            );
        }
        assert!(rows.iter().any(|e| e.contains("fast")), "{rows:?}");
    } else {
        assert_ne!(std::env::var("LANCET_REQUIRE_GPU").as_deref(), Ok("1"));
    }
    let v = ok_json(&lancet_without_gpu(&args));
    let rows = engines(&v);
    assert!(rows.iter().all(|e| !e.starts_with("gpu-")), "{rows:?}");
    assert!(rows.iter().any(|e| e.contains("fast")), "{rows:?}");
    let skipped = v["skipped"].as_array().unwrap();
    assert_eq!(skipped.len(), 1, "{skipped:?}");
    assert!(
        skipped[0]
            .as_str()
            .unwrap()
            .starts_with("gpu rows skipped: "),
        "{skipped:?}"
    );
}

#[test]
fn without_a_gpu_auto_runs_on_the_cpu_and_says_why() {
    let out = lancet_without_gpu(&["run", "--engine", "auto", "--no-output"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("engine: cpu-fast-f32"), "{stdout}");
    let note = stdout
        .lines()
        .find(|l| l.starts_with("note: "))
        .unwrap_or_else(|| panic!("no note in:\n{stdout}"));
    assert!(
        note.contains("no usable GPU")
            && note.contains("no GPU adapter found")
            && note.contains("WGPU_BACKEND=\"vulkan\"")
            && note.contains("running the fast CPU engine"),
        "{note}"
    );
    // The same in the JSON summary.
    let out = lancet_without_gpu(&["run", "--engine", "auto", "--steps", "20", "--json"]);
    let v = json_of(&out);
    assert_eq!(v["engine"], "cpu-fast-f32");
    assert!(v["engine_note"]
        .as_str()
        .is_some_and(|n| n.contains("no usable GPU")));
}

#[test]
fn without_a_gpu_engine_gpu_exits_2_saying_what_to_install() {
    let out = lancet_without_gpu(&["run", "--engine", "gpu", "--no-output"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let err = String::from_utf8_lossy(&out.stderr);
    let line = err
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("no error line in:\n{err}"));
    assert!(
        line.contains("no GPU adapter found")
            && line.contains("WGPU_BACKEND")
            && line.contains("mesa-vulkan-drivers")
            && line.contains("--engine cpu"),
        "{line}"
    );
}

#[test]
fn unknown_wgpu_backend_is_a_clear_error() {
    let out = Command::new(env!("CARGO_BIN_EXE_lancet"))
        .args(["run", "--engine", "gpu", "--no-output"])
        .env("WGPU_BACKEND", "glide")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("WGPU_BACKEND=\"glide\" names no backend"),
        "{err}"
    );
}

/// wgpu's OpenGL backend on llvmpipe runs compute but has no float atomics: there, bench skips
/// the atomic-float row with a note and run refuses it with exit code 2. Skipped where no GL
/// adapter exists.
#[test]
fn atomic_float_without_float_atomics_is_skipped_in_bench_and_refused_in_run() {
    let with_gl = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_lancet"))
            .args(args)
            .env("WGPU_BACKEND", "gl")
            .output()
            .unwrap()
    };
    let out = with_gl(&[
        "bench",
        "--cube",
        "3",
        "--steps",
        "20",
        "--engine",
        "gpu",
        "--layout",
        "edges",
        "--accumulation",
        "gather,atomic-float",
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    if err.contains("no GPU adapter found") {
        eprintln!("skipped: no OpenGL adapter ({err})");
        return;
    }
    let v = json_of(&out);
    let rows = v["rows"].as_array().unwrap();
    assert!(
        rows.iter()
            .any(|r| r["accumulation"] == "gather" && r["engine"].as_str().unwrap().contains("Gl")),
        "{v}"
    );
    let float_row = rows.iter().any(|r| r["accumulation"] == "atomic-float");
    let run = with_gl(&[
        "run",
        "--engine",
        "gpu",
        "--layout",
        "edges",
        "--accumulation",
        "atomic-float",
        "--steps",
        "20",
        "--no-output",
    ]);
    if float_row {
        eprintln!("this OpenGL adapter has float atomics; the refusal is not exercised");
        assert_ne!(run.status.code(), Some(2));
        return;
    }
    let skipped = v["skipped"].as_array().unwrap();
    assert_eq!(skipped.len(), 1, "{v}");
    assert!(
        skipped[0]
            .as_str()
            .unwrap()
            .contains("needs float32 atomics"),
        "{v}"
    );
    assert_eq!(run.status.code(), Some(2));
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains("needs float32 atomics") && err.contains("--accumulation atomic-fixed"),
        "{err}"
    );
}

#[test]
fn bench_collide_reports_each_surface_and_tool_count_with_a_culling_ratio() {
    if common::gpu().is_none() {
        return;
    }
    let out = lancet(&[
        "bench",
        "collide",
        "--triangles",
        "400,1600",
        "--tools",
        "1,2",
        "--repeats",
        "2",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json_of(&out);
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 4, "two surfaces times two tool counts");
    for r in rows {
        let (tris, ratio) = (
            r["triangles"].as_u64().unwrap(),
            r["culling_ratio"].as_f64().unwrap(),
        );
        assert!(tris >= 400, "{r}");
        // Millimetre tools touch a small part of a centimetre surface.
        assert!(ratio > 0.0 && ratio < 0.5, "{r}");
        for key in [
            "gpu_tool_ms",
            "bvh_tool_ms",
            "narrow_us_per_candidate",
            "gpu_pose_to_force_ms",
            "cpu_pose_to_force_ms",
        ] {
            assert!(r[key].as_f64().unwrap() > 0.0, "{key}: {r}");
        }
    }
}

/// `bench cut` inputs that cannot give a cut, or a quality floor that is not a volume-length
/// ratio, are refused with exit code 2 and a message saying what to give instead, before any
/// row is printed (they once gave rows of 0 cuts and NaN nodes/cm2, and exit code 0).
#[test]
fn bench_cut_refuses_inputs_that_cannot_cut() {
    let smallest = lancet::report::cut_bench::smallest_cube();
    let too_small = (smallest - 1).to_string();
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec!["--cube", "1"],
            format!("give cubes of {smallest} cells or more"),
        ),
        (
            vec!["--cube", "2"],
            format!("give cubes of {smallest} cells or more"),
        ),
        (
            vec!["--cube", &too_small],
            format!("give cubes of {smallest} cells or more"),
        ),
        (vec!["--length", "0"], "must be positive and finite".into()),
        (vec!["--length=-0.01"], "must be positive and finite".into()),
        (
            vec!["--length", "nan"],
            "must be positive and finite".into(),
        ),
        (
            vec!["--length", "inf"],
            "must be positive and finite".into(),
        ),
        (vec!["--quality-floor", "nan"], "in [0, 1)".into()),
        (vec!["--quality-floor", "inf"], "in [0, 1)".into()),
        (vec!["--quality-floor=-0.1"], "in [0, 1)".into()),
        (vec!["--quality-floor", "1"], "in [0, 1)".into()),
        (vec!["--quality-floor", "0.2,1.5"], "in [0, 1)".into()),
        // Long enough to be valid, too short to meet an edge: found out by trying.
        (
            vec!["--cube", "4", "--length", "0.001"],
            "made no cut".into(),
        ),
        (vec!["--incisions", "0"], "at least one incision".into()),
        // A 12-cell box fits five planes two cells apart a cell from its sides, and one 3 cm
        // incision across in x ((12 - 2 - 3) / (3 + 2) < 2).
        (
            vec!["--cube", "12", "--incisions", "6"],
            "(5 do, two cells apart".into(),
        ),
    ];
    for (args, says) in cases {
        let mut all = vec!["bench", "cut", "--engine", "fast"];
        all.extend(&args);
        let out = lancet(&all);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(&says), "{args:?}: {err}");
        assert!(out.stdout.is_empty(), "{args:?} printed rows");
    }
}

/// More incisions cut more: each is a separate incision of the same size (the cut area grows
/// with their number and the growth per area stays that of one), placed at further planes and
/// then further along the box.
#[test]
fn bench_cut_makes_as_many_incisions_as_asked() {
    let row = |incisions: &str| {
        let out = lancet(&[
            "bench",
            "cut",
            "--cube",
            "20",
            "--engine",
            "fast",
            "--method",
            "remove",
            "--incisions",
            incisions,
            "--json",
        ]);
        ok_json(&out).as_array().unwrap()[0].clone()
    };
    // 20 cells: 9 planes (y = 1.3 ... 17.3 cells) at the middle, and centres 5 cells either
    // side, so 12 incisions take a second column.
    let (four, twelve) = (row("4"), row("12"));
    let f = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap();
    assert!((f(&twelve, "area_cm2") - 3.0 * f(&four, "area_cm2")).abs() < 1e-9);
    // The same incision elsewhere takes about as many events (the tissue sags differently
    // near the sides, so not exactly as many).
    let cuts = |r: &serde_json::Value| r["cuts"].as_u64().unwrap() as f64;
    assert!(
        (cuts(&twelve) - 3.0 * cuts(&four)).abs() <= 0.1 * 3.0 * cuts(&four),
        "{four:#} {twelve:#}"
    );
    let per_area = |r: &serde_json::Value| f(r, "tets_removed_per_cm2");
    assert!(
        (per_area(&twelve) - per_area(&four)).abs() < 0.2 * per_area(&four),
        "{four:#} {twelve:#}"
    );
}

/// The smallest box the refusal names does cut, with every method: a row there has cuts and a
/// finite growth per cut area.
#[test]
fn bench_cut_cuts_in_the_smallest_box_it_accepts() {
    let smallest = lancet::report::cut_bench::smallest_cube().to_string();
    let out = lancet(&[
        "bench", "cut", "--cube", &smallest, "--engine", "fast", "--json",
    ]);
    let v = ok_json(&out);
    let rows = v.as_array().unwrap();
    assert_eq!(rows.len(), 3, "{v:#}");
    for r in rows {
        assert!(r["cuts"].as_u64().unwrap() > 0, "{r:#}");
        assert!(
            r["nodes_per_cm2"].as_f64().is_some_and(f64::is_finite),
            "{r:#}"
        );
        // The slowest event's parts are the whole of the largest latency.
        let s = &r["slowest"];
        let parts: f64 = ["read_ms", "cut_ms", "apply_ms", "surface_ms"]
            .iter()
            .map(|k| s[k].as_f64().unwrap())
            .sum();
        let max = r["max_ms"].as_f64().unwrap();
        assert!((parts - max).abs() <= 1e-9 * max.max(1.0), "{r:#}");
        // The quiet steps before and after the incisions were timed; the CPU engine has no
        // device time to give.
        for k in ["quiet_step_before_ms", "quiet_step_after_ms"] {
            let ms = r[k].as_f64().unwrap_or(f64::NAN);
            assert!(ms > 0.0 && ms.is_finite(), "{k}: {r:#}");
        }
        for k in ["quiet_device_before_ms", "quiet_device_after_ms"] {
            assert!(
                r.get(k).is_some_and(serde_json::Value::is_null),
                "{k}: {r:#}"
            );
        }
    }
}

/// The engine column of the `bench cut` table holds the short engine label; the GPU adapter,
/// whose name is long, is named once above the table instead of cut off in every row.
#[test]
fn bench_cut_table_names_the_adapter_once_above_short_engine_labels() {
    if common::gpu().is_none() {
        return;
    }
    let smallest = lancet::report::cut_bench::smallest_cube().to_string();
    let out = lancet(&[
        "bench",
        "cut",
        "--cube",
        &smallest,
        "--engine",
        "gpu",
        "--layout",
        "connectivity,valence",
        "--method",
        "separate",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let device = stdout
        .lines()
        .find_map(|l| l.strip_prefix("gpu device: "))
        .unwrap_or_else(|| panic!("no device line:\n{stdout}"));
    assert_eq!(stdout.matches(device).count(), 1, "{stdout}");
    for label in ["gpu-connectivity ", "gpu-valence "] {
        assert!(
            stdout.lines().any(|l| l.contains(label)),
            "{label}: {stdout}"
        );
    }
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

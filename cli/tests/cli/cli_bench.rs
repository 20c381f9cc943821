//! `lancet bench` from the command line: every engine, layout and accumulation with bandwidth
//! and error, `bench cut` and `bench collide`, and the GPU rows skipped with the reason
//! where no adapter is found.

use crate::cli::{json_of, lancet, ok_json};
use crate::common;
use std::process::{Command, Output};

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

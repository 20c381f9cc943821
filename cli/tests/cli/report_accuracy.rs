//! `lancet::report::accuracy`: error against run time over a ladder of time steps.

use crate::common;
use std::path::Path;

use lancet::engine::EngineKind;
use lancet::engine::Integrator;
use lancet::layout::edges::Accumulation;
use lancet::layout::LayoutKind;
use lancet::report::accuracy::{
    model_accuracy, scene_accuracy, step_for_times, AccuracyOptions, AccuracyReport, AccuracyRow,
};
use lancet::scene::runner::{build_mesh, model_config};
use lancet::scene::Scene;

/// A 3 x 2 x 2-cell box of soft tissue (36 nodes), clamped at x = 0, released from rest under
/// gravity. `damping` is mass-proportional, 1/s. Its scene runs 400 steps at 0.9 of the bound.
fn tiny_box(damping: f64) -> Scene {
    let text = format!(
        r#"Scene(
            name: "tiny box",
            mesh: Box((cells: (3, 2, 2), size: (0.03, 0.02, 0.02))),
            material: (
                stiffness: Material(youngs_modulus: 10e3, poisson_ratio: 0.25),
                mass: Density(1000.0),
            ),
            gravity: (0.0, 0.0, -9.81),
            mass_damping: {damping:?},
            fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: 1e-9)],
            dt: BoundFraction(0.9),
            steps: 400,
        )"#
    );
    Scene::from_ron(&text, Path::new("tiny_box.ron")).unwrap()
}

fn cpu_options(ladder: &[f64]) -> AccuracyOptions {
    AccuracyOptions {
        engines: vec![EngineKind::Reference, EngineKind::Fast],
        ladder: ladder.to_vec(),
        implicit_ladder: Vec::new(),
        ..Default::default()
    }
}

fn run(scene: &Scene, opts: &AccuracyOptions) -> AccuracyReport {
    scene_accuracy(scene, Path::new("tiny_box.ron"), opts, |_| {}).unwrap()
}

fn rows<'a>(report: &'a AccuracyReport, series: &str) -> Vec<&'a AccuracyRow> {
    report.rows.iter().filter(|r| r.series == series).collect()
}

/// The tiny box's model without gravity, and a smooth initial velocity: the free end moving
/// up at 5 cm/s, growing linearly from the clamp. Springs start at rest length, so the start
/// has no force and Verlet's start-up is exact to third order.
fn flicked_box(damping: f64) -> (lancet::PackedModel, AccuracyOptions) {
    let mut scene = tiny_box(damping);
    scene.gravity = [0.0; 3];
    let mesh = build_mesh(&scene, Path::new("tiny_box.ron")).unwrap();
    let model = lancet::SpringModel::build(&mesh, &model_config(&scene))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let v = model
        .rest
        .iter()
        .map(|p| [0.0, 0.0, 0.05 * p[0] / 0.03])
        .collect();
    let opts = AccuracyOptions {
        // Converged reference at 1/256 of the bound, so that its own error (1/16 of the
        // finest row's at second order) barely touches the ratios.
        reference_fraction: 1.0 / 256.0,
        initial_velocity: Some(v),
        ..cpu_options(&[0.25, 0.125, 0.0625])
    };
    (model, opts)
}

/// Ratios of each rung's error to the next finer rung's, at each sample time, for the
/// reference engine.
fn halving_ratios(report: &AccuracyReport) -> Vec<f64> {
    let reference = rows(report, "cpu-reference-f64");
    let mut out = Vec::new();
    for pair in reference.windows(2) {
        for (coarse, fine) in pair[0].errors.iter().zip(&pair[1].errors) {
            out.push(coarse.relative_l2 / fine.relative_l2);
            assert!(fine.max_error_m < coarse.max_error_m);
        }
    }
    out
}

#[test]
fn undamped_verlet_error_falls_at_second_order_as_dt_halves() {
    let (model, opts) = flicked_box(0.0);
    let report = model_accuracy(
        "flicked box",
        &model,
        Integrator::Verlet,
        0.2,
        &opts,
        |_| {},
    )
    .unwrap();
    // Second order: halving dt cuts the error 4x in the limit. Measured on this box: 4.0 to
    // 4.2 (the rungs' steps are not exactly halved, as they must divide the sample times).
    // 3 leaves room and is still far from first order's 2.
    let ratios = halving_ratios(&report);
    assert!(ratios.iter().all(|&r| r > 3.0), "{ratios:?}");
    // The reference's self-check (2 dt against dt, both 16 times finer than the finest
    // rung) is far below the finest rung: the reference is converged relative to the rows.
    let finest = rows(&report, "cpu-reference-f64")
        .last()
        .unwrap()
        .worst_relative_l2();
    assert!(
        report.reference_self_error() < finest / 10.0,
        "self-check {:.3e} vs finest row {finest:.3e}",
        report.reference_self_error()
    );
}

#[test]
fn damped_verlet_converges_at_first_order() {
    // The damping force takes the backward-difference velocity, an O(dt) approximation, so a
    // damped run converges at first order: halving dt about halves the error. Measured: 2.0
    // to 2.1.
    let (model, opts) = flicked_box(200.0);
    let report = model_accuracy(
        "flicked box",
        &model,
        Integrator::Verlet,
        0.2,
        &opts,
        |_| {},
    )
    .unwrap();
    let ratios = halving_ratios(&report);
    assert!(ratios.iter().all(|r| (1.6..2.6).contains(r)), "{ratios:?}");
}

#[test]
fn a_run_from_rest_under_gravity_converges_at_first_order() {
    // The engines start Verlet with the previous positions equal to the current ones, so the
    // first step under gravity moves h^2 g instead of h^2 g / 2: an O(dt) error in the
    // initial velocity, hence first order overall even without damping. Measured: 2.0 to 2.3.
    let opts = AccuracyOptions {
        reference_fraction: 1.0 / 256.0,
        ..cpu_options(&[0.25, 0.125])
    };
    let report = run(&tiny_box(0.0), &opts);
    let ratios = halving_ratios(&report);
    assert!(ratios.iter().all(|r| (1.6..2.6).contains(r)), "{ratios:?}");
}

/// The reference is fourth-order Runge–Kutta: its self-check (the reference at twice its step
/// against itself) falls about sixteen times when its step halves, and it sits far below the
/// error of the float64 Verlet rows it judges.
#[test]
fn the_reference_converges_at_fourth_order_far_below_the_rows() {
    let report_at = |reference_fraction: f64| {
        let opts = AccuracyOptions {
            engines: vec![EngineKind::Reference],
            reference_fraction,
            ..cpu_options(&[0.5, 0.125])
        };
        run(&tiny_box(0.0), &opts)
    };
    let (coarse, fine) = (report_at(0.25), report_at(0.125));
    for r in [&coarse, &fine] {
        // The self-check runs at twice the reference step (exactly, here).
        assert!((r.reference.check_dt / r.reference.dt - 2.0).abs() < 1e-12);
        assert!(
            r.reference.engine.contains("runge-kutta-4"),
            "{}",
            r.reference.engine
        );
    }
    let ratio = coarse.reference_self_error() / fine.reference_self_error();
    assert!(
        (10.0..24.0).contains(&ratio),
        "self-check fell {ratio}x per halving"
    );
    let finest_row = coarse.rows[1].worst_relative_l2();
    assert!(
        coarse.reference_self_error() < 0.1 * finest_row,
        "reference self-check {:e} against the finest Verlet row's error {finest_row:e}",
        coarse.reference_self_error()
    );
    assert!(coarse.rows[0].worst_relative_l2() > finest_row);
}

#[test]
fn every_engine_and_layout_appears_once_per_dt_with_positive_times() {
    let gpu = common::gpu();
    let ladder = [1.0, 0.5, 0.25];
    let opts = AccuracyOptions {
        engines: vec![EngineKind::Reference, EngineKind::Fast, EngineKind::Gpu],
        layouts: vec![
            LayoutKind::Connectivity,
            LayoutKind::Valence,
            LayoutKind::Edges,
        ],
        ..cpu_options(&ladder)
    };
    let report = run(&tiny_box(0.0), &opts);
    let mut expected = vec!["cpu-reference-f64", "cpu-fast-f32"];
    if gpu.is_some() {
        expected.extend(["gpu-connectivity", "gpu-valence", "gpu-edges"]);
        assert!(report.skipped.is_empty(), "{:?}", report.skipped);
    } else {
        assert_eq!(report.skipped.len(), 1, "{:?}", report.skipped);
    }
    assert_eq!(report.series(), expected);
    assert_eq!(report.rows.len(), expected.len() * ladder.len());
    let bound = report.dt_bound;
    for s in &expected {
        let fractions: Vec<f64> = rows(&report, s).iter().map(|r| r.fraction).collect();
        assert_eq!(fractions, ladder, "{s}");
    }
    let reference_rows = rows(&report, "cpu-reference-f64");
    for r in &report.rows {
        assert!(r.diverged.is_none(), "{}: {:?}", r.series, r.diverged);
        assert!(r.wall_s_per_sim_s > 0.0 && r.wall_s_per_sim_s.is_finite());
        assert!(r.dt <= r.fraction * bound && r.dt > 0.9 * r.fraction * bound);
        assert_eq!(r.errors.len(), report.sample_times.len());
        // Steps land on the sample times.
        let last = *report.sample_times.last().unwrap();
        assert!((r.steps as f64 * r.dt - last).abs() < 1e-9 * last);
        // At equal dt, time discretisation dominates: a float32 engine's error is the float64
        // engine's to within a few per cent (float32 rounding is ~1e-7 relative per step).
        let same = reference_rows
            .iter()
            .find(|q| q.fraction == r.fraction)
            .unwrap();
        for (a, b) in r.errors.iter().zip(&same.errors) {
            assert!(
                (a.relative_l2 - b.relative_l2).abs() <= 0.05 * b.relative_l2,
                "{} at {}: {:.4e} vs reference engine {:.4e}",
                r.series,
                r.fraction,
                a.relative_l2,
                b.relative_l2
            );
        }
    }
    assert!(report.reference.wall_s_per_sim_s > 0.0);
}

/// `--accumulation`: the edge layout runs once per accumulation variant, each its own series
/// named for it, with the float64 Verlet engine's error at the same step (the variants change
/// only the order of float32 additions); a variant the adapter cannot run is listed as skipped.
#[test]
fn each_edge_accumulation_is_its_own_series() {
    if common::gpu().is_none() {
        eprintln!("skipped: no GPU adapter");
        return;
    }
    let opts = AccuracyOptions {
        engines: vec![EngineKind::Reference, EngineKind::Gpu],
        layouts: vec![LayoutKind::Valence, LayoutKind::Edges],
        accumulations: vec![
            Accumulation::Gather,
            Accumulation::AtomicFixed,
            Accumulation::AtomicFloat,
        ],
        ..cpu_options(&[0.5])
    };
    let report = run(&tiny_box(0.0), &opts);
    let series = report.series();
    for s in ["gpu-valence", "gpu-edges", "gpu-edges-atomic-fixed"] {
        assert!(series.iter().any(|x| x == s), "{s} missing from {series:?}");
    }
    let float_ran = series.iter().any(|x| x == "gpu-edges-atomic-float");
    let float_skipped = report
        .skipped
        .iter()
        .any(|m| m.contains("gpu-edges-atomic-float"));
    assert!(
        float_ran != float_skipped,
        "{series:?} {:?}",
        report.skipped
    );
    assert_eq!(series.len(), 4 + usize::from(float_ran), "{series:?}");
    let reference = rows(&report, "cpu-reference-f64")[0].worst_relative_l2();
    for s in series.iter().filter(|s| s.starts_with("gpu-edges")) {
        let row = rows(&report, s)[0];
        assert!(row.engine.contains("edges"), "{}", row.engine);
        let e = row.worst_relative_l2();
        assert!(
            (e - reference).abs() <= 0.05 * reference,
            "{s}: {e:e} vs {reference:e}"
        );
    }
}

#[test]
fn steps_divide_every_sample_time() {
    let (dt, counts) = step_for_times(&[0.01, 0.025], 1e-3).unwrap();
    assert!(dt <= 1e-3);
    assert_eq!(counts, vec![10, 25]);
    let (dt, counts) = step_for_times(&[0.01, 0.025], 3e-4).unwrap();
    assert!(dt <= 3e-4 && dt > 2.5e-4, "{dt}");
    for (c, t) in counts.iter().zip([0.01, 0.025]) {
        assert!((*c as f64 * dt - t).abs() < 1e-15);
    }
    // A target a hair below `t0 / 3` (inside the rounding slack): the step must not come out
    // above it (a rung at the bound would then be refused as unstable).
    for t0 in [0.01, 3.4111658238659263e-6 * 3.0, 0.7] {
        let target = (t0 / 3.0) * (1.0 - 1e-13);
        let (dt, counts) = step_for_times(&[t0], target).unwrap();
        assert!(dt <= target, "step {dt:e} above the target {target:e}");
        assert_eq!(counts, vec![3]);
    }
    assert!(step_for_times(&[1.0, std::f64::consts::SQRT_2], 1e-3).is_err());
    assert!(step_for_times(&[0.0], 1e-3).is_err());
}

/// A scene with tools or cuts is refused, naming what the report would leave out: it steps the
/// model alone (the crossing-cut box, run without its blades, does not move at all).
#[test]
fn scenes_with_tools_or_cuts_are_refused_naming_what_would_be_left_out() {
    for (file, what) in [
        ("cut_two_crossing.ron", "a cut"),
        ("grasp_lift.ron", "tools"),
    ] {
        let path = Path::new(crate::REPO).join("fixtures/scenes").join(file);
        let scene = Scene::read(&path).unwrap();
        let err = scene_accuracy(&scene, &path, &cpu_options(&[1.0]), |_| {}).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains(what) && msg.contains(file), "{file}: {msg}");
    }
}

#[test]
fn steps_above_the_bound_or_an_empty_ladder_are_refused() {
    let scene = tiny_box(0.0);
    for ladder in [vec![1.5], vec![], vec![-0.5]] {
        let err =
            scene_accuracy(&scene, Path::new("x.ron"), &cpu_options(&ladder), |_| {}).unwrap_err();
        assert!(
            matches!(err, lancet::Error::Options(_)),
            "{ladder:?}: {err}"
        );
    }
}

#[cfg(feature = "plot")]
mod plots {
    use super::*;
    use lancet::report::plot::{find_font, write_plots};

    const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

    fn report() -> AccuracyReport {
        run(&tiny_box(0.0), &cpu_options(&[1.0, 0.5]))
    }

    #[test]
    fn plots_are_written_as_svg_and_png_naming_each_series() {
        let report = report();
        let dir = tempfile::tempdir().unwrap();
        let files = write_plots(&report, dir.path(), find_font().as_deref()).unwrap();
        let svg = std::fs::read_to_string(&files.svg).unwrap();
        assert!(svg.contains("<svg"));
        for s in report.series() {
            assert!(svg.contains(&s), "SVG lacks {s}");
        }
        let png = std::fs::read(&files.png).unwrap();
        assert_eq!(png[..8], PNG_SIGNATURE);
        if find_font().is_some() {
            assert!(files.note.is_none(), "{:?}", files.note);
        }
    }

    /// The image widens to its legend's longest line (a backward Euler series of the edge
    /// layout's float atomics is 37 characters: a fixed 240 px legend cut it off), and the
    /// legend names what was asked for but not run, with no reason it was not given.
    #[test]
    fn the_legend_is_as_wide_as_its_longest_series_and_names_what_was_not_run() {
        let mut report = report();
        let long = "gpu-edges-atomic-float-backward-euler".to_string();
        let first = report.rows[0].series.clone();
        for r in report.rows.iter_mut().filter(|r| r.series == first) {
            r.series = long.clone();
        }
        report.skipped.push(
            "gpu-edges-atomic-fixed-backward-euler skipped: the fixed-point accumulation is \
             refused under backward Euler"
                .into(),
        );
        let dir = tempfile::tempdir().unwrap();
        let files = write_plots(&report, dir.path(), None).unwrap();
        let svg = std::fs::read_to_string(&files.svg).unwrap();
        let attribute = |name: &str| -> f64 {
            let at = svg.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
            let end = at + svg[at..].find('"').unwrap();
            svg[at..end].parse().unwrap()
        };
        // The chart is 760 px wide and the legend's text starts 48 px into the rest; DejaVu
        // Sans at 14 px advances about 7.7 px a character.
        let width = attribute("width");
        assert!(
            width >= 760.0 + 48.0 + 7.7 * long.len() as f64,
            "{width} px is too narrow for {long}"
        );
        assert!(svg.contains(&long));
        assert!(
            svg.contains("gpu-edges-atomic-fixed-backward-euler"),
            "{svg}"
        );
        assert!(!svg.contains("no adapter"));
    }

    #[test]
    fn without_a_font_the_png_is_still_written_and_says_so() {
        let report = report();
        let dir = tempfile::tempdir().unwrap();
        let files = write_plots(&report, dir.path(), None).unwrap();
        let png = std::fs::read(&files.png).unwrap();
        assert_eq!(png[..8], PNG_SIGNATURE);
        assert!(files.note.unwrap().contains("without text"));
        // The SVG needs no font metrics for its legend.
        let svg = std::fs::read_to_string(&files.svg).unwrap();
        assert!(svg.contains("cpu-fast-f32"));
    }
}

/// Backward Euler converges at first order: its error grows about fourfold from 2 to 8 times
/// the bound, and at each step it is no better than the explicit engine's at the bound (its
/// numerical damping is the price of its stability).
#[test]
fn implicit_series_run_above_the_bound_and_converge_at_first_order() {
    let opts = AccuracyOptions {
        engines: vec![EngineKind::Reference],
        implicit_ladder: vec![2.0, 8.0],
        ..cpu_options(&[1.0])
    };
    // Damped, as tissue is: undamped, backward Euler's numerical damping takes the motion
    // away entirely at these steps, and its error is the whole oscillation.
    let report = run(&tiny_box(60.0), &opts);
    let implicit = rows(&report, "cpu-reference-f64-backward-euler");
    assert_eq!(implicit.len(), 2, "{:?}", report.series());
    for r in &implicit {
        assert_eq!(r.integrator, "BackwardEuler");
        assert!(r.diverged.is_none(), "{:?}", r.diverged);
        assert!(r.dt_over_bound > 0.5 * r.fraction && r.dt_over_bound <= r.fraction);
    }
    let (e2, e8) = (
        implicit[0].worst_relative_l2(),
        implicit[1].worst_relative_l2(),
    );
    let ratio = e8 / e2 * (implicit[0].dt / implicit[1].dt) * 4.0;
    assert!(
        (2.0..8.0).contains(&ratio),
        "{e2:e} at 2x, {e8:e} at 8x: {ratio}"
    );
    let explicit = rows(&report, "cpu-reference-f64")[0].worst_relative_l2();
    assert!(e2 > explicit, "{e2:e} vs explicit {explicit:e}");
    // Time to error: a target every row meets gives each series a time; one no row meets, none.
    let all = report.time_to_error(f64::INFINITY);
    assert!(
        all.iter().all(|(_, t)| t.is_some_and(|t| t > 0.0)),
        "{all:?}"
    );
    let none = report.time_to_error(0.0);
    assert!(none.iter().all(|(_, t)| t.is_none()), "{none:?}");
}

/// The implicit series solve with the scene's `solver` settings (a stiff scene raises the cap
/// the default 100 would cut its large steps short at) and report their conjugate-gradient
/// iterations: a cap of 2 at a tolerance no solve meets stops every solve at 2 and counts
/// each as capped; with the default settings the same rows take more than 2 and none is
/// capped. Explicit rows report no iterations.
#[test]
fn implicit_rows_solve_with_the_scene_solver_and_report_their_iterations() {
    let mut scene = tiny_box(10.0);
    let opts = AccuracyOptions {
        engines: vec![EngineKind::Reference],
        implicit_ladder: vec![4.0],
        times: vec![0.01],
        ..cpu_options(&[1.0])
    };
    let default = run(&scene, &opts);
    scene.solver.tolerance = 1e-14;
    scene.solver.max_iterations = 2;
    let capped = run(&scene, &opts);
    for report in [&default, &capped] {
        assert!(rows(report, "cpu-reference-f64")[0].cg_iterations.is_none());
    }
    let of = |r: &AccuracyReport| {
        rows(r, "cpu-reference-f64-backward-euler")[0]
            .cg_iterations
            .expect("an implicit row reports its iterations")
    };
    let (d, c) = (of(&default), of(&capped));
    assert!(d.mean > 2.0 && d.capped == 0, "default settings: {d:?}");
    let steps = rows(&capped, "cpu-reference-f64-backward-euler")[0].steps;
    assert!(
        c.mean <= 2.0 && c.capped == steps,
        "cap 2: {c:?} over {steps} steps"
    );
}

//! `lancet report accuracy`: error against run time, with plots.

use super::*;

/// What `--model-error` asks for.
pub(crate) struct ModelErrorArgs {
    /// Measure the model error.
    pub on: bool,
    /// Meshes: the scene's and its refinements.
    pub refinements: usize,
    /// Skip the time-step ladder.
    pub only: bool,
    /// The force models of the table.
    pub force_models: Vec<lancet::physics::ForceModelKind>,
    /// The beam's cells along, across and split, where they replace the scene's.
    pub cells_along: Option<usize>,
    /// Cells across each side of the section.
    pub cells_across: Option<usize>,
    /// How cells are split.
    pub split: Option<lancet::mesh::generate::TetSplit>,
    /// The largest error on the finest mesh the run accepts (a fraction).
    pub expect_within: Option<f64>,
}

/// Run the accuracy report, print it, write its plots; with `--model-error`, the model error
/// beside it.
pub(crate) fn accuracy(
    scene_path: Option<&Path>,
    opts: &lancet::report::accuracy::AccuracyOptions,
    json: bool,
    plot: PlotTo,
    model_error: ModelErrorArgs,
) -> lancet::Result<ExitCode> {
    let (scene, path) = match scene_path {
        None => (
            Scene::default_scene(),
            PathBuf::from("<embedded default scene>"),
        ),
        Some(p) => (Scene::read(p)?, p.to_path_buf()),
    };
    if let Some(w) = model_error
        .expect_within
        .filter(|w| !(w.is_finite() && *w > 0.0))
    {
        return Err(lancet::Error::Options(format!(
            "--expect-within takes a positive fraction of the analytic answer (0.03 for 3%), \
             got {w}"
        )));
    }
    let models = if model_error.on {
        use lancet::report::model_error::with_beam_cells;
        let meshed = match (
            model_error.cells_along,
            model_error.cells_across,
            model_error.split,
        ) {
            (None, None, None) => scene.clone(),
            (along, across, split) => with_beam_cells(&scene, along, across, split)?,
        };
        Some(lancet::report::model_error::model_error(
            &meshed,
            &model_error.force_models,
            model_error.refinements,
            |line| {
                if !json {
                    eprintln!("solving {line}");
                }
            },
        )?)
    } else {
        None
    };
    // `--expect-within`: the finest mesh's error of each element model, checked after the
    // tables are printed, so that a failing run still shows them.
    let beyond = match (&models, model_error.expect_within) {
        (Some(m), Some(within)) => m.beyond(within),
        _ => Vec::new(),
    };
    let verdict = || {
        for b in &beyond {
            eprintln!("error: {b}");
        }
        if beyond.is_empty() {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        }
    };
    if model_error.only {
        let m = models.expect("--model-error-only requires --model-error");
        if json {
            let v = json!({ "model_error": m });
            println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        } else {
            print_model_error(&m);
        }
        return Ok(verdict());
    }
    let report = lancet::report::accuracy::scene_accuracy(&scene, &path, opts, |line| {
        if !json {
            eprintln!("running {line}");
        }
    })?;
    let plot_dir = match plot {
        PlotTo::Nowhere => None,
        PlotTo::Dir(d) => Some(d),
        PlotTo::Default => Some(match (&scene.output, scene_path) {
            (Some(o), Some(p)) => p.parent().unwrap_or(Path::new(".")).join(&o.dir),
            _ => PathBuf::from("."),
        }),
    };
    let plots = match plot_dir {
        Some(dir) => Some(write_accuracy_plots(&report, &dir)?),
        None => None,
    };
    if json {
        let v = json!({ "report": report, "model_error": models, "plots": plots });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(verdict());
    }
    print_accuracy(&report);
    print_time_to_error(&report, opts.target_error);
    if let Some(m) = &models {
        print_model_error(m);
    }
    if let Some(p) = plots {
        for f in ["svg", "png"] {
            if let Some(path) = p.get(f).and_then(|v| v.as_str()) {
                println!("wrote {path}");
            }
        }
    }
    Ok(verdict())
}

/// The model-error table.
pub(crate) fn print_model_error(m: &lancet::report::model_error::ModelErrorReport) {
    println!("model error against {}", m.analytic);
    println!("analytic tip deflection: {:.4e} m", m.analytic_tip_m);
    println!(
        "{:<14} {:>14} {:>8} {:>12} {:>9} {:>7} {:>8} {:>9}",
        "force model", "cells", "tets", "tip (m)", "error", "newton", "cg its", "solve s"
    );
    for r in &m.rows {
        println!(
            "{:<14} {:>14} {:>8} {:>12.4e} {:>8.2}% {:>7} {:>8} {:>9.3}",
            r.force_model,
            format!(
                "{} x {} x {}",
                r.cells_along, r.cells_across, r.cells_across
            ),
            r.tets,
            r.tip_m,
            100.0 * r.relative_error,
            r.newton,
            r.cg_iterations,
            r.solve_s
        );
    }
    for x in &m.extrapolated {
        println!(
            "{:<14} {:>14} {:>8} {:>12.4e} {:>8.2}%  (Richardson over the last three meshes, \
             order {:.2})",
            x.force_model,
            "no end",
            "",
            x.tip_m,
            100.0 * x.relative_error,
            x.order
        );
    }
    println!(
        "error: (tip - analytic) / analytic of the static answer (float64); negative: stiffer \
         than the beam. The time-step error above is against the same model, this against \
         elasticity."
    );
    if !m.extrapolated.is_empty() {
        println!(
            "no end: where the last three meshes converge to; trust it once they converge at \
             the element's order (2 for linear tets), not on coarse meshes."
        );
    }
}

/// Write the plots; their paths (and a note when the PNG has no text) as JSON.
#[cfg(feature = "plot")]
pub(crate) fn write_accuracy_plots(
    report: &lancet::report::accuracy::AccuracyReport,
    dir: &Path,
) -> lancet::Result<serde_json::Value> {
    use lancet::report::plot;
    let font = plot::find_font();
    let files = plot::write_plots(report, dir, font.as_deref())?;
    if let Some(n) = &files.note {
        eprintln!("note: {n}");
    }
    Ok(json!({
        "svg": files.svg.display().to_string(),
        "png": files.png.display().to_string(),
        "font": font.map(|f| f.display().to_string()),
        "note": files.note,
    }))
}

#[cfg(not(feature = "plot"))]
pub(crate) fn write_accuracy_plots(
    _: &lancet::report::accuracy::AccuracyReport,
    _: &Path,
) -> lancet::Result<serde_json::Value> {
    eprintln!("note: this build draws no plots (enable the `plot` cargo feature)");
    Ok(json!({ "note": "this build draws no plots" }))
}

pub(crate) fn print_accuracy(r: &lancet::report::accuracy::AccuracyReport) {
    println!(
        "scene: {} ({} nodes, {} springs), {}, force model {}, stable bound {:.4e} s",
        r.scene, r.nodes, r.springs, r.integrator, r.force_model, r.dt_bound
    );
    let times: Vec<String> = r.sample_times.iter().map(|t| format!("{t:.4e}")).collect();
    println!("sample times (s): {}", times.join(", "));
    let self_err: Vec<String> = r
        .reference
        .self_error
        .iter()
        .map(|e| format!("{:.2e}", e.relative_l2))
        .collect();
    println!(
        "reference: {} at dt {:.4e} s ({:.4} of the bound, {} steps, {:.3} s wall per simulated s)",
        r.reference.engine,
        r.reference.dt,
        r.reference.dt_over_bound,
        r.reference.steps,
        r.reference.wall_s_per_sim_s
    );
    println!(
        "reference self-check (dt {:.4e} s against dt {:.4e} s), rel L2 at each time: {}",
        r.reference.check_dt,
        r.reference.dt,
        self_err.join(", ")
    );
    for s in &r.skipped {
        println!("note: {s}");
    }
    print_gpu_devices(r.rows.iter().map(|row| row.engine.as_str()));
    print!(
        "{:<32} {:>8} {:>10} {:>8} {:>11} {:>6}",
        "series", "dt/bound", "dt (s)", "steps", "wall s/sim s", "CG it"
    );
    for k in 1..=r.sample_times.len() {
        print!(" {:>9} {:>9}", format!("relL2@t{k}"), format!("maxm@t{k}"));
    }
    println!();
    for row in &r.rows {
        let cg = row
            .cg_iterations
            .map_or("-".to_string(), |c| format!("{:.1}", c.mean));
        print!(
            "{:<32} {:>8.4} {:>10.3e} {:>8} {:>11.3e} {:>6}",
            row.series, row.dt_over_bound, row.dt, row.steps, row.wall_s_per_sim_s, cg
        );
        for e in &row.errors {
            print!(" {:>9.2e} {:>9.2e}", e.relative_l2, e.max_error_m);
        }
        if let Some(m) = &row.diverged {
            print!("  {m}");
        }
        if let Some(c) = row.cg_iterations.filter(|c| c.capped > 0) {
            print!(
                "  warning: {} solves stopped at the iteration cap",
                c.capped
            );
        }
        println!();
    }
    println!(
        "relL2: |x - x_ref| / |x_ref - x_rest| over all nodes; maxm: largest nodal error, m; \
         wall s/sim s: stepping time per simulated second; CG it: conjugate-gradient \
         iterations per solve (implicit rows)"
    );
}

/// Each series' least run time to `target` error, and how much sooner the best implicit series
/// gets there than the best explicit one.
fn print_time_to_error(r: &lancet::report::accuracy::AccuracyReport, target: f64) {
    let times = r.time_to_error(target);
    if times.is_empty() {
        return;
    }
    println!("time to relL2 <= {target:.0e} (least wall s per simulated s among the rows that reach it):");
    for (series, t) in &times {
        match t {
            Some(t) => println!("  {series:<34} {t:.3e}"),
            None => println!("  {series:<34} not reached"),
        }
    }
    let best = |implicit: bool| {
        times
            .iter()
            .filter(|(s, _)| s.ends_with("-backward-euler") == implicit)
            .filter_map(|(s, t)| t.map(|t| (s, t)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    };
    if let (Some((es, et)), Some((is, it))) = (best(false), best(true)) {
        println!(
            "  best implicit ({is}) reaches it {:.1}x sooner than the best explicit ({es})",
            et / it
        );
    }
}

/// Where `lancet report accuracy` writes its plots.
pub(crate) enum PlotTo {
    /// The scene's output folder, else the current folder.
    Default,
    /// This folder.
    Dir(PathBuf),
    /// No plots.
    Nowhere,
}

//! `lancet run`: scenes, folders of scenes and the embedded default, with their summaries.

use super::*;

/// Run one scene, a folder of scenes, or the default scene.
pub(crate) fn run(scene: Option<&Path>, json: bool, opts: &RunOptions) -> lancet::Result<ExitCode> {
    let scenes: Vec<(Scene, PathBuf)> = match scene {
        None => vec![(
            Scene::default_scene(),
            PathBuf::from("<embedded default scene>"),
        )],
        Some(p) if p.is_dir() => {
            let mut files: Vec<PathBuf> = std::fs::read_dir(p)
                .map_err(|e| lancet::Error::io(p, e))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| f.extension().is_some_and(|x| x == "ron"))
                .collect();
            files.sort();
            if files.is_empty() {
                return Err(lancet::Error::Scene {
                    path: p.to_path_buf(),
                    message: "folder holds no .ron scene files".into(),
                });
            }
            files
                .into_iter()
                .map(|f| Scene::read(&f).map(|s| (s, f)))
                .collect::<lancet::Result<_>>()?
        }
        Some(p) => vec![(Scene::read(p)?, p.to_path_buf())],
    };
    let folder = scene.is_some_and(|p| p.is_dir());
    if let Some(dir) = scene.filter(|_| folder) {
        check_distinct_series(dir, &scenes, opts)?;
    }
    let mut summaries = Vec::with_capacity(scenes.len());
    for (scene, path) in &scenes {
        for w in scene.warnings() {
            eprintln!("warning: {}: {w}", path.display());
        }
        if let Some(note) = ignored_cut_options(scene, opts) {
            eprintln!("note: {}: {note}", path.display());
        }
        // The layout and accumulation choose how the GPU engine runs; a CPU engine has neither.
        let engine = opts.engine.unwrap_or(scene.engine);
        if matches!(engine, EngineKind::Reference | EngineKind::Fast)
            && (opts.layout.is_some() || opts.accumulation.is_some())
        {
            eprintln!(
                "note: {}: --layout and --accumulation apply to the GPU engine; the {engine} engine ignores them",
                path.display()
            );
        }
        // In a folder run, a scene on a real mesh is skipped (with a note) when the folder of
        // real meshes is not configured; run on its own it is an error that says so.
        if folder && needs_mesh_dir(scene) && std::env::var_os("LANCET_MESH_DIR").is_none() {
            eprintln!(
                "skipped {}: its mesh is under $LANCET_MESH_DIR, which is not set",
                path.display()
            );
            continue;
        }
        for method in run_methods(scene, opts) {
            let opts = RunOptions {
                cut_method: method,
                ..opts.clone()
            };
            let steps = opts.steps.unwrap_or(scene.steps);
            let mut bar = crate::progress::RunProgress::new(&scene.name, steps, json);
            let summary = run_scene(scene, path, &opts, |done, total| bar.update(done, total));
            bar.finish();
            let summary = summary?;
            if !json {
                print_summary(&summary);
            }
            summaries.push(summary);
        }
    }
    let all_passed = summaries.iter().all(|s| s.expectations_passed);
    if json {
        let value = if summaries.len() == 1 {
            serde_json::to_value(&summaries[0])
        } else {
            serde_json::to_value(&summaries)
        };
        println!(
            "{}",
            serde_json::to_string_pretty(
                &value.unwrap_or_else(|e| json!({"error": e.to_string()}))
            )
            .unwrap_or_default()
        );
    } else if summaries.len() > 1 {
        print_table(&summaries);
    }
    Ok(if all_passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// The cut methods `scene` runs with, once each: those it names, unless `--method` picks one;
/// `[None]` for a scene that does not cut.
fn run_methods(scene: &Scene, opts: &RunOptions) -> Vec<Option<lancet::cut::CutMethod>> {
    match (&scene.cut, opts.cut_method) {
        (Some(_), Some(m)) => vec![Some(m)],
        (Some(c), None) => c.methods.iter().map(|&m| Some(m)).collect(),
        (None, _) => vec![None],
    }
}

/// Refuse a folder run, before anything runs, in which two runs would write the same series
/// (the later one's frames would silently replace the earlier one's): two scenes with the
/// same name, or names that differ only in letter case (one file on macOS and Windows), in the
/// same output folder. The error names both scene files and the series.
pub(crate) fn check_distinct_series(
    folder: &Path,
    scenes: &[(Scene, PathBuf)],
    opts: &RunOptions,
) -> lancet::Result<()> {
    let mut seen: std::collections::HashMap<String, (PathBuf, &Path, &str)> =
        std::collections::HashMap::new();
    for (scene, path) in scenes {
        if needs_mesh_dir(scene) && std::env::var_os("LANCET_MESH_DIR").is_none() {
            continue; // skipped: writes nothing
        }
        for method in run_methods(scene, opts) {
            let opts = RunOptions {
                cut_method: method,
                ..opts.clone()
            };
            let Some(pvd) = lancet::scene::runner::series_path(scene, path, &opts) else {
                continue;
            };
            let key = comparable(&pvd);
            if let Some((first, first_path, first_name)) = seen.get(&key) {
                let case = if *first == pvd {
                    ""
                } else {
                    " (the names differ only in letter case: one file where case is ignored, as on macOS and Windows)"
                };
                return Err(lancet::Error::Scene {
                    path: folder.to_path_buf(),
                    message: format!(
                        "{} (scene {first_name:?}) and {} (scene {:?}) would both write the series {}{case}; nothing was run. Give the scenes different names or output folders",
                        first_path.display(),
                        path.display(),
                        scene.name,
                        first.display()
                    ),
                });
            }
            seen.insert(key, (pvd, path, &scene.name));
        }
    }
    Ok(())
}

/// A series path in a form that two paths to the same file share: the folder resolved where
/// it exists (lexically cleaned where not yet), letters lower-cased.
fn comparable(pvd: &Path) -> String {
    let dir = pvd.parent().unwrap_or(Path::new("."));
    let dir = std::fs::canonicalize(dir).unwrap_or_else(|_| {
        dir.components()
            .filter(|c| !matches!(c, std::path::Component::CurDir))
            .collect()
    });
    dir.join(pvd.file_name().unwrap_or_default())
        .to_string_lossy()
        .to_lowercase()
}

/// Why `--method` or `--check`, when given, do nothing for `scene`: both act on cuts, and a
/// scene without a `cut` section makes none. Said rather than refused, so that a folder of
/// scenes, some of which cut, can still be run with them.
pub(crate) fn ignored_cut_options(scene: &Scene, opts: &RunOptions) -> Option<String> {
    if scene.cut.is_some() {
        return None;
    }
    let given: Vec<&str> = [
        opts.cut_method.map(|_| "--method"),
        opts.check.then_some("--check"),
    ]
    .into_iter()
    .flatten()
    .collect();
    (!given.is_empty()).then(|| {
        format!(
            "{} {} no effect: the scene does not cut (it has no `cut` section)",
            given.join(" and "),
            if given.len() > 1 { "have" } else { "has" }
        )
    })
}

/// Whether a scene reads its mesh from the folder of real meshes.
pub(crate) fn needs_mesh_dir(scene: &Scene) -> bool {
    matches!(&scene.mesh, lancet::scene::MeshSource::File(f) if f.starts_with("$LANCET_MESH_DIR/"))
}

pub(crate) fn print_summary(s: &RunSummary) {
    println!("scene: {}", s.scene);
    println!(
        "model: {} nodes, {} tets, {} springs; force model: {}",
        s.nodes, s.tets, s.springs, s.force_model
    );
    println!(
        "engine: {} ({}), dt {:.3e} s, stable bound {:.3e} s (node {})",
        s.engine, s.integrator, s.dt, s.dt_bound, s.dt_bound_node
    );
    if let Some(line) = time_step_change(s) {
        println!("{line}");
    }
    if let Some(r) = &s.solver {
        println!(
            "solver: {:.1} conjugate-gradient iterations per solve (max {}), final relative \
             residual {:.2e} (tolerance {:.0e})",
            r.mean_iterations, r.max_iterations, r.final_residual, r.tolerance
        );
        if r.factorisations > 0 {
            println!(
                "solver: {} sparse Cholesky factorisations, {:.3} s; {:.2} factor solves per \
                 linear solve",
                r.factorisations,
                r.factor_seconds,
                r.factor_solves as f64 / r.solves.max(1) as f64
            );
        }
        if r.capped > 0 {
            println!(
                "warning: {} of {} solves stopped at the iteration cap ({}) above the \
                 tolerance: raise solver.max_iterations or the tolerance, or lower dt",
                r.capped, r.solves, r.iteration_cap
            );
        }
    }
    if let Some(n) = &s.engine_note {
        println!("note: {n}");
    }
    if let Some(m) = &s.message {
        let what = if s.refused {
            "refused"
        } else if s.stopped {
            "stopped after a cut"
        } else {
            "diverged"
        };
        println!("{what}: {m}");
    }
    println!(
        "ran {} steps ({:.4} s simulated) in {:.3} s wall, {:.0} steps/s",
        s.steps, s.simulated_s, s.wall_s, s.steps_per_s
    );
    println!(
        "max displacement {:.4e} m, volume ratio {:.5}, energy: kinetic {:.3e} J, elastic {:.3e} J",
        s.max_displacement, s.volume_ratio, s.energy.kinetic, s.energy.elastic
    );
    if let Some(p) = &s.pvd {
        println!("wrote {} frames, series {}", s.frames_written, p.display());
    }
    for t in &s.tools {
        let f = t.final_force;
        println!(
            "tool {}: largest force {:.4e} N, final force ({:.3e}, {:.3e}, {:.3e}) N, deepest \
             penetration {:.2e} m, in contact {} steps",
            t.name, t.max_force, f[0], f[1], f[2], t.max_depth, t.contact_steps
        );
        if t.max_held > 0 {
            println!(
                "tool {}: held up to {} nodes, carried them up to {:.4e} m from rest",
                t.name, t.max_held, t.max_carried
            );
        }
    }
    if s.self_contact_steps > 0 {
        println!(
            "self-contact: {} steps in contact, deepest penetration {:.2e} m before resolution",
            s.self_contact_steps, s.self_contact_deepest
        );
    }
    if let Some(c) = &s.cuts {
        println!(
            "cuts ({}): {} steps cut, {} tets touched ({} removed), {} nodes added, {} springs \
             touched, {} fragments, volume removed {:.3}%",
            c.method,
            c.cuts,
            c.tets_touched,
            c.tets_removed,
            c.nodes_added,
            c.springs_touched,
            c.fragments,
            100.0 * c.volume_removed_fraction
        );
        println!(
            "  uploaded {} of {} layout bytes a rebuild per cut would{} ({:.2}%; at most {:.2}% \
             in one cut); passes rebuilt at {} cuts, {} buffers grown ({} bytes copied on the \
             device); per cut p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; {} invariant checks, \
             {} violations; lowest tet quality {:.3} (uncut {:.3}, floor {})",
            c.bytes_uploaded,
            c.bytes_full,
            time_step_part(c.bytes_time_step),
            100.0 * c.bytes_uploaded as f64 / c.bytes_full.max(1) as f64,
            100.0 * c.max_upload_fraction,
            c.passes_rebuilt,
            c.buffers_grown,
            c.bytes_copied,
            c.p50_ms,
            c.p99_ms,
            c.max_ms,
            c.checks,
            c.violations.len(),
            c.min_quality,
            c.min_quality_uncut,
            c.quality_floor
        );
        let reads = c.near_reads;
        if reads.ahead + reads.direct > 0 {
            println!(
                "  reads of the nodes near a blade: {} with the step before the cut, {} with a \
                 round trip of their own",
                reads.ahead, reads.direct
            );
        }
        // A few cuts one by one; `--json` lists them all.
        const SHOWN: usize = 8;
        for e in c.events.iter().take(SHOWN) {
            println!(
                "  cut at step {} by {}: {} tets touched ({} removed), {} nodes added, {} springs \
                 touched, {} of {} layout bytes uploaded{}{}, {:.3} ms",
                e.step,
                e.blade,
                e.tets_touched,
                e.tets_removed,
                e.nodes_added,
                e.springs_touched,
                e.bytes_uploaded,
                e.layout_bytes,
                time_step_part(e.time_step_bytes),
                patched(e),
                e.ms
            );
        }
        if c.events.len() > SHOWN {
            println!(
                "  ... {} more cuts (--json lists every one)",
                c.events.len() - SHOWN
            );
        }
        for e in &c.time_step_events {
            println!("  {e}");
        }
        for v in c.violations.iter().take(5) {
            println!("  violation: {v}");
        }
    }
    if !s.expectations.is_empty() {
        println!("expectations:");
        for e in &s.expectations {
            let measured = e.measured.map_or(String::new(), |v| {
                format!(" (measured {})", measured_text(v))
            });
            let verdict = match (e.skipped, e.passed) {
                (true, _) => "skip",
                (false, true) => "pass",
                (false, false) => "FAIL",
            };
            println!("  {verdict}  {}{measured}", e.expectation);
        }
    }
    println!(
        "result: {}\n",
        if s.expectations_passed {
            "pass"
        } else {
            "FAIL"
        }
    );
}

/// What part of an upload rebuilt the engine at a new time step, for the cut lines.
/// How a cut's patch met buffers without room: ", passes rebuilt", ", 1 buffer grown (N
/// bytes copied on the device)", or nothing.
pub(crate) fn patched(e: &lancet::scene::cuts::CutEvent) -> String {
    if e.passes_rebuilt {
        ", passes rebuilt".into()
    } else if e.buffers_grown > 0 {
        let s = if e.buffers_grown == 1 { "" } else { "s" };
        format!(
            ", {} buffer{s} grown ({} bytes copied on the device)",
            e.buffers_grown, e.bytes_copied
        )
    } else {
        String::new()
    }
}

pub(crate) fn time_step_part(bytes: u64) -> String {
    if bytes == 0 {
        String::new()
    } else {
        format!(" ({bytes} of them step parameters at a new dt)")
    }
}

/// A line saying how cuts changed the time step or its bound during the run, if they did (the
/// engine line gives the values the run started with).
pub(crate) fn time_step_change(s: &RunSummary) -> Option<String> {
    let bound = format!(
        "stable bound now {:.3e} s (node {})",
        s.dt_bound_final, s.dt_bound_node_final
    );
    if s.dt_final != s.dt {
        Some(format!(
            "dt changed from {:.3e} s to {:.3e} s during the run; {bound}",
            s.dt, s.dt_final
        ))
    } else if s.dt_bound_final != s.dt_bound {
        Some(format!("dt unchanged; {bound}"))
    } else {
        None
    }
}

/// The one-line-per-run table of a folder run.
pub(crate) fn print_table(summaries: &[RunSummary]) {
    let w = summaries
        .iter()
        .map(|s| s.scene.len())
        .max()
        .unwrap_or(5)
        .max(5);
    println!(
        "{:<w$}  {:>9}  {:>8}  {:>9}  {:>8}  {:>10}  {:>9}  {:>6}  result",
        "scene", "method", "nodes", "after cut", "steps", "dt (s)", "wall (s)", "expect"
    );
    for s in summaries {
        // Expectations for another cut method were skipped: counted neither way.
        let checked = s.expectations.iter().filter(|e| !e.skipped);
        let (passed, total) = checked.fold((0, 0), |(p, t), e| (p + e.passed as usize, t + 1));
        // The step the run ended at, marked where a cut lowered it.
        let mark = if s.dt_final != s.dt { '*' } else { ' ' };
        // Cuts only append nodes, so the count at the end is the start's plus those added.
        let after_cut = s
            .cuts
            .as_ref()
            .map_or("-".to_string(), |c| (s.nodes + c.nodes_added).to_string());
        println!(
            "{:<w$}  {:>9}  {:>8}  {:>9}  {:>8}  {:>10}  {:>9.3}  {:>6}  {}",
            s.scene,
            s.cut_method.as_deref().unwrap_or("-"),
            s.nodes,
            after_cut,
            s.steps,
            format!("{:.3e}{mark}", s.dt_final),
            s.wall_s,
            format!("{passed}/{total}"),
            if s.expectations_passed {
                "pass"
            } else {
                "FAIL"
            }
        );
    }
    println!(
        "nodes: before cutting; after cut: at the end of a scene that cuts; expect: expectations \
         met / checked (those for another cut method are skipped)"
    );
    if summaries.iter().any(|s| s.dt_final != s.dt) {
        println!("* a cut lowered dt during the run; the final dt is shown");
    }
    let failed = summaries.iter().filter(|s| !s.expectations_passed).count();
    // A scene that cuts runs once per method it lists: count both.
    let scenes: std::collections::BTreeSet<&str> =
        summaries.iter().map(|s| s.scene.as_str()).collect();
    println!(
        "{} runs ({} scenes), {} failed",
        summaries.len(),
        scenes.len(),
        failed
    );
}

/// A measured value for the summary: a whole number (a count: fragments, cuts, nodes) as one,
/// anything else in scientific notation.
pub(crate) fn measured_text(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{v:.0}")
    } else {
        format!("{v:.4e}")
    }
}

//! Scene fixtures run and meet their expectations on every CPU engine; the embedded default
//! scene is valid.

use std::path::{Path, PathBuf};

use lancet::engine::EngineKind;
use lancet::scene::{run_scene, RunOptions, Scene};
use rstest::rstest;

fn fixture(name: &str) -> PathBuf {
    Path::new(crate::REPO).join("fixtures/scenes").join(name)
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

/// Whether `scene` reads a mesh from `LANCET_MESH_DIR` while it is not set (then it is skipped).
fn needs_missing_meshes(scene: &Scene) -> bool {
    std::env::var_os("LANCET_MESH_DIR").is_none()
        && matches!(&scene.mesh, lancet::scene::MeshSource::File(f) if f.starts_with("$LANCET_MESH_DIR/"))
}

/// The stiff fixtures step with backward Euler at 1 ms, far above their explicit bounds, on the
/// fast engine, and meet their expectations with every cut method they name; no solve stops at
/// the iteration cap.
#[rstest]
fn implicit_fixture_meets_its_expectations_at_one_millisecond(
    #[values(
        "implicit_beam.ron",
        "implicit_stiffness_contrast.ron",
        "implicit_probe_press.ron",
        "implicit_grasp_lift.ron",
        "implicit_cylinder.ron",
        "implicit_cylinder_factored.ron",
        "implicit_cut_liver_incision.ron"
    )]
    file: &str,
) {
    let path = fixture(file);
    let scene = Scene::read(&path).unwrap();
    if needs_missing_meshes(&scene) {
        println!("LANCET_MESH_DIR is not set: skipping {file}");
        return;
    }
    assert_eq!(scene.integrator, lancet::engine::Integrator::BackwardEuler);
    assert_eq!(scene.dt, lancet::scene::TimeStep::Seconds(1e-3));
    let methods: Vec<Option<lancet::cut::CutMethod>> = match &scene.cut {
        Some(c) => c.methods.iter().copied().map(Some).collect(),
        None => vec![None],
    };
    for method in methods {
        let opts = RunOptions {
            no_output: true,
            cut_method: method,
            ..Default::default()
        };
        let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
        assert!(
            summary.engine.starts_with("cpu-fast"),
            "{file}: {}",
            summary.engine
        );
        // Above the explicit bound, where an explicit scheme would be refused (the liver is at 4x).
        assert!(summary.dt > 2.0 * summary.dt_bound, "{file}: {summary:?}");
        assert!(
            summary.expectations_passed,
            "{file} {method:?}: {:#?}",
            summary.expectations
        );
        let solver = summary.solver.expect("backward Euler reports its solver");
        assert_eq!(solver.capped, 0, "{file} {method:?}: {solver:?}");
    }
}

/// The factored preconditioner earns its place on the stiff cylinder: the factor of an earlier
/// step's system leaves a handful of iterations a solve where symmetric Gauss-Seidel needs
/// about a hundred, each iteration pays exactly one pair of triangular solves (none for a
/// residual already converged), and the factor is built again only rarely.
#[test]
fn the_factored_cylinder_needs_a_few_iterations_and_rare_factorisations() {
    let path = fixture("implicit_cylinder_factored.ron");
    let scene = Scene::read(&path).unwrap();
    if needs_missing_meshes(&scene) {
        println!("LANCET_MESH_DIR is not set: skipping the factored cylinder");
        return;
    }
    let opts = RunOptions {
        no_output: true,
        ..Default::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    assert!(summary.expectations_passed, "{:#?}", summary.expectations);
    let solver = summary.solver.expect("backward Euler reports its solver");
    assert_eq!(solver.capped, 0, "{solver:?}");
    assert!(solver.mean_iterations <= 4.0, "{solver:?}");
    assert_eq!(
        solver.factor_solves,
        (solver.mean_iterations * solver.solves as f64).round() as u64,
        "{solver:?}"
    );
    assert!(
        solver.factorisations >= 1 && solver.factorisations * 10 <= solver.solves,
        "{solver:?}"
    );
}

/// Tip sag (the first expectation's measured value) of a beam fixture.
fn measured_tip_sag(file: &str) -> f64 {
    let path = fixture(file);
    let scene = Scene::read(&path).unwrap();
    let opts = RunOptions {
        no_output: true,
        ..Default::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    let first = &summary.expectations[0];
    assert!(first.expectation.contains("displacement[2]"), "{first:?}");
    first.measured.unwrap()
}

/// Static equilibrium does not depend on the integrator: the default beam stepped by backward
/// Euler at 1 ms settles to the tip sag of the explicit default scene within 1%.
#[test]
fn the_default_beam_at_one_millisecond_settles_to_the_explicit_sag() {
    let explicit = measured_tip_sag("default.ron");
    let implicit = measured_tip_sag("implicit_beam.ron");
    assert!(explicit < 0.0);
    assert!(
        (implicit / explicit - 1.0).abs() < 0.01,
        "implicit {implicit:e} m, explicit {explicit:e} m"
    );
}

/// The 10^4 stiffness contrast stepped by backward Euler at 1 ms settles where the same scene
/// stepped explicitly (Verlet at 0.9 of its bound, 7 us, over the same 0.3 s) does: the soft
/// half's far top corner within 1%.
#[test]
fn the_stiffness_contrast_at_one_millisecond_settles_where_an_explicit_run_does() {
    let path = fixture("implicit_stiffness_contrast.ron");
    let scene = Scene::read(&path).unwrap();
    let opts = RunOptions {
        no_output: true,
        ..Default::default()
    };
    let implicit = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    let mut explicit_scene = scene.clone();
    explicit_scene.integrator = lancet::engine::Integrator::Verlet;
    explicit_scene.dt = lancet::scene::TimeStep::BoundFraction(0.9);
    let simulated = scene.steps as f64 * 1e-3;
    explicit_scene.steps = (simulated / (0.9 * implicit.dt_bound)).ceil() as u64;
    // (Its kinetic energy expectation is not asked of it: undamped by its integrator, the
    // explicit run is still ringing faintly at 0.3 s, 2e-9 J.)
    let explicit = run_scene(&explicit_scene, &path, &opts, |_, _| {}).unwrap();
    assert!(!explicit.refused && !explicit.diverged, "{explicit:?}");
    // The second expectation: the soft half's far top corner.
    let corner = |s: &lancet::scene::RunSummary| {
        let e = &s.expectations[1];
        assert!(e.expectation.contains("displacement[2]"), "{e:?}");
        e.measured.unwrap()
    };
    let (a, b) = (corner(&implicit), corner(&explicit));
    assert!(b < 0.0);
    assert!(
        (a / b - 1.0).abs() < 0.01,
        "implicit {a:e} m, explicit {b:e} m"
    );
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

/// A scene of a small box with `tools` and `cut`, as RON.
fn scene_text(tools: &str, cut: &str) -> String {
    format!(
        r#"Scene(
    name: "x",
    mesh: Box((cells: (2, 2, 2), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    dt: BoundFraction(0.5),
    steps: 10,
    tools: [{tools}],
    cut: {cut},
)"#
    )
}

/// The message a scene is refused with.
fn refusal(text: &str) -> String {
    Scene::from_ron(text, Path::new("x.ron"))
        .expect_err("the scene is refused")
        .to_string()
}

/// Messages are read whole: a string broken over two source lines once carried the next line's
/// indentation into them.
#[test]
fn scene_errors_read_as_single_spaced_sentences() {
    let unknown_blade = refusal(&scene_text(
        "",
        r#"Some((methods: [Separate], blades: ["nope"]))"#,
    ));
    assert_eq!(
        unknown_blade,
        "x.ron: cut: blade \"nope\" is not one of the scene's tools; name a tool from `tools`"
    );
    let grasper = |windows: &str| {
        format!(
            r#"(name: "g", shape: Grasper(jaw: (0.001, 0.006, 0.003), opening: 0.002),
               trajectory: Keyframes([(time: 0.0, translation: (0.0, 0.0, 0.02))]),
               grasp: [{windows}])"#
        )
    };
    let backwards = refusal(&scene_text(&grasper("(close: 0.3, open: 0.2)"), "None"));
    assert_eq!(
        backwards,
        "x.ron: tool 0 (\"g\"): grasp window 0: opens at 0.2 s, not after it closes at 0.3 s; \
         give open > close"
    );
    let overlapping = refusal(&scene_text(
        &grasper("(close: 0.1, open: 0.3), (close: 0.2, open: 0.4)"),
        "None",
    ));
    assert_eq!(
        overlapping,
        "x.ron: tool 0 (\"g\"): grasp window 1 closes at 0.2 s, before window 0 opens at 0.3 s; \
         list windows in increasing time without overlap"
    );
    for m in [unknown_blade, backwards, overlapping] {
        assert!(!m.contains("  "), "{m}");
    }
}

/// A quality floor is a volume-length ratio in [0, 1): 0 turns it off, so a negative one is
/// refused rather than read as "off".
#[test]
fn a_quality_floor_outside_zero_to_one_is_refused() {
    for floor in ["-0.1", "1.0", "2.0"] {
        let m = refusal(&scene_text(
            "",
            &format!("Some((methods: [Separate], quality_floor: {floor}))"),
        ));
        assert!(m.contains("in [0, 1)"), "{floor}: {m}");
    }
    let ok = scene_text("", "Some((methods: [Separate], quality_floor: 0.0))");
    assert!(Scene::from_ron(&ok, Path::new("x.ron")).is_ok());
}

/// A scene that cuts with no blade among its tools is allowed (a scene may check that other
/// tools do not cut), but warned about; one with a blade is not.
#[test]
fn a_cut_without_a_blade_is_warned_about() {
    let cut = "Some((methods: [Separate]))";
    let without = Scene::from_ron(&scene_text("", cut), Path::new("x.ron")).unwrap();
    let w = without.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].contains("no blade"), "{w:?}");
    let blade = r#"(name: "b", shape: Blade(width: 0.02, length: 0.02, thickness: 2e-4),
                    trajectory: Keyframes([(time: 0.0, translation: (0.0, 0.0, 0.05))]))"#;
    let with = Scene::from_ron(&scene_text(blade, cut), Path::new("x.ron")).unwrap();
    assert!(with.warnings().is_empty(), "{:?}", with.warnings());
    // A scene that does not cut has nothing to warn about.
    let plain = Scene::from_ron(&scene_text("", "None"), Path::new("x.ron")).unwrap();
    assert!(plain.warnings().is_empty());
}

/// A scene's `layout` and `accumulation` fields choose the GPU engine's layout and edge variant
/// (the runner gives them to the engine as `GpuOptions`, apart from `SimConfig`), and the run
/// options override them as `--layout` does.
#[test]
fn the_scene_layout_and_accumulation_reach_the_gpu_engine() {
    if lancet::engine::gpu::GpuContext::new().is_err()
        && std::env::var("LANCET_REQUIRE_GPU").as_deref() != Ok("1")
    {
        eprintln!("skipped: no GPU adapter");
        return;
    }
    let text = r#"Scene(
    name: "x",
    mesh: Box((cells: (2, 2, 2), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    dt: BoundFraction(0.5),
    steps: 10,
    engine: Gpu,
    layout: Edges,
    accumulation: AtomicFixed,
)"#;
    let path = Path::new("x.ron");
    let scene = Scene::from_ron(text, path).unwrap();
    let run = |opts: &RunOptions| run_scene(&scene, path, opts, |_, _| {}).unwrap().engine;
    let engine = run(&RunOptions::default());
    assert!(engine.starts_with("gpu-edges-atomicfixed on"), "{engine}");
    let valence = RunOptions {
        layout: Some(lancet::layout::LayoutKind::Valence),
        ..RunOptions::default()
    };
    let engine = run(&valence);
    assert!(engine.starts_with("gpu-valence on"), "{engine}");
}

/// The extent of a mesh's rest positions along each axis.
fn extent(mesh: &lancet::mesh::TetMesh) -> [f64; 3] {
    let (lo, hi) = mesh.bounds().unwrap();
    (hi - lo).into()
}

/// The SOFA liver has no units and read as metres is a 6.5 m, 36 t organ. Its fixture scales
/// it with `mesh_transform` (a field scenes did not have): the placed mesh is the file's times
/// the scale, an adult human liver in size (about 20-25 cm across) and mass (1.2-1.8 kg at
/// the density of water), and the scene, whose held box and expectations are in those metres,
/// settles as it expects.
#[test]
fn the_liver_fixture_is_scaled_to_the_size_and_mass_of_a_human_liver() {
    let Some(dir) = std::env::var_os("LANCET_MESH_DIR") else {
        println!("LANCET_MESH_DIR is not set: skipping");
        return;
    };
    let path = fixture("liver_in_metres.ron");
    let scene = Scene::read(&path).unwrap();
    let placed = lancet::scene::runner::build_mesh(&scene, &path).unwrap();
    let file = lancet::mesh::io::read(Path::new(&dir).join("sofa/liver.msh"))
        .unwrap()
        .mesh;
    let scale = scene.mesh_transform.scale;
    for (p, f) in extent(&placed).into_iter().zip(extent(&file)) {
        assert!(
            (p - f * scale).abs() <= 1e-12 * f,
            "{p} against {f} x {scale}"
        );
    }
    let across = extent(&placed).into_iter().fold(0.0, f64::max);
    assert!((0.2..0.25).contains(&across), "{across} m across");
    let mass = 1000.0 * placed.volume();
    assert!((1.2..1.8).contains(&mass), "{mass} kg");
    let opts = RunOptions {
        no_output: true,
        ..Default::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    assert!(summary.expectations_passed, "{:#?}", summary.expectations);
}

/// A scene whose step is refused (above the bound, and it does not expect the refusal) runs no
/// step: its expectations are shown as not run instead of measured on the rest state, where a
/// volume ratio of 1 passed and a displacement of 0 failed, and the run still fails.
#[test]
fn a_refused_run_shows_its_expectations_as_not_run() {
    let text = r#"Scene(
    name: "x",
    mesh: Box((cells: (2, 2, 2), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    gravity: (0.0, 0.0, -9.81),
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (0.0, 0.0, 1.0), tolerance: 1e-9)],
    dt: BoundFraction(1.5),
    steps: 10,
    expect: [
        VolumeRatio(min: Some(0.99), max: Some(1.01)),
        MaxDisplacement(min: Some(1e-6)),
    ],
)"#;
    let path = Path::new("x.ron");
    let scene = Scene::from_ron(text, path).unwrap();
    let summary = run_scene(&scene, path, &RunOptions::default(), |_, _| {}).unwrap();
    assert!(summary.refused);
    assert_eq!(summary.steps, 0);
    assert_eq!(summary.expectations.len(), 2);
    for e in &summary.expectations {
        assert!(e.skipped && e.measured.is_none(), "{e:?}");
    }
    assert!(!summary.expectations_passed);
}

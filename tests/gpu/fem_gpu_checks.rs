//! Checks both finite-element force models' GPU tests make (`gpu_tensor_mass.rs`,
//! `gpu_corotational.rs`): the GPU engine against the float64 reference, and the box of
//! `tests/common/fem_cut.rs` cut on the GPU, every cut checked against a rebuild by the world,
//! then the cut engine stepped beside one built afresh from the cut model.

use crate::common;
use lancet::engine::{EngineKind, ForceModelKind, GpuOptions, Integrator, SimConfig, Simulation};
use lancet::model::{PackedModel, SpringModel};
use lancet::report::bench::relative_l2;

/// Run `model` from the state `(x, v)` for `steps` steps under `config` on the GPU in `layout`
/// and on the float64 reference engine, and on the reference engine under the force model
/// `other`: the relative L2 errors of the GPU run and of the `other` run against the reference
/// run. The first is float32 rounding where the GPU steps the model; the second shows how far
/// the model is from `other`, so that the first is seen to be small.
pub fn against_the_reference(
    model: &PackedModel,
    config: SimConfig,
    (x, v): (&[[f64; 3]], &[[f64; 3]]),
    layout: impl Into<GpuOptions>,
    steps: u64,
    other: ForceModelKind,
) -> (f64, f64) {
    let layout: GpuOptions = layout.into();
    let run = |kind: EngineKind, config: SimConfig| {
        let mut sim = Simulation::with_gpu(model.clone(), kind, config, layout).unwrap();
        sim.set_state(x, v).unwrap();
        sim.run(steps).unwrap();
        sim.positions()
    };
    let gpu = run(EngineKind::Gpu, config);
    let reference = run(EngineKind::Reference, config);
    let apart = run(
        EngineKind::Reference,
        SimConfig {
            force_model: other,
            ..config
        },
    );
    (
        relative_l2(&model.rest, &gpu, &reference),
        relative_l2(&model.rest, &apart, &reference),
    )
}

/// Cut the box with `method` on the GPU in `layout` under the force model `kind` and
/// `integrator` (an explicit one at 0.8 of the stable bound, backward Euler at 4 times it):
/// after every cut the world's checks (`Engine::differences_from_rebuild`) find nothing, and
/// the cut engine then steps as a GPU engine built afresh from the cut model does, to float32
/// rounding (and the solver's tolerance).
pub fn cut_model_equals_a_rebuilt_one(
    kind: ForceModelKind,
    layout: impl Into<GpuOptions>,
    method: lancet::cut::CutMethod,
    integrator: Integrator,
) {
    let layout: GpuOptions = layout.into();
    use lancet::scene::driver::SceneDriver;
    use lancet::scene::runner::{build_mesh, model_config};
    use lancet::scene::{RunOptions, Scene};
    use lancet::world::WorldBuilder;
    let Some(_) = common::gpu() else { return };
    let path = std::path::Path::new("gpu_fem_cuts.ron");
    // The blade's edge sweeps down through the box and across over 20 ms (40 steps).
    let text = crate::fem_cut::scene([0.011, 0.012, 0.04], [0.019, 0.021, -0.01], 40);
    let scene = Scene::from_ron(&text, path).unwrap();
    let mesh = build_mesh(&scene, path).unwrap();
    let mconfig = model_config(&scene);
    let packed = SpringModel::build(&mesh, &mconfig)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let fraction = if integrator.is_implicit() { 4.0 } else { 0.8 };
    let config = SimConfig {
        integrator,
        force_model: kind,
        ..SimConfig::new(fraction * kind.stable_time_step(&packed).unwrap().dt)
    };
    let mut world = WorldBuilder::new(mesh, &mconfig, config)
        .unwrap()
        .engine(EngineKind::Gpu)
        .gpu(layout)
        .build()
        .unwrap();
    let opts = RunOptions {
        cut_method: Some(method),
        check: true,
        ..RunOptions::default()
    };
    world.set_up_scene(&scene, &opts).unwrap();
    let mut driver = SceneDriver::new(&scene);
    for _ in 0..scene.steps {
        driver.step(&mut world).unwrap();
    }
    let report = &world.cutting().unwrap().report;
    assert!(report.cuts > 0, "{kind} {layout:?} {method}: nothing cut");
    assert!(report.nodes_added > 0, "{kind} {layout:?} {method}");
    assert_eq!(report.checks, report.cuts);
    assert!(
        report.violations.is_empty(),
        "{kind} {layout:?} {method}: {:#?}",
        report.violations
    );
    let sim = world.sim_mut();
    assert!(sim.engine_name().starts_with("gpu-"));
    let model = sim.model().clone();
    let (x, v) = (sim.positions(), sim.velocities());
    let mut fresh =
        Simulation::with_gpu(model.clone(), EngineKind::Gpu, *sim.config(), layout).unwrap();
    fresh.set_state(&x, &v).unwrap();
    sim.set_state(&x, &v).unwrap();
    sim.run(30).unwrap();
    fresh.run(30).unwrap();
    let (a, b) = (sim.positions(), fresh.positions());
    let motion = a
        .iter()
        .zip(&x)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f64::max);
    let worst = a
        .iter()
        .zip(&b)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f64::max);
    assert!(motion > 1e-6, "the cut box moves ({motion:e})");
    assert!(
        worst <= 1e-4 * motion,
        "{kind} {layout:?} {method}: cut and rebuilt engines differ by {worst:e} (motion {motion:e})"
    );
}

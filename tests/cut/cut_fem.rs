//! Cuts under the finite-element force models on the float64 reference engine: each cut
//! subtracts the shares of the tets it removes or re-corners and adds those of the tets it
//! makes. Random blade strokes through a hanging box with every method and both models keep
//! every invariant after every cut: the element model equals one rebuilt from scratch to 1e-12
//! and no tensor couples nodes across the cut, the packed model's tets are the cut mesh's, and
//! the run stays finite, on the reference and the fast engine (whose float32 arrays, patched
//! where a cut touched them, equal a rebuild's). The liver incision fixture meets its
//! expectations with every method on both.

use std::collections::BTreeSet;
use std::path::Path;

use crate::models::Rng;
use lancet::cut::CutMethod;
use lancet::engine::{EngineKind, ForceModelKind, SimConfig};
use lancet::model::{corner_set, SpringModel};
use lancet::physics::TensorMass;
use lancet::scene::driver::SceneDriver;
use lancet::scene::runner::{build_mesh, model_config};
use lancet::scene::{run_scene, RunOptions, Scene};
use lancet::world::{World, WorldBuilder};
use rstest::rstest;

/// A 3 cm box of 4 x 4 x 4 cells hanging from its y = 0 face, a blade entering from above at a
/// random place and angle and sweeping down and across it over 20 ms.
fn scene_text(seed: u64) -> String {
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let x0 = 0.004 + 0.022 * rng.next();
    let x1 = 0.004 + 0.022 * rng.next();
    let y0 = 0.008 + 0.018 * rng.next();
    let y1 = 0.008 + 0.018 * rng.next();
    let depth = -0.004 - 0.02 * rng.next();
    scene_with([x0, y0, 0.04], [x1, y1, depth])
}

/// The box with the blade's edge moving from `from` to `to` over 20 ms, for 400 steps.
fn scene_with(from: [f64; 3], to: [f64; 3]) -> String {
    crate::fem_cut::scene(from, to, 400)
}

/// `scene`'s tools and cuts (by `method`, every cut checked) stepped through a world of `mesh`
/// under `config` on `engine`, for the scene's steps.
fn run_cuts(
    scene: &Scene,
    mesh: lancet::TetMesh,
    config: SimConfig,
    engine: EngineKind,
    method: CutMethod,
) -> (World, SceneDriver) {
    let mut world = WorldBuilder::new(mesh, &model_config(scene), config)
        .unwrap()
        .engine(engine)
        .build()
        .unwrap();
    let opts = RunOptions {
        cut_method: Some(method),
        check: true,
        ..RunOptions::default()
    };
    world.set_up_scene(scene, &opts).unwrap();
    let mut driver = SceneDriver::new(scene);
    for _ in 0..scene.steps {
        driver.step(&mut world).unwrap();
    }
    (world, driver)
}

#[rstest]
fn random_cuts_with_finite_elements_keep_every_invariant_and_equal_a_rebuild(
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
    #[values(1, 2)] seed: u64,
    #[values(EngineKind::Reference, EngineKind::Fast)] engine: EngineKind,
) {
    let path = Path::new("fem_cuts.ron");
    let scene = Scene::from_ron(&scene_text(seed), path).unwrap();
    let mesh = build_mesh(&scene, path).unwrap();
    let model = SpringModel::build(&mesh, &model_config(&scene)).unwrap();
    let packed = model.pack(&mesh).unwrap();
    let bound = kind.stable_time_step(&packed).unwrap().dt;
    let config = SimConfig {
        force_model: kind,
        ..SimConfig::new(0.8 * bound)
    };
    let _ = (model, packed);
    let (world, _) = run_cuts(&scene, mesh, config, engine, method);
    let (sim, cut) = (world.sim(), world.cutting().unwrap());
    let report = &cut.report;
    assert!(report.cuts > 0, "seed {seed} {method} {kind}: nothing cut");
    assert_eq!(report.checks, report.cuts);
    // Every cut was checked: the mesh invariants and the patched element model against a
    // rebuild (`Simulation::differences_from_rebuild`; on the fast engine its float32 rows or
    // tets as well, rewritten only where the cut touched them).
    assert!(
        report.violations.is_empty(),
        "seed {seed} {method} {kind}: {:#?}",
        report.violations
    );
    assert!(sim.differences_from_rebuild().unwrap().is_empty());
    // The packed model's tets, kept by diffs, are the cut mesh's.
    let cut_mesh = cut.mesh();
    let dense = cut_mesh.dense_nodes().index;
    let want: BTreeSet<[u32; 4]> = cut_mesh
        .tets()
        .map(|(_, t)| corner_set(t.nodes.map(|k| dense[k])))
        .collect();
    let got: BTreeSet<[u32; 4]> = sim
        .model()
        .tets
        .iter()
        .map(|t| corner_set(t.nodes))
        .collect();
    assert_eq!(got.len(), sim.model().tets.len(), "a tet is listed twice");
    assert_eq!(got, want, "seed {seed} {method} {kind}");
    if method != CutMethod::Remove {
        assert!(report.nodes_added > 0, "seed {seed} {method} {kind}");
    }
    // The run stayed finite (a piece the blade cut off falls freely: no bound on how far).
    assert!(sim.positions().iter().flatten().all(|c| c.is_finite()));
}

/// A separating cut through the middle of a box opens it: the tensor-mass model rebuilt from
/// the cut mesh has no tensor between the two sides, and neither has the patched one (the
/// rebuild comparison names any tensor coupling nodes no tet joins). Checked by hand here on
/// the nodes: every edge tensor's two nodes are corners of one tet of the model.
#[test]
fn no_tensor_couples_nodes_across_a_completed_cut() {
    let path = Path::new("fem_cut_through.ron");
    let text = scene_with([0.015, 0.0151, 0.04], [0.015, 0.0151, -0.04]);
    let scene = Scene::from_ron(&text, path).unwrap();
    let mesh = build_mesh(&scene, path).unwrap();
    let model = SpringModel::build(&mesh, &model_config(&scene)).unwrap();
    let packed = model.pack(&mesh).unwrap();
    let kind = ForceModelKind::TensorMass;
    let config = SimConfig {
        force_model: kind,
        ..SimConfig::new(0.8 * kind.stable_time_step(&packed).unwrap().dt)
    };
    let _ = model;
    let (world, _) = run_cuts(
        &scene,
        mesh,
        config,
        EngineKind::Reference,
        CutMethod::Separate,
    );
    let sim = world.sim();
    let report = &world.cutting().unwrap().report;
    assert!(report.cuts > 0 && report.nodes_added > 0);
    assert!(report.violations.is_empty(), "{:#?}", report.violations);
    let m = sim.model();
    let joined: BTreeSet<[u32; 2]> = m
        .tets
        .iter()
        .flat_map(|t| {
            let n = t.nodes;
            [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
                .map(|(a, b)| [n[a].min(n[b]), n[a].max(n[b])])
        })
        .collect();
    let rebuilt = TensorMass::new(&m.rest, &m.tets).unwrap();
    for e in rebuilt.edge_tensors() {
        assert!(joined.contains(&e.nodes), "{:?}", e.nodes);
    }
    // The two lips: nodes at the same rest position (a node and its copy) are never coupled.
    for e in rebuilt.edge_tensors() {
        let [a, b] = e.nodes.map(|i| m.rest[i as usize]);
        assert!(a != b, "a tensor couples a node and its copy {:?}", e.nodes);
    }
}

/// The liver incision with corotational elements (the real mesh, from `LANCET_MESH_DIR`): on
/// the reference engine with every method its fixture lists; on the fast engine with the two
/// methods that between them remove, re-corner and add tets (separating re-corners, which is a
/// removal and an addition; subdividing adds sub-tets), since carving only removes, which both
/// of those do too, and each run costs a float64 polar decomposition per tet per step.
#[rstest]
#[case(CutMethod::Separate, EngineKind::Reference)]
#[case(CutMethod::Remove, EngineKind::Reference)]
#[case(CutMethod::Subdivide, EngineKind::Reference)]
#[case(CutMethod::Separate, EngineKind::Fast)]
#[case(CutMethod::Subdivide, EngineKind::Fast)]
fn the_liver_incision_with_corotational_elements_meets_its_expectations(
    #[case] method: CutMethod,
    #[case] engine: EngineKind,
) {
    if std::env::var_os("LANCET_MESH_DIR").is_none() {
        println!("LANCET_MESH_DIR is not set: skipping the liver");
        return;
    }
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/fem_cut_liver_incision.ron");
    let scene = Scene::read(&path).unwrap();
    assert_eq!(scene.force_model, ForceModelKind::Corotational);
    let opts = RunOptions {
        cut_method: Some(method),
        engine: Some(engine),
        no_output: true,
        ..Default::default()
    };
    let s = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    assert!(!s.diverged, "{method}: {:?}", s.message);
    assert_eq!(s.force_model, "corotational");
    assert!(s.expectations_passed, "{method}: {:#?}", s.expectations);
}

/// The rebuild comparison sees a stale element model: a diff removing one tet and adding it
/// back with its corners renumbered, applied to the model but not to the elements, is
/// reported (as a tensor or element the model no longer has); patched, nothing is.
#[rstest]
fn an_element_model_the_diff_did_not_reach_differs_from_a_rebuild(
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
) {
    use lancet::mesh::generate::BoxGrid;
    use lancet::model::{Material, ModelConfig};
    use lancet::physics::ElementForces;
    let mesh = BoxGrid::cube_cells([2, 2, 2], 0.01).build().unwrap();
    let config = ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0));
    let mut model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let mut elements = ElementForces::new(kind, &model).unwrap().unwrap();
    assert!(elements
        .differences_from_rebuild(&model)
        .unwrap()
        .is_empty());
    // Tet 0 loses its first corner to a copy of it (what separating does to one tet).
    let diff = crate::fem_cut::recorner_first_tet(&model);
    model.apply(&diff).unwrap();
    let stale = elements.differences_from_rebuild(&model).unwrap();
    assert!(!stale.is_empty(), "{kind}: a stale model passed");
    elements.patch(&model.rest, &diff).unwrap();
    let patched = elements.differences_from_rebuild(&model).unwrap();
    assert!(patched.is_empty(), "{kind}: {patched:#?}");
    // The same removal again names a tet the model no longer has: refused, nothing changes.
    assert!(elements.patch(&model.rest, &diff).is_err());
    assert!(elements
        .differences_from_rebuild(&model)
        .unwrap()
        .is_empty());
}

/// Cuts under backward Euler with finite elements on the fast engine: the blade's 20 ms
/// stroke through the hanging box in 2 ms steps (about 6 times the cut box's explicit bound,
/// which a cut lowers and the implicit step ignores), with every method and both models.
/// Every cut keeps every invariant (each checked, the float32 arrays against a rebuild), the
/// step is never lowered and no solve hits its cap; and the patched engine then steps as one
/// built from scratch on the cut model (float32 rounding in another node order, where a block
/// row left stale by a cut moves its nodes by the size of the motion).
#[rstest]
fn cuts_under_backward_euler_with_finite_elements_keep_every_invariant(
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
) {
    use lancet::engine::{Integrator, Simulation};
    use lancet::report::bench::relative_l2;
    let path = Path::new("fem_cuts_implicit.ron");
    let text = crate::fem_cut::scene([0.012, 0.02, 0.04], [0.02, 0.012, -0.01], 15);
    let scene = Scene::from_ron(&text, path).unwrap();
    let mesh = build_mesh(&scene, path).unwrap();
    let dt = 2e-3;
    let config = SimConfig {
        force_model: kind,
        integrator: Integrator::BackwardEuler,
        ..SimConfig::new(dt)
    };
    let (mut world, _) = run_cuts(&scene, mesh, config, EngineKind::Fast, method);
    let report = &world.cutting().unwrap().report;
    assert!(report.cuts > 0, "{method} {kind}: nothing cut");
    assert_eq!(report.checks, report.cuts);
    assert!(
        report.violations.is_empty(),
        "{method} {kind}: {:#?}",
        report.violations
    );
    let bound = kind.stable_time_step(world.sim().model()).unwrap().dt;
    assert!(dt > 5.0 * bound, "bound {bound:e} s");
    assert_eq!(world.sim().config().dt, dt);
    let cuts = report.cuts;
    let stats = world.sim().solver_stats().unwrap();
    assert_eq!(stats.solves, scene.steps, "{method} {kind}");
    assert_eq!(stats.capped, 0, "{method} {kind}: {stats:?}");

    let (x, v) = (world.sim().positions(), world.sim().velocities());
    let config = *world.sim().config();
    let mut rebuilt =
        Simulation::new(world.sim().model().clone(), EngineKind::Fast, config).unwrap();
    rebuilt.set_state(&x, &v).unwrap();
    world.sim_mut().run(10).unwrap();
    rebuilt.run(10).unwrap();
    let rest = &world.sim().model().rest;
    let e = relative_l2(rest, &world.sim().positions(), &rebuilt.positions());
    let moved = relative_l2(rest, &x, &rebuilt.positions());
    eprintln!("{method} {kind}: {cuts} cuts, {e:.2e} off a rebuilt engine, moved {moved:.2e}");
    assert!(e < 1e-5, "{method} {kind}: {e:.2e} off a rebuilt engine");
    assert!(moved > 1e-3, "{method} {kind}: at rest ({moved:.2e})");
    assert!(world
        .sim()
        .positions()
        .iter()
        .flatten()
        .all(|c| c.is_finite()));
}

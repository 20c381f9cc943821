//! The finite-element force models in a simulation: chosen by `SimConfig::force_model` or a
//! scene's `force_model`, run on the float64 reference engine (and the fast engine,
//! tests/engine/fast_fem.rs); both run on the GPU too (tests/gpu/gpu_tensor_mass.rs,
//! tests/gpu/gpu_corotational.rs), explicitly only; their
//! stable time step bounds the true critical step of explicit integration.

use std::path::Path;

use lancet::engine::{EngineKind, ForceModelKind, Integrator};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{FixedSelector, Material, ModelConfig, ModelDiff, PackedModel, SpringModel};
use lancet::physics::{ForceModel, Linearization, TensorMass};
use lancet::scene::{run_scene, RunOptions, Scene};
use lancet::{Error, SimConfig, Simulation};
use nalgebra::{DMatrix, SymmetricEigen};

/// A 1 cm cube of 2 x 2 x 2 cells (six tets each), E = 10 kPa, nu = 0.3, base clamped, under
/// gravity.
fn block() -> PackedModel {
    let mesh = BoxGrid::cube_cells([2, 2, 2], 0.005).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    }];
    SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap()
}

fn config(dt: f64, force_model: ForceModelKind) -> SimConfig {
    SimConfig {
        force_model,
        ..SimConfig::new(dt)
    }
}

#[test]
fn a_finite_element_model_runs_on_the_reference_engine_with_its_own_energy() {
    let model = block();
    for kind in [ForceModelKind::TensorMass, ForceModelKind::Corotational] {
        let bound = kind.stable_time_step(&model).unwrap();
        let mut sim = Simulation::new(
            model.clone(),
            EngineKind::Reference,
            config(0.9 * bound.dt, kind),
        )
        .unwrap();
        sim.run(200).unwrap();
        let x = sim.positions();
        // The energy the checks see is the finite-element model's, not the springs'.
        let linear = TensorMass::new(&model.rest, &model.tets).unwrap();
        let elastic = sim.energy().elastic;
        assert!(elastic > 0.0, "{kind}");
        if kind == ForceModelKind::TensorMass {
            assert!((elastic - linear.potential_energy(&x)).abs() <= 1e-12 * elastic);
        }
        assert!(
            (elastic - model.elastic_energy(&x)).abs() > 1e-3 * elastic,
            "{kind}"
        );
        // The block sagged under gravity.
        assert!(
            x.iter().zip(&model.rest).any(|(p, r)| p[2] < r[2] - 1e-6),
            "{kind}"
        );
    }
}

/// Corotational elements under backward Euler run on the GPU where a device opens (the block
/// pass feeding the tensor-mass solve; without a device the error is the device's, never a
/// refusal of the model), and `Auto` without a GPU engine runs the fast one with a note.
#[test]
fn the_gpu_engine_runs_an_implicit_corotational_model_and_auto_runs_the_fast_engine() {
    let model = block();
    let bound = ForceModelKind::TensorMass.stable_time_step(&model).unwrap();
    match Simulation::new(
        model.clone(),
        EngineKind::Gpu,
        SimConfig {
            integrator: Integrator::BackwardEuler,
            ..config(4.0 * bound.dt, ForceModelKind::Corotational)
        },
    ) {
        Ok(mut sim) => {
            assert_eq!(sim.kind(), EngineKind::Gpu);
            sim.run(5).unwrap();
            let x = sim.positions();
            // The block sagged under gravity.
            assert!(x.iter().zip(&model.rest).any(|(p, r)| p[2] < r[2] - 1e-9));
        }
        Err(err) => assert!(matches!(&err, Error::Gpu(_)), "{err}"),
    }
    let auto = Simulation::new(
        model,
        EngineKind::Auto,
        config(0.5 * bound.dt, ForceModelKind::TensorMass),
    )
    .unwrap();
    assert_eq!(auto.kind(), EngineKind::Fast);
    assert!(auto
        .engine_note()
        .is_some_and(|n| n.contains("tensor-mass")));
}

#[test]
fn a_step_above_the_finite_element_bound_and_a_diff_naming_no_tet_are_refused() {
    let model = block();
    let kind = ForceModelKind::Corotational;
    let bound = kind.stable_time_step(&model).unwrap();
    // The springs' bound is another number: the finite-element one is what is checked.
    assert!((bound.dt - lancet::model::stable_time_step(&model).dt).abs() > 1e-3 * bound.dt);
    let err = Simulation::new(
        model.clone(),
        EngineKind::Reference,
        config(1.01 * bound.dt, kind),
    )
    .err()
    .expect("refused");
    assert!(matches!(err, Error::UnstableTimeStep { .. }), "{err}");
    let mut sim =
        Simulation::new(model, EngineKind::Reference, config(0.5 * bound.dt, kind)).unwrap();
    // Cuts are taken (tests/cut/cut_fem.rs); a diff removing a tet the model does not have
    // is refused before anything changes.
    sim.apply(&ModelDiff::default()).unwrap();
    let before = sim.model().clone();
    let err = sim
        .apply(&ModelDiff {
            removed_tets: vec![[0, 1, 2, 1_000_000]],
            ..ModelDiff::default()
        })
        .unwrap_err();
    assert!(matches!(err, Error::DiffMismatch(_)), "{err}");
    assert_eq!(sim.model(), &before);
    assert_eq!(sim.bound().dt, kind.stable_time_step(&before).unwrap().dt);
}

#[test]
fn a_model_without_a_continuum_material_is_refused_with_the_tet() {
    let mesh = BoxGrid::cube_cells([1, 1, 1], 0.01).build().unwrap();
    let model = SpringModel::build(&mesh, &ModelConfig::new(Material::springs(10.0, 1e-3)))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let err = Simulation::new(
        model,
        EngineKind::Reference,
        config(1e-4, ForceModelKind::TensorMass),
    )
    .err()
    .expect("refused")
    .to_string();
    assert!(
        err.contains("tet 0") && err.contains("youngs_modulus"),
        "{err}"
    );
}

/// The dense stiffness of `model` from its products on unit vectors, restricted to the free
/// nodes' components, and scaled by the masses: `M^-1/2 K M^-1/2`.
fn scaled_stiffness(model: &PackedModel, forces: &dyn ForceModel) -> DMatrix<f64> {
    let free: Vec<usize> = (0..model.node_count())
        .filter(|&i| !model.fixed[i])
        .collect();
    let n = model.node_count();
    let mut k = DMatrix::zeros(3 * free.len(), 3 * free.len());
    for (col, &j) in free.iter().enumerate() {
        for c in 0..3 {
            let mut e = vec![[0.0; 3]; n];
            e[j][c] = 1.0;
            let mut out = vec![[0.0; 3]; n];
            forces.add_stiffness_product(&model.rest, Linearization::Exact, &e, &mut out);
            for (row, &i) in free.iter().enumerate() {
                for r in 0..3 {
                    k[(3 * row + r, 3 * col + c)] =
                        -out[i][r] / (model.mass[i] * model.mass[j]).sqrt();
                }
            }
        }
    }
    k
}

#[test]
fn the_finite_element_bound_lies_below_the_critical_step_and_explicit_runs_diverge_above_it() {
    let model = block();
    let linear = TensorMass::new(&model.rest, &model.tets).unwrap();
    let eigen = SymmetricEigen::new(scaled_stiffness(&model, &linear));
    let omega = eigen.eigenvalues.max().sqrt();
    let critical = 2.0 / omega;
    let bound = ForceModelKind::TensorMass.stable_time_step(&model).unwrap();
    println!("critical step {critical:e} s, bound {:e} s", bound.dt);
    assert!(
        bound.dt <= critical,
        "bound {} above the critical step {critical}",
        bound.dt
    );
    assert!(
        bound.dt > 0.2 * critical,
        "bound {} needlessly small",
        bound.dt
    );
    // Verlet from a small kick: bounded at the bound, exploding above the critical step.
    let run = |dt: f64| {
        let c = SimConfig {
            allow_unstable: true,
            integrator: Integrator::Verlet,
            ..config(dt, ForceModelKind::TensorMass)
        };
        let mut sim = Simulation::new(model.clone(), EngineKind::Reference, c).unwrap();
        let v: Vec<[f64; 3]> = (0..model.node_count())
            .map(|i| [1e-3 * ((i * 7919) % 13) as f64 - 6e-3, 0.0, 0.0])
            .collect();
        sim.set_state(&model.rest, &v).unwrap();
        sim.run(3000)
    };
    assert!(run(bound.dt).is_ok());
    assert!(matches!(run(1.05 * critical), Err(Error::Diverged { .. })));
}

#[test]
fn a_scene_selects_its_force_model_and_its_summary_names_it() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/fem_cantilever.ron");
    let scene = Scene::read(&path).unwrap();
    assert_eq!(scene.force_model, ForceModelKind::Corotational);
    let opts = RunOptions {
        no_output: true,
        ..Default::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    assert_eq!(summary.force_model, "corotational");
    assert!(summary.expectations_passed, "{:#?}", summary.expectations);
    // A scene that does not name a force model keeps the springs.
    let default = Scene::default_scene();
    assert_eq!(default.force_model, ForceModelKind::Springs);
}

//! Float32 and small steps: Verlet stores two positions, so far below the stable bound its
//! increment `h^2 a` is a few float32 ulps of the displacement and partly rounded away;
//! symplectic Euler follows the same trajectory in exact arithmetic and stores the velocity.
//! A float32 symplectic Euler run at a sixteenth of the bound stays on the float64 trajectory,
//! and a float32 Verlet run that far below the bound carries a note saying so.

use lancet::engine::{EngineKind, Integrator, SimConfig, Simulation};
use lancet::mesh::generate::beam;
use lancet::model::{stable_time_step, FixedSelector, Material, ModelConfig, PackedModel};
use lancet::report::bench::relative_l2;
use lancet::SpringModel;

/// The default scene's beam, coarser: 50 mm, E = 50 kPa, clamped at x = 0, under gravity.
fn hanging_beam() -> PackedModel {
    let mesh = beam(0.05, 0.02, 0.02, 10, 4).unwrap();
    let mut config = ModelConfig::new(Material::elastic(50e3, 0.25, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.mass_damping = 60.0;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal: [1.0, 0.0, 0.0],
        tolerance: 1e-9,
    });
    SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap()
}

fn run(
    model: &PackedModel,
    kind: EngineKind,
    integrator: Integrator,
    dt: f64,
    steps: u64,
) -> Simulation {
    let mut config = SimConfig::new(dt);
    config.integrator = integrator;
    let mut sim = Simulation::new(model.clone(), kind, config).unwrap();
    sim.run(steps).unwrap();
    sim
}

#[test]
fn float32_symplectic_euler_keeps_float64_accuracy_far_below_the_bound() {
    let model = hanging_beam();
    let dt = stable_time_step(&model).dt / 16.0;
    let steps = (0.1 / dt) as u64; // 100 ms: about 5,000 steps
    let reference = run(
        &model,
        EngineKind::Reference,
        Integrator::SymplecticEuler,
        dt,
        steps,
    );
    let fast = run(
        &model,
        EngineKind::Fast,
        Integrator::SymplecticEuler,
        dt,
        steps,
    );
    let e = relative_l2(&model.rest, &fast.positions(), &reference.positions());
    // Float32 rounding of a velocity-carrying state: measured 7e-7. Float32 Verlet, which
    // carries two positions, measured 9e-3 against float64 Verlet in the same run.
    assert!(e < 1e-5, "float32 symplectic Euler off float64 by {e:.2e}");
    assert!(fast.engine_note().is_none());
}

#[test]
fn float32_verlet_far_below_the_bound_says_so() {
    let model = hanging_beam();
    let bound = stable_time_step(&model).dt;
    let note = |kind, integrator, fraction: f64| {
        let mut config = SimConfig::new(fraction * bound);
        config.integrator = integrator;
        Simulation::new(model.clone(), kind, config)
            .unwrap()
            .engine_note()
            .map(str::to_string)
    };
    let n = note(EngineKind::Fast, Integrator::Verlet, 1.0 / 16.0).expect("a note");
    assert!(n.contains("SymplecticEuler") && n.contains("0.06"), "{n}");
    assert_eq!(note(EngineKind::Fast, Integrator::Verlet, 0.9), None);
    assert_eq!(
        note(EngineKind::Fast, Integrator::SymplecticEuler, 1.0 / 16.0),
        None
    );
    assert_eq!(
        note(EngineKind::Reference, Integrator::Verlet, 1.0 / 16.0),
        None
    );
}

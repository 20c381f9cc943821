//! The implicit integrator (linearised backward Euler with conjugate gradients) on the
//! reference engine, far above the explicit stable bound: it settles a hanging beam to the
//! explicit engines' static equilibrium, and stiff undamped springs lose energy step after
//! step instead of blowing up.

use lancet::engine::reference::ReferenceEngine;
use lancet::engine::{Engine, Integrator};
use lancet::model::stable_time_step;
use lancet::physics::{BackwardEuler, Explicit, SolverSettings};
use lancet::{EngineKind, PackedModel, SimConfig, Simulation};

use super::physics_beam::{cantilever_damped as cantilever, tip_sag};

fn implicit(model: &PackedModel, dt: f64) -> ReferenceEngine {
    ReferenceEngine::with_integrator(
        model,
        dt,
        Box::new(BackwardEuler::new(SolverSettings::default())),
    )
}

/// Kinetic, elastic and gravitational energy, J.
fn total_energy(model: &PackedModel, engine: &dyn Engine) -> f64 {
    let (x, v) = engine.state();
    model.kinetic_energy(&v) + model.elastic_energy(&x) + model.gravity_energy(&x)
}

#[test]
fn the_implicit_step_settles_a_hanging_beam_where_the_explicit_engines_do() {
    let model = cantilever(100.0);
    let bound = stable_time_step(&model).dt;
    // 4 ms: about 30 times the explicit bound.
    let dt = 4e-3;
    assert!(dt > 20.0 * bound, "bound {bound:e} s");
    let mut engine = implicit(&model, dt);
    engine.step((0.5 / dt) as u32);
    let sag = tip_sag(&model, &engine.positions());

    // The explicit fast engine, at 0.9 of its bound, over the same 0.5 s (25 decay times).
    let explicit_dt = 0.9 * bound;
    let mut config = SimConfig::new(explicit_dt);
    config.integrator = Integrator::Verlet;
    let mut sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    sim.run((0.5 / explicit_dt) as u64).unwrap();
    let explicit_sag = tip_sag(&model, &sim.positions());
    assert!(explicit_sag < 0.0);
    assert!(
        (sag / explicit_sag - 1.0).abs() < 0.01,
        "implicit sag {sag:e} m, explicit {explicit_sag:e} m"
    );
    // And still: the implicit state is an equilibrium, not a snapshot of a swing.
    let before = sag;
    engine.step(50);
    let after = tip_sag(&model, &engine.positions());
    assert!(
        (after - before).abs() < 1e-4 * before.abs(),
        "{before:e} -> {after:e}"
    );
}

#[test]
fn undamped_stiff_springs_lose_energy_monotonically_at_a_hundred_times_the_bound() {
    let model = cantilever(0.0);
    let dt = 100.0 * stable_time_step(&model).dt;
    let mut engine = implicit(&model, dt);
    let mut energy = total_energy(&model, &engine);
    let start = energy;
    for step in 0..200 {
        engine.step(1);
        let next = total_energy(&model, &engine);
        assert!(next.is_finite(), "step {step}: energy {next}");
        assert!(
            next <= energy + 1e-12 * energy.abs().max(next.abs()),
            "step {step}: energy rose from {energy:e} J to {next:e} J"
        );
        energy = next;
    }
    // It fell under gravity (energy was released and dissipated), and it did not explode.
    assert!(energy < start);
    let x = engine.positions();
    assert!(
        tip_sag(&model, &x).abs() < 0.05,
        "the tip moved by more than half the beam's length"
    );

    // The same step with the explicit scheme blows up: the test is far above the bound.
    let mut explicit =
        ReferenceEngine::with_integrator(&model, dt, Box::new(Explicit::new(Integrator::Verlet)));
    explicit.step(200);
    let e = total_energy(&model, &explicit);
    // (Measured against the energy the implicit run released, the scale of this motion.)
    let blew_up = !e.is_finite() || e.abs() > 1e3 * energy.abs();
    assert!(blew_up, "explicit energy {e:e} J stayed bounded");
}

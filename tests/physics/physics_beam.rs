//! A cantilever beam fixed at x = 0, hanging under gravity with mass damping, settles into a
//! static equilibrium; its transient converges as the time step shrinks.

use lancet::engine::Integrator;
use lancet::mesh::generate::beam;
use lancet::model::{stable_time_step, FixedSelector};
use lancet::{EngineKind, Material, ModelConfig, PackedModel, SimConfig, Simulation, SpringModel};

const G: f64 = 9.81;

/// 10 cm x 2 cm x 2 cm, E = 1 MPa: the Euler-Bernoulli sag `q L^4 / (8 E I)` is about 4 mm, small
/// enough to stay near-linear. Mass damping 100/s is just under critical for the first bending
/// mode (about 10 Hz, w = 63/s), and every underdamped mode decays as exp(-50 t).
fn cantilever() -> PackedModel {
    cantilever_damped(100.0)
}

/// The cantilever clamped at x = 0 under gravity, with mass damping `alpha` (1/s).
pub(crate) fn cantilever_damped(alpha: f64) -> PackedModel {
    let mesh = beam(0.1, 0.02, 0.02, 10, 2).unwrap();
    let mut config = ModelConfig::new(Material::elastic(1e6, 0.25, 1000.0));
    config.gravity = [0.0, 0.0, -G];
    config.mass_damping = alpha;
    config.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [1.0, 0.0, 0.0],
        tolerance: 1e-9,
    }];
    SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap()
}

/// Mean z-displacement of the nodes at the free end (x = 0.1).
pub(crate) fn tip_sag(model: &PackedModel, x: &[[f64; 3]]) -> f64 {
    let tip: Vec<f64> = x
        .iter()
        .zip(&model.rest)
        .filter(|(_, r)| (r[0] - 0.1).abs() < 1e-9)
        .map(|(p, r)| p[2] - r[2])
        .collect();
    tip.iter().sum::<f64>() / tip.len() as f64
}

fn simulation(model: &PackedModel, dt: f64) -> Simulation {
    let mut config = SimConfig::new(dt);
    config.integrator = Integrator::Verlet;
    config.check_every = 100;
    Simulation::new(model.clone(), EngineKind::Reference, config).unwrap()
}

/// Net spring + gravity force on node `i` at positions `x`, computed here in float64.
fn net_forces(model: &PackedModel, x: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut f: Vec<[f64; 3]> = model
        .mass
        .iter()
        .map(|m| model.gravity.map(|g| m * g))
        .collect();
    for s in model.springs() {
        let (a, b) = (s.nodes[0] as usize, s.nodes[1] as usize);
        let d = [0, 1, 2].map(|c| x[b][c] - x[a][c]);
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let t = s.stiffness * (l - s.rest_length) / l;
        for c in 0..3 {
            f[a][c] += t * d[c];
            f[b][c] -= t * d[c];
        }
    }
    f
}

#[test]
fn a_hanging_beam_settles_into_static_equilibrium() {
    let model = cantilever();
    let dt = 0.9 * stable_time_step(&model).dt;
    let mut sim = simulation(&model, dt);
    let steps = (0.5 / dt) as u64; // 25 decay times of the damping
    sim.run(steps).unwrap();
    let sag = tip_sag(&model, &sim.positions());
    // Within 30% of the beam theory estimate (the spring network is not exactly a continuum
    // of E = 1 MPa, and the section is only two cells across): the sign and size are right.
    let (q, i) = (1000.0 * G * 0.02 * 0.02, 0.02f64.powi(4) / 12.0);
    let theory = q * 0.1f64.powi(4) / (8.0 * 1e6 * i);
    assert!(sag < 0.0, "the beam did not sag down: {sag}");
    assert!(
        (-sag / theory - 1.0).abs() < 0.3,
        "sag {sag} vs beam theory {theory}"
    );

    // Settled: kinetic energy negligible against the work gravity did, and the tip still.
    let e = sim.energy();
    let work = model.mass.iter().sum::<f64>() * G * -sag;
    assert!(
        e.kinetic < 1e-12 * work,
        "kinetic {:e} J vs {work:e} J",
        e.kinetic
    );
    sim.run((0.02 / dt) as u64).unwrap();
    let later = tip_sag(&model, &sim.positions());
    assert!(
        (later - sag).abs() < 1e-9 * sag.abs(),
        "tip moved from {sag} to {later}"
    );

    // Static equilibrium: on every free node, springs balance gravity to 1e-6 of its weight.
    let x = sim.positions();
    for (i, f) in net_forces(&model, &x).iter().enumerate() {
        if model.fixed[i] {
            continue;
        }
        let weight = model.mass[i] * G;
        let net = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        assert!(
            net < 1e-6 * weight,
            "node {i}: net force {net:e} N, weight {weight:e} N"
        );
    }
}

/// The tip sag at the same simulated time (mid-transient, 40 ms) with dt, dt/2 and dt/4: the
/// differences shrink at least as fast as first order (the backward-difference damping
/// velocity makes the scheme first order in dt when damped; undamped it is second order).
#[test]
fn the_sag_converges_as_the_time_step_shrinks() {
    let model = cantilever();
    let dt = 0.8 * stable_time_step(&model).dt;
    let time = 0.04;
    // The same number of steps of dt at every refinement, so the simulated time is identical.
    let steps = (time / dt).round() as u64;
    let sags: Vec<f64> = [1u64, 2, 4]
        .iter()
        .map(|&r| {
            let mut sim = simulation(&model, dt / r as f64);
            sim.run(steps * r).unwrap();
            tip_sag(&model, &sim.positions())
        })
        .collect();
    let d1 = (sags[0] - sags[1]).abs();
    let d2 = (sags[1] - sags[2]).abs();
    assert!(d1 > 0.0, "no dependence on dt at all: {sags:?}");
    assert!(
        d2 < 0.6 * d1,
        "differences {d1:e} then {d2:e} do not shrink: {sags:?}"
    );
}

//! A single spring with one end fixed is a harmonic oscillator: `x'' = -(k/m) x`, period
//! `2 pi sqrt(m/k)`, and released from rest at displacement `A` it swings between `+-A`.
//!
//! At `dt = T/200` the discrete period of the central-difference recurrence is
//! `2 pi / acos(1 - w^2 h^2 / 2)` per `h`, within 4e-5 of `T`, and the discrete amplitude is
//! within 1.3e-4 of `A`: far inside the 0.5% asked of the engines.

use lancet::engine::Integrator;
use lancet::{EngineKind, PackedModel, SimConfig, Simulation};
use rstest::rstest;

const MASS: f64 = 0.1;
const STIFFNESS: f64 = 40.0;
const REST: f64 = 0.1;
const AMPLITUDE: f64 = 0.01;

/// Node 0 fixed at the origin, node 1 at `(REST, 0, 0)`.
fn one_spring() -> PackedModel {
    let mut m = PackedModel::from_springs(
        vec![[0.0; 3], [REST, 0.0, 0.0]],
        vec![MASS, MASS],
        &[([0, 1], STIFFNESS, 0.0)],
    )
    .unwrap();
    m.fixed[0] = true;
    m
}

fn period() -> f64 {
    2.0 * std::f64::consts::PI * (MASS / STIFFNESS).sqrt()
}

/// The displacement of the free node along the spring, one sample per step, released from
/// `AMPLITUDE` at rest.
fn trajectory(kind: EngineKind, integrator: Integrator, steps: usize) -> Vec<f64> {
    let mut config = SimConfig::new(period() / 200.0);
    config.integrator = integrator;
    let mut sim = Simulation::new(one_spring(), kind, config).unwrap();
    sim.set_state(&[[0.0; 3], [REST + AMPLITUDE, 0.0, 0.0]], &[[0.0; 3]; 2])
        .unwrap();
    let mut u = vec![AMPLITUDE];
    for _ in 0..steps {
        sim.run(1).unwrap();
        let x = sim.positions()[1];
        // The motion stays on the spring's axis.
        assert!(
            x[1].abs() < 1e-12 && x[2].abs() < 1e-12,
            "left the axis: {x:?}"
        );
        u.push(x[0] - REST);
    }
    u
}

/// Times (in steps) where `u` changes sign, by linear interpolation.
fn zero_crossings(u: &[f64]) -> Vec<f64> {
    u.windows(2)
        .enumerate()
        .filter(|(_, w)| (w[0] > 0.0) != (w[1] > 0.0))
        .map(|(i, w)| i as f64 + w[0] / (w[0] - w[1]))
        .collect()
}

#[rstest]
fn a_single_spring_oscillates_with_the_analytic_period_and_amplitude(
    #[values(EngineKind::Reference, EngineKind::Fast)] kind: EngineKind,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let periods = 6;
    let u = trajectory(kind, integrator, periods * 200 + 50);
    let z = zero_crossings(&u);
    assert!(z.len() >= 2 * periods, "only {} zero crossings", z.len());
    // Successive crossings are half a period apart; average over all of them.
    let half = (z[z.len() - 1] - z[0]) / (z.len() - 1) as f64;
    let measured = 2.0 * half * period() / 200.0;
    let rel = (measured - period()).abs() / period();
    assert!(
        rel < 5e-3,
        "period {measured} s vs {} s ({rel:.2e})",
        period()
    );
    let peak = u.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let rel = (peak - AMPLITUDE).abs() / AMPLITUDE;
    assert!(rel < 5e-3, "amplitude {peak} vs {AMPLITUDE} ({rel:.2e})");
}

/// Four nodes (one fixed) joined by six damped springs, with gravity and mass damping, started
/// from a tilted, moving state: the full force law in 3D.
fn damped_tet() -> (PackedModel, Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let rest = vec![
        [0.0, 0.0, 0.0],
        [0.1, 0.0, 0.0],
        [0.0, 0.1, 0.0],
        [0.0, 0.0, 0.1],
    ];
    let mut springs = Vec::new();
    for a in 0..4u32 {
        for b in a + 1..4 {
            springs.push(([a, b], STIFFNESS * (1.0 + a as f64), 0.05));
        }
    }
    let mut m = PackedModel::from_springs(rest.clone(), vec![MASS; 4], &springs).unwrap();
    m.fixed[0] = true;
    m.gravity = [0.0, -9.81, 0.0];
    m.mass_damping = 0.5;
    let x = vec![
        rest[0],
        [0.11, 0.005, -0.003],
        [0.004, 0.092, 0.001],
        [-0.006, 0.002, 0.107],
    ];
    let v = vec![
        [0.0; 3],
        [0.0, 0.1, 0.0],
        [0.05, 0.0, -0.02],
        [0.0, 0.0, 0.0],
    ];
    (m, x, v)
}

/// Verlet with the backward-difference velocity and symplectic Euler are the same recurrence
/// (`x_n - x_{n-1} = h v_n`), so their trajectories differ by rounding only: about 1e-16 per
/// step in float64, about 1e-7 of the coordinates per step in float32.
#[rstest]
#[case::reference(EngineKind::Reference, 1e-9)]
#[case::fast(EngineKind::Fast, 1e-3)]
fn verlet_and_symplectic_euler_agree_to_rounding(#[case] kind: EngineKind, #[case] tol: f64) {
    let (model, x0, v0) = damped_tet();
    let dt = period() / 200.0;
    let run = |integrator| {
        let mut config = SimConfig::new(dt);
        config.integrator = integrator;
        let mut sim = Simulation::new(model.clone(), kind, config).unwrap();
        sim.set_state(&x0, &v0).unwrap();
        sim.run(2000).unwrap();
        sim.positions()
    };
    let (a, b) = (run(Integrator::Verlet), run(Integrator::SymplecticEuler));
    // Compare displacements from rest against the size of the motion.
    let scale = a
        .iter()
        .zip(&model.rest)
        .flat_map(|(p, r)| (0..3).map(move |c| (p[c] - r[c]).abs()))
        .fold(0.0f64, f64::max);
    assert!(scale > 1e-3, "the tet barely moved: {scale}");
    for (n, (p, q)) in a.iter().zip(&b).enumerate() {
        for c in 0..3 {
            let d = (p[c] - q[c]).abs() / scale;
            assert!(d < tol, "node {n} axis {c}: {} vs {} ({d:.2e})", p[c], q[c]);
        }
    }
}

//! The float32 fast engine against the float64 reference.
//!
//! Tolerance: float32 rounds each position to about 6e-8 of its magnitude (coordinates up to
//! 0.1 m here, so ~6e-9 m) at every step, and the rounding noise excites the same stable modes
//! as the motion itself; over a thousand steps it accumulates (as a random walk, ~30x) but
//! does not grow exponentially (the run is stable). Against displacements of order 1e-4..1e-3 m
//! that is 1e-5..1e-4 relative; we require 1e-3 relative L2 error, leaving a margin of ten for
//! the sum over ~14 springs per node and the conditioning of the stiffest modes.

use lancet::engine::Integrator;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, FixedSelector, SpringDamping};
use lancet::{EngineKind, Material, ModelConfig, PackedModel, SimConfig, Simulation, SpringModel};
use rstest::rstest;

const TOLERANCE: f64 = 1e-3;
const H: f64 = 0.01;

/// xorshift64*: a tiny seeded generator, enough for test inputs.
struct Rng(u64);

impl Rng {
    /// Uniform in `[-1, 1)`.
    fn sym(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let u = (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64;
        2.0 * u - 1.0
    }
}

/// A 8x5x4-cell box in two materials, damped, fixed at x = 0, optionally under gravity.
fn box_model(gravity: bool) -> PackedModel {
    let mut mesh = BoxGrid::cube_cells([8, 5, 4], H).build().unwrap();
    mesh.set_region_where(1, |c| c.x > 0.04);
    let soft = Material::elastic(2e4, 0.3, 1000.0)
        .with_damping(SpringDamping::StiffnessProportional(1e-4));
    let mut config = ModelConfig::new(soft);
    config.regions.insert(
        1,
        Material::elastic(8e4, 0.3, 1200.0).with_damping(SpringDamping::Absolute(0.01)),
    );
    if gravity {
        config.gravity = [0.0, -9.81, -3.0];
    }
    config.mass_damping = 2.0;
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

/// Run `steps` steps at 0.8 of the bound from `x0` at rest; positions in model order.
fn run(
    model: &PackedModel,
    kind: EngineKind,
    integrator: Integrator,
    x0: &[[f64; 3]],
    steps: u64,
) -> Vec<[f64; 3]> {
    let mut config = SimConfig::new(0.8 * stable_time_step(model).dt);
    config.integrator = integrator;
    let mut sim = Simulation::new(model.clone(), kind, config).unwrap();
    sim.set_state(x0, &vec![[0.0; 3]; x0.len()]).unwrap();
    sim.run(steps).unwrap();
    sim.positions()
}

/// `||u_fast - u_ref|| / ||u_ref||` over all nodes, `u` the displacement from rest.
fn relative_l2(model: &PackedModel, fast: &[[f64; 3]], reference: &[[f64; 3]]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for ((f, r), rest) in fast.iter().zip(reference).zip(&model.rest) {
        for c in 0..3 {
            num += (f[c] - r[c]).powi(2);
            den += (r[c] - rest[c]).powi(2);
        }
    }
    (num / den).sqrt()
}

fn compare(model: &PackedModel, x0: &[[f64; 3]], integrator: Integrator) {
    let steps = 1500;
    let reference = run(model, EngineKind::Reference, integrator, x0, steps);
    let fast = run(model, EngineKind::Fast, integrator, x0, steps);
    let err = relative_l2(model, &fast, &reference);
    assert!(err <= TOLERANCE, "relative L2 displacement error {err:.2e}");
    // Node by node, in model order: a permutation left visible would fail here at once.
    let max_u = reference
        .iter()
        .zip(&model.rest)
        .flat_map(|(p, r)| (0..3).map(move |c| (p[c] - r[c]).abs()))
        .fold(0.0f64, f64::max);
    for (n, (f, r)) in fast.iter().zip(&reference).enumerate() {
        for c in 0..3 {
            let d = (f[c] - r[c]).abs() / max_u;
            assert!(
                d <= TOLERANCE,
                "node {n} axis {c}: {} vs {} ({d:.1e})",
                f[c],
                r[c]
            );
        }
        if model.fixed[n] {
            assert_eq!(*f, model.rest[n], "fixed node {n} moved");
        }
    }
}

#[rstest]
fn the_fast_engine_agrees_with_the_reference_under_gravity(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = box_model(true);
    compare(&model, &model.rest, integrator);
}

#[rstest]
fn the_fast_engine_agrees_with_the_reference_from_a_random_perturbation(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = box_model(false);
    let mut rng = Rng(0xdead_beef_cafe_f00d);
    let x0: Vec<[f64; 3]> = model
        .rest
        .iter()
        .map(|r| r.map(|c| c + 0.05 * H * rng.sym()))
        .collect();
    compare(&model, &x0, integrator);
}

/// The internal reordering never shows: state set in model order comes back in model order.
#[test]
fn the_fast_engine_returns_state_in_model_order() {
    let model = box_model(false);
    let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    config.integrator = Integrator::SymplecticEuler;
    let mut sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    // Each node's x-coordinate gets its own index as an offset, its velocity too.
    let x: Vec<[f64; 3]> = model
        .rest
        .iter()
        .enumerate()
        .map(|(i, r)| [r[0] + i as f64 * 1e-6, r[1], r[2]])
        .collect();
    let v: Vec<[f64; 3]> = (0..x.len()).map(|i| [0.0, i as f64 * 1e-3, 0.0]).collect();
    sim.set_state(&x, &v).unwrap();
    let (px, pv) = (sim.positions(), sim.velocities());
    for i in 0..x.len() {
        if model.fixed[i] {
            assert_eq!(px[i], model.rest[i]);
            assert_eq!(pv[i], [0.0; 3]);
        } else {
            assert!((px[i][0] - x[i][0]).abs() < 1e-8, "node {i}: {:?}", px[i]);
            assert!((pv[i][1] - v[i][1]).abs() < 1e-6, "node {i}: {:?}", pv[i]);
        }
    }
}

//! Finite elements on the fast float32 engine: tensor-mass (3x3 blocks per adjacency slot) and
//! corotational (a per-tet pass and a per-node gather) against the float64 reference engine
//! on jittered meshes with slivers, explicit schemes and backward Euler; bit-identical on one
//! and two threads.
//!
//! Tolerance: as for springs (`engine_agreement.rs`), float32 rounds each displacement and
//! each block product to about 6e-8 of its size at every step; over a few hundred steps the
//! rounding noise accumulates as a random walk through stable modes, 1e-5..1e-4 of the motion.
//! We require 1e-3 relative L2 error of the displacements.

use lancet::engine::fast::on_threads;
use lancet::engine::{ForceModelKind, Integrator};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{FixedSelector, SpringDamping};
use lancet::report::bench::relative_l2;
use lancet::{EngineKind, Material, ModelConfig, PackedModel, SimConfig, Simulation, SpringModel};
use rstest::rstest;

const TOLERANCE: f64 = 1e-3;

/// xorshift64*, uniform in `[-1, 1)`.
struct Rng(u64);

impl Rng {
    fn sym(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let u = (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64;
        2.0 * u - 1.0
    }
}

/// A box of `cells` 1 cm cells, each inner node moved by up to 0.3 of a cell (the seed picks
/// how), fixed at x = 0, under gravity, Rayleigh-damped in one half; its smallest tet quality.
fn jittered(cells: [usize; 3], seed: u64) -> (PackedModel, f64) {
    let h = 0.01;
    let mut mesh = BoxGrid::cube_cells(cells, h).build().unwrap();
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let size = cells.map(|c| c as f64 * h);
    let keys: Vec<_> = mesh.nodes().map(|(k, n)| (k, n.rest)).collect();
    let mut tets_at = std::collections::HashMap::new();
    for (t, tet) in mesh.tets() {
        for n in tet.nodes {
            tets_at.entry(n).or_insert_with(Vec::new).push(t);
        }
    }
    for (k, p) in keys {
        let inner = (0..3).all(|c| p[c] > 1e-9 && p[c] < size[c] - 1e-9);
        if !inner {
            continue;
        }
        // A move that would invert a tet is halved until none does (or dropped).
        let d = nalgebra::Vector3::new(rng.sym(), rng.sym(), rng.sym()) * 0.3 * h;
        for scale in [1.0, 0.5, 0.25, 0.0] {
            mesh.set_rest(k, p + d * scale).unwrap();
            if tets_at[&k].iter().all(|&t| mesh.tet_volume(t) > 0.0) {
                break;
            }
        }
    }
    mesh.set_region_where(1, |c| c.x > 0.5 * size[0]);
    let quality = mesh.min_volume_length_ratio();
    let mut config = ModelConfig::new(Material::elastic(2e4, 0.3, 1000.0));
    config.regions.insert(
        1,
        Material::elastic(6e4, 0.45, 1100.0)
            .with_damping(SpringDamping::StiffnessProportional(2e-4)),
    );
    config.gravity = [0.0, -9.81, -3.0];
    config.mass_damping = 1.0;
    config.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [1.0, 0.0, 0.0],
        tolerance: 1e-9,
    }];
    let packed = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    (packed, quality)
}

fn sim(
    model: &PackedModel,
    engine: EngineKind,
    kind: ForceModelKind,
    integrator: Integrator,
) -> Simulation {
    let bound = kind.stable_time_step(model).unwrap().dt;
    let config = SimConfig {
        force_model: kind,
        integrator,
        ..SimConfig::new(if integrator.is_implicit() { 8.0 } else { 0.8 } * bound)
    };
    Simulation::new(model.clone(), engine, config).unwrap()
}

/// A smooth start: each node displaced by a few percent of the size and swung about the
/// x axis by 40 degrees (a rotation the linear model resists and the corotational does not).
fn start(model: &PackedModel, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = Rng(seed | 1);
    let a = [rng.sym(), rng.sym(), rng.sym()].map(|v| 0.002 * v);
    let angle: f64 = 0.7;
    model
        .rest
        .iter()
        .zip(&model.fixed)
        .map(|(p, &fixed)| {
            if fixed {
                return *p;
            }
            let s = (p[0] * 40.0).sin();
            let (y, z) = (p[1] - 0.02, p[2] - 0.02);
            let t = angle * p[0] / 0.06;
            [
                p[0] + a[0] * s,
                0.02 + y * t.cos() - z * t.sin() + a[1] * s,
                0.02 + y * t.sin() + z * t.cos() + a[2] * s,
            ]
        })
        .collect()
}

#[rstest]
fn the_fast_engine_follows_the_reference_with_finite_elements(
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(1, 2)] seed: u64,
) {
    let (model, quality) = jittered([6, 4, 4], seed);
    // Slivers among them: the jitter makes tets far below a regular one's quality 1.
    assert!(quality < 0.2, "seed {seed}: smallest quality {quality}");
    let x0 = start(&model, seed);
    let v0 = vec![[0.0; 3]; x0.len()];
    let mut reference = sim(&model, EngineKind::Reference, kind, integrator);
    let mut fast = sim(&model, EngineKind::Fast, kind, integrator);
    reference.set_state(&x0, &v0).unwrap();
    fast.set_state(&x0, &v0).unwrap();
    reference.run(300).unwrap();
    fast.run(300).unwrap();
    let (r, f) = (reference.positions(), fast.positions());
    let e = relative_l2(&model.rest, &f, &r);
    assert!(e < TOLERANCE, "{kind} {integrator:?} seed {seed}: {e:.2e}");
    // It moved: the comparison is of a motion, not of two bodies at rest.
    assert!(relative_l2(&model.rest, &x0, &r) > 0.05);
    // The energy the checks see is the element model's, on both.
    let (er, ef) = (reference.energy().elastic, fast.energy().elastic);
    assert!((er - ef).abs() < 1e-2 * er, "{er} {ef}");
}

/// Every pass writes disjoint outputs and sums in a fixed order: one and two threads give
/// the same bits (more than one block of nodes and of tets, so two threads share the work).
#[rstest]
fn finite_elements_on_the_fast_engine_are_bit_identical_on_one_and_two_threads(
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
    #[values(Integrator::Verlet, Integrator::BackwardEuler)] integrator: Integrator,
) {
    let (model, _) = jittered([12, 10, 10], 7);
    assert!(model.node_count() > 1024 && model.tets.len() > 1024);
    let x0 = start(&model, 3);
    // Backward Euler at 10 times the explicit step: a few steps, each tens of iterations.
    let steps = if integrator.is_implicit() { 3 } else { 50 };
    let run = |threads: usize| {
        on_threads(threads, || {
            let mut s = sim(&model, EngineKind::Fast, kind, integrator);
            s.set_state(&x0, &vec![[0.0; 3]; x0.len()]).unwrap();
            s.run(steps).unwrap();
            s.positions()
        })
        .unwrap()
    };
    let (one, two) = (run(1), run(2));
    let bits = |x: &[[f64; 3]]| x.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert!(
        bits(&one) == bits(&two),
        "{kind} {integrator:?}: one and two threads differ"
    );
}

/// One backward Euler step and a few more at 20 times the explicit bound, both models, on a
/// jittered box with slivers, Rayleigh damping in one region, mass damping and gravity, from
/// a swung and strained state moving at a random velocity: the fast engine's float32 system
/// (the elements' 3x3 blocks, corotational rotations frozen at the step's start as the
/// reference freezes them) equals the reference's float64 one. Both solve to 1e-7 with block
/// Jacobi, so what is left is float32 rounding, amplified by the conditioning at 20 times
/// the bound: under 1e-5 of the motion (about 2e-6 measured), where a missing damping block,
/// a wrong `h` power or an unrotated block is of the order of the motion itself.
#[rstest]
fn a_backward_euler_step_on_the_fast_engine_equals_the_reference_s_with_finite_elements(
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
) {
    let (model, _) = jittered([5, 3, 3], 3);
    let dt = 20.0 * kind.stable_time_step(&model).unwrap().dt;
    let config = SimConfig {
        force_model: kind,
        integrator: Integrator::BackwardEuler,
        solver: lancet::physics::SolverSettings {
            tolerance: 1e-7,
            max_iterations: 1000,
            preconditioner: lancet::physics::Preconditioner::BlockJacobi,
            ..Default::default()
        },
        ..SimConfig::new(dt)
    };
    let x0 = start(&model, 5);
    let mut rng = Rng(11);
    let v0: Vec<[f64; 3]> = model
        .fixed
        .iter()
        .map(|&f| {
            let v = [rng.sym(), rng.sym(), rng.sym()].map(|c| 0.05 * c);
            if f {
                [0.0; 3]
            } else {
                v
            }
        })
        .collect();
    let mut reference = Simulation::new(model.clone(), EngineKind::Reference, config).unwrap();
    let mut fast = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    reference.set_state(&x0, &v0).unwrap();
    fast.set_state(&x0, &v0).unwrap();
    for steps in [1, 3] {
        reference.run(steps).unwrap();
        fast.run(steps).unwrap();
        let (r, f) = (reference.positions(), fast.positions());
        let e = relative_l2(&model.rest, &f, &r);
        let ev = relative_l2(
            &vec![[0.0; 3]; r.len()],
            &fast.velocities(),
            &reference.velocities(),
        );
        let moved = relative_l2(&model.rest, &x0, &r);
        eprintln!(
            "{kind}, {steps} more: {e:.2e} positions, {ev:.2e} velocities, moved {moved:.2e}"
        );
        assert!(e < 1e-5 && ev < 1e-5, "{kind}: {e:.2e} {ev:.2e}");
        assert!(moved > 1e-2, "{kind}: moved {moved:.2e}");
    }
    let (a, b) = (
        fast.solver_stats().unwrap(),
        reference.solver_stats().unwrap(),
    );
    assert_eq!(a.capped, 0, "{a:?}");
    // The same system: about as many iterations to the same tolerance.
    let (ia, ib) = (a.iterations as f64, b.iterations as f64);
    assert!((ia - ib).abs() <= 0.2 * ib + 4.0, "{a:?} against {b:?}");
}

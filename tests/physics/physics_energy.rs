//! Energy: an undamped body conserves it (the integrators are symplectic, so the discrete
//! energy oscillates about its start without drift), and a damped body only loses it.

use lancet::engine::Integrator;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, SpringDamping};
use lancet::{EngineKind, Material, ModelConfig, PackedModel, SimConfig, Simulation, SpringModel};
use rstest::rstest;

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

const H: f64 = 0.01;

fn block(material: Material, mass_damping: f64) -> PackedModel {
    let mesh = BoxGrid::cube_cells([5, 4, 3], H).build().unwrap();
    let mut config = ModelConfig::new(material);
    config.mass_damping = mass_damping;
    SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap()
}

/// A run at half the stable bound, started at rest from a smooth random displacement: along
/// each axis, a sum of half-waves across the block with random amplitudes (up to 2% of the cell
/// size) and phases. Smooth, so that the energy sits in the low modes, where `w h` is small and
/// the discrete energy is close to the conserved one; random so that every run differs from a
/// hand-picked mode.
fn start(model: PackedModel, kind: EngineKind, integrator: Integrator) -> Simulation {
    let bound = stable_time_step(&model).dt;
    let mut config = SimConfig::new(0.5 * bound);
    config.integrator = integrator;
    let mut rng = Rng(0x1234_5678_9abc_def1);
    let size = [0.05, 0.04, 0.03];
    // waves[c][a] = (amplitude, wave number, phase) of component c along axis a.
    let waves: Vec<Vec<(f64, f64, f64)>> = (0..3)
        .map(|_| {
            (0..3)
                .map(|_| {
                    (
                        0.02 * H * rng.sym(),
                        1.0 + (rng.sym() + 1.0).floor(),
                        3.0 * rng.sym(),
                    )
                })
                .collect()
        })
        .collect();
    let x: Vec<[f64; 3]> = model
        .rest
        .iter()
        .map(|r| {
            [0, 1, 2].map(|c| {
                r[c] + (0..3)
                    .map(|a| {
                        let (amp, k, phase) = waves[c][a];
                        amp * (std::f64::consts::PI * k * r[a] / size[a] + phase).sin()
                    })
                    .sum::<f64>()
            })
        })
        .collect();
    let v = vec![[0.0; 3]; x.len()];
    let mut sim = Simulation::new(model, kind, config).unwrap();
    sim.set_state(&x, &v).unwrap();
    sim
}

/// Energy with the centred velocity `(x_{n+1} - x_{n-1}) / 2h`, the mean of the engine's
/// velocities at steps `n` and `n + 1`: conserved by the scheme to O((w h)^2).
fn centred_energy(sim: &mut Simulation) -> f64 {
    let (x, v0) = (sim.positions(), sim.velocities());
    sim.run(1).unwrap();
    let v1 = sim.velocities();
    let v: Vec<[f64; 3]> = v0
        .iter()
        .zip(&v1)
        .map(|(a, b)| [0, 1, 2].map(|c| 0.5 * (a[c] + b[c])))
        .collect();
    let m = sim.model();
    m.kinetic_energy(&v) + m.elastic_energy(&x) + m.gravity_energy(&x)
}

/// Over 6,000 steps at half the bound, the centred energy stays within 3% of its start (it measures about 2%: the smooth start still puts some energy into modes with `w h` near 1), and
/// `Simulation::energy` (whose kinetic part uses the backward-difference velocity, half a step
/// behind the positions) within 15%: that lag makes it oscillate by O(w h) for each mode, about
/// 10% for the lowest modes of this block at this step, without drifting.
#[rstest]
fn an_undamped_block_keeps_its_energy(
    #[values(EngineKind::Reference, EngineKind::Fast)] kind: EngineKind,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = block(Material::elastic(1e4, 0.25, 1000.0), 0.0);
    let mut sim = start(model, kind, integrator);
    let e0 = sim.energy().total();
    let c0 = centred_energy(&mut sim);
    assert!(e0 > 0.0 && c0 > 0.0);
    let (mut worst, mut worst_centred) = (0.0f64, 0.0f64);
    for _ in 0..60 {
        sim.run(99).unwrap();
        worst = worst.max((sim.energy().total() - e0).abs() / e0);
        worst_centred = worst_centred.max((centred_energy(&mut sim) - c0).abs() / c0);
    }
    assert!(
        worst_centred < 0.03,
        "centred energy strayed {:.2}%",
        worst_centred * 100.0
    );
    assert!(
        worst < 0.15,
        "energy strayed {:.2}% from its start",
        worst * 100.0
    );
}

/// With spring and mass damping, every chunk of 50 steps ends with less energy than it started,
/// until the energy is down to 1e-6 of its start: below that the float32 engine's rounding of
/// displacements (~6e-8 of them) leaves a noise floor that may rise from one chunk to the next.
#[rstest]
fn a_damped_block_loses_energy_monotonically(
    #[values(EngineKind::Reference, EngineKind::Fast)] kind: EngineKind,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let material = Material::elastic(1e4, 0.25, 1000.0)
        .with_damping(SpringDamping::StiffnessProportional(2e-4));
    let model = block(material, 5.0);
    let mut sim = start(model, kind, integrator);
    let e0 = sim.energy().total();
    let mut last = e0;
    for chunk in 0..60 {
        sim.run(50).unwrap();
        let e = sim.energy().total();
        if last > 1e-6 * e0 {
            assert!(
                e < last,
                "chunk {chunk}: energy rose from {last:e} to {e:e}"
            );
        }
        last = e;
    }
    assert!(
        last < 0.5 * e0,
        "damping removed too little: {last:e} of {e0:e}"
    );
}

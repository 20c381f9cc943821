//! The checks of `Simulation::run` outside scenes: inverted tets are reported like a
//! divergence (unless allowed), and a divergence or an inversion is reported at the first bad
//! step, not at the step of the periodic check that saw it.

use lancet::engine::{EngineKind, SimConfig, Simulation, INVERSION_CHECK_EVERY};
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::TetMesh;
use lancet::model::{stable_time_step, FixedSelector, Material, ModelConfig, SpringModel};
use lancet::{BadStep, Error};

/// A 10 mm cube of 2x2x2 cells standing on its fixed base under gravity, of Young's modulus
/// `e` Pa, damped at 5/s: its mesh and a simulation of it at 3e-4 s, with its tets watched.
fn cube(e: f64, kind: EngineKind, allow_inverted: bool) -> (TetMesh, Simulation) {
    let mesh = BoxGrid::cube_cells([2, 2, 2], 0.005).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(e, 0.25, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.mass_damping = 5.0;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    });
    let model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    // Free fall takes sqrt(2 h / g) = 45 ms, 150 steps, to bring the top to the base: the
    // tets turn over well after the first step and before the first inversion check.
    let dt = 3e-4;
    assert!(dt < stable_time_step(&model).dt);
    let mut sim_config = SimConfig::new(dt);
    sim_config.allow_inverted = allow_inverted;
    let mut sim = Simulation::new(model, kind, sim_config).unwrap();
    sim.watch_mesh(&mesh).unwrap();
    (mesh, sim)
}

/// Six times the signed volume of tet `t` of `mesh` at positions `x`.
fn volume6(mesh: &TetMesh, t: usize, x: &[[f64; 3]]) -> f64 {
    let dense = mesh.dense_nodes();
    let (_, tet) = mesh.tets().nth(t).unwrap();
    let p = tet.nodes.map(|k| x[dense.index[k] as usize]);
    let d = |i: usize| [0, 1, 2].map(|c| p[i][c] - p[0][c]);
    let (a, b, c) = (d(1), d(2), d(3));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// Whether any tet of `mesh` is turned over at `x` (every tet of a generated box is positive
/// at rest).
fn any_inverted(mesh: &TetMesh, x: &[[f64; 3]]) -> bool {
    (0..mesh.tet_count()).any(|t| volume6(mesh, t, x) < 0.0)
}

/// With E = 1 Pa the cube's weight (rho g h = 98 Pa at its base, about a hundred times E)
/// crushes it: `Simulation::run`, with no scene around it, stops at the first step with a
/// turned-over tet, which a plain step-by-step run confirms: the tet named is inverted at that
/// step and no tet is at the step before. The check that found it ran later, on the cadence.
#[test]
fn run_reports_the_first_step_with_an_inverted_tet() {
    for kind in [EngineKind::Reference, EngineKind::Fast] {
        let (mesh, mut sim) = cube(1.0, kind, false);
        let (step, tet, count, ratio, found) = match sim.run(3000) {
            Err(Error::Inverted {
                step,
                tet,
                count,
                ratio,
                found,
            }) => (step, tet, count, ratio, found),
            other => panic!("{kind}: expected an inversion, got {other:?}"),
        };
        assert!(
            count >= 1 && ratio < 0.0,
            "{kind}: {count} tets, ratio {ratio}"
        );
        let found = found.unwrap_or_else(|| panic!("{kind}: no check window"));
        assert!(found.replayed, "{kind}: {found:?}");
        assert!(
            found.last_good < step && step < found.found_at,
            "{kind}: {found:?}"
        );
        assert!(
            step > 10,
            "{kind}: inverted at step {step}, before any check could see it"
        );
        assert!(found.found_at - found.last_good <= INVERSION_CHECK_EVERY + 10);
        assert_eq!(sim.steps(), step, "{kind}: left at the first bad step");

        // The same run, a step at a time, with the tets looked at after every step.
        let (_, mut plain) = cube(1.0, kind, true);
        plain.run(step - 1).unwrap();
        let before = plain.positions();
        assert!(
            !any_inverted(&mesh, &before),
            "{kind}: inverted before step {step}"
        );
        plain.run(1).unwrap();
        let at = plain.positions();
        let v = volume6(&mesh, tet, &at);
        assert!(v < 0.0, "{kind}: tet {tet} at step {step} has 6V = {v}");
    }
}

/// `allow_inverted` runs on through the same crush; a cube stiff enough to carry its weight
/// (E = 50 kPa: strain about 2e-3) runs on without it.
#[test]
fn allowed_inversions_and_a_stiff_cube_run_on() {
    let (mesh, mut crushed) = cube(1.0, EngineKind::Fast, true);
    crushed.run(3000).unwrap();
    assert!(any_inverted(&mesh, &crushed.positions()));
    let (_, mut stiff) = cube(50e3, EngineKind::Fast, false);
    stiff.run(3000).unwrap();
}

/// An elastic box perturbed by 1e-6 of its size and run at twice the stable step (1.15 times
/// its measured threshold, see `stability.rs`) diverges within a few dozen steps. Checked every 50 steps, the divergence is reported at the step a
/// run checked after every step reports, and the check that saw it ran later.
#[test]
fn a_divergence_is_reported_at_its_first_bad_step() {
    for kind in [EngineKind::Reference, EngineKind::Fast] {
        let diverge = |check_every: u32| {
            let mesh = BoxGrid::cube_cells([6, 5, 4], 0.01).build().unwrap();
            let model = SpringModel::build(
                &mesh,
                &ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0)),
            )
            .unwrap()
            .pack(&mesh)
            .unwrap();
            let mut config = SimConfig::new(2.0 * stable_time_step(&model).dt);
            config.allow_unstable = true;
            config.check_every = check_every;
            let x0: Vec<[f64; 3]> = model
                .rest
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    // A fixed, irregular perturbation of 1e-8 m (1e-6 of the size).
                    let s = ((i * 7919) % 13) as f64 / 6.0 - 1.0;
                    [r[0] + 1e-8 * s, r[1] - 1e-8 * s, r[2] + 0.5e-8 * s]
                })
                .collect();
            let mut sim = Simulation::new(model, kind, config).unwrap();
            sim.set_state(&x0, &vec![[0.0; 3]; x0.len()]).unwrap();
            match sim.run(100_000) {
                Err(Error::Diverged { step, found, .. }) => (step, found, sim.steps()),
                other => panic!("{kind}: expected a divergence, got {other:?}"),
            }
        };
        let (every_step, _, _) = diverge(1);
        let (step, found, left_at) = diverge(50);
        let found: BadStep = found.unwrap_or_else(|| panic!("{kind}: no check window"));
        assert_eq!(step, every_step, "{kind}: {found:?}");
        assert!(found.replayed, "{kind}: {found:?}");
        assert_eq!(found.found_at % 50, 0, "{kind}: {found:?}");
        assert!(step < found.found_at, "{kind}: {step} {found:?}");
        assert!(found.last_good < step, "{kind}: {step} {found:?}");
        assert_eq!(left_at, step, "{kind}");
    }
}

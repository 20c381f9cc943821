//! The fast engine's divergence probe (`Engine::divergence_probe`), which the simulation's
//! checks read instead of copying the whole state: its kinetic and gravitational energies are those of the
//! state the engine reports, computed in float64 from the model's masses; it names the node
//! (model index) that is not finite; and it does not depend on the number of threads.

use crate::models::{random_model, random_state};
use lancet::engine::fast::{on_threads, FastEngine};
use lancet::engine::{Engine, Health, Integrator, SimConfig};
use lancet::model::stable_time_step;

#[test]
fn the_probe_gives_the_state_s_energies_and_its_first_bad_node() {
    let mut model = random_model(23, true);
    model.gravity = [0.7, -1.3, -9.81];
    for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
        let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
        config.integrator = integrator;
        let (x, v) = random_state(&model, 23);
        let probe = |threads: usize| {
            on_threads(threads, || {
                let mut e = FastEngine::new(&model, config);
                e.set_state(&x, &v);
                e.step(20);
                let h: Health = e
                    .divergence_probe()
                    .expect("the fast engine has a probe")
                    .unwrap();
                (h, e.positions(), e.velocities())
            })
            .unwrap()
        };
        let (h, pos, vel) = probe(2);
        let kinetic = model.kinetic_energy(&vel);
        let gravity = model.gravity_energy(&pos);
        assert!(kinetic > 0.0 && gravity.abs() > 0.0);
        // Float32 masses and state summed in float64: rounding of a few 1e-7.
        let off = |a: f64, b: f64| (a - b).abs() / b.abs();
        assert!(
            off(h.kinetic, kinetic) < 1e-5,
            "{integrator:?}: {h:?}, {kinetic}"
        );
        assert!(
            off(h.gravity, gravity) < 1e-5,
            "{integrator:?}: {h:?}, {gravity}"
        );
        assert_eq!(h.non_finite, None);
        assert_eq!(probe(1).0, h, "{integrator:?}: 1 and 2 threads differ");

        // A node not finite is named by its model index.
        let bad = (0..model.node_count()).filter(|&i| !model.fixed[i]);
        let bad: Vec<usize> = bad.skip(5).step_by(7).take(2).collect();
        let mut e = FastEngine::new(&model, config);
        let mut broken = x.clone();
        for &b in &bad {
            broken[b][1] = f64::NAN;
        }
        e.set_state(&broken, &v);
        let found = e.divergence_probe().unwrap().unwrap().non_finite;
        // The probe scans in the engine's internal order: either may come first there.
        assert!(
            found.is_some_and(|n| bad.contains(&n)),
            "{found:?} not in {bad:?}"
        );
    }
}

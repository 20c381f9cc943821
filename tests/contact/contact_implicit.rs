//! Contact under backward Euler: a probe pressed 1 mm into a block and held should read the
//! same static force after implicit steps of 1 ms (five times the explicit bound) as after
//! explicit steps of half the bound, and both the static reaction of the block's fixed base.
//!
//! Ignored until contact enters the implicit solve: contact corrects positions between steps,
//! and a backward Euler step at 1 ms lets the whole block relax back into the probe (the
//! contact nodes end each step about 0.65 mm inside it, against 0.03 mm explicitly), so neither
//! the state nor the reading `m dx / h^2` is the held contact's (0.011 N against 0.069 N).

use crate::tissue;
use lancet::collide::broad::Surface;
use lancet::collide::{Tool, ToolShape};
use lancet::contact::response::{resolve_contacts, ContactSettings};
use lancet::engine::{EngineKind, Integrator, SimConfig, Simulation};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, SpringModel};
use nalgebra::{Isometry3, Vector3};

const RADIUS: f64 = 3e-3;
const TOP: f64 = 0.012;

/// The block of `contact_probe` and `fixtures/scenes/probe_press.ron` (24 x 24 x 12 mm, 2 mm
/// cells, E = 20 kPa, base fixed, mass damping 80/s, no gravity) stepped by `integrator` at
/// `dt` (half the stable bound where `None`) on the fast engine.
fn block(integrator: Integrator, dt: Option<f64>) -> Simulation {
    let mesh = BoxGrid::cube_cells([12, 12, 6], 0.002).build().unwrap();
    let model = SpringModel::build(&mesh, &tissue::clamped([0.0, 0.0, 1.0], 80.0))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let mut config = SimConfig::new(dt.unwrap_or(0.5 * stable_time_step(&model).dt));
    config.integrator = integrator;
    let mut sim = Simulation::new(model, EngineKind::Fast, config).unwrap();
    sim.set_surface(Surface::of(&mesh).triangles).unwrap();
    sim
}

/// The sphere's pose with its lowest point `depth` below the block's top, over its centre.
fn pose(depth: f64) -> Isometry3<f64> {
    Isometry3::translation(0.012, 0.012, TOP + RADIUS - depth)
}

/// The probe lowered from 1 mm above the top to 1 mm into it over 0.15 s, then held to 0.4 s
/// (the block settles within about 0.05 s); the force it read at the last step.
fn press(sim: &mut Simulation) -> Vector3<f64> {
    let s = ContactSettings::default();
    let dt = sim.config().dt;
    let steps = (0.4 / dt).round() as usize;
    let mut tool = Tool::new(ToolShape::Sphere { radius: RADIUS }, pose(-1e-3)).unwrap();
    let mut force = Vector3::zeros();
    for k in 1..=steps {
        let t = k as f64 * dt;
        tool.set_pose(pose(-1e-3 + 2e-3 * (t / 0.15).min(1.0)));
        sim.run(1).unwrap();
        force = resolve_contacts(sim, std::slice::from_ref(&tool), &s).unwrap()[0].force;
    }
    force
}

/// What holds the block against the probe: the force the springs put on the fixed base nodes.
/// In static equilibrium without gravity the free nodes' springs and the probe balance, and
/// the springs' forces sum to zero over all nodes, so the probe pushes the tissue with exactly
/// this force and feels its opposite.
fn base_reaction(sim: &Simulation) -> Vector3<f64> {
    let (m, x) = (sim.model(), sim.positions());
    let mut f = Vector3::zeros();
    for s in m.springs() {
        let [a, b] = s.nodes.map(|i| i as usize);
        let d = Vector3::from(x[b]) - Vector3::from(x[a]);
        let l = d.norm();
        let on_a = d * (s.stiffness * (l - s.rest_length) / l);
        if m.fixed[a] {
            f += on_a;
        }
        if m.fixed[b] {
            f -= on_a;
        }
    }
    f
}

#[test]
#[ignore = "fails until contact enters the implicit solve (see the module's comment)"]
fn the_implicit_probe_press_reads_the_explicit_static_force() {
    let mut explicit = block(Integrator::Verlet, None);
    let mut implicit = block(Integrator::BackwardEuler, Some(1e-3));
    assert!(implicit.config().dt > 4.0 * explicit.config().dt);
    let (fe, fi) = (press(&mut explicit), press(&mut implicit));
    let (be, bi) = (-base_reaction(&explicit), -base_reaction(&implicit));
    eprintln!(
        "probe force: explicit {:.4} N (base {:.4} N), implicit {:.4} N (base {:.4} N)",
        fe.z, be.z, fi.z, bi.z
    );
    // Away from the tissue, and about Hertz's 0.051 N (see probe_press.ron).
    assert!(fe.z > 0.025 && fe.z < 0.15, "explicit: {fe:?}");
    for (what, f, base) in [("explicit", fe, be), ("implicit", fi, bi)] {
        assert!(
            (f.z - base.z).abs() <= 0.1 * base.z,
            "{what}: the probe reads {:.4} N, the base holds {:.4} N",
            f.z,
            base.z
        );
    }
    assert!(
        (fi.z - fe.z).abs() <= 0.1 * fe.z,
        "implicit {:.4} N against explicit {:.4} N",
        fi.z,
        fe.z
    );
}

//! Small blocks and flaps of soft tissue for the contact and grasp tests.
#![allow(dead_code)] // each test file uses a different subset

use lancet::collide::broad::Surface;
use lancet::collide::Tool;
use lancet::contact::response::{resolve_contacts, ContactSettings, ToolForce};
use lancet::engine::{EngineKind, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, FixedSelector, Material, ModelConfig, SpringModel};
use nalgebra::{Isometry3, Vector3};

/// Soft tissue (E = 20 kPa, nu = 0.3, 1000 kg/m^3) with mass damping `alpha` (1/s), its nodes on
/// the plane through the origin with normal `normal` held fixed.
pub fn clamped(normal: [f64; 3], alpha: f64) -> ModelConfig {
    let mut config = ModelConfig::new(Material::elastic(20e3, 0.3, 1000.0));
    config.mass_damping = alpha;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal,
        tolerance: 1e-9,
    });
    config
}

/// A simulation of `grid` under `config` on engine `kind` at half the stable step, with its
/// surface given for contact.
pub fn tissue(grid: BoxGrid, config: &ModelConfig, kind: EngineKind) -> Simulation {
    tissue_in(grid, config, kind, LayoutKind::default())
}

/// [`tissue`] with the GPU engine's spring layout chosen (ignored by the CPU engines).
pub fn tissue_in(
    grid: BoxGrid,
    config: &ModelConfig,
    kind: EngineKind,
    layout: LayoutKind,
) -> Simulation {
    let mesh = grid.build().unwrap();
    let model = SpringModel::build(&mesh, config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let dt = 0.5 * stable_time_step(&model).dt;
    let sim_config = SimConfig::new(dt);
    let mut sim = Simulation::with_gpu(model, kind, sim_config, layout.into()).unwrap();
    sim.set_surface(Surface::of(&mesh).triangles).unwrap();
    sim
}

/// Move a sphere of `radius` to `to`, step once and resolve contacts; returns what it felt and
/// checks that no node ends the step more than 20 um inside it (the probe advances at most
/// 1 um per step; corrections leave a node a few um inside where several contacts pull on it).
pub fn step_sphere(
    sim: &mut Simulation,
    tool: &mut Tool,
    to: Isometry3<f64>,
    s: &ContactSettings,
    radius: f64,
) -> ToolForce {
    tool.set_pose(to);
    sim.run(1).unwrap();
    let f = resolve_contacts(sim, std::slice::from_ref(tool), s).unwrap()[0];
    let centre = tool.pose().translation.vector;
    for p in sim.positions() {
        let d = (Vector3::from(p) - centre).norm();
        assert!(
            d > radius - 2e-5,
            "a node is {:.2e} m inside the probe",
            radius - d
        );
    }
    f
}

//! Small blocks and flaps of soft tissue for the contact and grasp tests.

use lancet::collide::broad::Surface;
use lancet::engine::{EngineKind, SimConfig, Simulation};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, FixedSelector, Material, ModelConfig, SpringModel};

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
    let mesh = grid.build().unwrap();
    let model = SpringModel::build(&mesh, config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let dt = 0.5 * stable_time_step(&model).dt;
    let mut sim = Simulation::new(model, kind, SimConfig::new(dt)).unwrap();
    sim.set_surface(Surface::of(&mesh).triangles).unwrap();
    sim
}

//! Random models shared by the layout and GPU tests. Included with `#[path]` so the CPU tests do
//! not pull in the GPU helpers of `common/mod.rs`.
#![allow(dead_code)] // each test file uses a different subset

use lancet::mesh::generate::BoxGrid;
use lancet::model::{
    FixedSelector, Material, ModelConfig, PackedModel, SpringDamping, SpringModel,
};

/// A small xorshift generator: reproducible random inputs without another dependency.
pub struct Rng(pub u64);
impl Rng {
    /// The next value, uniform in [0, 1).
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A box with random per-spring stiffness, damping and masses, gravity, mass damping and a
/// fixed base: every term of the force law is exercised, and corner, edge, face and inner nodes
/// differ in valence.
pub fn random_box(seed: u64, damped: bool) -> PackedModel {
    let mut rng = Rng(seed);
    let mesh = BoxGrid::cube_cells([5, 4, 3], 0.01).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(5e3, 0.25, 1000.0).with_damping(
        if damped {
            SpringDamping::StiffnessProportional(2e-4)
        } else {
            SpringDamping::None
        },
    ));
    config.gravity = [0.3, -0.2, -9.81];
    config.mass_damping = 3.0;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    });
    let mut model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    for s in &mut model.springs {
        let f = 0.5 + rng.next();
        s.stiffness *= f;
        s.damping *= f;
    }
    for m in &mut model.mass {
        *m *= 0.5 + rng.next();
    }
    model
}

/// [`random_box`] plus two springless nodes (a valence bucket of width 0).
pub fn random_model(seed: u64, damped: bool) -> PackedModel {
    let mut model = random_box(seed, damped);
    for p in [[0.05, 0.05, 0.05], [-0.02, 0.01, 0.03]] {
        model.rest.push(p);
        model.mass.push(1e-4);
        model.fixed.push(false);
        model.node_keys.push(model.node_keys[0]);
    }
    model
}

/// Random displacements of about 5% of a cell and random velocities, model order, with fixed
/// nodes at rest.
pub fn random_state(model: &PackedModel, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = Rng(seed);
    let mut x = Vec::new();
    let mut v = Vec::new();
    for (i, r) in model.rest.iter().enumerate() {
        let mut u = [0.0; 3];
        let mut w = [0.0; 3];
        if !model.fixed[i] {
            for c in 0..3 {
                u[c] = (rng.next() - 0.5) * 1e-3;
                w[c] = (rng.next() - 0.5) * 0.1;
            }
        }
        x.push([r[0] + u[0], r[1] + u[1], r[2] + u[2]]);
        v.push(w);
    }
    (x, v)
}

//! The box the finite-element cut tests cut: 3 cm, 4 x 4 x 4 cells, hanging from its y = 0
//! face, Rayleigh-damped, a blade whose edge moves from one point to another over 20 ms, every
//! cut checked against a rebuild (`tests/cut/cut_fem.rs` on the CPU engines,
//! `tests/gpu/fem_gpu_checks.rs` on the GPU layouts, for tensor-mass and corotational; each picks
//! its engine and method).

/// The scene's RON text: the blade's edge from `from` to `to` (m), `steps` steps at 0.8 of the
/// stable bound.
pub fn scene(from: [f64; 3], to: [f64; 3], steps: u64) -> String {
    let ([x0, y0, z0], [x1, y1, z1]) = (from, to);
    format!(
        r#"Scene(
    name: "finite-element cuts",
    mesh: Box((cells: (4, 4, 4), size: (0.03, 0.03, 0.03))),
    material: (
        stiffness: Material(youngs_modulus: 1e4, poisson_ratio: 0.3),
        mass: Density(1000.0),
        damping: StiffnessProportional(1e-3),
    ),
    gravity: (0.0, -9.81, 0.0),
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (0.0, 1.0, 0.0), tolerance: 1e-9)],
    dt: BoundFraction(0.8),
    steps: {steps},
    engine: Reference,
    tools: [(
        name: "scalpel",
        shape: Blade(width: 0.1, length: 0.1, thickness: 2e-4),
        trajectory: Keyframes([
            (time: 0.0, translation: ({x0}, {y0}, {z0})),
            (time: 0.02, translation: ({x1}, {y1}, {z1})),
        ]),
    )],
    cut: Some((methods: [Separate, Remove, Subdivide], check: true, time_step: Substep)),
)"#
    )
}

/// The diff that gives tet 0 of `model` a copy of its first corner in place of that corner
/// (what separating does to one tet): a node added with the corner's state, the tet removed and
/// re-added on the copy.
pub fn recorner_first_tet(model: &lancet::model::PackedModel) -> lancet::model::ModelDiff {
    use lancet::model::{AddedNode, ModelDiff, PackedTet};
    let t: PackedTet = model.tets[0];
    let n = model.node_count() as u32;
    let copy = t.nodes[0];
    ModelDiff {
        added_nodes: vec![AddedNode {
            key: Default::default(),
            rest: model.rest[copy as usize],
            mass: model.mass[copy as usize],
            fixed: false,
            state_from: Some(copy),
            blend: None,
        }],
        removed_tets: vec![t.nodes],
        added_tets: vec![PackedTet {
            nodes: [n, t.nodes[1], t.nodes[2], t.nodes[3]],
            ..t
        }],
        ..ModelDiff::default()
    }
}

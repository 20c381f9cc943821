//! The spring model follows its documented rules: one spring per unique tet edge, lumped mass
//! `rho V`, the dilation energy of the stiffness rules, exact removal of a tet's share, fixed
//! selectors and parameter validation.

use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::model::{FixedSelector, Mass, SpringDamping, Stiffness, StiffnessRule};
use lancet::{Error, Material, ModelConfig, SpringModel, TetMesh};
use nalgebra::Point3;
use rstest::rstest;

/// xorshift64*: a tiny seeded generator, enough for test inputs.
struct Rng(u64);

impl Rng {
    fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in `[-1, 1)`.
    fn sym(&mut self) -> f64 {
        2.0 * self.next_f64() - 1.0
    }
}

fn boxes() -> Vec<TetMesh> {
    [TetSplit::Six, TetSplit::Five]
        .into_iter()
        .map(|split| {
            BoxGrid {
                cells: [4, 3, 2],
                size: [0.04, 0.03, 0.02],
                origin: [0.1, -0.2, 0.3],
                split,
            }
            .build()
            .unwrap()
        })
        .collect()
}

fn material(rule: StiffnessRule) -> Material {
    Material {
        stiffness: Stiffness::Material {
            youngs_modulus: 5e3,
            poisson_ratio: 0.42,
            rule,
        },
        mass: Mass::Density(1060.0),
        damping: SpringDamping::StiffnessProportional(0.01),
    }
}

#[test]
fn there_is_one_spring_per_unique_tet_edge() {
    for mesh in boxes() {
        let model =
            SpringModel::build(&mesh, &ModelConfig::new(material(Default::default()))).unwrap();
        let edges = mesh.edges();
        assert_eq!(model.spring_count(), edges.len());
        let packed = model.pack(&mesh).unwrap();
        let springs: Vec<[u32; 2]> = packed.springs().iter().map(|s| s.nodes).collect();
        assert_eq!(springs, edges);
    }
}

#[test]
fn total_mass_is_density_times_volume() {
    for mesh in boxes() {
        let model =
            SpringModel::build(&mesh, &ModelConfig::new(material(Default::default()))).unwrap();
        let expected = 1060.0 * 0.04 * 0.03 * 0.02;
        let rel = (model.total_mass() - expected).abs() / expected;
        assert!(rel < 1e-12, "{} vs {expected}", model.total_mass());
        assert!((mesh.volume() - 0.04 * 0.03 * 0.02).abs() < 1e-15);
    }
}

/// Random tets: well-shaped ones and slivers (four nearly coplanar points) and needles.
fn random_tets() -> Vec<[[f64; 3]; 4]> {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut out = Vec::new();
    for t in 0..60 {
        // Flatness of the fourth point: 1 (regular-ish) down to 1e-4 (sliver).
        let flat = [1.0, 0.1, 1e-2, 1e-3, 1e-4][t % 5];
        let mut p = [[0.0; 3]; 4];
        for (i, q) in p.iter_mut().enumerate() {
            *q = [
                rng.sym(),
                rng.sym(),
                rng.sym() * if i == 3 { flat } else { 1.0 },
            ];
        }
        if t % 7 == 0 {
            // Stretch into a needle.
            for q in &mut p {
                q[0] *= 50.0;
            }
        }
        out.push(p);
    }
    out
}

/// Under `x -> (1 + s) x` every edge stretches by `s l`, so a tet stores
/// `sum_e 1/2 (C V / l_e^2) (s l_e)^2 = 3 C V s^2`: with `C = E` (Van Gelder) that is
/// `3 E V s^2`; with `C = 3K/2` (bulk matched) it is `9/2 K V s^2`, the energy of an isotropic
/// solid under the same dilation.
#[rstest]
#[case::bulk_matched(StiffnessRule::BulkMatched)]
#[case::van_gelder(StiffnessRule::VanGelder)]
fn dilation_energy_of_any_tet_matches_the_documented_formula(#[case] rule: StiffnessRule) {
    let (e, nu) = (5e3, 0.42);
    let bulk = e / (3.0 * (1.0 - 2.0 * nu));
    for (t, p) in random_tets().into_iter().enumerate() {
        let (mesh, _) = TetMesh::from_arrays(&p, &[[0, 1, 2, 3]], None).unwrap();
        let volume = mesh.volume();
        let packed = SpringModel::build(&mesh, &ModelConfig::new(material(rule)))
            .unwrap()
            .pack(&mesh)
            .unwrap();
        for s in [1e-3, -0.02, 0.1] {
            let x: Vec<[f64; 3]> = packed
                .rest
                .iter()
                .map(|r| r.map(|c| (1.0 + s) * c))
                .collect();
            let energy = packed.elastic_energy(&x);
            let expected = match rule {
                StiffnessRule::BulkMatched => 4.5 * bulk * volume * s * s,
                StiffnessRule::VanGelder => 3.0 * e * volume * s * s,
            };
            let rel = (energy - expected).abs() / expected;
            assert!(
                rel < 1e-9,
                "tet {t}, s = {s}: {energy} vs {expected} ({rel:.1e})"
            );
        }
    }
}

fn rel_diff(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}

/// Removing a tet's share leaves exactly the model of the mesh without the tet. On a
/// five-tet split, tet 0 is the central tet of the corner cell (all its edges shared), tet 1 the
/// corner tet at the box's corner node (its removal deletes springs and that node's mass), and
/// so is the last tet, at the opposite corner.
/// A box of 4 x 3 x 2 cells of 1 cm, five tets each, at the origin.
fn five_tet_box() -> TetMesh {
    BoxGrid {
        cells: [4, 3, 2],
        size: [0.04, 0.03, 0.02],
        origin: [0.0; 3],
        split: TetSplit::Five,
    }
    .build()
    .unwrap()
}

#[rstest]
#[case::central_tet_of_the_corner_cell(0, false)]
#[case::corner_tet(1, true)]
#[case::interior(60, false)]
#[case::corner_tet_at_the_far_corner(119, true)]
fn removing_a_tets_share_gives_the_model_of_the_mesh_without_it(
    #[case] which: usize,
    #[case] deletes_springs: bool,
) {
    let mut mesh = five_tet_box();
    // Two materials so that shares differ across the region boundary. Only parameters that
    // come per tet (material stiffness, density, stiffness-proportional damping) have this
    // property: the per-spring and per-node values (`Stiffness::Spring`, `Mass::PerNode`,
    // `SpringDamping::Absolute`) are split by the incidence counts of the mesh they were built
    // on, so a rebuild after a cut redistributes them.
    mesh.set_region_where(2, |c| c.x > 0.02);
    let mut config = ModelConfig::new(material(StiffnessRule::BulkMatched));
    config.regions.insert(
        2,
        Material::elastic(4e4, 0.3, 900.0).with_damping(SpringDamping::StiffnessProportional(0.02)),
    );
    let tk = mesh.tets().nth(which).unwrap().0;
    let mut model = SpringModel::build(&mesh, &config).unwrap();
    let removed = model.remove_tet(&mesh, tk).unwrap();
    assert_eq!(
        !removed.is_empty(),
        deletes_springs,
        "deleted springs: {removed:?}"
    );
    let mut without = mesh.clone();
    without.remove_tet(tk).unwrap();
    let rebuilt = SpringModel::build(&without, &config).unwrap();

    assert_eq!(model.spring_count(), rebuilt.spring_count());
    for (_, s) in model.springs() {
        let r = rebuilt
            .spring_between(s.nodes[0], s.nodes[1])
            .expect("a spring the rebuilt model lacks");
        assert!(rel_diff(s.stiffness, r.stiffness) < 1e-12, "{s:?} vs {r:?}");
        assert!(rel_diff(s.damping, r.damping) < 1e-12, "{s:?} vs {r:?}");
        assert_eq!(s.tets, r.tets);
        assert_eq!(s.rest_length, r.rest_length);
    }
    for (k, _) in mesh.nodes() {
        match (model.mass(k), rebuilt.mass(k)) {
            (Some(a), Some(b)) => assert!(rel_diff(a, b) < 1e-12, "mass {a} vs {b}"),
            (a, b) => assert_eq!(a, b, "a node has mass in one model only"),
        }
    }
}

fn plane_x0(p: &Point3<f64>) -> bool {
    p.x == 0.0
}
fn unit_box(p: &Point3<f64>) -> bool {
    p.x <= 1.0 && p.y <= 1.0 && p.z <= 1.0
}
fn x_at_most_1(p: &Point3<f64>) -> bool {
    p.x <= 1.0
}
fn y_above_2(p: &Point3<f64>) -> bool {
    p.y >= 2.0
}

/// On a 3x3x3 grid of unit cells, each selector picks exactly the nodes its geometry says.
#[rstest]
#[case::plane(
    FixedSelector::Plane { point: [0.0, 5.0, -1.0], normal: [2.0, 0.0, 0.0], tolerance: 1e-9 },
    plane_x0, 16
)]
#[case::boxed(FixedSelector::Box { min: [-1.0; 3], max: [1.0; 3] }, unit_box, 8)]
#[case::half_space(
    FixedSelector::HalfSpace { point: [1.0, 0.0, 0.0], normal: [1.0, 0.0, 0.0], tolerance: 1e-9 },
    x_at_most_1, 32
)]
// Region 7 is the top layer of cells (centroid y > 2), whose nodes have y = 2 or 3.
#[case::region(FixedSelector::Region(7), y_above_2, 32)]
fn fixed_selectors_pick_the_right_nodes(
    #[case] selector: FixedSelector,
    #[case] expected: fn(&Point3<f64>) -> bool,
    #[case] count: usize,
) {
    let mut mesh = BoxGrid::cube_cells([3, 3, 3], 1.0).build().unwrap();
    mesh.set_region_where(7, |c| c.y > 2.0);
    let mut config = ModelConfig::new(Material::elastic(1e3, 0.3, 1.0));
    config.fixed = vec![selector];
    let model = SpringModel::build(&mesh, &config).unwrap();
    assert_eq!(model.fixed_count(), count);
    for (k, n) in mesh.nodes() {
        assert_eq!(model.is_fixed(k), expected(&n.rest), "node at {:?}", n.rest);
    }
    let packed = model.pack(&mesh).unwrap();
    assert_eq!(packed.fixed.iter().filter(|&&f| f).count(), count);
}

#[rstest]
#[case::nan_modulus(Material::elastic(f64::NAN, 0.3, 1000.0), "young's modulus")]
#[case::negative_modulus(Material::elastic(-1.0, 0.3, 1000.0), "young's modulus")]
#[case::incompressible(Material::elastic(1e3, 0.5, 1000.0), "poisson ratio")]
#[case::nan_poisson(Material::elastic(1e3, f64::NAN, 1000.0), "poisson ratio")]
#[case::negative_poisson(Material::elastic(1e3, -0.1, 1000.0), "poisson ratio")]
#[case::negative_density(Material::elastic(1e3, 0.3, -1.0), "density")]
#[case::nan_density(Material::elastic(1e3, 0.3, f64::NAN), "density")]
#[case::nan_spring(Material::springs(f64::NAN, 1.0), "spring stiffness")]
#[case::negative_spring(Material::springs(-5.0, 1.0), "spring stiffness")]
#[case::negative_node_mass(Material::springs(5.0, -1.0), "mass")]
#[case::negative_damping(
    Material::elastic(1e3, 0.3, 1e3).with_damping(SpringDamping::Absolute(-1.0)), "damping"
)]
#[case::nan_damping(
    Material::elastic(1e3, 0.3, 1e3).with_damping(SpringDamping::StiffnessProportional(f64::NAN)),
    "damping"
)]
fn material_validation_rejects_bad_parameters_by_name(
    #[case] material: Material,
    #[case] name: &str,
) {
    match material.validate() {
        Err(Error::InvalidParameter { name: got, .. }) => {
            assert!(got.contains(name), "{got:?} does not name {name:?}")
        }
        other => panic!("expected a model error naming {name}, got {other:?}"),
    }
    // Building a model refuses it too.
    let mesh = BoxGrid::cube_cells([1, 1, 1], 1.0).build().unwrap();
    assert!(SpringModel::build(&mesh, &ModelConfig::new(material)).is_err());
}

#[test]
fn valid_materials_pass_validation() {
    for m in [
        Material::elastic(1e3, 0.0, 1000.0),
        Material::elastic(1e3, 0.499, 1000.0),
        Material::springs(10.0, 0.1).with_damping(SpringDamping::Absolute(0.0)),
    ] {
        m.validate().unwrap();
    }
}

/// The journal a cut's diff is made from: while recording, each spring and node is noted as
/// it was before its first change, and nothing that did not change is noted.
#[test]
fn the_journal_notes_each_change_once_with_the_state_before_it() {
    let mesh = five_tet_box();
    let config = ModelConfig::new(material(StiffnessRule::BulkMatched));
    let mut model = SpringModel::build(&mesh, &config).unwrap();
    let before = model.clone();
    // Two tets sharing corners: the second removal changes springs and nodes the first
    // changed already, which must keep their first state.
    let first = mesh.tets().next().unwrap();
    let shared = mesh
        .tets()
        .skip(1)
        .find(|(_, t)| t.nodes.iter().filter(|n| first.1.nodes.contains(n)).count() == 3)
        .expect("a face neighbour");
    model.record_changes();
    for (tk, _) in [first, shared] {
        model.remove_tet(&mesh, tk).unwrap();
    }
    let changes = model.take_changes();
    let mut edges = std::collections::BTreeSet::new();
    let mut corners = std::collections::BTreeSet::new();
    for (_, t) in [first, shared] {
        corners.extend(t.nodes);
        for [a, b] in lancet::mesh::TET_EDGES {
            let (p, q) = (t.nodes[a], t.nodes[b]);
            edges.insert(if p < q { [p, q] } else { [q, p] });
        }
    }
    let noted: std::collections::BTreeSet<_> = changes.springs.keys().copied().collect();
    assert_eq!(noted, edges, "every edge of the two tets, and nothing else");
    for (e, was) in &changes.springs {
        let s = before.spring_between(e[0], e[1]).expect("existed");
        assert_eq!(*was, Some((s.rest_length, s.stiffness, s.damping)));
    }
    let noted: std::collections::BTreeSet<_> = changes.nodes.keys().copied().collect();
    assert_eq!(noted, corners);
    for (n, was) in &changes.nodes {
        assert_eq!(*was, (before.mass(*n), before.is_fixed(*n)));
        assert_ne!(model.mass(*n), before.mass(*n), "each corner lost mass");
    }
    // Recording stopped with the take.
    let (tk, _) = mesh.tets().nth(30).unwrap();
    model.remove_tet(&mesh, tk).unwrap();
    let later = model.take_changes();
    assert!(later.springs.is_empty() && later.nodes.is_empty());
}

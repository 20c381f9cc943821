//! The corotational model: no force under any rigid motion, forces that turn with the body,
//! the linear model's forces under small deformation, a finite restoring force for inverted
//! tets, and the force-model contract.

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};

use super::corotational::polar_rotation;
use super::force_model::{ForceModel, Linearization, Vec3};
use super::force_model_tests::{
    assert_diagonal_blocks_are_products, assert_force_is_minus_gradient, damping_product_gap,
    forces, relative_gap, stiffness_product_gap, Rng,
};
use super::tensor_mass_tests::random_tets;
use super::{Corotational, TensorMass};
use crate::mesh::generate::BoxGrid;
use crate::model::{Material, ModelConfig, PackedTet, SpringDamping, SpringModel};

/// A 1 cm cube of 2x2x2 cells, six tets each, E = 1 MPa, nu = 0.3, Rayleigh beta 0.01 s.
fn cube() -> (Vec<Vec3>, Vec<PackedTet>) {
    let mesh = BoxGrid::cube_cells([2, 2, 2], 0.005).build().unwrap();
    let material = Material::elastic(1e6, 0.3, 1000.0)
        .with_damping(SpringDamping::StiffnessProportional(0.01));
    let packed = SpringModel::build(&mesh, &ModelConfig::new(material))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    (packed.rest.clone(), packed.tets.clone())
}

fn rotation(axis: Vec3, degrees: f64) -> Matrix3<f64> {
    Rotation3::from_axis_angle(
        &Unit::new_normalize(Vector3::from(axis)),
        degrees.to_radians(),
    )
    .into_inner()
}

fn apply(q: &Matrix3<f64>, t: Vec3, x: &[Vec3]) -> Vec<Vec3> {
    x.iter()
        .map(|p| {
            let r = q * Vector3::from(*p);
            [r[0] + t[0], r[1] + t[1], r[2] + t[2]]
        })
        .collect()
}

fn largest(f: &[Vec3]) -> f64 {
    f.iter()
        .map(|f| f.iter().map(|c| c * c).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

/// The largest force and the energy of the linear model under a 1e-3 strain of the cube: the
/// scales the rigid-motion forces and energies are measured against.
fn scales(rest: &[Vec3], tets: &[PackedTet]) -> (f64, f64) {
    let stretched: Vec<Vec3> = rest.iter().map(|p| [p[0] * 1.001, p[1], p[2]]).collect();
    let linear = TensorMass::new(rest, tets).unwrap();
    (
        largest(&forces(&linear, &stretched, &vec![[0.0; 3]; rest.len()])),
        linear.potential_energy(&stretched),
    )
}

#[test]
fn a_rigid_motion_gives_no_force_even_at_ninety_and_one_eighty_degrees() {
    let (rest, tets) = cube();
    let model = Corotational::new(&rest, &tets).unwrap();
    let linear = TensorMass::new(&rest, &tets).unwrap();
    let (scale, energy_scale) = scales(&rest, &tets);
    let zero = vec![[0.0; 3]; rest.len()];
    let mut r = Rng(5);
    let mut cases = vec![
        ([0.0, 0.0, 1.0], 90.0),
        ([1.0, 0.0, 0.0], 180.0),
        ([1.0, 1.0, 1.0], 180.0),
        ([0.3, -1.0, 0.2], 90.0),
    ];
    for _ in 0..6 {
        cases.push((r.vec(1.0), r.signed(180.0)));
    }
    for (axis, degrees) in cases {
        let x = apply(&rotation(axis, degrees), r.vec(0.05), &rest);
        let f = largest(&forces(&model, &x, &zero));
        assert!(
            f < 1e-9 * scale,
            "rotation by {degrees} degrees about {axis:?}: force {f:e} N (scale {scale:e} N)"
        );
        let energy = model.potential_energy(&x);
        assert!(
            energy.abs() < 1e-12 * energy_scale,
            "{degrees} degrees: {energy:e} J"
        );
        // The linear model is not invariant: its ghost force is far above the strain's.
        if degrees.abs() > 30.0 {
            assert!(
                largest(&forces(&linear, &x, &zero)) > scale,
                "{degrees} degrees"
            );
        }
    }
}

#[test]
fn the_forces_turn_with_the_deformed_state() {
    let (rest, tets) = cube();
    let model = Corotational::new(&rest, &tets).unwrap();
    let zero = vec![[0.0; 3]; rest.len()];
    let mut r = Rng(9);
    for _ in 0..5 {
        // A deformation of a few percent strain, then a rotation of the whole.
        let x: Vec<Vec3> = rest
            .iter()
            .map(|p| {
                let d = r.vec(2e-4);
                [0, 1, 2].map(|c| p[c] + d[c])
            })
            .collect();
        let q = rotation(r.vec(1.0), r.signed(180.0));
        let f = forces(&model, &x, &zero);
        let turned = forces(&model, &apply(&q, r.vec(0.01), &x), &zero);
        let expected: Vec<Vec3> = apply(&q, [0.0; 3], &f);
        let gap = relative_gap(&turned, &expected);
        assert!(gap < 1e-10, "f(Q x) is {gap:e} from Q f(x)");
        assert!(largest(&f) > 0.0);
    }
}

#[test]
fn under_small_deformation_the_forces_are_the_linear_models() {
    let (rest, tets) = cube();
    let model = Corotational::new(&rest, &tets).unwrap();
    let linear = TensorMass::new(&rest, &tets).unwrap();
    let zero = vec![[0.0; 3]; rest.len()];
    // The two differ by the rotation of each tet, of the order of the strain: the gap shrinks
    // with the displacement.
    let mut gaps = Vec::new();
    for size in [1e-5, 1e-7] {
        let mut r = Rng(13);
        let x: Vec<Vec3> = rest
            .iter()
            .map(|p| {
                let d = r.vec(size);
                [0, 1, 2].map(|c| p[c] + d[c])
            })
            .collect();
        gaps.push(relative_gap(
            &forces(&model, &x, &zero),
            &forces(&linear, &x, &zero),
        ));
    }
    // Strains of about 2e-3 and 2e-5 (displacements over a 5 mm cell).
    assert!(gaps[0] < 2e-2, "gap {:e} at 1e-5 m", gaps[0]);
    assert!(gaps[1] < 2e-4, "gap {:e} at 1e-7 m", gaps[1]);
    assert!(
        gaps[1] < 0.05 * gaps[0],
        "gaps {gaps:?} do not shrink with the strain"
    );
}

#[test]
fn an_inverted_tet_is_pushed_back_with_a_finite_force() {
    let rest: Vec<Vec3> = vec![
        [0.0, 0.0, 0.0],
        [0.01, 0.0, 0.0],
        [0.0, 0.01, 0.0],
        [0.0, 0.0, 0.01],
    ];
    let tet = PackedTet {
        nodes: [0, 1, 2, 3],
        region: 0,
        material: Material::elastic(1e6, 0.3, 1000.0),
    };
    let model = Corotational::new(&rest, &[tet]).unwrap();
    let zero = vec![[0.0; 3]; 4];
    // The apex pushed through its opposite face (z = 0) to below it, and flat onto it.
    for z in [-0.005, -0.0001, 0.0] {
        let mut x = rest.clone();
        x[3][2] = z;
        let f = forces(&model, &x, &zero);
        assert!(f.iter().flatten().all(|c| c.is_finite()), "z = {z}: {f:?}");
        assert!(f[3][2] > 0.0, "z = {z}: the apex is pushed {:?}", f[3]);
        assert!(model.potential_energy(&x).is_finite());
        let r = polar_rotation(&model.elements()[0].deformation_gradient(&x));
        assert!(
            (r.determinant() - 1.0).abs() < 1e-12,
            "z = {z}: R is no rotation"
        );
    }
}

#[test]
fn corotational_keeps_the_force_model_contract() {
    for seed in 0..3 {
        let (rest, tets) = random_tets(seed + 30, 9);
        let model = Corotational::new(&rest, &tets).unwrap();
        let mut r = Rng(seed + 80);
        let q = rotation(r.vec(1.0), r.signed(180.0));
        let placed = apply(&q, r.vec(0.01), &rest);
        let w: Vec<Vec3> = (0..rest.len()).map(|_| r.vec(1.0)).collect();
        let v: Vec<Vec3> = (0..rest.len()).map(|_| r.vec(0.1)).collect();
        // At a rigid placement R K R^T is the exact derivative (dR multiplies a zero
        // displacement, and K ignores the rigid field dR^T x).
        for lin in [Linearization::Exact, Linearization::Definite] {
            let gap = stiffness_product_gap(&model, &placed, lin, &w);
            assert!(
                gap < 1e-5,
                "seed {seed}: K w {gap:e} from the difference at rest"
            );
        }
        let gap = damping_product_gap(&model, &placed, &v, &w);
        assert!(gap < 1e-8, "seed {seed}: D w {gap:e} from the difference");
    }
    // Deformed by a few percent and turned: the force is minus the gradient of the energy
    // (the terms in dR cancel), the damping product is exact. On the cube's regular tets,
    // where the differences' step is a small fraction of a tet (on a sliver the energy is too
    // curved for a central difference at 1e-7 m).
    let (rest, tets) = cube();
    let model = Corotational::new(&rest, &tets).unwrap();
    let mut r = Rng(90);
    let q = rotation(r.vec(1.0), r.signed(180.0));
    let x: Vec<Vec3> = apply(&q, r.vec(0.01), &rest)
        .iter()
        .map(|p| {
            let d = r.vec(1e-4);
            [0, 1, 2].map(|c| p[c] + d[c])
        })
        .collect();
    let w: Vec<Vec3> = (0..rest.len()).map(|_| r.vec(1.0)).collect();
    let v: Vec<Vec3> = (0..rest.len()).map(|_| r.vec(0.1)).collect();
    assert_force_is_minus_gradient(&model, &x, 1e-5);
    let gap = damping_product_gap(&model, &x, &v, &w);
    assert!(gap < 1e-8, "D w {gap:e} from the difference");
    assert_diagonal_blocks_are_products(&model, &x, 1e-12);
}

//! The tensor-mass model against linear elasticity assembled another way (nalgebra, strain-
//! displacement matrices in Voigt notation), against the force-model contract, the patch
//! test, a rigid rotation's ghost energy (known in closed form), and its per-tet shares.

use nalgebra::{DMatrix, DVector, Matrix4, SMatrix};

use super::force_model::{ForceModel, Linearization, Vec3};
use super::force_model_tests::{
    assert_diagonal_blocks_are_products, assert_force_is_minus_gradient, damping_product_gap,
    forces, stiffness_product_gap, Rng,
};
use super::linear_tet::lame;
use super::TensorMass;
use crate::mesh::generate::{BoxGrid, TetSplit};
use crate::model::{Material, ModelConfig, PackedTet, SpringDamping, SpringModel};

const E: f64 = 1e6;
const NU: f64 = 0.3;

/// Six times the signed volume of `a b c d`.
fn volume6(p: [Vec3; 4]) -> f64 {
    let d = |k: usize| [0, 1, 2].map(|c| p[k][c] - p[0][c]);
    let (a, b, c) = (d(1), d(2), d(3));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// Random tets on a 1 cm cloud, positively oriented, a third of them slivers (the fourth
/// corner a thousandth of the tet's size off the plane of the other three), with
/// stiffness-proportional damping.
pub(super) fn random_tets(seed: u64, count: usize) -> (Vec<Vec3>, Vec<PackedTet>) {
    let mut r = Rng(seed);
    let mut x: Vec<Vec3> = (0..8).map(|_| r.vec(0.01)).collect();
    let material =
        Material::elastic(E, NU, 1000.0).with_damping(SpringDamping::StiffnessProportional(0.01));
    let mut tets = Vec::new();
    while tets.len() < count {
        let pick = |r: &mut Rng, n: usize| (r.next() * n as f64) as u32 % n as u32;
        let mut nodes = [
            pick(&mut r, x.len()),
            pick(&mut r, x.len()),
            pick(&mut r, x.len()),
            0,
        ];
        if tets.len() % 3 == 2 {
            // A sliver: a new node just off the plane of three, near their centroid.
            let p = nodes.map(|n| x[n as usize]);
            let normal = {
                let (a, b) = (
                    [0, 1, 2].map(|c| p[1][c] - p[0][c]),
                    [0, 1, 2].map(|c| p[2][c] - p[0][c]),
                );
                [
                    a[1] * b[2] - a[2] * b[1],
                    a[2] * b[0] - a[0] * b[2],
                    a[0] * b[1] - a[1] * b[0],
                ]
            };
            let scale = 1e-3 / (normal.iter().map(|c| c * c).sum::<f64>().sqrt().max(1e-30)) * 0.01;
            x.push([0, 1, 2].map(|c| (p[0][c] + p[1][c] + p[2][c]) / 3.0 + scale * normal[c]));
            nodes[3] = x.len() as u32 - 1;
        } else {
            nodes[3] = pick(&mut r, x.len());
        }
        let mut sorted = nodes;
        sorted.sort_unstable();
        if sorted.windows(2).any(|w| w[0] == w[1]) {
            continue;
        }
        let v6 = volume6(nodes.map(|n| x[n as usize]));
        if v6.abs() < 1e-15 {
            continue;
        }
        if v6 < 0.0 {
            nodes.swap(0, 1);
        }
        tets.push(PackedTet {
            nodes,
            region: 0,
            material,
        });
    }
    (x, tets)
}

/// The stiffness matrix of `tets` assembled densely as `sum V B^T D B`, with the shape
/// functions from the inverse of each tet's `[1 x y z]` matrix: nothing shared with the model.
fn dense_stiffness(x: &[Vec3], tets: &[PackedTet]) -> DMatrix<f64> {
    let n = x.len();
    let (lambda, mu) = (
        E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU)),
        E / (2.0 * (1.0 + NU)),
    );
    let mut d = SMatrix::<f64, 6, 6>::zeros();
    for i in 0..3 {
        for j in 0..3 {
            d[(i, j)] = lambda;
        }
        d[(i, i)] += 2.0 * mu;
        d[(i + 3, i + 3)] = mu;
    }
    let mut k = DMatrix::zeros(3 * n, 3 * n);
    for t in tets {
        let p = Matrix4::from_fn(|r, c| {
            if c == 0 {
                1.0
            } else {
                x[t.nodes[r] as usize][c - 1]
            }
        });
        let volume = p.determinant() / 6.0;
        let coefficients = p.try_inverse().unwrap();
        let mut b = SMatrix::<f64, 6, 12>::zeros();
        for a in 0..4 {
            let (gx, gy, gz) = (
                coefficients[(1, a)],
                coefficients[(2, a)],
                coefficients[(3, a)],
            );
            let c = 3 * a;
            b[(0, c)] = gx;
            b[(1, c + 1)] = gy;
            b[(2, c + 2)] = gz;
            b[(3, c)] = gy;
            b[(3, c + 1)] = gx;
            b[(4, c + 1)] = gz;
            b[(4, c + 2)] = gy;
            b[(5, c)] = gz;
            b[(5, c + 2)] = gx;
        }
        let ke = b.transpose() * d * b * volume;
        for a in 0..4 {
            for bb in 0..4 {
                for i in 0..3 {
                    for j in 0..3 {
                        k[(3 * t.nodes[a] as usize + i, 3 * t.nodes[bb] as usize + j)] +=
                            ke[(3 * a + i, 3 * bb + j)];
                    }
                }
            }
        }
    }
    k
}

fn flat(v: &[Vec3]) -> DVector<f64> {
    DVector::from_iterator(3 * v.len(), v.iter().flatten().copied())
}

/// A random displacement of `rest` by up to `s` m.
fn displaced(rest: &[Vec3], seed: u64, s: f64) -> Vec<Vec3> {
    let mut r = Rng(seed);
    rest.iter()
        .map(|p| {
            let d = r.vec(s);
            [0, 1, 2].map(|c| p[c] + d[c])
        })
        .collect()
}

#[test]
fn the_energy_is_half_u_k_u_with_k_assembled_independently_slivers_included() {
    for seed in 0..6 {
        let (rest, tets) = random_tets(seed, 12);
        let model = TensorMass::new(&rest, &tets).unwrap();
        let k = dense_stiffness(&rest, &tets);
        let x = displaced(&rest, seed + 50, 1e-4);
        let u = flat(&x) - flat(&rest);
        let expected = 0.5 * u.dot(&(&k * &u));
        let energy = model.potential_energy(&x);
        assert!(
            (energy - expected).abs() <= 1e-10 * expected,
            "seed {seed}: energy {energy:e}, 1/2 u^T K u {expected:e}"
        );
        // The force is -K u, entry by entry.
        let f = flat(&forces(&model, &x, &vec![[0.0; 3]; x.len()]));
        let expected = -(&k * &u);
        let gap = (&f - &expected).amax() / expected.amax();
        assert!(gap < 1e-10, "seed {seed}: force {gap:e} from -K u");
    }
}

#[test]
fn tensor_mass_keeps_the_force_model_contract() {
    for seed in 0..4 {
        let (rest, tets) = random_tets(seed + 10, 9);
        let model = TensorMass::new(&rest, &tets).unwrap();
        let x = displaced(&rest, seed + 60, 1e-4);
        let mut r = Rng(seed + 70);
        let w: Vec<Vec3> = (0..x.len()).map(|_| r.vec(1.0)).collect();
        let v: Vec<Vec3> = (0..x.len()).map(|_| r.vec(0.1)).collect();
        assert_force_is_minus_gradient(&model, &x, 1e-5);
        for lin in [Linearization::Exact, Linearization::Definite] {
            let gap = stiffness_product_gap(&model, &x, lin, &w);
            assert!(gap < 1e-6, "seed {seed}: K w {gap:e} from the difference");
        }
        let gap = damping_product_gap(&model, &x, &v, &w);
        assert!(gap < 1e-8, "seed {seed}: D w {gap:e} from the difference");
        assert_diagonal_blocks_are_products(&model, &x, 1e-12);
    }
}

/// A 3 cm cube of 3x3x3 cells (`split` tets each) with its interior nodes moved at random
/// by up to a tenth of a cell, so that the patch test runs on irregular tets; returns the
/// rest positions, tets and which nodes are on the boundary.
fn jittered_cube(split: TetSplit) -> (Vec<Vec3>, Vec<PackedTet>, Vec<bool>, Vec<[u32; 2]>) {
    let mesh = BoxGrid {
        cells: [3, 3, 3],
        size: [0.03; 3],
        origin: [0.0; 3],
        split,
    }
    .build()
    .unwrap();
    let packed = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(E, NU, 1000.0)))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let boundary: Vec<bool> = packed
        .rest
        .iter()
        .map(|p| {
            p.iter()
                .any(|&c| c.abs() < 1e-12 || (c - 0.03).abs() < 1e-12)
        })
        .collect();
    let mut r = Rng(7);
    let rest: Vec<Vec3> = packed
        .rest
        .iter()
        .zip(&boundary)
        .map(|(p, &b)| {
            let d = if b { [0.0; 3] } else { r.vec(0.001) };
            [0, 1, 2].map(|c| p[c] + d[c])
        })
        .collect();
    let springs = packed.springs().iter().map(|s| s.nodes).collect();
    (rest, packed.tets.clone(), boundary, springs)
}

#[test]
fn a_linear_displacement_field_leaves_interior_nodes_in_equilibrium() {
    for split in [TetSplit::Five, TetSplit::Six] {
        let (rest, tets, boundary, _) = jittered_cube(split);
        let model = TensorMass::new(&rest, &tets).unwrap();
        // u = A X + c with a general (not symmetric) A of strains about 1e-3.
        let mut r = Rng(11);
        let a: [Vec3; 3] = [r.vec(1e-3), r.vec(1e-3), r.vec(1e-3)];
        let c = r.vec(1e-4);
        let x: Vec<Vec3> = rest
            .iter()
            .map(|p| {
                [0, 1, 2].map(|i| p[i] + a[i][0] * p[0] + a[i][1] * p[1] + a[i][2] * p[2] + c[i])
            })
            .collect();
        let f = forces(&model, &x, &vec![[0.0; 3]; x.len()]);
        let norm = |f: &Vec3| f.iter().map(|c| c * c).sum::<f64>().sqrt();
        let (mut inside, mut outside) = (0.0f64, 0.0f64);
        for (f, &b) in f.iter().zip(&boundary) {
            if b {
                outside = outside.max(norm(f));
            } else {
                inside = inside.max(norm(f));
            }
        }
        // The boundary carries the tractions of the uniform stress; inside they cancel.
        // Tractions of about E 1e-3 on faces of a square centimetre: 0.1 N.
        assert!(outside > 1e-2, "{split:?}: boundary forces {outside}");
        assert!(
            inside < 1e-10 * outside,
            "{split:?}: interior force {inside:e} N against {outside:e} N on the boundary"
        );
    }
}

#[test]
fn the_tensors_sit_on_the_springs_edges() {
    let (rest, tets, _, springs) = jittered_cube(TetSplit::Six);
    let model = TensorMass::new(&rest, &tets).unwrap();
    let mut edges: Vec<[u32; 2]> = model.edge_tensors().iter().map(|e| e.nodes).collect();
    edges.sort_unstable();
    assert_eq!(edges, springs);
}

/// The ghost force of linear elasticity: a rigid rotation by 90 degrees about z gives the
/// displacement `(R - I) X`, whose linear strain is `diag(-1, -1, 0)`, so the model stores
/// `V (mu (1 + 1) + lambda/2 (-2)^2) = 2 (lambda + mu) V` and pushes with forces of the
/// order of `E` times the body's area, though no shape has changed.
#[test]
fn a_rigid_rotation_by_ninety_degrees_stores_ghost_energy() {
    let mesh = BoxGrid::cube_cells([2, 2, 2], 0.005).build().unwrap();
    let packed = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(E, NU, 1000.0)))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let model = TensorMass::new(&packed.rest, &packed.tets).unwrap();
    let x: Vec<Vec3> = packed.rest.iter().map(|p| [-p[1], p[0], p[2]]).collect();
    let (lambda, mu) = lame(E, NU);
    let volume = mesh.volume();
    let expected = 2.0 * (lambda + mu) * volume;
    let energy = model.potential_energy(&x);
    assert!(
        (energy - expected).abs() < 1e-9 * expected,
        "ghost energy {energy} J, 2 (lambda + mu) V = {expected} J"
    );
    let f = forces(&model, &x, &vec![[0.0; 3]; x.len()]);
    let largest = f
        .iter()
        .map(|f| f.iter().map(|c| c * c).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    println!(
        "1 cm cube, E = 1 MPa, nu = 0.3, rotated 90 degrees: ghost energy {energy:.4} J, \
         largest nodal ghost force {largest:.1} N (E L^2 = {:.0} N)",
        E * 1e-4
    );
    assert!(
        largest > 0.1 * E * 1e-4 / 8.0,
        "largest ghost force {largest} N"
    );
}

#[test]
fn removing_a_tet_subtracts_exactly_its_share() {
    for seed in 0..4 {
        let (rest, tets) = random_tets(seed + 20, 12);
        let mut model = TensorMass::new(&rest, &tets).unwrap();
        let scale = model
            .node_tensors()
            .iter()
            .flatten()
            .flatten()
            .fold(0.0f64, |m, c| m.max(c.abs()));
        for gone in [3usize, 7, 0] {
            model.remove_tet(gone).unwrap();
        }
        let kept: Vec<PackedTet> = tets
            .iter()
            .enumerate()
            .filter(|(i, _)| ![3usize, 7, 0].contains(i))
            .map(|(_, t)| *t)
            .collect();
        let rebuilt = TensorMass::new(&rest, &kept).unwrap();
        let gap = |a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]| {
            a.iter()
                .flatten()
                .zip(b.iter().flatten())
                .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()))
        };
        for (i, (a, b)) in model
            .node_tensors()
            .iter()
            .zip(rebuilt.node_tensors())
            .enumerate()
        {
            assert!(gap(a, b) <= 1e-12 * scale, "seed {seed} node {i}");
        }
        for (i, (a, b)) in model
            .node_damping_tensors()
            .iter()
            .zip(rebuilt.node_damping_tensors())
            .enumerate()
        {
            assert!(
                gap(a, b) <= 1e-12 * scale * 0.01,
                "seed {seed} node {i} damping"
            );
        }
        assert_eq!(
            model.edge_tensors().len(),
            rebuilt.edge_tensors().len(),
            "seed {seed}"
        );
        for e in rebuilt.edge_tensors() {
            let patched = model
                .edge_tensor(e.nodes[0], e.nodes[1])
                .expect("edge kept");
            assert_eq!(patched.tets, e.tets);
            assert!(
                gap(&patched.stiffness, &e.stiffness) <= 1e-12 * scale,
                "seed {seed}"
            );
            assert!(
                gap(&patched.damping, &e.damping) <= 1e-12 * scale * 0.01,
                "seed {seed}"
            );
        }
        // A removed tet cannot be removed twice.
        assert!(model.remove_tet(3).is_err());
    }
}

#[test]
fn a_tet_a_finite_element_model_cannot_use_is_refused_with_its_index() {
    let (rest, mut tets) = random_tets(1, 5);
    tets[2].material = Material::springs(100.0, 0.001);
    let err = TensorMass::new(&rest, &tets).unwrap_err().to_string();
    assert!(
        err.contains("tet 2") && err.contains("youngs_modulus"),
        "{err}"
    );
    let (rest, mut tets) = random_tets(1, 5);
    tets[4].material.damping = SpringDamping::Absolute(0.1);
    let err = TensorMass::new(&rest, &tets).unwrap_err().to_string();
    assert!(
        err.contains("tet 4") && err.contains("StiffnessProportional"),
        "{err}"
    );
    let (rest, mut tets) = random_tets(1, 5);
    tets[1].nodes.swap(0, 1);
    let err = TensorMass::new(&rest, &tets).unwrap_err().to_string();
    assert!(err.contains("tet 1") && err.contains("volume"), "{err}");
    assert!(TensorMass::new(&rest, &[]).is_err());
}

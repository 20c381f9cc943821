//! The finite-element force models against elasticity: a cantilever under its own weight
//! against Timoshenko beam theory, converging as the mesh is refined, and the lateral
//! contraction of a bar in uniaxial tension against Poisson's ratio. Static solutions, by
//! Newton iterations on the force model (each a conjugate-gradient solve with its stiffness
//! products), so the checks are of the model, not of a transient.

use lancet::mesh::generate::{beam, BoxGrid, TetSplit};
use lancet::model::{FixedSelector, Material, ModelConfig, PackedModel, SpringModel};
use lancet::physics::{Corotational, ForceModel, Linearization, Mat3, TensorMass, Vec3};

const G: f64 = 9.81;

/// Builds a force model of a packed model.
type Build = dyn Fn(&PackedModel) -> Box<dyn ForceModel>;

/// The static equilibrium `F_elastic(x) + external = 0` of `model` from `x`, with the
/// components where `free` is false held where `x` has them: Newton iterations, each solving
/// `-K dx = residual` by Jacobi-preconditioned conjugate gradients on the free components.
fn static_solve(
    model: &dyn ForceModel,
    mut x: Vec<Vec3>,
    free: &[[bool; 3]],
    external: &[Vec3],
    newton: usize,
) -> Vec<Vec3> {
    let n = x.len();
    let zero = vec![[0.0; 3]; n];
    let mask = |v: &mut Vec<Vec3>| {
        for (v, f) in v.iter_mut().zip(free) {
            for c in 0..3 {
                if !f[c] {
                    v[c] = 0.0;
                }
            }
        }
    };
    let dot = |a: &[Vec3], b: &[Vec3]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
            .sum()
    };
    for _ in 0..newton {
        let mut r = external.to_vec();
        model.add_forces(&x, &zero, &mut r);
        mask(&mut r);
        // A w = -K w on the free components; Jacobi from the diagonal of -K.
        let (mut k, mut d): (Vec<Mat3>, Vec<Mat3>) =
            (vec![[[0.0; 3]; 3]; n], vec![[[0.0; 3]; 3]; n]);
        model.add_diagonal_blocks(&x, Linearization::Definite, &mut k, &mut d);
        let apply = |w: &[Vec3]| {
            let mut out = vec![[0.0; 3]; n];
            model.add_stiffness_product(&x, Linearization::Definite, w, &mut out);
            let mut out: Vec<Vec3> = out.iter().map(|o| o.map(|c| -c)).collect();
            mask(&mut out);
            out
        };
        let precondition = |r: &[Vec3]| -> Vec<Vec3> {
            r.iter()
                .enumerate()
                .map(|(i, r)| [0, 1, 2].map(|c| if free[i][c] { -r[c] / k[i][c][c] } else { 0.0 }))
                .collect()
        };
        let norm0 = dot(&r, &r).sqrt();
        if norm0 == 0.0 {
            break;
        }
        let mut dx = vec![[0.0; 3]; n];
        let mut z = precondition(&r);
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        for _ in 0..20_000 {
            let ap = apply(&p);
            let alpha = rz / dot(&p, &ap);
            for i in 0..n {
                for c in 0..3 {
                    dx[i][c] += alpha * p[i][c];
                    r[i][c] -= alpha * ap[i][c];
                }
            }
            if dot(&r, &r).sqrt() < 1e-10 * norm0 {
                break;
            }
            z = precondition(&r);
            let rz_next = dot(&r, &z);
            let beta = rz_next / rz;
            rz = rz_next;
            for i in 0..n {
                for c in 0..3 {
                    p[i][c] = z[i][c] + beta * p[i][c];
                }
            }
        }
        for i in 0..n {
            for c in 0..3 {
                x[i][c] += dx[i][c];
            }
        }
    }
    x
}

/// The clamped cantilever of the issue: 10 x 2 x 2 cm, E = 1 MPa, nu = 0.3, 1000 kg/m^3,
/// clamped at x = 0, under gravity along -z; `across` cells on each side of the section and
/// five times as many along.
fn cantilever(across: usize) -> PackedModel {
    let mesh = beam(0.1, 0.02, 0.02, 5 * across, across).unwrap();
    let mut config = ModelConfig::new(Material::elastic(1e6, 0.3, 1000.0));
    config.gravity = [0.0, 0.0, -G];
    config.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [1.0, 0.0, 0.0],
        tolerance: 1e-9,
    }];
    SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap()
}

/// Timoshenko's tip deflection of a cantilever under a uniform load `q` (N/m): bending
/// `q L^4 / (8 E I)` plus shear `q L^2 / (2 kappa G A)`, with Cowper's shear coefficient of a
/// rectangle `kappa = 10 (1 + nu) / (12 + 11 nu)`.
fn timoshenko_tip(length: f64, width: f64, height: f64, e: f64, nu: f64, density: f64) -> f64 {
    let area = width * height;
    let q = density * G * area;
    let i = width * height.powi(3) / 12.0;
    let shear_modulus = e / (2.0 * (1.0 + nu));
    let kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
    q * length.powi(4) / (8.0 * e * i) + q * length.powi(2) / (2.0 * kappa * shear_modulus * area)
}

/// The static tip sag of `model` under `forces` (mean downward displacement of the free end).
fn static_sag(packed: &PackedModel, forces: &dyn ForceModel, newton: usize) -> f64 {
    let free: Vec<[bool; 3]> = packed.fixed.iter().map(|&f| [!f; 3]).collect();
    let weight: Vec<Vec3> = packed
        .mass
        .iter()
        .map(|m| packed.gravity.map(|g| m * g))
        .collect();
    let x = static_solve(forces, packed.rest.clone(), &free, &weight, newton);
    let tip: Vec<f64> = x
        .iter()
        .zip(&packed.rest)
        .filter(|(_, r)| (r[0] - 0.1).abs() < 1e-9)
        .map(|(p, r)| r[2] - p[2])
        .collect();
    tip.iter().sum::<f64>() / tip.len() as f64
}

#[test]
fn the_cantilever_converges_to_timoshenko_under_its_own_weight() {
    let theory = timoshenko_tip(0.1, 0.02, 0.02, 1e6, 0.3, 1000.0);
    let mut errors = Vec::new();
    println!(
        "cells (along x across^2) | tets | tensor-mass sag | error | corotational sag | error"
    );
    for across in [2, 4, 8] {
        let packed = cantilever(across);
        let linear = TensorMass::new(&packed.rest, &packed.tets).unwrap();
        let sag = static_sag(&packed, &linear, 1);
        let error = (sag - theory) / theory;
        assert!(sag < theory, "{across}: {sag} m sags more than the beam");
        print!(
            "{} x {across} x {across} | {} | {:.4} mm | {:+.2}%",
            5 * across,
            packed.tets.len(),
            sag * 1e3,
            error * 100.0
        );
        // The corotational model on the coarser meshes (its rotations make the finest solve
        // too slow for a test): a sag of 4% of the length, so it agrees closely.
        if across <= 4 {
            let corotational = Corotational::new(&packed.rest, &packed.tets).unwrap();
            let co_sag = static_sag(&packed, &corotational, 3);
            let co_error = (co_sag - theory) / theory;
            print!(" | {:.4} mm | {:+.2}%", co_sag * 1e3, co_error * 100.0);
            assert!(
                (co_sag - sag).abs() < 0.02 * sag,
                "{across}: {co_sag} against {sag}"
            );
        }
        println!();
        errors.push(error.abs());
    }
    println!("Timoshenko: {:.4} mm", theory * 1e3);
    // Constant-strain tets lock in bending: every mesh is stiffer than the beam, and each
    // halving of the cells at least halves the error (first-order convergence of the
    // displacement in the energy norm, or better).
    assert!(
        errors.windows(2).all(|w| w[1] < 0.5 * w[0]),
        "the error does not halve with the cells: {errors:?}"
    );
    // 8% on 40 x 8 x 8 six-tet cells (3.5% on 80 x 16 x 16). Five-tet cells lock less: the 3%
    // the issue asks for is reached on 80 x 12 x 12 of them (`model_error.rs`,
    // `the_cantilever_is_within_3_percent_of_timoshenko_on_a_refined_mesh`).
    assert!(
        errors[2] < 0.10,
        "{:.2}% from Timoshenko on the finest mesh",
        errors[2] * 100.0
    );
}

/// The lateral contraction of a 4 x 1 x 1 cm bar stretched by 0.1% along x, free to contract:
/// the ends slide on their planes (only `u_x` held), and one node of the `x = 0` end is pinned
/// in y and z and another in z, to hold the rigid motions the sliding ends leave.
fn lateral_contraction(forces_of: &Build, nu: f64) -> f64 {
    let mesh = BoxGrid {
        cells: [8, 3, 3],
        size: [0.04, 0.01, 0.01],
        origin: [0.0; 3],
        split: TetSplit::Five,
    }
    .build()
    .unwrap();
    let packed = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(1e6, nu, 1000.0)))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let model = forces_of(&packed);
    let strain = 1e-3;
    let near = |a: f64, b: f64| (a - b).abs() < 1e-9;
    let mut x = packed.rest.clone();
    let mut free = vec![[true; 3]; x.len()];
    for (i, p) in packed.rest.iter().enumerate() {
        if near(p[0], 0.0) || near(p[0], 0.04) {
            free[i][0] = false;
            x[i][0] = p[0] * (1.0 + strain);
        }
        if near(p[0], 0.0) && near(p[1], 0.0) && near(p[2], 0.0) {
            free[i][1] = false;
            free[i][2] = false;
        }
        if near(p[0], 0.0) && near(p[1], 0.01) && near(p[2], 0.0) {
            free[i][2] = false;
        }
    }
    let none = vec![[0.0; 3]; x.len()];
    let x = static_solve(model.as_ref(), x, &free, &none, 4);
    // The width's change over the width, on the faces y = 0 and y = 0.01.
    let mean_y = |face: f64| {
        let ys: Vec<f64> = x
            .iter()
            .zip(&packed.rest)
            .filter(|(_, r)| near(r[1], face))
            .map(|(p, _)| p[1])
            .collect();
        ys.iter().sum::<f64>() / ys.len() as f64
    };
    let lateral = (mean_y(0.01) - mean_y(0.0) - 0.01) / 0.01;
    -lateral / strain
}

#[test]
fn a_bar_in_uniaxial_tension_contracts_by_poissons_ratio() {
    let linear = |p: &PackedModel| -> Box<dyn ForceModel> {
        Box::new(TensorMass::new(&p.rest, &p.tets).unwrap())
    };
    let corotational = |p: &PackedModel| -> Box<dyn ForceModel> {
        Box::new(Corotational::new(&p.rest, &p.tets).unwrap())
    };
    for nu in [0.3, 0.45] {
        let models: [(&str, &Build); 2] =
            [("tensor-mass", &linear), ("corotational", &corotational)];
        for (name, model) in models {
            let measured = lateral_contraction(model, nu);
            println!("{name}: nu = {nu}, lateral contraction over axial strain {measured:.5}");
            assert!(
                (measured - nu).abs() < 0.02 * nu,
                "{name}: contraction {measured} for nu = {nu}"
            );
        }
    }
}

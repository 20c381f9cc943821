//! The implicit step against a dense direct solve and against the closed-form recurrence of a
//! single damped spring.

use super::*;
use crate::model::PackedSpring;
use crate::physics::{SpringForces, Vec3};
use nalgebra::{DMatrix, DVector};

/// SplitMix64 in `0..1`.
fn uniform(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// A random chain-and-cross-link network of `n` nodes in a 1 cm cloud, rest lengths 0.5-1.5
/// times current (so the exact stiffness is indefinite somewhere), damped, two nodes fixed.
fn network(seed: u64, n: usize) -> (Vec<PackedSpring>, Vec<Vec3>, Vec<f64>, Vec<bool>) {
    let mut s = seed;
    let mut r = |scale: f64| scale * (2.0 * uniform(&mut s) - 1.0);
    let x: Vec<Vec3> = (0..n).map(|_| [r(0.01), r(0.01), r(0.01)]).collect();
    let mass: Vec<f64> = (0..n).map(|_| 1e-3 * (1.5 + r(1.0))).collect();
    let mut fixed = vec![false; n];
    fixed[0] = true;
    fixed[n / 2] = true;
    let mut springs = Vec::new();
    for a in 0..n {
        for b in a + 1..(a + 4).min(n) {
            let d = crate::physics::force_model::sub(x[b], x[a]);
            springs.push(PackedSpring {
                nodes: [a as u32, b as u32],
                rest_length: dot(d, d).sqrt() * (1.0 + 0.5 * r(1.0)),
                stiffness: 500.0 + 400.0 * r(1.0),
                damping: 0.05 + 0.04 * r(1.0),
            });
        }
    }
    (springs, x, mass, fixed)
}

#[test]
fn conjugate_gradients_reach_the_dense_direct_solution() {
    for seed in 0..6 {
        let n = 12;
        let (springs, x, mass, fixed) = network(seed, n);
        let forces = SpringForces::new(&springs);
        let nodes = Nodes {
            mass: &mass,
            fixed: &fixed,
            gravity: [0.0, -9.81, 0.0],
            mass_damping: 2.0,
        };
        // Far above the explicit bound (about 1e-4 s here).
        let h = 1e-2;
        let mut system = System::new(
            &forces,
            &nodes,
            &x,
            h,
            Linearization::Definite,
            vec![None; n],
        );
        // The dense matrix of the free degrees of freedom, column by column from the products.
        let free: Vec<usize> = (0..3 * n).filter(|d| !fixed[d / 3]).collect();
        let mut dense = DMatrix::<f64>::zeros(free.len(), free.len());
        let mut out = vec![[0.0; 3]; n];
        for (col, &d) in free.iter().enumerate() {
            let mut e = vec![[0.0; 3]; n];
            e[d / 3][d % 3] = 1.0;
            system.apply(&e, &mut out);
            for (row, &r) in free.iter().enumerate() {
                dense[(row, col)] = out[r / 3][r % 3];
            }
        }
        assert!(
            (&dense - dense.transpose()).amax() <= 1e-9 * dense.amax(),
            "seed {seed}: the system is not symmetric"
        );
        assert!(
            dense.clone().cholesky().is_some(),
            "seed {seed}: the definite system is not positive definite at h = {h}"
        );
        let mut b = vec![[0.0; 3]; n];
        let mut state = seed + 99;
        for (i, v) in b.iter_mut().enumerate() {
            if !fixed[i] {
                *v = [0, 1, 2].map(|_| uniform(&mut state) - 0.5);
            }
        }
        let rhs = DVector::from_iterator(free.len(), free.iter().map(|&d| b[d / 3][d % 3]));
        let direct = dense.clone().lu().solve(&rhs).expect("a regular system");
        let settings = SolverSettings {
            tolerance: 1e-13,
            max_iterations: 500,
            ..Default::default()
        };
        let mut y = vec![[0.0; 3]; n];
        let (iterations, residual) = system.solve(&b, &mut y, &settings);
        assert!(residual <= 1e-13, "seed {seed}: residual {residual:e}");
        assert!(
            iterations < free.len() as u32 + 5,
            "seed {seed}: {iterations} iterations"
        );
        for (row, &d) in free.iter().enumerate() {
            let (got, want) = (y[d / 3][d % 3], direct[row]);
            assert!(
                (got - want).abs() <= 1e-9 * direct.amax(),
                "seed {seed} dof {d}: CG {got:e}, direct {want:e}"
            );
        }
        for i in (0..n).filter(|&i| fixed[i]) {
            assert_eq!(y[i], [0.0; 3], "a fixed node moved");
        }
    }
}

#[test]
fn a_damped_spring_follows_the_backward_euler_recurrence() {
    // Node 1 (mass m) on a spring of stiffness k and damping c to node 0, fixed, along x;
    // displaced by u0 from rest. Backward Euler on m u'' = -k u - c u':
    // v+ (m + h c + h^2 k) = m v - h k u,  u+ = u + h v+.
    let (k, c, m, rest, u0) = (400.0, 0.3, 0.01, 0.05, 0.01);
    let springs = [PackedSpring {
        nodes: [0, 1],
        rest_length: rest,
        stiffness: k,
        damping: c,
    }];
    let forces = SpringForces::new(&springs);
    let (mass, fixed) = (vec![m, m], vec![true, false]);
    let nodes = Nodes {
        mass: &mass,
        fixed: &fixed,
        gravity: [0.0; 3],
        mass_damping: 0.0,
    };
    // Ten times the explicit bound 2 / sqrt(k / m) = 0.01 s.
    let h = 0.1;
    let mut state = NodeState {
        x: vec![[0.0; 3], [rest + u0, 0.0, 0.0]],
        v: vec![[0.0; 3]; 2],
    };
    let mut integrator = BackwardEuler::new(SolverSettings {
        tolerance: 1e-14,
        ..Default::default()
    });
    let (mut u, mut v) = (u0, 0.0);
    for step in 0..50 {
        integrator.step(&forces, &nodes, h, &mut state);
        v = (m * v - h * k * u) / (m + h * c + h * h * k);
        u += h * v;
        let got = state.x[1][0] - rest;
        assert!(
            (got - u).abs() <= 1e-12 * u0,
            "step {step}: u {got:e}, recurrence {u:e}"
        );
        assert!((state.v[1][0] - v).abs() <= 1e-12 * u0 / h);
        assert_eq!(state.x[0], [0.0; 3]);
    }
    // Far above the explicit bound it decays instead of blowing up.
    assert!(u.abs() < 0.5 * u0);
    assert!(integrator.stats().capped == 0);
}

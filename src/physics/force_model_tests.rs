//! The spring force model against its own definitions: the force is minus the gradient of the
//! energy, the products are the derivatives of the force (central differences), the diagonal
//! blocks are the products' diagonal, the definite linearisation is semi-definite where the
//! exact one is not, and the float64 law is the float32 one's reference. The checks of the
//! contract are functions of any [`ForceModel`], which the finite-element models' tests reuse.

use super::force_model::{dot, ForceModel, Linearization, Mat3, Vec3};
use super::{spring_force, Integrator, SpringForces, StepParams};
use crate::model::PackedSpring;

/// A small deterministic generator (SplitMix64), so the cases are the same on every run.
pub(super) struct Rng(pub(super) u64);

impl Rng {
    pub(super) fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in `-s..s`.
    pub(super) fn signed(&mut self, s: f64) -> f64 {
        s * (2.0 * self.next() - 1.0)
    }
    pub(super) fn vec(&mut self, s: f64) -> Vec3 {
        [self.signed(s), self.signed(s), self.signed(s)]
    }
}

/// `n` nodes in a 1 cm cloud joined by random springs whose rest lengths are 0.5-1.5 times
/// their current lengths (so some are stretched and some compressed), damped or not.
fn cloud(seed: u64, n: usize, damped: bool) -> (Vec<PackedSpring>, Vec<Vec3>, Vec<Vec3>) {
    let mut r = Rng(seed);
    let x: Vec<Vec3> = (0..n).map(|_| r.vec(0.01)).collect();
    let v: Vec<Vec3> = (0..n).map(|_| r.vec(0.3)).collect();
    let mut springs = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            if r.next() < 0.5 {
                let d = super::force_model::sub(x[b], x[a]);
                springs.push(PackedSpring {
                    nodes: [a as u32, b as u32],
                    rest_length: dot(d, d).sqrt() * (0.5 + r.next()),
                    stiffness: 10.0 + 990.0 * r.next(),
                    damping: if damped { 0.01 + r.next() } else { 0.0 },
                });
            }
        }
    }
    (springs, x, v)
}

pub(super) fn forces(m: &dyn ForceModel, x: &[Vec3], v: &[Vec3]) -> Vec<Vec3> {
    let mut f = vec![[0.0; 3]; x.len()];
    m.add_forces(x, v, &mut f);
    f
}

/// `x + s w`.
pub(super) fn moved(x: &[Vec3], s: f64, w: &[Vec3]) -> Vec<Vec3> {
    x.iter()
        .zip(w)
        .map(|(x, w)| [0, 1, 2].map(|c| x[c] + s * w[c]))
        .collect()
}

/// The largest component of `a - b` over the largest of `b`.
pub(super) fn relative_gap(a: &[Vec3], b: &[Vec3]) -> f64 {
    let scale = b.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
    let gap = a
        .iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
    gap / scale
}

/// Assert that the elastic force of `model` at `x` (zero velocity; positions of centimetres:
/// the differences step 1e-7 m) is minus the central difference of its energy, to `tolerance` of the largest force component.
pub(super) fn assert_force_is_minus_gradient(model: &dyn ForceModel, x: &[Vec3], tolerance: f64) {
    let f = forces(model, x, &vec![[0.0; 3]; x.len()]);
    let scale = f.iter().flatten().fold(1e-9f64, |m, c| m.max(c.abs()));
    let eps = 1e-7;
    for i in 0..x.len() {
        for c in 0..3 {
            let (mut plus, mut minus) = (x.to_vec(), x.to_vec());
            plus[i][c] += eps;
            minus[i][c] -= eps;
            let gradient =
                (model.potential_energy(&plus) - model.potential_energy(&minus)) / (2.0 * eps);
            assert!(
                (f[i][c] + gradient).abs() < tolerance * scale,
                "{}: node {i} axis {c}: force {} but -dE/dx {}",
                model.name(),
                f[i][c],
                -gradient
            );
        }
    }
}

/// How far `K w` (as `lin` linearises it) is from the central difference of the force along
/// `w` at `x` (zero velocity, so the damping force and its position derivative vanish),
/// relative to the difference's largest component.
pub(super) fn stiffness_product_gap(
    model: &dyn ForceModel,
    x: &[Vec3],
    lin: Linearization,
    w: &[Vec3],
) -> f64 {
    let rest = vec![[0.0; 3]; x.len()];
    let eps = 1e-8;
    let (fp, fm) = (
        forces(model, &moved(x, eps, w), &rest),
        forces(model, &moved(x, -eps, w), &rest),
    );
    let difference: Vec<Vec3> = fp
        .iter()
        .zip(&fm)
        .map(|(p, m)| [0, 1, 2].map(|c| (p[c] - m[c]) / (2.0 * eps)))
        .collect();
    let mut product = vec![[0.0; 3]; x.len()];
    model.add_stiffness_product(x, lin, w, &mut product);
    relative_gap(&product, &difference)
}

/// How far `D w` is from the central difference of the force along `w` in velocity at
/// `(x, v)`, relative to the difference's largest component.
pub(super) fn damping_product_gap(
    model: &dyn ForceModel,
    x: &[Vec3],
    v: &[Vec3],
    w: &[Vec3],
) -> f64 {
    let eps = 1e-6;
    let (fp, fm) = (
        forces(model, x, &moved(v, eps, w)),
        forces(model, x, &moved(v, -eps, w)),
    );
    let difference: Vec<Vec3> = fp
        .iter()
        .zip(&fm)
        .map(|(p, m)| [0, 1, 2].map(|c| (p[c] - m[c]) / (2.0 * eps)))
        .collect();
    let mut product = vec![[0.0; 3]; x.len()];
    model.add_damping_product(x, w, &mut product);
    relative_gap(&product, &difference)
}

/// Assert that the diagonal blocks of `model` at `x` are its products on unit vectors, for
/// both linearisations, to `tolerance` of the largest stiffness and damping entry.
pub(super) fn assert_diagonal_blocks_are_products(
    model: &dyn ForceModel,
    x: &[Vec3],
    tolerance: f64,
) {
    for lin in [Linearization::Exact, Linearization::Definite] {
        let mut stiffness: Vec<Mat3> = vec![[[0.0; 3]; 3]; x.len()];
        let mut damping: Vec<Mat3> = vec![[[0.0; 3]; 3]; x.len()];
        model.add_diagonal_blocks(x, lin, &mut stiffness, &mut damping);
        let largest = |m: &[Mat3]| {
            m.iter()
                .flatten()
                .flatten()
                .fold(1e-300f64, |a, c| a.max(c.abs()))
        };
        let (ks, ds) = (largest(&stiffness), largest(&damping));
        for i in 0..x.len() {
            for c in 0..3 {
                let mut e = vec![[0.0; 3]; x.len()];
                e[i][c] = 1.0;
                let (mut k, mut d) = (vec![[0.0; 3]; x.len()], vec![[0.0; 3]; x.len()]);
                model.add_stiffness_product(x, lin, &e, &mut k);
                model.add_damping_product(x, &e, &mut d);
                for r in 0..3 {
                    assert!(
                        (stiffness[i][r][c] - k[i][r]).abs() <= tolerance * ks,
                        "{}: node {i} K[{r}][{c}] {} but product {}",
                        model.name(),
                        stiffness[i][r][c],
                        k[i][r]
                    );
                    assert!((damping[i][r][c] - d[i][r]).abs() <= tolerance * ds.max(1.0));
                }
            }
        }
    }
}

#[test]
fn the_elastic_force_is_minus_the_gradient_of_the_energy() {
    for seed in 0..8 {
        let (springs, x, _) = cloud(seed, 9, false);
        assert_force_is_minus_gradient(&SpringForces::new(&springs), &x, 1e-5);
    }
}

#[test]
fn the_stiffness_product_is_the_derivative_of_the_force_along_the_direction() {
    for seed in 0..8 {
        let (springs, x, _) = cloud(seed, 10, true);
        let model = SpringForces::new(&springs);
        let w: Vec<Vec3> = {
            let mut r = Rng(seed + 100);
            (0..x.len()).map(|_| r.vec(1.0)).collect()
        };
        let gap = stiffness_product_gap(&model, &x, Linearization::Exact, &w);
        assert!(
            gap < 1e-6,
            "seed {seed}: K w is {gap:e} from the difference"
        );
        // The definite linearisation differs where a spring is compressed, and the cloud has
        // compressed springs.
        assert!(
            stiffness_product_gap(&model, &x, Linearization::Definite, &w) > 1e-3,
            "seed {seed}"
        );
    }
}

#[test]
fn the_damping_product_is_the_derivative_of_the_force_in_velocity() {
    for seed in 0..8 {
        let (springs, x, v) = cloud(seed, 10, true);
        let model = SpringForces::new(&springs);
        let w: Vec<Vec3> = {
            let mut r = Rng(seed + 200);
            (0..x.len()).map(|_| r.vec(1.0)).collect()
        };
        let gap = damping_product_gap(&model, &x, &v, &w);
        assert!(
            gap < 1e-8,
            "seed {seed}: D w is {gap:e} from the difference"
        );
    }
}

#[test]
fn the_diagonal_blocks_are_the_products_on_unit_vectors() {
    let (springs, x, _) = cloud(3, 7, true);
    assert_diagonal_blocks_are_products(&SpringForces::new(&springs), &x, 1e-9);
}

#[test]
fn the_definite_stiffness_is_negative_semidefinite_where_the_exact_one_is_not() {
    let mut exact_indefinite = 0;
    for seed in 0..20 {
        let (springs, x, _) = cloud(seed, 8, false);
        let model = SpringForces::new(&springs);
        let mut r = Rng(seed + 300);
        for _ in 0..20 {
            let w: Vec<Vec3> = (0..x.len()).map(|_| r.vec(1.0)).collect();
            let quadratic = |lin| {
                let mut kw = vec![[0.0; 3]; x.len()];
                model.add_stiffness_product(&x, lin, &w, &mut kw);
                w.iter().zip(&kw).map(|(a, b)| dot(*a, *b)).sum::<f64>()
            };
            assert!(quadratic(Linearization::Definite) <= 1e-9, "seed {seed}");
            if quadratic(Linearization::Exact) > 0.0 {
                exact_indefinite += 1;
            }
        }
    }
    // Springs compressed to half their rest length give the exact matrix directions of
    // positive curvature: the clamp is doing something.
    assert!(exact_indefinite > 0);
}

#[test]
fn the_float64_law_is_the_reference_of_the_float32_one() {
    let (springs, x, v) = cloud(5, 10, true);
    let model = SpringForces::new(&springs);
    let f64_forces = forces(&model, &x, &v);
    let p = StepParams {
        h: 1e-4,
        gravity: [0.0; 3],
        alpha: 0.0,
        integrator: Integrator::SymplecticEuler,
        damped: true,
    };
    let mut f32_forces = vec![[0.0f64; 3]; x.len()];
    for s in &springs {
        let (a, b) = (s.nodes[0] as usize, s.nodes[1] as usize);
        let to32 = |v: Vec3| v.map(|c| c as f32);
        let d = to32(super::force_model::sub(x[b], x[a]));
        let dv = to32(super::force_model::sub(v[b], v[a]));
        let f = spring_force(
            &p,
            s.stiffness as f32,
            s.rest_length as f32,
            s.damping as f32,
            d,
            dv,
        );
        for c in 0..3 {
            f32_forces[a][c] += f[c] as f64;
            f32_forces[b][c] -= f[c] as f64;
        }
    }
    let gap = relative_gap(&f32_forces, &f64_forces);
    assert!(gap < 1e-5, "float32 law {gap:e} from float64");
}

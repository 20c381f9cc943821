//! The rotation of a tet's deformation gradient for the fast engine's corotational pass: the
//! polar decomposition `F = R S` by Higham's scaled Newton iteration, `X <- (g X + X^{-T} / g)
//! / 2` from `X = F`, in float64 on plain arrays. Each iteration is a 3x3 cofactor matrix and a
//! determinant, a few dozen flops, where the reference's singular value decomposition
//! (`physics::corotational::polar_rotation`) iterates on a bidiagonal form: at a strain of a
//! few percent the iteration meets float64 rounding in four or five steps, many times cheaper.
//!
//! The iteration converges to the polar factor of any non-singular `F`, but for an inverted
//! tet (`det F < 0`) that factor is a reflection, and near a degenerate tet the scaling has
//! little to work with. Those tets (and any that do not converge in [`MAX_ITERATIONS`]) are
//! left to the reference's decomposition, which is robust there: [`rotation`] returns `None`.
//! Where both apply, they agree to float64 rounding (the polar factor of a non-singular matrix
//! is unique), so the fast engine's forces do not depend on which one ran.

/// A 3x3 matrix, row major, float64.
pub(super) type M3d = [[f64; 3]; 3];

/// Iterations before giving up (the scaled iteration needs about ten at a condition number
/// of 1e6, by Higham's analysis; four or five at the strains of tissue).
const MAX_ITERATIONS: usize = 24;

/// `det F` relative to the cube of `F`'s mean singular value below which the tet is left to
/// the singular value decomposition: inverted, flat or nearly so.
const DEGENERATE: f64 = 1e-6;

/// Cofactor matrix of `x`: `X^{-T} det X`.
#[inline(always)]
fn cofactor(x: &M3d) -> M3d {
    [
        [
            x[1][1] * x[2][2] - x[1][2] * x[2][1],
            x[1][2] * x[2][0] - x[1][0] * x[2][2],
            x[1][0] * x[2][1] - x[1][1] * x[2][0],
        ],
        [
            x[0][2] * x[2][1] - x[0][1] * x[2][2],
            x[0][0] * x[2][2] - x[0][2] * x[2][0],
            x[0][1] * x[2][0] - x[0][0] * x[2][1],
        ],
        [
            x[0][1] * x[1][2] - x[0][2] * x[1][1],
            x[0][2] * x[1][0] - x[0][0] * x[1][2],
            x[0][0] * x[1][1] - x[0][1] * x[1][0],
        ],
    ]
}

#[inline(always)]
fn frobenius2(x: &M3d) -> f64 {
    x.iter().flatten().map(|v| v * v).sum()
}

/// The rotation `R` of `F = R S` (`S` symmetric positive definite), or `None` where `F` is
/// inverted, nearly degenerate or not finite: then the caller's singular value decomposition
/// decides (see the module documentation).
#[inline]
pub(super) fn rotation(f: &M3d) -> Option<M3d> {
    let mut x = *f;
    let scale2 = frobenius2(&x) / 3.0;
    let c = cofactor(&x);
    let det: f64 = (0..3).map(|k| x[0][k] * c[0][k]).sum();
    // NaN goes to the decomposition too.
    if det.is_nan() || det <= DEGENERATE * scale2 * scale2.sqrt() {
        return None;
    }
    let (mut c, mut det) = (c, det);
    let mut scaling = true;
    for _ in 0..MAX_ITERATIONS {
        // X^{-T} = cof(X) / det X.
        let inv = 1.0 / det;
        let n2 = frobenius2(&x);
        // Frobenius scaling, `g = (|X^{-1}| / |X|)^(1/2)`, until close: near the rotation it
        // is 1 to rounding and only slows the quadratic convergence down.
        let g = if scaling {
            (frobenius2(&c).sqrt() * inv.abs() / n2.sqrt()).sqrt()
        } else {
            1.0
        };
        let mut next = [[0.0; 3]; 3];
        let mut change = 0.0;
        for r in 0..3 {
            for k in 0..3 {
                next[r][k] = 0.5 * (g * x[r][k] + c[r][k] * inv / g);
                let d = next[r][k] - x[r][k];
                change += d * d;
            }
        }
        x = next;
        // |X| of a rotation is sqrt(3): the change is relative to that.
        if change < 1e-26 {
            return Some(x);
        }
        scaling = change > 1e-4;
        c = cofactor(&x);
        det = (0..3).map(|k| x[0][k] * c[0][k]).sum();
        if det.is_nan() || det <= 0.0 {
            return None;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::corotational::polar_rotation;
    use nalgebra::{Matrix3, Rotation3, Unit, Vector3};

    fn to_m3d(m: &Matrix3<f64>) -> M3d {
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| m[(r, c)]))
    }

    /// A rotation about a skew axis times a symmetric stretch with principal stretches `s`
    /// along other skew axes.
    fn deformation(angle: f64, s: [f64; 3], seed: f64) -> Matrix3<f64> {
        let axis = Unit::new_normalize(Vector3::new(1.0, seed.sin(), 0.3 + seed.cos()));
        let r = Rotation3::from_axis_angle(&axis, angle);
        let q = Rotation3::from_euler_angles(0.3 * seed, 1.1, -0.7 + seed);
        let stretch =
            q.matrix() * Matrix3::from_diagonal(&Vector3::from(s)) * q.matrix().transpose();
        r.matrix() * stretch
    }

    #[test]
    fn the_newton_rotation_equals_the_decomposition_s_where_it_applies() {
        let mut checked = 0;
        for (k, angle) in [0.0, 0.3, 1.7, 3.1].into_iter().enumerate() {
            for s in [
                [1.0, 1.0, 1.0],
                [1.001, 0.999, 1.0005],
                [1.3, 0.7, 0.9],
                [5.0, 0.2, 1.0],
                [50.0, 0.05, 1.0],
            ] {
                let f = deformation(angle, s, k as f64);
                let fast = rotation(&to_m3d(&f)).expect("a non-singular F");
                let reference = to_m3d(&polar_rotation(&f));
                let worst = (0..9)
                    .map(|n| (fast[n / 3][n % 3] - reference[n / 3][n % 3]).abs())
                    .fold(0.0, f64::max);
                assert!(worst < 1e-12, "{angle} {s:?}: off by {worst:.2e}");
                checked += 1;
            }
        }
        assert_eq!(checked, 20);
    }

    #[test]
    fn inverted_flat_and_non_finite_tets_are_left_to_the_decomposition() {
        // Inverted: the Newton limit would be a reflection, not the decomposition's rotation.
        let inverted = deformation(0.4, [1.0, 1.0, -0.5], 1.0);
        assert!(rotation(&to_m3d(&inverted)).is_none());
        // Flat: a zero stretch.
        let flat = deformation(0.4, [1.0, 1.0, 0.0], 2.0);
        assert!(rotation(&to_m3d(&flat)).is_none());
        let mut nan = to_m3d(&deformation(0.4, [1.0, 1.0, 1.0], 3.0));
        nan[1][2] = f64::NAN;
        assert!(rotation(&nan).is_none());
    }
}

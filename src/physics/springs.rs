//! The spring force law: the force model of the mass-spring model.
//!
//! [`spring_force`] is the float32 law as the GPU computes it (twin of the WGSL `slot_force`
//! in `shaders/common.wgsl`; every layout's CPU twin calls it). [`SpringForces`] is the same
//! law in float64 as a [`ForceModel`], with its Jacobian-vector products: the reference engine
//! steps with it and an implicit integrator solves with it.

use super::force_model::{axpy, dot, sub, ForceModel, Linearization, Mat3, Vec3};
use super::StepParams;
use crate::model::PackedSpring;

/// Force of a spring (stiffness `k`, N/m; rest length `rest`, m; damping `c` along the spring,
/// N s/m) on the node it is seen from, given the current spring vector `d` (other minus self)
/// and the relative velocity `dv` (other minus self), as the WGSL `slot_force` computes it.
/// A spring of zero length pulls nowhere.
pub fn spring_force(
    p: &StepParams,
    k: f32,
    rest: f32,
    c: f32,
    d: [f32; 3],
    dv: [f32; 3],
) -> [f32; 3] {
    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if l <= 0.0 {
        return [0.0; 3];
    }
    let dir = [d[0] / l, d[1] / l, d[2] / l];
    let mut mag = k * (l - rest);
    if p.damped {
        mag += c * (dv[0] * dir[0] + dv[1] * dir[1] + dv[2] * dir[2]);
    }
    [mag * dir[0], mag * dir[1], mag * dir[2]]
}

/// The springs of a model as a [`ForceModel`] in float64: on each spring `(a, b)` with
/// `d = x_b - x_a`, `l = |d|`, `u = d / l`, the force on `a` is
/// `k (l - L) u + c ((v_b - v_a) . u) u` and the force on `b` its opposite. A spring of zero
/// length has no direction and contributes nothing (as in the float32 law).
#[derive(Debug, Clone, Copy)]
pub struct SpringForces<'a> {
    springs: &'a [PackedSpring],
}

impl<'a> SpringForces<'a> {
    /// The force model of these springs (node indices into the state vectors).
    pub fn new(springs: &'a [PackedSpring]) -> Self {
        SpringForces { springs }
    }

    /// Direction, length and the two ends of a spring at `x`; `None` at zero length.
    fn geometry(s: &PackedSpring, x: &[Vec3]) -> Option<(Vec3, f64, usize, usize)> {
        let (a, b) = (s.nodes[0] as usize, s.nodes[1] as usize);
        let d = sub(x[b], x[a]);
        let l = dot(d, d).sqrt();
        (l > 0.0).then(|| ([d[0] / l, d[1] / l, d[2] / l], l, a, b))
    }
}

/// The 3x3 block `k (u u^T + t (I - u u^T))` of a spring's stiffness, with `t = 1 - L/l` (the
/// transverse term, the tension per unit length over `k`), clamped at zero when `lin` asks for
/// a definite matrix. The force on `a` changes by this block times `w_b - w_a`.
pub fn spring_stiffness_block(k: f64, rest: f64, u: Vec3, l: f64, lin: Linearization) -> Mat3 {
    let mut t = 1.0 - rest / l;
    if lin == Linearization::Definite {
        t = t.max(0.0);
    }
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            let identity = if r == c { 1.0 } else { 0.0 };
            m[r][c] = k * (u[r] * u[c] + t * (identity - u[r] * u[c]));
        }
    }
    m
}

/// `c u u^T`: the block of a spring's damping derivative.
fn damping_block(c: f64, u: Vec3) -> Mat3 {
    [0, 1, 2].map(|r| [0, 1, 2].map(|col| c * u[r] * u[col]))
}

/// Add `m (w_b - w_a)` to `out[a]` and its opposite to `out[b]`.
fn add_pair_product(m: &Mat3, a: usize, b: usize, w: &[Vec3], out: &mut [Vec3]) {
    let r = super::force_model::mat_vec(m, sub(w[b], w[a]));
    axpy(&mut out[a], 1.0, r);
    axpy(&mut out[b], -1.0, r);
}

impl ForceModel for SpringForces<'_> {
    fn name(&self) -> &'static str {
        "springs"
    }

    fn add_forces(&self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        for s in self.springs {
            let Some((u, l, a, b)) = Self::geometry(s, x) else {
                continue;
            };
            let magnitude = s.stiffness * (l - s.rest_length) + s.damping * dot(sub(v[b], v[a]), u);
            axpy(&mut f[a], magnitude, u);
            axpy(&mut f[b], -magnitude, u);
        }
    }

    fn potential_energy(&self, x: &[Vec3]) -> f64 {
        self.springs
            .iter()
            .map(|s| {
                let d = sub(x[s.nodes[1] as usize], x[s.nodes[0] as usize]);
                0.5 * s.stiffness * (dot(d, d).sqrt() - s.rest_length).powi(2)
            })
            .sum()
    }

    fn add_stiffness_product(&self, x: &[Vec3], lin: Linearization, w: &[Vec3], out: &mut [Vec3]) {
        for s in self.springs {
            if let Some((u, l, a, b)) = Self::geometry(s, x) {
                let m = spring_stiffness_block(s.stiffness, s.rest_length, u, l, lin);
                add_pair_product(&m, a, b, w, out);
            }
        }
    }

    fn add_damping_product(&self, x: &[Vec3], w: &[Vec3], out: &mut [Vec3]) {
        for s in self.springs.iter().filter(|s| s.damping != 0.0) {
            if let Some((u, _, a, b)) = Self::geometry(s, x) {
                add_pair_product(&damping_block(s.damping, u), a, b, w, out);
            }
        }
    }

    fn add_diagonal_blocks(
        &self,
        x: &[Vec3],
        lin: Linearization,
        stiffness: &mut [Mat3],
        damping: &mut [Mat3],
    ) {
        // The force on `a` changes by `m (w_b - w_a)`: `-m` on the diagonal of both ends.
        let sub_block = |target: &mut [Mat3], node: usize, m: &Mat3| {
            for r in 0..3 {
                for c in 0..3 {
                    target[node][r][c] -= m[r][c];
                }
            }
        };
        for s in self.springs {
            if let Some((u, l, a, b)) = Self::geometry(s, x) {
                let m = spring_stiffness_block(s.stiffness, s.rest_length, u, l, lin);
                sub_block(stiffness, a, &m);
                sub_block(stiffness, b, &m);
                if s.damping != 0.0 {
                    let m = damping_block(s.damping, u);
                    sub_block(damping, a, &m);
                    sub_block(damping, b, &m);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::Integrator;

    fn params(damped: bool) -> StepParams {
        StepParams {
            h: 1e-4,
            gravity: [0.0; 3],
            alpha: 0.0,
            integrator: Integrator::Verlet,
            damped,
        }
    }

    #[test]
    fn a_stretched_spring_pulls_its_node_toward_the_other_by_hookes_law() {
        // Rest 1 m, stretched to 2 m along x with k = 3 N/m: 3 N toward the other end.
        let f = spring_force(
            &params(false),
            3.0,
            1.0,
            0.5,
            [2.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
        );
        assert_eq!(f, [3.0, 0.0, 0.0]);
        // Compressed to 0.5 m along -y: pushes away from the other end, along +y.
        let f = spring_force(&params(false), 4.0, 1.0, 0.0, [0.0, -0.5, 0.0], [0.0; 3]);
        assert_eq!(f, [0.0, 2.0, 0.0]);
    }

    #[test]
    fn damping_acts_along_the_spring_only_when_the_step_is_damped() {
        // At rest length, the other end receding at 2 m/s along the spring and 5 m/s across.
        let (d, dv) = ([0.0, 0.0, 1.0], [5.0, 0.0, 2.0]);
        assert_eq!(
            spring_force(&params(true), 3.0, 1.0, 0.25, d, dv),
            [0.0, 0.0, 0.5]
        );
        assert_eq!(
            spring_force(&params(false), 3.0, 1.0, 0.25, d, dv),
            [0.0; 3]
        );
        assert_eq!(
            spring_force(&params(true), 3.0, 1.0, 0.25, [0.0; 3], dv),
            [0.0; 3]
        );
    }
}

//! Twin of `shaders/health.wgsl` (pass `engine::gpu::health`): the divergence check, per
//! workgroup of 64 nodes the kinetic energy and the change of gravitational energy, and the
//! first node whose state is not finite.

use crate::physics::{velocity, StepParams};

/// What the check reads back: per-workgroup sums and the first non-finite node.
#[derive(Debug, Clone, PartialEq)]
pub struct HealthPartials {
    /// Per workgroup of 64 nodes: kinetic energy and change of gravitational energy, J.
    pub partials: Vec<[f32; 2]>,
    /// Lowest layout index whose displacement or second state is not finite.
    pub first_bad: Option<u32>,
}

impl HealthPartials {
    /// Total kinetic energy and change of gravitational energy, summed in float64.
    pub fn totals(&self) -> (f64, f64) {
        self.partials
            .iter()
            .fold((0.0, 0.0), |(k, g), p| (k + p[0] as f64, g + p[1] as f64))
    }
}

/// The check on the CPU exactly as `shaders/health.wgsl` computes it (the same pairwise tree in
/// each workgroup of 64 nodes).
pub fn health_cpu(
    p: &StepParams,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    second: &[[f32; 4]],
) -> HealthPartials {
    let n = cur.len();
    let finite = |v: &[f32; 4]| v[..3].iter().all(|x| x.is_finite());
    let mut first_bad = None;
    let mut partials = Vec::with_capacity(n.div_ceil(64));
    for start in (0..n.max(1)).step_by(64) {
        let mut k = [0.0f32; 64];
        let mut g = [0.0f32; 64];
        for l in 0..64 {
            let i = start + l;
            if i >= n {
                continue;
            }
            if !finite(&cur[i]) || !finite(&second[i]) {
                first_bad = first_bad.or(Some(i as u32));
            } else if inv_mass[i] > 0.0 {
                let m = 1.0 / inv_mass[i];
                let v = velocity(p, cur[i], second[i]);
                k[l] = 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
                let gu =
                    p.gravity[0] * cur[i][0] + p.gravity[1] * cur[i][1] + p.gravity[2] * cur[i][2];
                g[l] = -m * gu;
            }
        }
        let mut stride = 32;
        while stride > 0 {
            for l in 0..stride {
                k[l] += k[l + stride];
                g[l] += g[l + stride];
            }
            stride /= 2;
        }
        partials.push([k[0], g[0]]);
    }
    HealthPartials {
        partials,
        first_bad,
    }
}

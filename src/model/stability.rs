//! The stable time step of explicit integration, per node.
//!
//! Verlet (position form) and symplectic Euler are the same recurrence for a damped oscillator
//! `x'' = -w^2 x - c x'` with the velocity taken as a backward difference:
//! `x+ - 2x + x- = -w^2 h^2 x - c h (x - x-)`. Its characteristic polynomial
//! `z^2 - (2 - w^2 h^2 - c h) z + (1 - c h)` has both roots in the unit disc (Jury's test) iff
//! `w^2 h^2 + 2 c h < 4`, that is
//!
//! ```text
//! h < h(w, c) = (sqrt(c^2 + 4 w^2) - c) / w^2 = (2 / w) (sqrt(1 + xi^2) - xi),  xi = c / (2 w)
//! ```
//!
//! the central-difference bound with its damping correction (Belytschko, Liu, Moran,
//! "Nonlinear Finite Elements for Continua and Structures", 2000, section 6.2).
//!
//! For the whole model, the largest eigenvalue of `M^-1 K` is bounded by block Gershgorin
//! discs: at rest each spring contributes `k u u^T` (norm `k`) to the diagonal block of both
//! its nodes and `-k u u^T` off the diagonal, so `lambda_max <= max_i 2 sum_j k_ij / m_i`.
//! Damping `M^-1 C` is bounded the same way (`2 sum_j c_ij / m_i + alpha`). Each free node
//! gets `h_i = h(w_i, c_i)`; the bound is the smallest. Fixed nodes do not move and are left
//! out (their springs still count at their neighbours). It holds at rest and for any state
//! where no spring is compressed below half its rest length (the geometric stiffness
//! `k (1 - L/l)` stays below `k` there).

use super::PackedModel;

/// The stable time step of a model and where it comes from.
#[derive(Debug, Clone, PartialEq)]
pub struct StabilityBound {
    /// The largest stable step, s (`f64::INFINITY` if nothing can oscillate).
    pub dt: f64,
    /// The node with the smallest per-node bound.
    pub node: usize,
    /// Gershgorin bound on the highest angular frequency, rad/s.
    pub omega_max: f64,
    /// The bound of each node, s (`INFINITY` for fixed nodes).
    pub per_node: Vec<f64>,
}

/// `h(w, c)` from the module documentation.
pub fn damped_bound(omega: f64, c: f64) -> f64 {
    if omega > 0.0 {
        ((c * c + 4.0 * omega * omega).sqrt() - c) / (omega * omega)
    } else if c > 0.0 {
        2.0 / c
    } else {
        f64::INFINITY
    }
}

/// The per-node Gershgorin bound on the stable time step of `model`.
pub fn stable_time_step(model: &PackedModel) -> StabilityBound {
    let n = model.node_count();
    let mut k_sum = vec![0.0f64; n];
    let mut c_sum = vec![0.0f64; n];
    for s in &model.springs {
        for &i in &s.nodes {
            k_sum[i as usize] += s.stiffness;
            c_sum[i as usize] += s.damping;
        }
    }
    let mut per_node = vec![f64::INFINITY; n];
    let (mut dt, mut node, mut omega_max) = (f64::INFINITY, 0, 0.0f64);
    for i in 0..n {
        if model.fixed[i] {
            continue;
        }
        let m = model.mass[i];
        let omega = (2.0 * k_sum[i] / m).sqrt();
        let c = 2.0 * c_sum[i] / m + model.mass_damping;
        let h = damped_bound(omega, c);
        per_node[i] = h;
        omega_max = omega_max.max(omega);
        if h < dt {
            dt = h;
            node = i;
        }
    }
    StabilityBound {
        dt,
        node,
        omega_max,
        per_node,
    }
}

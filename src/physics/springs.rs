//! The spring force law: the force model of the mass-spring model. Twin of the WGSL
//! `slot_force` in `shaders/common.wgsl`; every layout's CPU twin calls it.

use super::StepParams;

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

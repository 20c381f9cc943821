//! Twins of the corotational passes (`engine::gpu::corotational`): `corotational_tets.wgsl`
//! (each tet's rotation, warm-started from the last, and its four corner forces) and
//! `corotational_gather.wgsl` (each node sums its records in table order and integrates). Every
//! operation is the shader's, in its order, so the two agree bit for bit on lavapipe.

use crate::layout::tet_table::TetTable;
use crate::physics::{integrate, velocity, StepParams};

/// Iterations of the rotation at most per step (`ROTATION_ITERATIONS` in the shader).
pub const ROTATION_ITERATIONS: u32 = 24;
/// The squared rotation update below which the iteration stops (`ROTATION_CONVERGED`).
pub const ROTATION_CONVERGED: f32 = 1e-12;

type V3 = [f32; 3];
/// A 3x3 matrix by rows.
type Rows = [V3; 3];

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: V3, s: f32) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// WGSL's `dot` of two lanes, as lavapipe lowers it: the products, then their sum.
fn dot2(a: [f32; 2], b: [f32; 2]) -> f32 {
    a[0] * b[0] + a[1] * b[1]
}

/// WGSL's `dot` of three lanes, summed left to right.
fn dot3(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// WGSL's `dot` of four lanes, summed left to right.
fn dot4(a: [f32; 4], b: [f32; 4]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// `a x b`, each lane a two-lane dot (`cross3`).
fn cross3(a: V3, b: V3) -> V3 {
    [
        dot2([a[1], a[2]], [b[2], -b[1]]),
        dot2([a[2], a[0]], [b[0], -b[2]]),
        dot2([a[0], a[1]], [b[1], -b[0]]),
    ]
}

fn xyz(v: [f32; 4]) -> V3 {
    [v[0], v[1], v[2]]
}

/// `R - I` of the unit quaternion `q` (`rotation_minus_identity`).
pub fn rotation_minus_identity(q: [f32; 4]) -> Rows {
    let (x, y, z, w) = (q[0], q[1], q[2], q[3]);
    [
        [
            -2.0 * dot2([y, z], [y, z]),
            2.0 * dot2([x, w], [y, -z]),
            2.0 * dot2([x, w], [z, y]),
        ],
        [
            2.0 * dot2([x, w], [y, z]),
            -2.0 * dot2([x, z], [x, z]),
            2.0 * dot2([y, w], [z, -x]),
        ],
        [
            2.0 * dot2([x, w], [z, -y]),
            2.0 * dot2([y, w], [z, x]),
            -2.0 * dot2([x, y], [x, y]),
        ],
    ]
}

/// `sum_a d_a b_a^T` over corners 1..3, `b` the gradients by column (`gradient`).
pub fn gradient(d: [V3; 3], b: [V3; 3]) -> Rows {
    [0, 1, 2].map(|i| {
        let di = [d[0][i], d[1][i], d[2][i]];
        [dot3(di, b[0]), dot3(di, b[1]), dot3(di, b[2])]
    })
}

/// The columns of `R` (`m = R - I`; `columns`).
fn columns(m: &Rows) -> Rows {
    [
        [m[0][0] + 1.0, m[1][0], m[2][0]],
        [m[0][1], m[1][1] + 1.0, m[2][1]],
        [m[0][2], m[1][2], m[2][2] + 1.0],
    ]
}

/// The rotation of `F = I + D` (rows of `D`) from the warm start `q0`, as `polar_rotation`
/// computes it (Müller et al. 2016; see the shader).
pub fn polar_rotation(d: &Rows, q0: [f32; 4]) -> [f32; 4] {
    polar_rotation_n(d, q0, ROTATION_ITERATIONS, true)
}

/// [`polar_rotation`] with at most `iterations` iterations, stopping at convergence where `stop`.
pub fn polar_rotation_n(d: &Rows, q0: [f32; 4], iterations: u32, stop: bool) -> [f32; 4] {
    let a = [
        [d[0][0] + 1.0, d[1][0], d[2][0]],
        [d[0][1], d[1][1] + 1.0, d[2][1]],
        [d[0][2], d[1][2], d[2][2] + 1.0],
    ];
    let mut q = q0;
    for _ in 0..iterations {
        let c = columns(&rotation_minus_identity(q));
        let num = add(
            add(cross3(c[0], a[0]), cross3(c[1], a[1])),
            cross3(c[2], a[2]),
        );
        let den = (dot3(c[0], a[0]) + dot3(c[1], a[1]) + dot3(c[2], a[2])).abs() + 1e-9;
        let omega = [num[0] / den, num[1] / den, num[2] / den];
        if stop && dot3(omega, omega) < ROTATION_CONVERGED {
            break;
        }
        let h = scale(omega, 0.5);
        let v = xyz(q);
        let x = cross3(h, v);
        let nv: V3 = [0, 1, 2].map(|k| dot3([v[k], h[k], x[k]], [1.0, q[3], 1.0]));
        let nw = q[3] - dot3(h, v);
        let n = [nv[0], nv[1], nv[2], nw];
        let len = dot4(n, n).sqrt();
        q = n.map(|c| c / len);
    }
    q
}

/// Rows of `R^T g`, plus `R^T - I` where `with_identity` (`m = R - I`; `rotated`).
fn rotated(m: &Rows, g: &Rows, with_identity: bool) -> Rows {
    let c = columns(m);
    let gc = [0, 1, 2].map(|j| [g[0][j], g[1][j], g[2][j]]);
    let mut e: Rows = [0, 1, 2].map(|i| [0, 1, 2].map(|j| dot3(c[i], gc[j])));
    if with_identity {
        for (i, row) in e.iter_mut().enumerate() {
            *row = add([m[0][i], m[1][i], m[2][i]], *row);
        }
    }
    e
}

/// `e + beta ev`, lane by lane (`plus_scaled`).
fn plus_scaled(e: V3, ev: V3, beta: f32) -> V3 {
    [0, 1, 2].map(|k| dot2([e[k], ev[k]], [1.0, beta]))
}

impl TetTable {
    /// The per-tet pass: each tet's rotation, from `rotations` (updated in place), and its four
    /// corner forces at `4 t + a`, as `corotational_tets.wgsl` computes them.
    pub fn tet_pass_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
        rotations: &mut [[f32; 4]],
    ) -> Vec<[f32; 4]> {
        let mut out = vec![[0.0f32; 4]; 4 * self.len()];
        for (t, (c, s)) in self.corners.iter().zip(&self.shape).enumerate() {
            let c = c.map(|i| i as usize);
            let b = [xyz(s[0]), xyz(s[1]), xyz(s[2])];
            // The gradients' lanes by column: (b1.x, b2.x, b3.x), ...
            let bc = [0, 1, 2].map(|j| [s[0][j], s[1][j], s[2][j]]);
            let u0 = xyz(cur[c[0]]);
            let d = gradient([1, 2, 3].map(|a| sub(xyz(cur[c[a]]), u0)), bc);
            let q = polar_rotation(&d, rotations[t]);
            rotations[t] = q;
            let m = rotation_minus_identity(q);
            let mut e = rotated(&m, &d, true);
            if p.damped {
                let v = [0, 1, 2, 3].map(|a| velocity(p, cur[c[a]], second[c[a]]));
                let g = gradient([1, 2, 3].map(|a| sub(v[a], v[0])), bc);
                let ev = rotated(&m, &g, false);
                for (row, dv) in e.iter_mut().zip(ev) {
                    *row = plus_scaled(*row, dv, s[2][3]);
                }
            }
            let (lam, mu2) = (s[0][3], s[1][3]);
            let tr = lam * (e[0][0] + e[1][1] + e[2][2]);
            let e01 = mu2 * (0.5 * (e[0][1] + e[1][0]));
            let e02 = mu2 * (0.5 * (e[0][2] + e[2][0]));
            let e12 = mu2 * (0.5 * (e[1][2] + e[2][1]));
            let k = [mu2, 1.0];
            let sg = [
                [dot2(k, [e[0][0], tr]), e01, e02],
                [e01, dot2(k, [e[1][1], tr]), e12],
                [e02, e12, dot2(k, [e[2][2], tr])],
            ];
            let rr = [
                [m[0][0] + 1.0, m[0][1], m[0][2]],
                [m[1][0], m[1][1] + 1.0, m[1][2]],
                [m[2][0], m[2][1], m[2][2] + 1.0],
            ];
            let f = b.map(|ba| {
                let g = [dot3(sg[0], ba), dot3(sg[1], ba), dot3(sg[2], ba)];
                [-dot3(rr[0], g), -dot3(rr[1], g), -dot3(rr[2], g)]
            });
            let f0 = add(add(f[0], f[1]), f[2]);
            out[4 * t] = [-f0[0], -f0[1], -f0[2], 0.0];
            for a in 0..3 {
                out[4 * t + a + 1] = [f[a][0], f[a][1], f[a][2], 0.0];
            }
        }
        out
    }

    /// The node pass's force: each node sums its records in table order.
    pub fn gather_cpu(&self, forces: &[[f32; 4]], nodes: usize) -> Vec<[f32; 3]> {
        (0..nodes)
            .map(|i| {
                let mut f = [0.0f32; 3];
                if let Some(&[start, end]) = self.rows.get(i) {
                    for &k in &self.incidence[start as usize..end as usize] {
                        f = add(f, xyz(forces[k as usize]));
                    }
                }
                f
            })
            .collect()
    }

    /// One corotational step on the CPU exactly as the passes take it: the tet pass (rotations
    /// updated in place), the gather, every free node (non-zero `inv_mass`, layout order)
    /// integrated; fixed nodes and holes get zeros.
    pub fn step_cpu(
        &self,
        p: &StepParams,
        inv_mass: &[f32],
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
        rotations: &mut [[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let forces = self.tet_pass_cpu(p, cur, second, rotations);
        let f = self.gather_cpu(&forces, cur.len());
        let n = cur.len();
        let mut next = vec![[0.0f32; 4]; n];
        let mut second_next = vec![[0.0f32; 4]; n];
        for i in 0..n {
            let m_inv = inv_mass.get(i).copied().unwrap_or(0.0);
            if m_inv == 0.0 {
                continue;
            }
            let vi = velocity(p, cur[i], second[i]);
            (next[i], second_next[i]) = integrate(p, cur[i], second[i], vi, f[i], m_inv);
        }
        (next, second_next)
    }
}

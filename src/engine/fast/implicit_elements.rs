//! Backward Euler's system with a finite-element force model on the fast engine: the same
//! equations, solver and preconditioners as the springs' (`implicit.rs`), on the elements'
//! full 3x3 blocks (`elements_jacobian.rs` forms them: tensor-mass's constant `K` and `C`,
//! corotational's `R K_e R^T` with each tet's rotation frozen at the linearisation's state,
//! Rayleigh's damping in the system).
//!
//! The rows are the springs' rows (the tet edges), assembled again at every linearisation: a
//! cut's patched rows and tets need nothing more. The diagonal block is the mass term plus the
//! sum of the row's blocks (an element's block rows sum to zero), symmetrised: the product,
//! the block-Jacobi inverse and the Gauss-Seidel sweep then all read the one set of blocks.

use super::{
    node_system, over_blocks, Graph, Implicit, Lin, NodeSystem, Params, SharedRows, IDENTITY,
};
use crate::engine::fast::elements::FastElements;

/// Form every free node's row, diagonal block, preconditioner and right-hand side from the
/// finite elements `fem` at the state `at`; returns `b . b`.
pub(super) fn assemble(
    imp: &mut Implicit,
    g: &Graph,
    p: Params,
    fem: &mut FastElements,
    at: Lin,
) -> f64 {
    let (x, v, newton) = match at {
        Lin::Start(x, v) => (x, v, None),
        Lin::Iterate => (&imp.xk[..], &imp.vk[..], Some(&imp.dv[..])),
    };
    fem.linearize(x, v);
    let fem = &*fem;
    let blocks = SharedRows(imp.full.as_mut_ptr(), imp.full.len());
    let starts = &imp.starts[..];
    let h = p.h;
    let [bb, _] = over_blocks(&mut imp.nodes, &mut imp.partials, |start, out| {
        let mut bb = 0.0f64;
        for (k, node) in out.iter_mut().enumerate() {
            let i = start + k;
            if g.fixed[i] {
                *node = NodeSystem {
                    diag: IDENTITY,
                    inverse: IDENTITY,
                    b: [0.0; 4],
                    lower: 0,
                };
                continue;
            }
            let (first, end) = (starts[i] as usize, starts[i + 1] as usize);
            // SAFETY: rows are disjoint, consecutive ranges (`Implicit::fit`), and node `i`'s
            // row is written only here, by the one task that owns node `i`.
            let row = unsafe { blocks.row(first, end) };
            let (f, kv) = fem.implicit_row(i, g, x, v, h, row);
            let mut sum = [0.0f32; 9];
            for e in row.iter() {
                for (s, m) in sum.iter_mut().zip(e.m) {
                    *s += m;
                }
            }
            // Blocks coupling `i` to an earlier node of its own block first (the Gauss-Seidel
            // sweep's lower part, see `precondition`); the product reads them in any order.
            let mut lower = 0;
            for e in 0..row.len() {
                let j = row[e].other as usize;
                if j >= start && j < i {
                    row.swap(lower, e);
                    lower += 1;
                }
            }
            let mh = (1.0 + h * p.alpha) / g.inv_mass[i];
            let diag = [
                sum[0] + mh,
                sum[4] + mh,
                sum[8] + mh,
                0.5 * (sum[1] + sum[3]),
                0.5 * (sum[2] + sum[6]),
                0.5 * (sum[5] + sum[7]),
            ];
            let m = 1.0 / g.inv_mass[i];
            let dv = newton.map(|dv| dv[i]);
            let (system, b2) = node_system(p, m, v[i], (f, kv), dv, diag, lower);
            *node = system;
            bb += b2;
        }
        [bb, 0.0]
    });
    bb
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::fast::implicit::{product, rows_of};
    use crate::engine::fast::FastEngine;
    use crate::engine::{Engine, Integrator, SimConfig};
    use crate::mesh::generate::BoxGrid;
    use crate::physics::{ForceModel, ForceModelKind};
    use crate::{Material, ModelConfig, SpringModel};

    /// `K w` read off the fast engine's assembled system, `(M w - A w) / h^2` through the
    /// product conjugate gradients use (undamped, so `A = M - h^2 K`), against a central
    /// difference of the float64 model's force, on a 3 x 2 x 2 box turned by 40 degrees about
    /// a skew axis and strained by `strain` of its size; relative error over the nodes.
    fn jacobian_error(kind: ForceModelKind, strain: f64) -> f64 {
        let mesh = BoxGrid::cube_cells([3, 2, 2], 0.01).build().unwrap();
        let config = ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0));
        let model = SpringModel::build(&mesh, &config)
            .unwrap()
            .pack(&mesh)
            .unwrap();
        // Far above the bound, so that `h^2 K` dominates the mass and `K w` is not lost in
        // the difference.
        let h = 100.0 * kind.stable_time_step(&model).unwrap().dt;
        let config = SimConfig {
            integrator: Integrator::BackwardEuler,
            force_model: kind,
            ..SimConfig::new(h)
        };
        let mut e = FastEngine::new(&model, config)
            .with_force_model(&model, kind)
            .unwrap();
        let axis = nalgebra::Vector3::new(1.0, 2.0, 3.0).normalize();
        let turn = nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), 0.7);
        let x: Vec<[f64; 3]> = model
            .rest
            .iter()
            .map(|p| {
                let q = turn * nalgebra::Vector3::from(*p);
                [
                    q.x + strain * 0.03 * (p[1] * 300.0).sin(),
                    q.y + strain * 0.03 * (p[0] * 200.0).cos(),
                    q.z + strain * 0.03 * (p[2] * 250.0).sin(),
                ]
            })
            .collect();
        let n = x.len();
        let w: Vec<[f64; 3]> = (0..n)
            .map(|i| [0, 1, 2].map(|c| ((i * 3 + c) as f64 * 0.77).sin()))
            .collect();
        e.set_state(&x, &vec![[0.0; 3]; n]);
        let (imp, fem) = (e.implicit.as_mut().unwrap(), e.elements.as_mut().unwrap());
        imp.fit(&e.graph);
        assemble(imp, &e.graph, e.params, fem, Lin::Start(&e.x, &e.second));
        for (i, &o) in e.order.iter().enumerate() {
            let v = w[o as usize].map(|c| c as f32);
            imp.p[i] = [v[0], v[1], v[2], 0.0];
        }
        let rows = rows_of(
            &imp.starts,
            &imp.blocks,
            &imp.full,
            &imp.lanes,
            imp.elements,
            imp.wide,
        );
        let (p, h32) = (&imp.p, e.params.h);
        product(
            &e.graph,
            rows,
            &imp.nodes,
            p,
            &mut imp.ap,
            &mut imp.partials,
            None,
        );
        // The float64 force's central difference along `w`.
        let force = |s: f64| {
            let xs: Vec<[f64; 3]> = (0..n)
                .map(|i| [0, 1, 2].map(|c| x[i][c] + s * w[i][c]))
                .collect();
            let mut f = vec![[0.0; 3]; n];
            fem.reference().add_forces(&xs, &vec![[0.0; 3]; n], &mut f);
            f
        };
        let eps = 1e-8;
        let (plus, minus) = (force(eps), force(-eps));
        let (mut diff, mut norm) = (0.0, 0.0);
        for (i, &o) in e.order.iter().enumerate() {
            let o = o as usize;
            let mh = (1.0 + h32 * e.params.alpha) / e.graph.inv_mass[i];
            for c in 0..3 {
                let kw = ((mh * imp.p[i][c] - imp.ap[i][c]) / (h32 * h32)) as f64;
                let fd = (plus[o][c] - minus[o][c]) / (2.0 * eps);
                diff += (kw - fd) * (kw - fd);
                norm += fd * fd;
            }
        }
        (diff / norm).sqrt()
    }

    /// The corotational rows hold exact transposes: row `i`'s block at `j` is, bit for bit,
    /// the transpose of row `j`'s block at `i` (each tet's `R K_ab R^T` formed once, its
    /// pair `b, a` read as the transpose), on a strained box turned by 40 degrees, so that the
    /// system conjugate gradients solve is symmetric in float32 too; and the blocks are
    /// not trivially so (the rotation's off-diagonal terms are there).
    #[test]
    fn the_corotational_rows_are_exact_transposes_of_each_other() {
        let mesh = BoxGrid::cube_cells([3, 2, 2], 0.01).build().unwrap();
        let config = ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0));
        let model = SpringModel::build(&mesh, &config)
            .unwrap()
            .pack(&mesh)
            .unwrap();
        let kind = ForceModelKind::Corotational;
        let config = SimConfig {
            integrator: Integrator::BackwardEuler,
            force_model: kind,
            ..SimConfig::new(10.0 * kind.stable_time_step(&model).unwrap().dt)
        };
        let mut e = FastEngine::new(&model, config)
            .with_force_model(&model, kind)
            .unwrap();
        let axis = nalgebra::Unit::new_normalize(nalgebra::Vector3::new(1.0, 2.0, 3.0));
        let turn = nalgebra::Rotation3::from_axis_angle(&axis, 0.7);
        let x: Vec<[f64; 3]> = model
            .rest
            .iter()
            .map(|p| {
                let q = turn * nalgebra::Vector3::from(*p);
                [q.x + 1e-4 * (p[1] * 300.0).sin(), q.y, q.z]
            })
            .collect();
        e.set_state(&x, &vec![[0.0; 3]; x.len()]);
        let (imp, fem) = (e.implicit.as_mut().unwrap(), e.elements.as_mut().unwrap());
        imp.fit(&e.graph);
        assemble(imp, &e.graph, e.params, fem, Lin::Start(&e.x, &e.second));
        let row = |i: usize| &imp.full[imp.starts[i] as usize..imp.starts[i + 1] as usize];
        let (mut pairs, mut skew) = (0, 0.0f32);
        for i in 0..e.graph.fixed.len() {
            for b in row(i) {
                let j = b.other as usize;
                let back = row(j).iter().find(|c| c.other as usize == i).unwrap();
                let m = &back.m;
                let t = [m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8]];
                assert_eq!(b.m.map(f32::to_bits), t.map(f32::to_bits), "{i} -> {j}");
                skew = skew.max((b.m[1] - b.m[3]).abs());
                pairs += 1;
            }
        }
        assert!(pairs > 100 && skew > 0.0, "{pairs} blocks, skew {skew:e}");
    }

    #[test]
    fn the_assembled_jacobian_times_a_vector_equals_a_difference_of_the_force() {
        // Tensor-mass is linear: the product is the force's derivative to float32 rounding.
        let e = jacobian_error(ForceModelKind::TensorMass, 1e-3);
        assert!(e < 1e-5, "tensor-mass: {e:.2e}");
        // Corotational: the rotation frozen at the state (its derivative left out) is exact
        // at a rigid placement and off by the order of the strain under it, never by the
        // order of the rotation (40 degrees: an unrotated block is off by about 1).
        let rigid = jacobian_error(ForceModelKind::Corotational, 0.0);
        assert!(rigid < 1e-5, "corotational, rigid: {rigid:.2e}");
        let strained = jacobian_error(ForceModelKind::Corotational, 1e-3);
        assert!(strained < 1e-2, "corotational, strained: {strained:.2e}");
        eprintln!("tensor-mass {e:.2e}, corotational {rigid:.2e} rigid, {strained:.2e} strained");
    }
}

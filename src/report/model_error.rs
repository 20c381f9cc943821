//! Model error: how far a force model's answer is from elasticity, beside the time-step error
//! the accuracy report measures (which compares each engine only with the same model in
//! float64, never with the continuum).
//!
//! A scene whose mesh is a generated beam (`mesh: Beam(...)`) clamped at `x = 0` under gravity
//! across it has an analytic answer: Timoshenko's tip deflection under its own weight,
//! `q L^4 / (8 E I) + q L^2 / (2 kappa G A)` with `q = rho g A` and Cowper's shear coefficient
//! of a rectangle `kappa = 10 (1 + nu) / (12 + 11 nu)`. Each force model (springs, tensor-mass,
//! corotational) is solved for its static equilibrium under the scene's gravity on the scene's
//! mesh, and, with refinements, on meshes with twice and four times the cells along each side:
//! the table shows the model error and its convergence.
//!
//! The static solve is of the float64 force model (Newton iterations, each a block-Jacobi
//! preconditioned conjugate-gradient solve with the model's stiffness products): what every
//! engine steps towards once the motion has settled. The fast engine steps the same models in
//! float32, equal to float64 to a relative 1e-3 of the motion (`tests/engine/fast_fem.rs`), far
//! below the model errors measured here.

use serde::Serialize;

use crate::error::{Error, Result};
use crate::model::{FixedSelector, Mass, PackedModel, SpringModel, Stiffness};
use crate::physics::{
    ElementForces, ForceModel, ForceModelKind, Linearization, Mat3, SpringForces, Vec3,
};
use crate::scene::{MeshSource, Scene};

/// One force model on one mesh against the analytic answer.
#[derive(Debug, Clone, Serialize)]
pub struct ModelErrorRow {
    /// "springs", "tensor-mass" or "corotational".
    pub force_model: String,
    /// Cells along the beam and across each side of its section.
    pub cells_along: usize,
    /// Cells across.
    pub cells_across: usize,
    /// Tets of the mesh.
    pub tets: usize,
    /// Static tip deflection (mean displacement of the free end along gravity), m.
    pub tip_m: f64,
    /// `(tip - analytic) / analytic`: negative where the model is stiffer than the beam.
    pub relative_error: f64,
    /// Newton iterations and conjugate-gradient iterations of the static solve.
    pub newton: usize,
    /// Conjugate-gradient iterations in all.
    pub cg_iterations: usize,
    /// Wall time of the solve, s.
    pub solve_s: f64,
}

/// The model error of a scene.
#[derive(Debug, Clone, Serialize)]
pub struct ModelErrorReport {
    /// What the analytic answer is.
    pub analytic: String,
    /// The analytic tip deflection, m.
    pub analytic_tip_m: f64,
    /// One row per force model and refinement.
    pub rows: Vec<ModelErrorRow>,
    /// Per force model with three or more meshes: the limit its last three meshes converge
    /// to, so that a user sees how much of the error is the mesh and how much the model.
    pub extrapolated: Vec<Extrapolated>,
}

/// Richardson extrapolation of one force model's tip deflection over its last three meshes
/// (each with twice the cells of the one before), with the order of convergence they show.
#[derive(Debug, Clone, Serialize)]
pub struct Extrapolated {
    /// "springs", "tensor-mass" or "corotational".
    pub force_model: String,
    /// Observed order `p` of `tip(h) = tip_0 + c h^p`.
    pub order: f64,
    /// The extrapolated tip deflection `tip_0`, m.
    pub tip_m: f64,
    /// `(tip_0 - analytic) / analytic`: what is left when the mesh is refined without end.
    pub relative_error: f64,
}

/// Richardson extrapolation of three values at mesh sizes `h`, `h/2`, `h/4`: the limit and
/// the observed order, if the three converge monotonically (else `None`: no order to read).
///
/// With `t(h) = t_0 + c h^p`, the differences `t(h) - t(h/2)` and `t(h/2) - t(h/4)` stand
/// in the ratio `2^p`, and `t_0 = t(h/4) + (t(h/4) - t(h/2)) / (2^p - 1)`.
pub fn richardson(coarse: f64, middle: f64, fine: f64) -> Option<(f64, f64)> {
    let d1 = middle - coarse;
    let d2 = fine - middle;
    let ratio = d1 / d2;
    if !(ratio.is_finite() && ratio > 1.0) {
        return None;
    }
    let order = ratio.log2();
    Some((fine + d2 / (ratio - 1.0), order))
}

/// `scene` with its beam meshed differently: `cells_along` cells along x, `cells_across` across
/// each side of the section, split by `split` (each `None` keeps the scene's). Refused, with
/// the reason, for a scene whose mesh is not a generated beam or for zero cells.
pub fn with_beam_cells(
    scene: &Scene,
    cells_along: Option<usize>,
    cells_across: Option<usize>,
    split: Option<crate::mesh::generate::TetSplit>,
) -> Result<Scene> {
    let mut out = scene.clone();
    let MeshSource::Beam {
        cells_along: along,
        cells_across: across,
        split: how,
        ..
    } = &mut out.mesh
    else {
        return Err(unsupported(
            "the scene's mesh is not a Beam, so it has no beam cells to set",
        ));
    };
    if cells_along == Some(0) || cells_across == Some(0) {
        return Err(Error::Options(
            "a beam needs at least one cell along and one across (got 0)".into(),
        ));
    }
    *along = cells_along.unwrap_or(*along);
    *across = cells_across.unwrap_or(*across);
    *how = split.unwrap_or(*how);
    Ok(out)
}

impl ModelErrorReport {
    /// The finite-element models (not springs: a spring network converges to no continuum)
    /// whose error on their finest mesh is larger than `within` (a fraction, 0.03 for 3%),
    /// each as a sentence naming the mesh and the error. Empty when all are within.
    pub fn beyond(&self, within: f64) -> Vec<String> {
        let mut out = Vec::new();
        let mut seen: Vec<&str> = Vec::new();
        for row in self.rows.iter().rev() {
            if row.force_model == ForceModelKind::Springs.to_string()
                || seen.contains(&row.force_model.as_str())
            {
                continue;
            }
            seen.push(&row.force_model);
            if row.relative_error.is_nan() || row.relative_error.abs() > within {
                out.push(format!(
                    "{} on {} x {} x {} cells ({} tets): {:+.2}% from the analytic tip \
                     deflection, beyond {:.2}%",
                    row.force_model,
                    row.cells_along,
                    row.cells_across,
                    row.cells_across,
                    row.tets,
                    100.0 * row.relative_error,
                    100.0 * within
                ));
            }
        }
        out.reverse();
        out
    }
}

/// The beam a scene describes, with its material and load.
struct BeamCase {
    length: f64,
    width: f64,
    height: f64,
    along: usize,
    across: usize,
    split: crate::mesh::generate::TetSplit,
    e: f64,
    nu: f64,
    density: f64,
    /// Gravity, m/s^2, and the axis (1 or 2) it acts along.
    g: f64,
    axis: usize,
}

fn unsupported(why: &str) -> Error {
    Error::Unsupported(format!(
        "model error needs an analytic answer, which this report has for a generated beam \
         (mesh: Beam(...)) of one material with Young's modulus and a density, clamped by a \
         Plane fixed selector at x = 0, under gravity along y or z: {why}"
    ))
}

impl BeamCase {
    fn of(scene: &Scene) -> Result<Self> {
        let MeshSource::Beam {
            length,
            width,
            height,
            cells_along,
            cells_across,
            split,
        } = &scene.mesh
        else {
            return Err(unsupported("the scene's mesh is not a Beam"));
        };
        let Stiffness::Material {
            youngs_modulus,
            poisson_ratio,
            ..
        } = scene.material.stiffness
        else {
            return Err(unsupported("the material gives a spring stiffness"));
        };
        let Mass::Density(density) = scene.material.mass else {
            return Err(unsupported("the material's mass is not a density"));
        };
        if !scene.regions.is_empty() {
            return Err(unsupported("the scene has regions of other materials"));
        }
        let clamped = scene.fixed.iter().any(|f| {
            matches!(f, FixedSelector::Plane { point, normal, .. }
                if point[0] == 0.0 && normal[1] == 0.0 && normal[2] == 0.0 && normal[0] != 0.0)
        });
        if !clamped {
            return Err(unsupported("no Plane fixed selector at x = 0"));
        }
        let g = scene.gravity;
        let axis = match (g[0] == 0.0, g[1] != 0.0, g[2] != 0.0) {
            (true, true, false) => 1,
            (true, false, true) => 2,
            _ => return Err(unsupported("gravity is not along y or z alone")),
        };
        Ok(BeamCase {
            length: *length,
            width: *width,
            height: *height,
            along: *cells_along,
            across: *cells_across,
            split: *split,
            e: youngs_modulus,
            nu: poisson_ratio,
            density,
            g: g[axis],
            axis,
        })
    }

    /// Timoshenko's tip deflection along gravity (signed as gravity), m.
    fn timoshenko(&self) -> f64 {
        // Bending across the axis gravity acts along: that side is the section's depth.
        let (b, d) = if self.axis == 2 {
            (self.width, self.height)
        } else {
            (self.height, self.width)
        };
        let area = b * d;
        let q = self.density * self.g * area;
        let i = b * d.powi(3) / 12.0;
        let shear = self.e / (2.0 * (1.0 + self.nu));
        let kappa = 10.0 * (1.0 + self.nu) / (12.0 + 11.0 * self.nu);
        q * self.length.powi(4) / (8.0 * self.e * i)
            + q * self.length.powi(2) / (2.0 * kappa * shear * area)
    }

    /// The packed model of `scene` at `k` times its cells each way.
    fn model(&self, scene: &Scene, k: usize) -> Result<PackedModel> {
        let mut refined = scene.clone();
        refined.mesh = MeshSource::Beam {
            length: self.length,
            width: self.width,
            height: self.height,
            cells_along: self.along * k,
            cells_across: self.across * k,
            split: self.split,
        };
        let path = std::path::Path::new("beam");
        let mesh = crate::scene::runner::build_mesh(&refined, path)?;
        SpringModel::build(&mesh, &crate::scene::runner::model_config(&refined))?.pack(&mesh)
    }
}

/// The model error of `scene` for each force model in `models`, on the scene's mesh and
/// `refinements - 1` refinements of it (twice, then four times the cells each way). Refused,
/// with the reason, for a scene without an analytic answer.
pub fn model_error(
    scene: &Scene,
    models: &[ForceModelKind],
    refinements: usize,
    mut progress: impl FnMut(&str),
) -> Result<ModelErrorReport> {
    let case = BeamCase::of(scene)?;
    let analytic = case.timoshenko();
    let mut rows = Vec::new();
    for r in 0..refinements.max(1) {
        let k = 1 << r;
        let model = case.model(scene, k)?;
        for &kind in models {
            progress(&format!(
                "{kind} on {} x {} x {} cells",
                case.along * k,
                case.across * k,
                case.across * k
            ));
            let start = std::time::Instant::now();
            let springs;
            let elements;
            let forces: &dyn ForceModel = match ElementForces::new(kind, &model)? {
                Some(e) => {
                    elements = e;
                    &elements
                }
                None => {
                    springs = SpringForces::new(model.springs());
                    &springs
                }
            };
            // Linear: one Newton step is exact. The others: until the update is small.
            let newton = if kind == ForceModelKind::TensorMass {
                1
            } else {
                8
            };
            let solved = static_solve(forces, &model, newton);
            let tip = tip_deflection(&model, &solved.x, case.length, case.axis);
            rows.push(ModelErrorRow {
                force_model: kind.to_string(),
                cells_along: case.along * k,
                cells_across: case.across * k,
                tets: model.tets.len(),
                tip_m: tip,
                relative_error: (tip - analytic) / analytic,
                newton: solved.newton,
                cg_iterations: solved.cg,
                solve_s: start.elapsed().as_secs_f64(),
            });
        }
    }
    let extrapolated = models
        .iter()
        .filter_map(|kind| {
            let name = kind.to_string();
            let tips: Vec<f64> = rows
                .iter()
                .filter(|r| r.force_model == name)
                .map(|r| r.tip_m)
                .collect();
            let [.., a, b, c] = tips[..] else {
                return None;
            };
            let (tip, order) = richardson(a, b, c)?;
            Some(Extrapolated {
                force_model: name,
                order,
                tip_m: tip,
                relative_error: (tip - analytic) / analytic,
            })
        })
        .collect();
    Ok(ModelErrorReport {
        extrapolated,
        analytic: format!(
            "Timoshenko cantilever under its own weight: {} x {} x {} m, E {} Pa, nu {}, {} kg/m^3",
            case.length, case.width, case.height, case.e, case.nu, case.density
        ),
        analytic_tip_m: analytic,
        rows,
    })
}

/// Mean displacement along gravity's axis of the nodes at the free end, m.
fn tip_deflection(model: &PackedModel, x: &[Vec3], length: f64, axis: usize) -> f64 {
    let tol = 1e-9 * length;
    let tip: Vec<f64> = x
        .iter()
        .zip(&model.rest)
        .filter(|(_, r)| (r[0] - length).abs() < tol)
        .map(|(p, r)| p[axis] - r[axis])
        .collect();
    tip.iter().sum::<f64>() / tip.len().max(1) as f64
}

struct Solved {
    x: Vec<Vec3>,
    newton: usize,
    cg: usize,
}

fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
        .sum()
}

/// The static equilibrium `F(x) + m g = 0` of `model` under `forces`, fixed nodes held at
/// rest: Newton iterations (at most `newton`, stopping when an update is below 1e-9 of the
/// displacement), each solving `-K dx = residual` by conjugate gradients preconditioned with
/// the inverse 3x3 diagonal blocks of `-K`.
fn static_solve(forces: &dyn ForceModel, model: &PackedModel, newton: usize) -> Solved {
    let n = model.node_count();
    let free = &model.fixed;
    let weight: Vec<Vec3> = model
        .mass
        .iter()
        .map(|m| model.gravity.map(|g| m * g))
        .collect();
    let zero = vec![[0.0; 3]; n];
    let mask = |v: &mut [Vec3]| {
        for (v, &fixed) in v.iter_mut().zip(free) {
            if fixed {
                *v = [0.0; 3];
            }
        }
    };
    let mut x = model.rest.clone();
    let (mut iterations, mut cg) = (0, 0);
    for _ in 0..newton {
        iterations += 1;
        let mut r = weight.clone();
        forces.add_forces(&x, &zero, &mut r);
        mask(&mut r);
        let (mut k, mut c): (Vec<Mat3>, Vec<Mat3>) =
            (vec![[[0.0; 3]; 3]; n], vec![[[0.0; 3]; 3]; n]);
        forces.add_diagonal_blocks(&x, Linearization::Definite, &mut k, &mut c);
        let inverse: Vec<Option<nalgebra::Matrix3<f64>>> = k
            .iter()
            .map(|b| nalgebra::Matrix3::from_fn(|i, j| -b[i][j]).try_inverse())
            .collect();
        let precondition = |r: &[Vec3]| -> Vec<Vec3> {
            r.iter()
                .zip(&inverse)
                .zip(free)
                .map(|((r, m), &fixed)| match (m, fixed) {
                    (Some(m), false) => {
                        let v = m * nalgebra::Vector3::from(*r);
                        [v[0], v[1], v[2]]
                    }
                    _ => [0.0; 3],
                })
                .collect()
        };
        let apply = |w: &[Vec3]| -> Vec<Vec3> {
            let mut out = vec![[0.0; 3]; n];
            forces.add_stiffness_product(&x, Linearization::Definite, w, &mut out);
            for o in out.iter_mut() {
                *o = o.map(|v| -v);
            }
            mask(&mut out);
            out
        };
        let norm0 = dot(&r, &r).sqrt();
        if norm0 == 0.0 {
            break;
        }
        let mut dx = vec![[0.0; 3]; n];
        let mut z = precondition(&r);
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        for _ in 0..(20 * n).max(1000) {
            cg += 1;
            let ap = apply(&p);
            let alpha = rz / dot(&p, &ap);
            for i in 0..n {
                for d in 0..3 {
                    dx[i][d] += alpha * p[i][d];
                    r[i][d] -= alpha * ap[i][d];
                }
            }
            if dot(&r, &r).sqrt() < 1e-10 * norm0 {
                break;
            }
            z = precondition(&r);
            let next = dot(&r, &z);
            let beta = next / rz;
            rz = next;
            for i in 0..n {
                for d in 0..3 {
                    p[i][d] = z[i][d] + beta * p[i][d];
                }
            }
        }
        for i in 0..n {
            for d in 0..3 {
                x[i][d] += dx[i][d];
            }
        }
        let u: Vec<Vec3> = x
            .iter()
            .zip(&model.rest)
            .map(|(x, r)| [0, 1, 2].map(|d| x[d] - r[d]))
            .collect();
        if dot(&dx, &dx).sqrt() <= 1e-9 * dot(&u, &u).sqrt() {
            break;
        }
    }
    Solved {
        x,
        newton: iterations,
        cg,
    }
}

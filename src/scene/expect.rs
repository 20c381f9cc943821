//! Checking a finished run against a scene's expectations.

use serde::Serialize;

use super::schema::{EnergyPart, Expectation};
use crate::engine::Energy;
use crate::mesh::{signed_volume6, TetMesh};
use crate::model::PackedModel;

/// The outcome of one expectation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExpectationResult {
    /// What was expected, in words.
    pub expectation: String,
    /// The value measured, if the expectation measures one.
    pub measured: Option<f64>,
    /// Whether it held.
    pub passed: bool,
    /// Whether it was skipped (an expectation for another cut method): it then counts neither
    /// as a pass nor as a failure.
    pub skipped: bool,
}

/// The state at the end of a run, as expectations see it.
pub struct FinalState<'a> {
    /// The mesh (rest geometry).
    pub mesh: &'a TetMesh,
    /// The packed model (node order of `positions`).
    pub model: &'a PackedModel,
    /// Final positions.
    pub positions: &'a [[f64; 3]],
    /// Final energies.
    pub energy: Energy,
    /// Whether the run diverged.
    pub diverged: bool,
    /// Whether the time step was refused.
    pub refused: bool,
    /// What each tool felt.
    pub tools: &'a [ToolReport],
    /// What the cuts did (scenes that cut).
    pub cuts: Option<&'a super::cuts::CutReport>,
    /// The cut method of this run (scenes that cut).
    pub method: Option<crate::cut::CutMethod>,
}

/// What a tool felt over a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ToolReport {
    /// The tool's name in the scene.
    pub name: String,
    /// Largest force magnitude over the run, N.
    pub max_force: f64,
    /// Force at the last step, N.
    pub final_force: [f64; 3],
    /// Deepest penetration found before it was resolved, m.
    pub max_depth: f64,
    /// Steps with at least one contact.
    pub contact_steps: u64,
    /// Most surface nodes the tool held at once (graspers with grasp windows).
    pub max_held: usize,
    /// How far the tool carried what it held: the largest, over the steps it held nodes, of
    /// their mean distance from their rest positions, m.
    pub max_carried: f64,
}

/// Largest nodal displacement from rest.
pub fn max_displacement(model: &PackedModel, x: &[[f64; 3]]) -> f64 {
    x.iter()
        .zip(&model.rest)
        .map(|(p, r)| dist(p, r))
        .fold(0.0, f64::max)
}

/// Total signed volume of the tets at positions `x` (node order of `mesh.dense_nodes()`).
pub fn deformed_volume(mesh: &TetMesh, x: &[[f64; 3]]) -> f64 {
    let dense = mesh.dense_nodes();
    mesh.tets()
        .map(|(_, t)| {
            let p = t
                .nodes
                .map(|k| nalgebra::Point3::from(x[dense.index[k] as usize]));
            signed_volume6(&p[0], &p[1], &p[2], &p[3]) / 6.0
        })
        .sum()
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn in_range(v: f64, min: Option<f64>, max: Option<f64>) -> bool {
    v.is_finite() && min.is_none_or(|m| v >= m) && max.is_none_or(|m| v <= m)
}

fn range_text(min: Option<f64>, max: Option<f64>) -> String {
    match (min, max) {
        (Some(a), Some(b)) => format!("in [{a:e}, {b:e}]"),
        (Some(a), None) => format!(">= {a:e}"),
        (None, Some(b)) => format!("<= {b:e}"),
        (None, None) => "finite".into(),
    }
}

/// Check one expectation.
pub fn check(e: &Expectation, s: &FinalState) -> ExpectationResult {
    let ran = !s.diverged && !s.refused;
    let ranged = |what: String, v: f64, min, max| ExpectationResult {
        expectation: format!("{what} {}", range_text(min, max)),
        measured: Some(v),
        passed: ran && in_range(v, min, max),
        skipped: false,
    };
    match e {
        Expectation::ToolForce { tool, min, max } => match s.tools.iter().find(|t| &t.name == tool)
        {
            Some(t) => ranged(
                format!("largest force on {tool} (N)"),
                t.max_force,
                *min,
                *max,
            ),
            None => ExpectationResult {
                expectation: format!("largest force on {tool}: the scene has no such tool"),
                measured: None,
                passed: false,
                skipped: false,
            },
        },
        Expectation::GraspCarried { tool, min, max } => {
            match s.tools.iter().find(|t| &t.name == tool) {
                Some(t) => ranged(
                    format!(
                        "largest mean displacement of the nodes {tool} held (m; it held up to {})",
                        t.max_held
                    ),
                    t.max_carried,
                    *min,
                    *max,
                ),
                None => ExpectationResult {
                    expectation: format!(
                        "displacement of what {tool} held: the scene has no such tool"
                    ),
                    measured: None,
                    passed: false,
                    skipped: false,
                },
            }
        }
        Expectation::MaxDisplacement { min, max } => ranged(
            "max displacement (m)".into(),
            max_displacement(s.model, s.positions),
            *min,
            *max,
        ),
        Expectation::DisplacementAt {
            point,
            component,
            min,
            max,
        } => {
            let node = s
                .model
                .rest
                .iter()
                .enumerate()
                .min_by(|(_, a), (_, b)| dist(a, point).total_cmp(&dist(b, point)))
                .map_or(0, |(i, _)| i);
            let (p, r) = (s.positions[node], s.model.rest[node]);
            let (what, v) = match component {
                Some(c) if *c < 3 => (
                    format!("displacement[{c}] at node {node} near {point:?} (m)"),
                    p[*c] - r[*c],
                ),
                Some(c) => (
                    format!("displacement component {c} (must be 0, 1 or 2)"),
                    f64::NAN,
                ),
                None => (
                    format!("displacement at node {node} near {point:?} (m)"),
                    dist(&p, &r),
                ),
            };
            ranged(what, v, *min, *max)
        }
        Expectation::VolumeRatio { min, max } => ranged(
            "volume ratio".into(),
            deformed_volume(s.mesh, s.positions) / s.mesh.volume(),
            *min,
            *max,
        ),
        Expectation::Energy { part, min, max } => {
            let v = match part {
                EnergyPart::Kinetic => s.energy.kinetic,
                EnergyPart::Elastic => s.energy.elastic,
                EnergyPart::Gravity => s.energy.gravity,
                EnergyPart::Total => s.energy.total(),
            };
            let part = format!("{part:?}").to_lowercase();
            ranged(format!("{part} energy (J)"), v, *min, *max)
        }
        Expectation::Method(method, inner) => {
            if s.method == Some(*method) {
                let mut r = check(inner, s);
                r.expectation = format!("[{method}] {}", r.expectation);
                r
            } else {
                ExpectationResult {
                    expectation: format!("[{method}] not this method"),
                    measured: None,
                    passed: true,
                    skipped: true,
                }
            }
        }
        Expectation::Fragments { .. }
        | Expectation::Cuts { .. }
        | Expectation::NodesAdded { .. }
        | Expectation::VolumeRemoved { .. }
        | Expectation::Opening { .. }
        | Expectation::UploadFraction { .. }
        | Expectation::InvariantsHold => check_cut(e, s, ran),
        Expectation::RefusesTimeStep => ExpectationResult {
            expectation: "time step refused as unstable".into(),
            measured: None,
            passed: s.refused,
            skipped: false,
        },
        Expectation::Diverges => ExpectationResult {
            expectation: "divergence detected and reported".into(),
            measured: None,
            passed: s.diverged,
            skipped: false,
        },
    }
}

/// The cut expectations.
fn check_cut(e: &Expectation, s: &FinalState, ran: bool) -> ExpectationResult {
    let Some(c) = s.cuts else {
        return ExpectationResult {
            expectation: format!("{e:?}: the scene does not cut (add a `cut` section)"),
            measured: None,
            passed: false,
            skipped: false,
        };
    };
    let counted = |what: &str, v: usize, min: Option<usize>, max: Option<usize>| {
        let (fmin, fmax) = (min.map(|m| m as f64), max.map(|m| m as f64));
        ExpectationResult {
            expectation: format!("{what} {}", range_text(fmin, fmax)),
            measured: Some(v as f64),
            passed: ran && in_range(v as f64, fmin, fmax),
            skipped: false,
        }
    };
    match e {
        Expectation::Fragments { min, max } => counted("fragments", c.fragments, *min, *max),
        Expectation::Cuts { min, max } => counted("steps that cut", c.cuts, *min, *max),
        Expectation::NodesAdded { min, max } => counted("nodes added", c.nodes_added, *min, *max),
        Expectation::VolumeRemoved { min, max } => ExpectationResult {
            expectation: format!("volume removed (fraction) {}", range_text(*min, *max)),
            measured: Some(c.volume_removed_fraction),
            passed: ran && in_range(c.volume_removed_fraction, *min, *max),
            skipped: false,
        },
        Expectation::Opening { min, max } => ExpectationResult {
            expectation: format!("incision opening (m) {}", range_text(*min, *max)),
            measured: Some(c.max_opening),
            passed: ran && in_range(c.max_opening, *min, *max),
            skipped: false,
        },
        Expectation::UploadFraction { max } => ExpectationResult {
            expectation: format!("largest layout fraction one cut uploaded <= {max}"),
            measured: Some(c.max_upload_fraction),
            passed: ran && c.max_upload_fraction <= *max,
            skipped: false,
        },
        _ => invariants_held(c, ran),
    }
}

/// [`Expectation::InvariantsHold`]: every cut was checked and none broke an invariant. A run
/// in which no cut was checked has shown nothing, so it fails, saying why.
fn invariants_held(c: &super::cuts::CutReport, ran: bool) -> ExpectationResult {
    let unchecked = if c.checks > 0 {
        None
    } else if c.cuts == 0 {
        Some(
            "no cut was checked: the blade never cut (move it through the tissue, or give \
             this expectation only to the methods that cut, with Method(...))",
        )
    } else {
        Some("no cut was checked: turn the checks on with `check: true` or `--check`")
    };
    let expectation = match unchecked {
        Some(why) => format!("invariants hold after every cut: {why}"),
        None => format!(
            "invariants hold after every cut ({} checks of {} cuts{})",
            c.checks,
            c.cuts,
            c.violations
                .first()
                .map_or(String::new(), |v| format!("; first failure: {v}"))
        ),
    };
    ExpectationResult {
        expectation,
        measured: Some(c.violations.len() as f64),
        passed: ran && unchecked.is_none() && c.checks == c.cuts && c.violations.is_empty(),
        skipped: false,
    }
}

//! Checks of a scene's fixed-node selectors and expectations when it is read, so that a
//! mistake is refused before any mesh is built instead of running unconstrained or failing
//! (or passing) only when the run ends.

use std::path::Path;

use super::schema::{Expectation, Scene};
use crate::collide::ToolShape;
use crate::error::{Error, Result};

impl Scene {
    /// Check the time step: a finite positive `Seconds`, or a finite positive
    /// `BoundFraction`; the message names the scene file (the engine, which checks it again,
    /// knows no file).
    pub fn validate_time_step(&self, path: &Path) -> Result<()> {
        let (what, v) = match self.dt {
            super::TimeStep::Seconds(s) => ("Seconds", s),
            super::TimeStep::BoundFraction(f) => ("BoundFraction", f),
        };
        if v.is_finite() && v > 0.0 {
            return Ok(());
        }
        Err(Error::Scene {
            path: path.to_path_buf(),
            message: format!(
                "dt: {what}({v}) must be finite and positive; give e.g. dt: BoundFraction(0.9)"
            ),
        })
    }

    /// Check every fixed-node selector's numbers ([`crate::model::FixedSelector::validate`]);
    /// the message names the selector by index. Whether it selects a node is checked when the
    /// model is built, against the mesh.
    pub fn validate_fixed(&self, path: &Path) -> Result<()> {
        for (i, sel) in self.fixed.iter().enumerate() {
            sel.validate().map_err(|m| Error::Scene {
                path: path.to_path_buf(),
                message: format!("fixed selector {i} ({sel:?}): {m}"),
            })?;
        }
        Ok(())
    }

    /// Check every expectation: bounds finite and in order, a point finite, a component 0, 1
    /// or 2, a tool named that the scene has (a grasper for `GraspCarried`), and a `cut`
    /// section for the expectations about cuts. The message names the expectation by index.
    pub fn validate_expectations(&self, path: &Path) -> Result<()> {
        for (i, e) in self.expect.iter().enumerate() {
            self.check_expectation(e).map_err(|m| Error::Scene {
                path: path.to_path_buf(),
                message: format!("expectation {i} ({}): {m}", head(e)),
            })?;
        }
        Ok(())
    }

    fn check_expectation(&self, e: &Expectation) -> std::result::Result<(), String> {
        use Expectation as E;
        let needs_cut = || {
            if self.cut.is_some() {
                Ok(())
            } else {
                Err(
                    "the scene does not cut; add a `cut` section or remove this expectation"
                        .to_string(),
                )
            }
        };
        match e {
            E::MaxDisplacement { min, max }
            | E::VolumeRatio { min, max }
            | E::Energy { min, max, .. } => bounds(*min, *max),
            E::DisplacementAt {
                point,
                component,
                min,
                max,
            } => {
                if !point.iter().all(|c| c.is_finite()) {
                    return Err(format!("point {point:?} must have finite coordinates"));
                }
                if let Some(c) = component.filter(|&c| c > 2) {
                    return Err(format!(
                        "component {c} does not exist; give 0 (x), 1 (y) or 2 (z), or leave it \
                         out for the magnitude"
                    ));
                }
                bounds(*min, *max)
            }
            E::ToolForce { tool, min, max } => {
                self.tool_named(tool)?;
                bounds(*min, *max)
            }
            E::GraspCarried { tool, min, max } => {
                if !matches!(self.tool_named(tool)?.shape, ToolShape::Grasper { .. }) {
                    return Err(format!(
                        "tool {tool:?} is not a grasper, so it carries nothing; name a grasper"
                    ));
                }
                bounds(*min, *max)
            }
            E::Fragments { min, max } | E::Cuts { min, max } | E::NodesAdded { min, max } => {
                needs_cut()?;
                match (min, max) {
                    (Some(a), Some(b)) if a > b => Err(format!(
                        "min {a} is above max {b}, so nothing can pass; swap them"
                    )),
                    _ => Ok(()),
                }
            }
            E::VolumeRemoved { min, max } | E::Opening { min, max } => {
                needs_cut()?;
                bounds(*min, *max)
            }
            E::UploadFraction { max } => {
                needs_cut()?;
                bounds(Some(0.0), Some(*max))
                    .map_err(|_| format!("max {max} must be a finite fraction of zero or more"))
            }
            E::InvariantsHold => needs_cut(),
            E::Method(_, inner) => {
                needs_cut()?;
                self.check_expectation(inner)
            }
            E::RefusesTimeStep | E::Diverges => Ok(()),
        }
    }

    fn tool_named(&self, name: &str) -> std::result::Result<&super::SceneTool, String> {
        self.tools.iter().find(|t| t.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.tools.iter().map(|t| t.name.as_str()).collect();
            match super::schema::nearest_name(name, &names) {
                Some(near) => format!("the scene has no tool {name:?}; did you mean {near:?}?"),
                None if names.is_empty() => {
                    format!("the scene has no tool {name:?} (it has no tools)")
                }
                None => format!("the scene has no tool {name:?}; its tools are {names:?}"),
            }
        })
    }
}

/// Bounds that can hold: each finite, and `min` not above `max`.
fn bounds(min: Option<f64>, max: Option<f64>) -> std::result::Result<(), String> {
    for (name, v) in [("min", min), ("max", max)] {
        if let Some(v) = v.filter(|v| !v.is_finite()) {
            return Err(format!("{name} {v} must be a finite number"));
        }
    }
    match (min, max) {
        (Some(a), Some(b)) if a > b => Err(format!(
            "min {a:e} is above max {b:e}, so nothing can pass; swap them"
        )),
        _ => Ok(()),
    }
}

/// The expectation's variant name, for messages.
fn head(e: &Expectation) -> String {
    let text = format!("{e:?}");
    let end = text.find([' ', '(', '{']).unwrap_or(text.len());
    text[..end].to_string()
}

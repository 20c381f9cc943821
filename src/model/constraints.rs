//! Selecting fixed nodes by region tag, box or plane.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use slotmap::SecondaryMap;

use crate::error::{Error, Result};
use crate::mesh::{NodeKey, TetMesh};

/// A set of nodes to hold at their rest positions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum FixedSelector {
    /// Every node of every tet with this region tag.
    Region(i32),
    /// Nodes inside an axis-aligned box (bounds included).
    Box {
        /// Smallest corner.
        min: [f64; 3],
        /// Largest corner.
        max: [f64; 3],
    },
    /// Nodes within `tolerance` of the plane through `point` with normal `normal`.
    Plane {
        /// A point on the plane.
        point: [f64; 3],
        /// The plane's normal (need not be unit length).
        normal: [f64; 3],
        /// Distance from the plane within which a node is selected.
        tolerance: f64,
    },
    /// Nodes on or behind the plane: signed distance `<= tolerance` along `normal`.
    HalfSpace {
        /// A point on the plane.
        point: [f64; 3],
        /// Outward normal: nodes on the other side are selected.
        normal: [f64; 3],
        /// Extra distance in front of the plane still selected.
        tolerance: f64,
    },
}

impl FixedSelector {
    /// Check the selector's numbers without a mesh: finite coordinates, a box whose `min` is
    /// not above its `max`, a non-zero normal and a finite tolerance of zero or more. Each of
    /// these, wrong, selects nothing (every comparison with NaN is false), which would run the
    /// body free with no word; the message says what to give instead.
    pub fn validate(&self) -> std::result::Result<(), String> {
        let finite = |name: &str, v: &[f64; 3]| {
            if v.iter().all(|c| c.is_finite()) {
                Ok(())
            } else {
                Err(format!("{name} {v:?} must have finite coordinates"))
            }
        };
        match self {
            FixedSelector::Region(_) => Ok(()),
            FixedSelector::Box { min, max } => {
                finite("min", min)?;
                finite("max", max)?;
                match (0..3).find(|&i| min[i] > max[i]) {
                    Some(i) => Err(format!(
                        "box min {min:?} is above max {max:?} along axis {i}, so the box holds \
                         nothing; swap them"
                    )),
                    None => Ok(()),
                }
            }
            FixedSelector::Plane {
                point,
                normal,
                tolerance,
            }
            | FixedSelector::HalfSpace {
                point,
                normal,
                tolerance,
            } => {
                finite("point", point)?;
                finite("normal", normal)?;
                if normal.iter().all(|&c| c == 0.0) {
                    return Err(format!(
                        "normal {normal:?} has no direction; give a non-zero normal"
                    ));
                }
                if !(tolerance.is_finite() && *tolerance >= 0.0) {
                    return Err(format!(
                        "tolerance {tolerance} must be a finite distance of zero or more, m"
                    ));
                }
                Ok(())
            }
        }
    }

    /// The nodes of `mesh` this selects, marked in `out`. A selector that selects no node is
    /// an error: a misplaced plane or a missing region would otherwise leave the body free.
    pub fn select(&self, mesh: &TetMesh, out: &mut SecondaryMap<NodeKey, ()>) -> Result<()> {
        self.validate()
            .map_err(|m| Error::Model(format!("fixed selector {self:?}: {m}")))?;
        let mut matched = 0usize;
        let mut mark = |k: NodeKey| {
            matched += 1;
            out.insert(k, ());
        };
        match self {
            FixedSelector::Region(r) => {
                for (_, t) in mesh.tets() {
                    if t.region == *r {
                        for &n in &t.nodes {
                            mark(n);
                        }
                    }
                }
            }
            FixedSelector::Box { min, max } => {
                let (lo, hi) = (Point3::from(*min), Point3::from(*max));
                for (k, n) in mesh.nodes() {
                    let p = n.rest;
                    if (0..3).all(|i| p[i] >= lo[i] && p[i] <= hi[i]) {
                        mark(k);
                    }
                }
            }
            FixedSelector::Plane {
                point,
                normal,
                tolerance,
            }
            | FixedSelector::HalfSpace {
                point,
                normal,
                tolerance,
            } => {
                let n = Vector3::from(*normal);
                let len = n.norm();
                if !(len.is_finite() && len > 0.0) {
                    return Err(Error::Model(format!(
                        "fixed plane normal {normal:?} has no direction; give a non-zero normal"
                    )));
                }
                let n = n / len;
                let p0 = Point3::from(*point);
                let half = matches!(self, FixedSelector::HalfSpace { .. });
                for (k, node) in mesh.nodes() {
                    let d = (node.rest - p0).dot(&n);
                    let hit = if half {
                        d <= *tolerance
                    } else {
                        d.abs() <= *tolerance
                    };
                    if hit {
                        mark(k);
                    }
                }
            }
        }
        if matched == 0 {
            return Err(Error::Model(format!(
                "fixed selector {self:?} selects no node of the mesh (its bounding box is {}); \
                 move it onto the mesh, or remove it to leave the body free",
                bounding_box_text(mesh)
            )));
        }
        Ok(())
    }
}

/// The mesh's rest bounding box, for messages: `[min] to [max]`.
fn bounding_box_text(mesh: &TetMesh) -> String {
    match mesh.bounds() {
        Some((lo, hi)) => format!("{:?} to {:?}", [lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]),
        None => "empty".into(),
    }
}

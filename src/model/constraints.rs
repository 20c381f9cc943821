//! Selecting fixed nodes by region tag, box or plane.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use slotmap::SecondaryMap;

use crate::error::{Error, Result};
use crate::mesh::{NodeKey, TetMesh};

/// A set of nodes to hold at their rest positions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// The nodes of `mesh` this selects, marked in `out`.
    pub fn select(&self, mesh: &TetMesh, out: &mut SecondaryMap<NodeKey, ()>) -> Result<()> {
        match self {
            FixedSelector::Region(r) => {
                for (_, t) in mesh.tets() {
                    if t.region == *r {
                        for &n in &t.nodes {
                            out.insert(n, ());
                        }
                    }
                }
            }
            FixedSelector::Box { min, max } => {
                let (lo, hi) = (Point3::from(*min), Point3::from(*max));
                for (k, n) in mesh.nodes() {
                    let p = n.rest;
                    if (0..3).all(|i| p[i] >= lo[i] && p[i] <= hi[i]) {
                        out.insert(k, ());
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
                        out.insert(k, ());
                    }
                }
            }
        }
        Ok(())
    }
}

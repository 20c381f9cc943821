//! Contact response between steps: the surface triangles a tool penetrates are pushed out of
//! it by position correction (which the integrator turns into velocity), and the reaction force
//! on each tool is what it took: `-sum m_i dx_i / dt^2` over the moved nodes, in newtons, for
//! force feedback.
//!
//! Per call: the tools' swept bounds (widened by the contact skin) go through the broad phase
//! ([`Simulation::cull_tools`], on the device for the GPU engine), only the candidate
//! triangles' nodes are read back, the narrow phase ([`super::narrow::tool_triangle`]) gives
//! each penetrating triangle its depth, normal and deepest point, and the triangle is moved
//! along the normal by the depth, spread over its free corners by their barycentric weights at
//! that point (the smallest such move). Nodes shared by several contacts take the mean of their
//! moves; a few such sweeps settle neighbouring contacts. Fixed nodes never move.

use nalgebra::{Point3, Vector3};

use super::broad::ToolBox;
use super::narrow::tool_triangle;
use super::tool::Tool;
use crate::engine::Simulation;
use crate::error::{Error, Result};

/// How contacts are resolved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactSettings {
    /// Nodes are pushed this far clear of the tool, m, so that a resting contact is found
    /// again at the next step instead of flickering.
    pub skin: f64,
    /// Sweeps over the contacts per call.
    pub iterations: usize,
}

impl Default for ContactSettings {
    fn default() -> Self {
        ContactSettings {
            skin: 1e-5,
            iterations: 8,
        }
    }
}

/// What a tool felt in one call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolForce {
    /// Reaction force on the tool, N (scene frame): it points away from the tissue it presses.
    pub force: Vector3<f64>,
    /// Penetrating triangles found in the first sweep.
    pub contacts: usize,
    /// Deepest penetration found in the first sweep, m (0 without contact).
    pub deepest: f64,
}

/// Barycentric weights of `p` (on or near the triangle's plane) in triangle `t`.
fn barycentric(t: &[Point3<f64>; 3], p: &Point3<f64>) -> [f64; 3] {
    let (v0, v1, v2) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (d00, d01, d11) = (v0.dot(&v0), v0.dot(&v1), v1.dot(&v1));
    let (d20, d21) = (v2.dot(&v0), v2.dot(&v1));
    let den = d00 * d11 - d01 * d01;
    if den <= 0.0 {
        return [1.0 / 3.0; 3];
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    [1.0 - v - w, v, w].map(|x| x.clamp(0.0, 1.0))
}

/// Resolve the contacts of `tools` (at their current poses, swept from their previous ones)
/// with the surface given to [`Simulation::set_surface`], and return the force on each tool.
pub fn resolve_contacts(
    sim: &mut Simulation,
    tools: &[Tool],
    settings: &ContactSettings,
) -> Result<Vec<ToolForce>> {
    let mut forces = vec![
        ToolForce {
            force: Vector3::zeros(),
            contacts: 0,
            deepest: 0.0,
        };
        tools.len()
    ];
    let boxes: Vec<ToolBox> = tools
        .iter()
        .map(|t| {
            let b = t.step_bounds(settings.skin);
            ToolBox::containing(b.min.coords.into(), b.max.coords.into())
        })
        .collect();
    let candidates = sim.cull_tools(&boxes)?;
    if candidates.is_empty() {
        return Ok(forces);
    }
    let surface = sim
        .surface()
        .ok_or_else(|| Error::Model("no surface: call set_surface first".into()))?;
    let triangles: Vec<[u32; 3]> = candidates.iter().map(|c| surface[c[0] as usize]).collect();
    let mut nodes: Vec<u32> = triangles.iter().flatten().copied().collect();
    nodes.sort_unstable();
    nodes.dedup();
    let slot = |n: u32| nodes.binary_search(&n).expect("every corner was collected");
    let original: Vec<Point3<f64>> = sim
        .node_positions(&nodes)?
        .into_iter()
        .map(Point3::from)
        .collect();
    let mut pos = original.clone();
    let model = sim.model();
    let free: Vec<bool> = nodes.iter().map(|&n| !model.fixed[n as usize]).collect();
    let mass: Vec<f64> = nodes.iter().map(|&n| model.mass[n as usize]).collect();
    let inv_h2 = 1.0 / (sim.config().dt * sim.config().dt);
    for sweep in 0..settings.iterations.max(1) {
        let mut moves = vec![Vector3::zeros(); nodes.len()];
        let mut count = vec![0u32; nodes.len()];
        // Per contact: (tool, node slot, move) to attribute the reaction once means are known.
        let mut parts: Vec<(usize, usize, Vector3<f64>)> = Vec::new();
        for (c, tri) in candidates.iter().zip(&triangles) {
            let tool = &tools[c[1] as usize];
            let slots = tri.map(slot);
            let corners = slots.map(|s| pos[s]);
            let Some(contact) = tool_triangle(&tool.shape, tool.pose(), &corners, settings.skin)?
            else {
                continue;
            };
            let depth = settings.skin - contact.distance;
            if depth <= 0.0 {
                continue;
            }
            if sweep == 0 {
                let f = &mut forces[c[1] as usize];
                f.contacts += 1;
                f.deepest = f.deepest.max(-contact.distance).max(0.0);
            }
            let mut w = barycentric(&corners, &contact.point_on_element);
            for (k, s) in slots.iter().enumerate() {
                if !free[*s] {
                    w[k] = 0.0;
                }
            }
            let norm2: f64 = w.iter().map(|x| x * x).sum();
            if norm2 == 0.0 {
                continue;
            }
            for (k, &s) in slots.iter().enumerate() {
                if w[k] > 0.0 {
                    let m = contact.normal * (depth * w[k] / norm2);
                    moves[s] += m;
                    count[s] += 1;
                    parts.push((c[1] as usize, s, m));
                }
            }
        }
        if parts.is_empty() {
            break;
        }
        for (s, m) in moves.iter().enumerate() {
            if count[s] > 0 {
                pos[s] += m / count[s] as f64;
            }
        }
        // The tool pushed each node by its mean move; it feels the opposite.
        for (tool, s, m) in parts {
            forces[tool].force -= mass[s] * (m / count[s] as f64) * inv_h2;
        }
    }
    let moved: Vec<usize> = (0..nodes.len())
        .filter(|&s| pos[s] != original[s])
        .collect();
    if !moved.is_empty() {
        let ids: Vec<u32> = moved.iter().map(|&s| nodes[s]).collect();
        let to: Vec<[f64; 3]> = moved.iter().map(|&s| pos[s].coords.into()).collect();
        sim.correct_positions(&ids, &to)?;
    }
    Ok(forces)
}

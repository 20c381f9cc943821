//! Contact response between steps: the surface triangles a tool penetrates are pushed out of
//! it by position correction (which the integrator turns into velocity), and the reaction force
//! on each tool is what it took: `-sum m_i dx_i / dt^2` over the moved nodes, in newtons, for
//! force feedback.
//!
//! Per call: the tools' swept bounds (widened by the contact skin) go through the broad phase
//! ([`Simulation::cull_tools`], on the device for the GPU engine), only the candidate
//! triangles' nodes are read back, the narrow phase ([`crate::collide::narrow::tool_triangle`]) gives
//! each penetrating triangle its depth, normal and deepest point, and the triangle is moved
//! along the normal by the depth, spread over its free corners by their barycentric weights at
//! that point (the smallest such move). Nodes shared by several contacts take the mean of their
//! moves; a few such sweeps settle neighbouring contacts. Fixed nodes never move, and neither
//! do nodes held by a grasper ([`resolve_contacts_excluding`]): the grasp owns them.
//!
//! Friction (Coulomb, coefficient [`ContactSettings::friction`]) is position-based, node by
//! node, after each sweep's normal moves: a node a tool has just pushed by `dn` slips, over
//! the step, by its motion (from where it began the step, [`Simulation::node_start_positions`],
//! to where it is now) less the motion of the tool's surface there (the tool's material point
//! now at the node, from the previous pose to the current one), without its part along `dn`.
//! When that tangential slip is at most `friction * |dn|` the node sticks and the whole slip
//! is cancelled; otherwise it slides and `friction * |dn|` of it is cancelled. Friction moves
//! count in the reaction force like normal ones ([`ToolForce::friction`] is their part), so
//! node by node the tangential force is at most `friction` times the normal force.
//!
//! With [`ContactSettings::in_solve`], under backward Euler on a CPU engine
//! ([`Simulation::takes_contact_constraints`]), contact also enters the solve: every free node a tool pushed is held, at the next step, on the plane
//! through where the correction left it, normal to the push
//! ([`crate::physics::NodeConstraint`], Baraff and Witkin's filtering), and so is a node held
//! at the step just taken whose constraint pushed (a positive force) while it is still among
//! the tool's candidates; a node whose constraint would have had to pull is let go. The force
//! on each tool is then read from the solve: minus the sum of its constraints' normal forces
//! over the step just taken (the filtered residual), plus friction's as above; the normal
//! corrections themselves (a node reaching the tool between steps) count for nothing. An
//! implicit step otherwise relaxes the whole tissue back into the tool within the step, so a
//! correction after it reads a fraction of the held force (0.011 N against 0.069 N on the probe
//! press). The constraints' tags are indices into the `tools` given: call with the same tools
//! in the same order at every step.
//!
//! Friction is taken per node rather than per triangle because a triangle's contact point is
//! pinned by moving its corners by their barycentric shares: cancelling its slip every step
//! that way drags the corner nearest the contact ahead of the tool and leaves the others
//! behind (the node under a sphere went 11% further than the sphere in a stuck drag).

use nalgebra::{Point3, Vector3};

use crate::collide::broad::ToolBox;
use crate::collide::narrow::tool_triangle;
use crate::collide::tool::Tool;
use crate::engine::Simulation;
use crate::error::{Error, Result};
use crate::physics::NodeConstraint;

/// How contacts are resolved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactSettings {
    /// Nodes are pushed this far clear of the tool, m, so that a resting contact is found
    /// again at the next step instead of flickering.
    pub skin: f64,
    /// Sweeps over the contacts per call.
    pub iterations: usize,
    /// Coulomb friction coefficient between tools and tissue (0: frictionless, the default).
    pub friction: f64,
    /// Under backward Euler on a CPU engine, hold the pushed nodes on the tools inside the
    /// implicit solve and read the tools' forces from those constraints (see the module
    /// documentation); ignored by explicit schemes and the GPU engine. Off by default: a world
    /// coupled to a haptic device does not yet settle with it (its proxy keeps drifting along
    /// the surface), so the world's contact keeps correcting positions.
    pub in_solve: bool,
}

impl Default for ContactSettings {
    fn default() -> Self {
        ContactSettings {
            skin: 1e-5,
            iterations: 8,
            friction: 0.0,
            in_solve: false,
        }
    }
}

/// What a tool felt in one call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolForce {
    /// Reaction force on the tool, N (scene frame): it points away from the tissue it presses.
    /// Friction included.
    pub force: Vector3<f64>,
    /// The part of `force` from friction, N (zero when frictionless): it opposes the tool's
    /// slip over the tissue.
    pub friction: Vector3<f64>,
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

/// The friction move of a node that `tool` has just pushed by `normal` (its normal correction
/// in this sweep), now at `at`, which began the step at `start`: its slip over the step
/// against the tool's surface there (where the tool's material point now at `at` was at the
/// previous pose), without its part along `normal`, is cancelled whole when it is at most
/// `mu |normal|` (sticking) and by `mu |normal|` otherwise (sliding).
fn friction_move(
    tool: &Tool,
    at: &Point3<f64>,
    start: &Point3<f64>,
    normal: &Vector3<f64>,
    mu: f64,
) -> Vector3<f64> {
    let Some(n) = normal.try_normalize(0.0) else {
        return Vector3::zeros();
    };
    // The node's motion over the step, `at - start`, less the tool's there, `at - tool_was`.
    let tool_was = tool.previous_pose() * tool.pose().inverse_transform_point(at);
    let slip = tool_was - start;
    let tangential = slip - n * n.dot(&slip);
    let (length, limit) = (tangential.norm(), mu * normal.norm());
    if length <= limit {
        -tangential
    } else {
        -tangential * (limit / length)
    }
}

/// Resolve the contacts of `tools` (at their current poses, swept from their previous ones)
/// with the surface given to [`Simulation::set_surface`], and return the force on each tool.
pub fn resolve_contacts(
    sim: &mut Simulation,
    tools: &[Tool],
    settings: &ContactSettings,
) -> Result<Vec<ToolForce>> {
    resolve_contacts_excluding(sim, tools, settings, &[])
}

/// [`resolve_contacts`], leaving the nodes `held` (model indices, any order) where they are:
/// nodes a grasper holds ([`crate::contact::grasp::Grasp::nodes`]) are placed by the grasp, not pushed
/// by contacts. Like fixed nodes they take no share of a contact's move.
pub fn resolve_contacts_excluding(
    sim: &mut Simulation,
    tools: &[Tool],
    settings: &ContactSettings,
    held: &[u32],
) -> Result<Vec<ToolForce>> {
    if !(settings.friction.is_finite() && settings.friction >= 0.0) {
        return Err(Error::Options(format!(
            "contact friction must be zero or positive and finite, got {}",
            settings.friction
        )));
    }
    let mut forces = vec![
        ToolForce {
            force: Vector3::zeros(),
            friction: Vector3::zeros(),
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
    // In the solve: the forces of the constraints held over the step just taken.
    let in_solve = settings.in_solve && sim.takes_contact_constraints();
    if !in_solve && !sim.contact_constraints().is_empty() {
        sim.set_contact_constraints(&[])?;
    }
    let was_held: Vec<(NodeConstraint, f64)> = if in_solve {
        let held: Vec<(NodeConstraint, f64)> = sim
            .contact_constraints()
            .iter()
            .copied()
            .zip(sim.contact_constraint_forces())
            .collect();
        for (c, f) in &held {
            if let Some(t) = forces.get_mut(c.tag as usize) {
                t.force -= Vector3::from(c.normal) * *f;
            }
        }
        held
    } else {
        Vec::new()
    };
    let candidates = sim.cull_tools(&boxes)?;
    if candidates.is_empty() {
        if in_solve && !was_held.is_empty() {
            sim.set_contact_constraints(&[])?;
        }
        return Ok(forces);
    }
    let surface = sim
        .surface()
        .ok_or_else(|| Error::NoSurface("no surface: call set_surface first".into()))?;
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
    // Where each node began the step (friction measures slip from there).
    let start: Vec<Point3<f64>> = if settings.friction > 0.0 {
        sim.node_start_positions(&nodes)?
            .into_iter()
            .map(Point3::from)
            .collect()
    } else {
        Vec::new()
    };
    let mut pos = original.clone();
    let model = sim.model();
    let mut held = held.to_vec();
    held.sort_unstable();
    let free: Vec<bool> = nodes
        .iter()
        .map(|&n| !model.fixed[n as usize] && held.binary_search(&n).is_err())
        .collect();
    let mass: Vec<f64> = nodes.iter().map(|&n| model.mass[n as usize]).collect();
    let inv_h2 = 1.0 / (sim.config().dt * sim.config().dt);
    // Per node slot, each tool's normal pushes over the sweeps (for the constraints).
    let mut pushes: Vec<(usize, usize, Vector3<f64>)> = Vec::new();
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
        // The tool pushed each node by its mean move; it feels the opposite (in the solve, it
        // feels the constraints instead).
        for &(tool, s, m) in &parts {
            if in_solve {
                pushes.push((s, tool, m / count[s] as f64));
            } else {
                forces[tool].force -= mass[s] * (m / count[s] as f64) * inv_h2;
            }
        }
        if settings.friction > 0.0 {
            // Each tool's share of each node's normal move in this sweep.
            let mut pushed: Vec<(usize, usize, Vector3<f64>)> = parts
                .iter()
                .map(|&(tool, s, m)| (s, tool, m / count[s] as f64))
                .collect();
            pushed.sort_unstable_by_key(|&(s, tool, _)| (s, tool));
            for group in pushed.chunk_by(|a, b| (a.0, a.1) == (b.0, b.1)) {
                let (s, t) = (group[0].0, group[0].1);
                let normal: Vector3<f64> = group.iter().map(|g| g.2).sum();
                let step = friction_move(&tools[t], &pos[s], &start[s], &normal, settings.friction);
                pos[s] += step;
                let f = -mass[s] * step * inv_h2;
                forces[t].force += f;
                forces[t].friction += f;
            }
        }
    }
    if in_solve {
        let held = hold_next(&nodes, &free, &pos, pushes, &was_held);
        sim.set_contact_constraints(&held)?;
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

/// The constraints for the next implicit step: each free node pushed in this call (`pushes`:
/// node slot, tool, normal move), by the tool that pushed it most, on the plane through its
/// corrected position `pos` normal to that tool's pushes; and each node held over the last step
/// (`was_held`, with its constraint's force) that was not pushed now, is still among the
/// candidates' free nodes and was pushed by its constraint, where it is now.
///
/// The planes are where the triangle correction left the nodes: a tool touching a triangle's
/// middle moves its corners by the full depth (the smallest move of the triangle), and a node
/// held on a tilted plane may slide along it away from a curved tool without being found again.
/// Both hold the tissue a little deeper than the tool's own surface: the probe press reads 9%
/// more than explicitly, where nodes relax between corrections.
fn hold_next(
    nodes: &[u32],
    free: &[bool],
    pos: &[Point3<f64>],
    mut pushes: Vec<(usize, usize, Vector3<f64>)>,
    was_held: &[(NodeConstraint, f64)],
) -> Vec<NodeConstraint> {
    pushes.sort_unstable_by_key(|&(s, tool, _)| (s, tool));
    let mut held: Vec<NodeConstraint> = Vec::new();
    for node in pushes.chunk_by(|a, b| a.0 == b.0) {
        let s = node[0].0;
        let strongest = node
            .chunk_by(|a, b| a.1 == b.1)
            .map(|by_tool| {
                (
                    by_tool[0].1,
                    by_tool.iter().map(|p| p.2).sum::<Vector3<f64>>(),
                )
            })
            .max_by(|a, b| a.1.norm().total_cmp(&b.1.norm()));
        let Some((tool, push)) = strongest else {
            continue;
        };
        let Some(n) = push.try_normalize(0.0) else {
            continue;
        };
        held.push(NodeConstraint {
            node: nodes[s],
            normal: n.into(),
            offset: n.dot(&pos[s].coords),
            tag: tool as u32,
        });
    }
    for (c, force) in was_held {
        let Ok(s) = nodes.binary_search(&c.node) else {
            continue;
        };
        let pushed = pushes.binary_search_by_key(&s, |p| p.0).is_ok();
        if *force <= 0.0 || !free[s] || pushed {
            continue;
        }
        let n = Vector3::from(c.normal);
        held.push(NodeConstraint {
            offset: n.dot(&pos[s].coords),
            ..*c
        });
    }
    held
}

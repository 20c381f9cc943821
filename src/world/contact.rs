//! The contact part of a world step (stages 7 and 8 of [`super`]): graspers close, hold and
//! release, tissue is pushed out of the tools that do not cut, and the tissue's surfaces are
//! separated from each other. Without the `collide` feature there is no narrow phase: a world
//! with a tool that pushes says so at its first step.

use nalgebra::Vector3;

use super::step::{SelfContactStep, ToolStep};
use crate::collide::Tool;
use crate::engine::Simulation;
use crate::error::Result;

#[cfg(feature = "collide")]
use crate::contact::{
    grasp::Grasp,
    response::{resolve_contacts_excluding, ContactSettings},
    self_response::{resolve_self_contacts, SelfContactSettings},
};

/// What a grasper does at the next step.
#[cfg(feature = "collide")]
#[derive(Debug, Clone, Default)]
enum GraspSlot {
    /// Open.
    #[default]
    Open,
    /// Asked to close, capturing nodes within this reach (m), after the next step.
    Closing(f64),
    /// Closed on these nodes.
    Held(Grasp),
}

/// The contact settings, each tool's grasp and the self-contact settings.
#[cfg(feature = "collide")]
#[derive(Debug, Clone, Default)]
pub(super) struct ContactPhase {
    pub(super) settings: ContactSettings,
    pub(super) self_contact: Option<SelfContactSettings>,
    grasps: Vec<GraspSlot>,
}

/// Without the narrow phase: tools that cut, nothing that pushes.
#[cfg(not(feature = "collide"))]
#[derive(Debug, Clone, Default)]
pub(super) struct ContactPhase;

/// A tool's report before contact: nothing felt, nothing held.
fn quiet() -> ToolStep {
    ToolStep {
        force: Vector3::zeros(),
        friction: Vector3::zeros(),
        contacts: 0,
        deepest: 0.0,
        held: 0,
        carried: 0.0,
        cuts: false,
        rendered: None,
        proxy: None,
    }
}

#[cfg(feature = "collide")]
impl ContactPhase {
    /// Make room for one more tool (open).
    pub(super) fn add_tool(&mut self) {
        self.grasps.push(GraspSlot::Open);
    }

    /// Close grasper `i` at the next step, capturing within `reach`; nothing if it is closed.
    pub(super) fn grasp(&mut self, i: usize, reach: f64) {
        if !matches!(self.grasps[i], GraspSlot::Held(_)) {
            self.grasps[i] = GraspSlot::Closing(reach);
        }
    }

    /// Open grasper `i` now (its nodes go back to the springs).
    pub(super) fn release(&mut self, i: usize) {
        self.grasps[i] = GraspSlot::Open;
    }

    /// Whether grasper `i` is closed or closing.
    pub(super) fn grasping(&self, i: usize) -> bool {
        !matches!(self.grasps[i], GraspSlot::Open)
    }

    /// The nodes tool `i` holds (empty when open).
    pub(super) fn held(&self, i: usize) -> &[u32] {
        match &self.grasps[i] {
            GraspSlot::Held(g) => g.nodes(),
            _ => &[],
        }
    }

    /// After the step and the cuts: close, hold and release the graspers, push the tissue out
    /// of the tools that do not (`cuts[i]`), separate self-contacts. One report per tool.
    pub(super) fn after_step(
        &mut self,
        sim: &mut Simulation,
        tools: &[Tool],
        cuts: &[bool],
    ) -> Result<(Vec<ToolStep>, Option<SelfContactStep>)> {
        let mut reports: Vec<ToolStep> = cuts
            .iter()
            .map(|&c| ToolStep { cuts: c, ..quiet() })
            .collect();
        let mut held: Vec<u32> = Vec::new();
        for (k, tool) in tools.iter().enumerate() {
            if let GraspSlot::Closing(reach) = self.grasps[k] {
                self.grasps[k] = GraspSlot::Held(Grasp::close(sim, tool, reach)?);
            }
            let GraspSlot::Held(grasp) = &self.grasps[k] else {
                continue;
            };
            grasp.hold(sim, tool)?;
            reports[k].held = grasp.nodes().len();
            if !grasp.nodes().is_empty() {
                let rest = &sim.model().rest;
                let targets = grasp.targets(tool);
                let carried = grasp
                    .nodes()
                    .iter()
                    .zip(&targets)
                    .map(|(&n, p)| {
                        let r = rest[n as usize];
                        ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2) + (p[2] - r[2]).powi(2))
                            .sqrt()
                    })
                    .sum::<f64>()
                    / targets.len() as f64;
                reports[k].carried = carried;
            }
            held.extend_from_slice(grasp.nodes());
        }
        // Cutting blades pass through the tissue; the other tools push it.
        let pushing: Vec<usize> = (0..tools.len()).filter(|&i| !cuts[i]).collect();
        let forces = if pushing.len() == tools.len() {
            resolve_contacts_excluding(sim, tools, &self.settings, &held)?
        } else {
            let some: Vec<Tool> = pushing.iter().map(|&i| tools[i].clone()).collect();
            resolve_contacts_excluding(sim, &some, &self.settings, &held)?
        };
        for (&i, f) in pushing.iter().zip(forces) {
            let r = &mut reports[i];
            r.force = f.force;
            r.friction = f.friction;
            r.contacts = f.contacts;
            r.deepest = f.deepest;
        }
        let self_contact = match &self.self_contact {
            Some(settings) => {
                let r = resolve_self_contacts(sim, settings)?;
                Some(SelfContactStep {
                    vertex_face: r.vertex_face,
                    edge_edge: r.edge_edge,
                    deepest: r.deepest,
                })
            }
            None => None,
        };
        Ok((reports, self_contact))
    }
}

#[cfg(not(feature = "collide"))]
impl ContactPhase {
    /// Nothing to keep per tool.
    pub(super) fn add_tool(&mut self) {}

    /// Refused when a tool pushes (it needs the narrow phase); nothing otherwise.
    pub(super) fn after_step(
        &mut self,
        _: &mut Simulation,
        tools: &[Tool],
        cuts: &[bool],
    ) -> Result<(Vec<ToolStep>, Option<SelfContactStep>)> {
        if cuts.iter().any(|&c| !c) {
            return Err(crate::Error::Unsupported(
                "this world has a tool that pushes the tissue but this build has no collision \
                 handling (enable the `collide` cargo feature)"
                    .into(),
            ));
        }
        let reports = tools.iter().map(|_| ToolStep {
            cuts: true,
            ..quiet()
        });
        Ok((reports.collect(), None))
    }
}

#[cfg(feature = "collide")]
impl super::World {
    /// Close grasper `handle` on the tissue after the next step: it captures the surface nodes
    /// between its jaws, within `reach` (m) of the space between their inner faces (the jaw's
    /// half-thickness is a good reach), and carries them at every step until
    /// [`World::release`](super::World::release). Nothing if it is already closed; refused for
    /// a tool that is not a grasper.
    pub fn grasp(&mut self, handle: super::ToolHandle, reach: f64) -> Result<()> {
        let i = self.check_handle(handle)?;
        if !matches!(
            self.tools[i].shape,
            crate::collide::ToolShape::Grasper { .. }
        ) {
            return Err(crate::Error::Options(format!(
                "tool `{}` cannot grasp: only a Grasper grasps",
                self.names[i]
            )));
        }
        if !(reach.is_finite() && reach >= 0.0) {
            return Err(crate::Error::Options(format!(
                "grasp reach must be zero or positive and finite, got {reach}"
            )));
        }
        self.contact.grasp(i, reach);
        Ok(())
    }

    /// Open grasper `handle` now: what it held goes back to the springs.
    pub fn release(&mut self, handle: super::ToolHandle) -> Result<()> {
        let i = self.check_handle(handle)?;
        self.contact.release(i);
        Ok(())
    }

    /// Whether grasper `handle` is closed (or will close at the next step).
    pub fn is_grasping(&self, handle: super::ToolHandle) -> bool {
        self.contact.grasping(handle.0)
    }

    /// The nodes grasper `handle` holds (model indices; empty when open).
    pub fn held_nodes(&self, handle: super::ToolHandle) -> &[u32] {
        self.contact.held(handle.0)
    }

    /// How tool contacts are resolved (skin, sweeps, friction).
    pub fn set_contact_settings(&mut self, settings: ContactSettings) {
        self.contact.settings = settings;
    }

    /// The contact settings.
    pub fn contact_settings(&self) -> &ContactSettings {
        &self.contact.settings
    }

    /// Separate the tissue's surfaces from each other at every step, under `settings`
    /// (`None`: no more).
    pub fn set_self_contact(&mut self, settings: Option<SelfContactSettings>) -> Result<()> {
        if settings.is_some() {
            self.give_surface()?;
        }
        self.contact.self_contact = settings;
        Ok(())
    }
}

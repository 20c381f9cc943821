//! Tools in a scene run: each step the tools take their poses from their trajectories, the
//! simulation steps, graspers whose grasp window has begun close on the tissue between their
//! jaws (and let go when it ends) and carry what they hold, and penetrating tissue is pushed
//! out of the tools ([`crate::contact::response::resolve_contacts_excluding`], held nodes left
//! to their grasp); what each tool felt is kept for the summary and the `ToolForce` and
//! `GraspCarried` expectations.

use super::expect::ToolReport;
use super::schema::Scene;
use crate::engine::Simulation;
use crate::error::Result;
use crate::mesh::TetMesh;

#[cfg(feature = "collide")]
use crate::collide::{broad::Surface, Tool, ToolShape};
#[cfg(feature = "collide")]
use crate::contact::{
    grasp::Grasp,
    response::{resolve_contacts_excluding, ContactSettings},
    self_response::{resolve_self_contacts, SelfContactSettings},
};

/// The tools of a running scene.
#[cfg(feature = "collide")]
pub struct ToolStage {
    tools: Vec<Tool>,
    scene_tools: Vec<super::schema::SceneTool>,
    /// What each tool holds now (graspers inside a grasp window).
    grasps: Vec<Option<Grasp>>,
    settings: ContactSettings,
    /// What each tool felt so far.
    pub reports: Vec<ToolReport>,
    /// Cutting, for scenes with a `cut` section: its blades cut instead of pushing.
    pub cut: Option<super::cuts::CutStage>,
    /// Self-contact, for scenes with a `self_contact` section.
    self_contact: Option<SelfContactSettings>,
    /// Steps at which surfaces of the tissue touched each other.
    pub self_contact_steps: u64,
    /// Deepest self-penetration found before it was resolved, m.
    pub self_contact_deepest: f64,
}

#[cfg(feature = "collide")]
impl ToolStage {
    /// The stage for `scene`'s tools (`None` when it has none), with the mesh's boundary given
    /// to the simulation for culling.
    pub fn new(scene: &Scene, mesh: &TetMesh, sim: &mut Simulation) -> Result<Option<Self>> {
        if scene.tools.is_empty() && scene.self_contact.is_none() {
            return Ok(None);
        }
        sim.set_surface(Surface::of(mesh).triangles)?;
        let t0 = sim.time();
        let tools = scene
            .tools
            .iter()
            .map(|t| Tool::new(t.shape, t.trajectory.pose_at(t0)))
            .collect::<Result<Vec<_>>>()?;
        Ok(Some(ToolStage {
            tools,
            scene_tools: scene.tools.clone(),
            grasps: vec![None; scene.tools.len()],
            settings: ContactSettings::default(),
            reports: scene
                .tools
                .iter()
                .map(|t| ToolReport {
                    name: t.name.clone(),
                    max_force: 0.0,
                    final_force: [0.0; 3],
                    max_depth: 0.0,
                    contact_steps: 0,
                    max_held: 0,
                    max_carried: 0.0,
                })
                .collect(),
            cut: None,
            self_contact: scene.self_contact.map(|s| SelfContactSettings {
                thickness: s.thickness,
                max_depth: s.max_depth,
                iterations: s.iterations,
            }),
            self_contact_steps: 0,
            self_contact_deepest: 0.0,
        }))
    }

    /// The tools at their current poses, in the scene's order.
    pub fn tools(&self) -> &[Tool] {
        &self.tools
    }

    /// Pose the tools for the end of the next step, step once (with the divergence check),
    /// close, hold or release the graspers by their grasp windows, and resolve the contacts
    /// of the nodes no grasper holds.
    pub fn step(&mut self, sim: &mut Simulation) -> Result<()> {
        let t = sim.time() + sim.config().dt;
        for (tool, scene_tool) in self.tools.iter_mut().zip(&self.scene_tools) {
            tool.set_pose(scene_tool.trajectory.pose_at(t));
        }
        if let Some(cut) = &self.cut {
            cut.before_step(sim, &self.tools);
        }
        sim.run(1)?;
        if let Some(cut) = self.cut.as_mut() {
            cut.after_step(sim, &self.tools)?;
        }
        let mut held: Vec<u32> = Vec::new();
        for (k, (tool, scene_tool)) in self.tools.iter().zip(&self.scene_tools).enumerate() {
            let window = scene_tool.grasp_at(t);
            match (window, &self.grasps[k]) {
                (Some(w), None) => {
                    let reach = match (w.reach, tool.shape) {
                        (Some(r), _) => r,
                        (None, ToolShape::Grasper { jaw, .. }) => jaw[0],
                        (None, _) => 0.0,
                    };
                    self.grasps[k] = Some(Grasp::close(sim, tool, reach)?);
                }
                (None, Some(_)) => self.grasps[k] = None,
                _ => {}
            }
            if let Some(grasp) = &self.grasps[k] {
                grasp.hold(sim, tool)?;
                let report = &mut self.reports[k];
                report.max_held = report.max_held.max(grasp.nodes().len());
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
                    report.max_carried = report.max_carried.max(carried);
                }
                held.extend_from_slice(grasp.nodes());
            }
        }
        // Cutting blades pass through the tissue; the other tools push it.
        let pushing: Vec<usize> = (0..self.tools.len())
            .filter(|&i| !self.cut.as_ref().is_some_and(|c| c.cuts_with(i)))
            .collect();
        let forces = if pushing.len() == self.tools.len() {
            resolve_contacts_excluding(sim, &self.tools, &self.settings, &held)?
        } else {
            let tools: Vec<Tool> = pushing.iter().map(|&i| self.tools[i].clone()).collect();
            resolve_contacts_excluding(sim, &tools, &self.settings, &held)?
        };
        for (&i, f) in pushing.iter().zip(forces) {
            let r = &mut self.reports[i];
            r.max_force = r.max_force.max(f.force.norm());
            r.final_force = f.force.into();
            r.max_depth = r.max_depth.max(f.deepest);
            r.contact_steps += u64::from(f.contacts > 0);
        }
        if let Some(settings) = &self.self_contact {
            let r = resolve_self_contacts(sim, settings)?;
            self.self_contact_steps += u64::from(r.vertex_face + r.edge_edge > 0);
            self.self_contact_deepest = self.self_contact_deepest.max(r.deepest);
        }
        Ok(())
    }
}

/// Without the `collide` feature a scene with tools cannot run; say so.
#[cfg(not(feature = "collide"))]
pub struct ToolStage {
    /// Never filled.
    pub reports: Vec<ToolReport>,
    /// Never made.
    pub cut: Option<super::cuts::CutStage>,
    /// Never counted.
    pub self_contact_steps: u64,
    /// Never measured.
    pub self_contact_deepest: f64,
}

#[cfg(not(feature = "collide"))]
impl ToolStage {
    /// `None` for a scene without tools; an error otherwise.
    pub fn new(scene: &Scene, _: &TetMesh, _: &mut Simulation) -> Result<Option<Self>> {
        if scene.tools.is_empty() && scene.self_contact.is_none() {
            return Ok(None);
        }
        Err(crate::Error::Unsupported(
            "this scene has tools but this build has no collision handling (enable the \
             `collide` cargo feature)"
                .into(),
        ))
    }

    /// Unreachable: no stage is ever made.
    pub fn tools(&self) -> &[crate::collide::Tool] {
        &[]
    }

    /// Unreachable: no stage is ever made.
    pub fn step(&mut self, _: &mut Simulation) -> Result<()> {
        Ok(())
    }
}

//! Tools in a scene run: each step the tools take their poses from their trajectories, the
//! simulation steps, and penetrating tissue is pushed out of them
//! ([`crate::collide::response::resolve_contacts`]); what each tool felt is kept for the
//! summary and the `ToolForce` expectation.

use super::expect::ToolReport;
use super::schema::Scene;
use crate::engine::Simulation;
use crate::error::Result;
use crate::mesh::TetMesh;

#[cfg(feature = "collide")]
use crate::collide::{
    broad::Surface,
    response::{resolve_contacts, ContactSettings},
    Tool, Trajectory,
};

/// The tools of a running scene.
#[cfg(feature = "collide")]
pub struct ToolStage {
    tools: Vec<Tool>,
    trajectories: Vec<Trajectory>,
    settings: ContactSettings,
    /// What each tool felt so far.
    pub reports: Vec<ToolReport>,
    /// Cutting, for scenes with a `cut` section: its blades cut instead of pushing.
    pub cut: Option<super::cuts::CutStage>,
}

#[cfg(feature = "collide")]
impl ToolStage {
    /// The stage for `scene`'s tools (`None` when it has none), with the mesh's boundary given
    /// to the simulation for culling.
    pub fn new(scene: &Scene, mesh: &TetMesh, sim: &mut Simulation) -> Result<Option<Self>> {
        if scene.tools.is_empty() {
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
            trajectories: scene.tools.iter().map(|t| t.trajectory.clone()).collect(),
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
                })
                .collect(),
            cut: None,
        }))
    }

    /// Pose the tools for the end of the next step, step once (with the divergence check) and
    /// resolve the contacts.
    pub fn step(&mut self, sim: &mut Simulation) -> Result<()> {
        let t = sim.time() + sim.config().dt;
        for (tool, trajectory) in self.tools.iter_mut().zip(&self.trajectories) {
            tool.set_pose(trajectory.pose_at(t));
        }
        sim.run(1)?;
        if let Some(cut) = self.cut.as_mut() {
            cut.after_step(sim, &self.tools)?;
        }
        // Cutting blades pass through the tissue; the other tools push it.
        let pushing: Vec<usize> = (0..self.tools.len())
            .filter(|&i| !self.cut.as_ref().is_some_and(|c| c.cuts_with(i)))
            .collect();
        let tools: Vec<Tool> = pushing.iter().map(|&i| self.tools[i].clone()).collect();
        let forces = resolve_contacts(sim, &tools, &self.settings)?;
        for (&i, f) in pushing.iter().zip(forces) {
            let r = &mut self.reports[i];
            r.max_force = r.max_force.max(f.force.norm());
            r.final_force = f.force.into();
            r.max_depth = r.max_depth.max(f.deepest);
            r.contact_steps += u64::from(f.contacts > 0);
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
}

#[cfg(not(feature = "collide"))]
impl ToolStage {
    /// `None` for a scene without tools; an error otherwise.
    pub fn new(scene: &Scene, _: &TetMesh, _: &mut Simulation) -> Result<Option<Self>> {
        if scene.tools.is_empty() {
            return Ok(None);
        }
        Err(crate::Error::Unsupported(
            "this scene has tools but this build has no collision handling (enable the \
             `collide` cargo feature)"
                .into(),
        ))
    }

    /// Unreachable: no stage is ever made.
    pub fn step(&mut self, _: &mut Simulation) -> Result<()> {
        Ok(())
    }
}

//! The scene's side of a run: each step the tools take their poses from their trajectories and
//! graspers close and open by their grasp windows, then the [`World`] steps; what each tool felt
//! is kept for the summary and the `ToolForce` and `GraspCarried` expectations.

use super::expect::ToolReport;
use super::schema::{Scene, SceneTool};
use crate::error::Result;
use crate::world::{StepReport, World};

/// Drives a [`World`] made by [`World::from_scene`] through the scene's trajectories and grasp
/// windows, and keeps what the tools felt.
pub struct SceneDriver {
    tools: Vec<SceneTool>,
    /// What each tool felt so far.
    pub reports: Vec<ToolReport>,
    /// Steps at which surfaces of the tissue touched each other.
    pub self_contact_steps: u64,
    /// Deepest self-penetration found before it was resolved, m.
    pub self_contact_deepest: f64,
}

impl SceneDriver {
    /// The driver of `scene`'s tools (added to the world in the scene's order).
    pub fn new(scene: &Scene) -> Self {
        SceneDriver {
            tools: scene.tools.clone(),
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
            self_contact_steps: 0,
            self_contact_deepest: 0.0,
        }
    }

    /// Pose the tools for the end of the next step, close or open the graspers whose grasp
    /// window begins or ends then, and step the world.
    pub fn step(&mut self, world: &mut World) -> Result<StepReport> {
        let t = world.sim().time() + world.sim().config().dt;
        for (k, scene_tool) in self.tools.iter().enumerate() {
            let handle = world.tool_handle(k).ok_or_else(|| {
                crate::Error::Options(format!(
                    "the world has no tool {k} (`{}`): make it with World::from_scene",
                    scene_tool.name
                ))
            })?;
            world.set_tool_pose(handle, scene_tool.trajectory.pose_at(t))?;
            #[cfg(feature = "collide")]
            match (scene_tool.grasp_at(t), world.is_grasping(handle)) {
                (Some(w), false) => {
                    let reach = match (w.reach, scene_tool.shape) {
                        (Some(r), _) => r,
                        (None, crate::collide::ToolShape::Grasper { jaw, .. }) => jaw[0],
                        (None, _) => 0.0,
                    };
                    world.grasp(handle, reach)?;
                }
                (None, true) => world.release(handle)?,
                _ => {}
            }
        }
        let step = world.step()?;
        for (r, s) in self.reports.iter_mut().zip(&step.tools) {
            r.max_held = r.max_held.max(s.held);
            r.max_carried = r.max_carried.max(s.carried);
            if !s.cuts {
                r.max_force = r.max_force.max(s.force.norm());
                r.final_force = s.force.into();
                r.max_depth = r.max_depth.max(s.deepest);
                r.contact_steps += u64::from(s.contacts > 0);
            }
        }
        if let Some(s) = &step.self_contact {
            self.self_contact_steps += u64::from(s.vertex_face + s.edge_edge > 0);
            self.self_contact_deepest = self.self_contact_deepest.max(s.deepest);
        }
        Ok(step)
    }
}

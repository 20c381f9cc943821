//! A grasper holding tissue: closing it captures the surface nodes between its jaws (their
//! positions in the tool frame are kept), every step while closed they are moved with the tool
//! by position correction, and opening it releases them to the springs.

use nalgebra::Point3;

use crate::collide::broad::ToolBox;
use crate::collide::tool::{Tool, ToolShape};
use crate::engine::Simulation;
use crate::error::{Error, Result};

/// Nodes held by a closed grasper, with their positions in its frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Grasp {
    nodes: Vec<u32>,
    local: Vec<Point3<f64>>,
}

impl Grasp {
    /// Close `tool` (a grasper) on the tissue: capture the surface nodes (of the surface given
    /// to [`Simulation::set_surface`]) that lie between its jaws, within `reach` (m) of the
    /// space between their inner faces. Fixed nodes are not captured.
    pub fn close(sim: &mut Simulation, tool: &Tool, reach: f64) -> Result<Grasp> {
        let ToolShape::Grasper { jaw, opening } = tool.shape else {
            return Err(Error::Model(
                "only a grasper can grasp; this tool is another shape".into(),
            ));
        };
        let half = [0.5 * opening + reach, jaw[1] + reach, jaw[2] + reach];
        let centre = Point3::new(0.0, 0.0, jaw[2]);
        let inside = |p: &Point3<f64>| {
            let q = tool.pose().inverse_transform_point(p) - centre;
            (0..3).all(|k| q[k].abs() <= half[k])
        };
        let b = tool.aabb(tool.pose(), reach);
        let boxes = [ToolBox::containing(
            b.min.coords.into(),
            b.max.coords.into(),
        )];
        let candidates = sim.cull_tools(&boxes)?;
        let surface = sim
            .surface()
            .ok_or_else(|| Error::NoSurface("no surface: call set_surface first".into()))?;
        let mut nodes: Vec<u32> = candidates
            .iter()
            .flat_map(|c| surface[c[0] as usize])
            .filter(|&n| !sim.model().fixed[n as usize])
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        let positions = sim.node_positions(&nodes)?;
        let (mut held, mut local) = (Vec::new(), Vec::new());
        for (n, p) in nodes.into_iter().zip(positions) {
            let p = Point3::from(p);
            if inside(&p) {
                held.push(n);
                local.push(tool.pose().inverse_transform_point(&p));
            }
        }
        Ok(Grasp { nodes: held, local })
    }

    /// The held nodes (model indices).
    pub fn nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// Where the held nodes belong with the tool at its current pose, m (in the order of
    /// [`Grasp::nodes`]).
    pub fn targets(&self, tool: &Tool) -> Vec<[f64; 3]> {
        self.local
            .iter()
            .map(|p| tool.pose().transform_point(p).coords.into())
            .collect()
    }

    /// Move the held nodes with the tool at its current pose (call once per step, after the
    /// step, while the grasper stays closed). Contacts should leave them alone
    /// ([`crate::contact::response::resolve_contacts_excluding`] with [`Grasp::nodes`]).
    pub fn hold(&self, sim: &mut Simulation, tool: &Tool) -> Result<()> {
        sim.correct_positions(&self.nodes, &self.targets(tool))
    }
}

//! One simulated world: the tissue (mesh, model and [`Simulation`]), the tools in it, the
//! cutting, the contacts and the grasps, stepped together by [`World::step`]. The scene runner
//! ([`crate::scene::run_scene`]) drives a `World` from a scene's trajectories and grasp windows;
//! an embedding program drives the same `World` from a haptic device, so both run the same
//! step.
//!
//! ```
//! use lancet::collide::ToolShape;
//! use lancet::mesh::generate::BoxGrid;
//! use lancet::world::WorldBuilder;
//! use lancet::{Material, ModelConfig, SimConfig};
//! use nalgebra::{Isometry3, Vector3};
//!
//! // A 2 cm cube of soft tissue, stepped at half the stable step.
//! let mesh = BoxGrid::cube_cells([2, 2, 2], 0.01).build().unwrap();
//! let model = ModelConfig::new(Material::elastic(2e4, 0.3, 1000.0));
//! let mut world = WorldBuilder::new(mesh, &model, SimConfig::new(1.0))
//!     .unwrap()
//!     .bound_fraction(0.5)
//!     .unwrap()
//!     .build()
//!     .unwrap();
//! let start = Isometry3::translation(0.01, 0.01, 0.03);
//! let probe = world.add_tool("probe", ToolShape::Sphere { radius: 0.003 }, start).unwrap();
//! for k in 0..10 {
//!     // The device's pose for the end of the step: down 1 mm a step.
//!     let z = 0.03 - 1e-3 * k as f64;
//!     world.set_tool_pose(probe, Isometry3::translation(0.01, 0.01, z)).unwrap();
//!     let report = world.step().unwrap();
//!     let _force: Vector3<f64> = report.tools[probe.index()].force;
//! }
//! ```
//!
//! # The order of a step
//!
//! [`World::step`] takes one time step `h` and does, in this order:
//!
//! 1. **Pose.** Each tool takes the pose given by [`World::set_tool_pose`] since the last step
//!    (a tool given none stays where it is), and a tool held by a [`VirtualCoupling`] moves its
//!    proxy toward the device's pose. The pose is the tool's pose at the *end* of the step; the
//!    tool remembers the pose it had, so that everything below sees the whole motion of the
//!    step (a fast tool cannot jump over a thin layer of tissue).
//! 2. **Read ahead.** The sweeps of the blades that touched the tissue (or were about to) are
//!    handed to the engine, so that on the GPU the positions the cuts will read come back with
//!    the step instead of in a round trip of their own.
//! 3. **Step.** The simulation takes the step (with its divergence and inversion checks) with
//!    the tissue as the last step left it.
//! 4. **Sweep and cut.** Each cutting blade's sweep from its previous pose to its new one goes
//!    to the [`crate::cut::Cutter`], which reads the positions near it and edits the mesh.
//! 5. **Apply the patch.** A cut that changed something is given to the simulation as a
//!    [`crate::model::ModelDiff`] (only its dirty ranges are uploaded); when it lowered the
//!    stable bound below the step, the [`TimeStepPolicy`] stops, warns or lowers the step.
//! 6. **Edit the surface.** The boundary triangles the cut removed and made are changed in the
//!    simulation's surface, which the contacts below and the next cull read.
//! 7. **Grasp.** Graspers asked to close ([`World::grasp`]) capture the surface nodes between
//!    their jaws; closed ones carry their nodes to their new pose.
//! 8. **Resolve contacts.** Tissue inside a tool that does not cut is pushed out of it by
//!    position correction (held nodes are left to their grasp), which gives each tool the
//!    reaction force; then the tissue's surfaces are separated from each other
//!    (self-contact, when enabled).
//!
//! Why this order: the step comes after the poses so that the tools' motion is known for the
//! whole step, and before the cuts and contacts because both are position corrections made
//! between steps, on the state the step produced, which the integrator turns into velocity at
//! the next step. Cutting comes before contact because a cut changes the model and the surface:
//! contacts resolved first would push nodes that the cut is about to remove or split, against
//! triangles that no longer exist, and the reaction force would count them. The patch is
//! applied before the surface is edited because the surface's new triangles name the nodes the
//! patch adds. Grasps come before contacts so that the nodes a grasper holds are known and
//! left out of the contact response (the grasp owns them), and self-contact comes last so
//! that it separates the surfaces as the tools left them.

mod builder;
mod contact;
pub mod coupling;
#[cfg(feature = "cut")]
pub mod cutting;
#[cfg(feature = "scene")]
mod scene;
mod step;

pub use builder::WorldBuilder;
pub use coupling::{ProxyState, VirtualCoupling};
#[cfg(feature = "cut")]
pub use cutting::{CutEvent, CutReport, CutSettings, TimeStepPolicy};
pub use step::{SelfContactStep, StepReport, ToolStep};

use nalgebra::{Isometry3, Vector3};

use crate::collide::{Tool, ToolShape};
use crate::engine::Simulation;
use crate::error::{Error, Result};
use crate::mesh::TetMesh;
use crate::model::{PackedModel, SpringModel};
#[cfg(feature = "cut")]
use cutting::Cutting;

/// A tool in a [`World`], as [`World::add_tool`] returned it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ToolHandle(usize);

impl ToolHandle {
    /// The tool's index: its place in [`StepReport::tools`] and [`World::tools`] (tools are
    /// numbered in the order they were added).
    pub fn index(self) -> usize {
        self.0
    }
}

/// A tool coupled to a haptic device: the coupling, the proxy's state and the device's.
#[derive(Debug, Clone)]
struct Coupled {
    coupling: VirtualCoupling,
    proxy: ProxyState,
    device: Isometry3<f64>,
    device_velocity: Vector3<f64>,
    /// The contact force on the proxy at the last step, N.
    contact: Vector3<f64>,
}

/// The tissue, the tools, the cutting and the contacts, stepped together; see the module
/// documentation for the order of a step.
pub struct World {
    /// The mesh as built (cuts edit the cutter's copy: [`World::mesh`]).
    mesh: TetMesh,
    /// The model as built (the simulation holds the current one); the cutter starts from it.
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    model: SpringModel,
    sim: Simulation,
    tools: Vec<Tool>,
    names: Vec<String>,
    /// Whether each tool was given a pose since the last step.
    posed: Vec<bool>,
    couplings: Vec<Option<Coupled>>,
    #[cfg(feature = "cut")]
    cutting: Option<Cutting>,
    contact: contact::ContactPhase,
    /// Whether the simulation was given the mesh's boundary (for the tools and self-contact).
    surface_given: bool,
}

impl World {
    /// The world of a built simulation: `mesh` and `model` are what `sim` was packed from.
    fn from_parts(mesh: TetMesh, model: SpringModel, sim: Simulation) -> World {
        World {
            mesh,
            model,
            sim,
            tools: Vec::new(),
            names: Vec::new(),
            posed: Vec::new(),
            couplings: Vec::new(),
            #[cfg(feature = "cut")]
            cutting: None,
            // A unit struct without the `collide` feature.
            #[allow(clippy::default_constructed_unit_structs)]
            contact: contact::ContactPhase::default(),
            surface_given: false,
        }
    }

    /// The simulation (for its state, time, energy and engine).
    pub fn sim(&self) -> &Simulation {
        &self.sim
    }

    /// The simulation, mutable: for what the world does not wrap (node corrections, state).
    /// Changing the model through it behind the world's back (`apply`) leaves the cutter's
    /// mesh out of step with it.
    pub fn sim_mut(&mut self) -> &mut Simulation {
        &mut self.sim
    }

    /// The current mesh: as cut so far when cutting is enabled. Its nodes are numbered as the
    /// simulation's (cuts add nodes at the end and remove none).
    pub fn mesh(&self) -> &TetMesh {
        #[cfg(feature = "cut")]
        if let Some(c) = &self.cutting {
            return c.mesh();
        }
        &self.mesh
    }

    /// The current packed model (the simulation's: cuts patch it).
    pub fn model(&self) -> &PackedModel {
        self.sim.model()
    }

    /// The node positions now, m (dense model order).
    pub fn positions(&self) -> Vec<[f64; 3]> {
        self.sim.positions()
    }

    /// The tools, in the order they were added.
    pub fn tools(&self) -> &[Tool] {
        &self.tools
    }

    /// The tool `handle` names.
    pub fn tool(&self, handle: ToolHandle) -> &Tool {
        &self.tools[handle.0]
    }

    /// The handle of the tool at `index` (in the order tools were added), if there is one.
    pub fn tool_handle(&self, index: usize) -> Option<ToolHandle> {
        (index < self.tools.len()).then_some(ToolHandle(index))
    }

    /// The name of the tool `handle` names.
    pub fn tool_name(&self, handle: ToolHandle) -> &str {
        &self.names[handle.0]
    }

    /// The tool named `name`, if any.
    pub fn tool_by_name(&self, name: &str) -> Option<ToolHandle> {
        self.names.iter().position(|n| n == name).map(ToolHandle)
    }

    /// Cutting, when enabled: its method, mesh and report so far.
    #[cfg(feature = "cut")]
    pub fn cutting(&self) -> Option<&Cutting> {
        self.cutting.as_ref()
    }

    /// The cutting, mutably (to follow its cuts with a render surface), when enabled.
    #[cfg(feature = "cut")]
    pub fn cutting_mut(&mut self) -> Option<&mut Cutting> {
        self.cutting.as_mut()
    }

    /// End the run for a render surface following the cuts ([`Cutting::follow_cuts`]): hand
    /// it the strokes each blade swept since its last cut without changing a tet (a blade still
    /// moving inside the tissue at the end), which would otherwise never come, since they wait
    /// for the blade's next cut, its leaving the tissue or its stopping. Call it after the last
    /// [`World::step`], then take the cuts ([`Cutting::take_cuts`]) and give them to the
    /// surface one last time (the scene runner does, before its last frame). Stepping may go on
    /// after it; nothing happens without cutting.
    #[cfg(feature = "cut")]
    pub fn finish_cuts(&mut self) {
        if let Some(c) = self.cutting.as_mut() {
            c.finish_strokes();
        }
    }

    /// What the cuts did so far, finished at the current positions (latency percentiles,
    /// fragments, opening), when cutting is enabled.
    #[cfg(feature = "cut")]
    pub fn cut_report(&self) -> Option<CutReport> {
        let cutting = self.cutting.as_ref()?;
        let mut report = cutting.report_at(&self.sim.positions());
        report.near_reads = self.sim.near_reads();
        Some(report)
    }

    /// Add a tool at `pose`, at rest (its previous pose is `pose` too). Names must be unique.
    /// A blade cuts when cutting is enabled and its settings name it (or name no blade);
    /// every other tool pushes the tissue.
    pub fn add_tool(
        &mut self,
        name: &str,
        shape: ToolShape,
        pose: Isometry3<f64>,
    ) -> Result<ToolHandle> {
        if self.tool_by_name(name).is_some() {
            return Err(Error::Options(format!(
                "a tool named `{name}` is already in the world; give each tool its own name"
            )));
        }
        let tool = Tool::new(shape, pose)?;
        self.give_surface()?;
        let index = self.tools.len();
        #[cfg(feature = "cut")]
        if let Some(c) = self.cutting.as_mut() {
            if c.settings().cuts_with(name, &shape) {
                c.add_blade(index, name);
            }
        }
        self.tools.push(tool);
        self.names.push(name.to_string());
        self.posed.push(false);
        self.couplings.push(None);
        self.contact.add_tool();
        Ok(ToolHandle(index))
    }

    /// Give the simulation the mesh's boundary, once: the tools' broad phase and the contacts
    /// cull against it, and cuts edit it.
    fn give_surface(&mut self) -> Result<()> {
        if !self.surface_given {
            let triangles = crate::collide::broad::Surface::of(self.mesh()).triangles;
            self.sim.set_surface(triangles)?;
            self.surface_given = true;
        }
        Ok(())
    }

    fn check_handle(&self, handle: ToolHandle) -> Result<usize> {
        if handle.0 < self.tools.len() {
            Ok(handle.0)
        } else {
            Err(Error::Options(format!(
                "tool handle {} names no tool of this world (it has {})",
                handle.0,
                self.tools.len()
            )))
        }
    }

    /// Pose tool `handle` for the end of the next step (metres, scene frame). Call it once per
    /// step per moving tool; a tool not posed before a step stays where it is. Refused for a
    /// tool held by a coupling (give its device's pose: [`World::set_device_pose`]).
    pub fn set_tool_pose(&mut self, handle: ToolHandle, pose: Isometry3<f64>) -> Result<()> {
        let i = self.check_handle(handle)?;
        if self.couplings[i].is_some() {
            return Err(Error::Options(format!(
                "tool `{}` follows a haptic coupling: give the device's pose with \
                 set_device_pose instead",
                self.names[i]
            )));
        }
        if self.posed[i] {
            // Posed twice before one step: the later pose replaces the earlier, and the step
            // still sweeps from where the tool was.
            let previous = *self.tools[i].previous_pose();
            self.tools[i].set_pose(previous);
        }
        self.tools[i].set_pose(pose);
        self.posed[i] = true;
        Ok(())
    }

    /// Cut with the world's blades (those added before and after) under `settings` from now
    /// on. Refused when cutting is already enabled.
    #[cfg(feature = "cut")]
    pub fn enable_cutting(&mut self, settings: CutSettings) -> Result<()> {
        if self.cutting.is_some() {
            return Err(Error::Options("cutting is already enabled".into()));
        }
        let mut cutting = Cutting::new(&self.mesh, &self.model, settings)?;
        for (i, (tool, name)) in self.tools.iter().zip(&self.names).enumerate() {
            if cutting.settings().cuts_with(name, &tool.shape) {
                cutting.add_blade(i, name);
            }
        }
        self.cutting = Some(cutting);
        Ok(())
    }

    /// Give the simulation the current mesh's tets to watch for inversion again, when a cut
    /// touched the watched ones. Cuts leave the tets they touched unwatched until then: call
    /// this every few steps while cutting (the scene runner does at every frame and at least
    /// every [`crate::engine::INVERSION_CHECK_EVERY`] steps).
    pub fn rewatch(&mut self) -> Result<()> {
        #[cfg(feature = "cut")]
        if self.cutting.is_some() && self.sim.watched_tets_touched() {
            let mesh = self
                .cutting
                .as_ref()
                .map(Cutting::mesh)
                .expect("cutting is on");
            self.sim.watch_mesh(mesh)?;
        }
        Ok(())
    }

    /// Couple tool `handle` to a haptic device by `coupling`: from now on the tool is the
    /// coupling's proxy, which the device's pose ([`World::set_device_pose`]) pulls and the
    /// tissue pushes, and [`ToolStep::rendered`] is the force to send to the device. The proxy
    /// starts at rest at the tool's pose, and so does the device.
    pub fn couple(&mut self, handle: ToolHandle, coupling: VirtualCoupling) -> Result<()> {
        let i = self.check_handle(handle)?;
        coupling.validate()?;
        let pose = *self.tools[i].pose();
        self.couplings[i] = Some(Coupled {
            coupling,
            proxy: ProxyState::at_rest(pose.translation.vector),
            device: pose,
            device_velocity: Vector3::zeros(),
            contact: Vector3::zeros(),
        });
        Ok(())
    }

    /// The haptic device's pose and linear velocity (m/s) for tool `handle`, coupled by
    /// [`World::couple`]. The proxy takes the device's orientation; its position follows
    /// through the coupling.
    pub fn set_device_pose(
        &mut self,
        handle: ToolHandle,
        pose: Isometry3<f64>,
        velocity: Vector3<f64>,
    ) -> Result<()> {
        let i = self.check_handle(handle)?;
        let Some(c) = self.couplings[i].as_mut() else {
            return Err(Error::Options(format!(
                "tool `{}` is not coupled to a device: couple it first, or pose it with \
                 set_tool_pose",
                self.names[i]
            )));
        };
        c.device = pose;
        c.device_velocity = velocity;
        Ok(())
    }

    /// The proxy of tool `handle`, when coupled.
    pub fn proxy(&self, handle: ToolHandle) -> Option<ProxyState> {
        self.couplings.get(handle.0)?.as_ref().map(|c| c.proxy)
    }
}

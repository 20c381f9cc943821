//! [`World::step`]: one time step in the order the module documentation gives, and what it
//! reports.

use nalgebra::Vector3;

use super::coupling::ProxyState;
#[cfg(feature = "cut")]
use super::cutting::CutEvent;
use super::World;
use crate::error::Result;

/// What one tool did in one step.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolStep {
    /// Reaction force of the tissue on the tool, N (scene frame; it points away from the
    /// tissue it presses): `-sum m dx / h^2` of the position correction that pushed the tissue
    /// out of it. Friction included. Zero for a blade that cuts. This force is an impulse per
    /// step squared: it jumps at first contact. A haptic device should be sent
    /// [`ToolStep::rendered`] instead (see [`super::VirtualCoupling`]).
    pub force: Vector3<f64>,
    /// The part of `force` from friction, N.
    pub friction: Vector3<f64>,
    /// Penetrating surface triangles found.
    pub contacts: usize,
    /// Deepest penetration found before it was resolved, m.
    pub deepest: f64,
    /// Surface nodes the tool holds (a closed grasper).
    pub held: usize,
    /// Mean distance of the held nodes from their rest positions, m (0 when none is held).
    pub carried: f64,
    /// Whether the tool cut instead of pushing (a blade, with cutting enabled).
    pub cuts: bool,
    /// For a tool coupled to a haptic device: the coupling force on the device, N, which
    /// pulls it toward the proxy (in a steady press, the tissue's reaction).
    pub rendered: Option<Vector3<f64>>,
    /// For a coupled tool: its proxy after the step.
    pub proxy: Option<ProxyState>,
}

/// What the tissue's surfaces did against each other in one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SelfContactStep {
    /// Node-triangle contacts found.
    pub vertex_face: usize,
    /// Edge-edge contacts found.
    pub edge_edge: usize,
    /// Deepest self-penetration found before it was resolved, m.
    pub deepest: f64,
}

/// What one [`World::step`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct StepReport {
    /// Steps taken so far, this one included.
    pub step: u64,
    /// Simulated time at the end of the step, s.
    pub time: f64,
    /// Each tool, in the order they were added ([`super::ToolHandle::index`]).
    pub tools: Vec<ToolStep>,
    /// The cuts this step made, in blade order.
    #[cfg(feature = "cut")]
    pub cuts: Vec<CutEvent>,
    /// Penetrating surface triangles over all tools.
    pub contacts: usize,
    /// Deepest tool penetration over all tools, m.
    pub deepest: f64,
    /// Self-contact, when enabled.
    pub self_contact: Option<SelfContactStep>,
}

impl World {
    /// Take one step: pose, read ahead, step, sweep and cut, apply the patch, edit the surface,
    /// grasp, resolve contacts (the module documentation says why in that order).
    ///
    /// Errors: a divergence or inverted tet found by the simulation's checks (the simulation
    /// is left at the first bad step), a cut that lowered the stable bound under
    /// [`super::TimeStepPolicy::Stop`] (the cut is made and reported in
    /// [`World::cut_report`] first), or a tool that pushes in a build without `collide`.
    pub fn step(&mut self) -> Result<StepReport> {
        let h = self.sim.config().dt;
        for i in 0..self.tools.len() {
            if let Some(c) = self.couplings[i].as_mut() {
                c.proxy =
                    c.coupling
                        .advance(&c.proxy, &c.device, &c.device_velocity, &c.contact, h);
                let pose = nalgebra::Isometry3::from_parts(
                    nalgebra::Translation3::from(c.proxy.position),
                    c.device.rotation,
                );
                self.tools[i].set_pose(pose);
            } else if !self.posed[i] {
                // Not moved: the step sweeps nothing (its previous pose is its pose).
                let pose = *self.tools[i].pose();
                self.tools[i].set_pose(pose);
            }
            self.posed[i] = false;
        }
        #[cfg(feature = "cut")]
        if let Some(cut) = &self.cutting {
            cut.before_step(&mut self.sim, &self.tools);
        }
        self.sim.run(1)?;
        #[cfg(feature = "cut")]
        let cuts = {
            let before = self.cutting.as_ref().map_or(0, |c| c.report.events.len());
            if let Some(cut) = self.cutting.as_mut() {
                cut.after_step(&mut self.sim, &self.tools)?;
            }
            self.cutting
                .as_ref()
                .map_or(Vec::new(), |c| c.report.events[before..].to_vec())
        };
        let cutting: Vec<bool> = (0..self.tools.len()).map(|i| self.cuts_with(i)).collect();
        let (mut tools, self_contact) = if self.tools.is_empty() && !self.self_contact_on() {
            (Vec::new(), None)
        } else {
            self.contact
                .after_step(&mut self.sim, &self.tools, &cutting)?
        };
        for (i, t) in tools.iter_mut().enumerate() {
            if let Some(c) = self.couplings[i].as_mut() {
                c.contact = t.force;
                t.rendered = Some(c.coupling.force(&c.proxy, &c.device, &c.device_velocity));
                t.proxy = Some(c.proxy);
            }
        }
        Ok(StepReport {
            step: self.sim.steps(),
            time: self.sim.time(),
            contacts: tools.iter().map(|t| t.contacts).sum(),
            deepest: tools.iter().map(|t| t.deepest).fold(0.0, f64::max),
            tools,
            #[cfg(feature = "cut")]
            cuts,
            self_contact,
        })
    }

    /// Whether tool `i` cuts (a blade, with cutting enabled) instead of pushing.
    fn cuts_with(&self, i: usize) -> bool {
        #[cfg(feature = "cut")]
        {
            self.cutting.as_ref().is_some_and(|c| c.cuts_with(i))
        }
        #[cfg(not(feature = "cut"))]
        {
            let _ = i;
            false
        }
    }

    /// Whether self-contact is resolved at each step.
    fn self_contact_on(&self) -> bool {
        #[cfg(feature = "collide")]
        {
            self.contact.self_contact.is_some()
        }
        #[cfg(not(feature = "collide"))]
        {
            false
        }
    }

    /// Whether a step does anything besides the simulation's: tools, or self-contact.
    pub fn has_contacts(&self) -> bool {
        !self.tools.is_empty() || self.self_contact_on()
    }

    /// Take `steps` steps. A world with nothing between steps (no tool, no self-contact) hands
    /// them to the simulation at once (the GPU engine then batches them), calling
    /// `progress(steps_done)` after each chunk; otherwise it takes them one [`World::step`] at
    /// a time, the tools where they were posed, calling `progress` after each.
    pub fn run_with(&mut self, steps: u64, mut progress: impl FnMut(u64)) -> Result<()> {
        if self.has_contacts() {
            for k in 0..steps {
                self.step()?;
                progress(k + 1);
            }
            Ok(())
        } else {
            self.sim.run_with(steps, progress)
        }
    }
}

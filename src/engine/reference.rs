//! The float64 reference engine: serial, one spring (or tet) at a time, no tricks. Everything
//! faster is checked against it, and it is where the finite-element force models run first.

use super::{Engine, SimConfig};
use crate::model::PackedModel;
use crate::physics::{
    integrator_for, ElementForces, ForceModel, ForceModelKind, NodeState, Nodes, SolverStats,
    SpringForces, TimeIntegrator,
};

type V3 = [f64; 3];

/// Float64 serial engine: the model's [`SpringForces`] (or a finite-element force model,
/// [`ReferenceEngine::with_force_model`]) stepped by a [`TimeIntegrator`], the two seams of
/// [`crate::physics`] with nothing in between.
pub struct ReferenceEngine {
    model: PackedModel,
    dt: f64,
    integrator: Box<dyn TimeIntegrator>,
    state: NodeState,
    /// The finite-element force model, if one replaces the springs.
    elements: Option<ElementForces>,
}

impl ReferenceEngine {
    /// Start at rest at the rest positions, stepping the springs (whatever
    /// `config.force_model` says: [`ReferenceEngine::with_force_model`] chooses another).
    pub fn new(model: &PackedModel, config: SimConfig) -> Self {
        Self::with_integrator(
            model,
            config.dt,
            integrator_for(config.integrator, config.solver),
        )
    }

    /// Start at rest at the rest positions, stepping with `integrator` at `dt` (s): how an
    /// integrator that [`crate::physics::Integrator`] does not name yet is run and tested.
    pub fn with_integrator(
        model: &PackedModel,
        dt: f64,
        integrator: Box<dyn TimeIntegrator>,
    ) -> Self {
        ReferenceEngine {
            model: model.clone(),
            dt,
            integrator,
            state: NodeState {
                x: model.rest.clone(),
                v: vec![[0.0; 3]; model.node_count()],
            },
            elements: None,
        }
    }

    /// Step with the force model `kind` of `model` (the model this engine was built on)
    /// instead of the springs; `Springs` changes nothing. Fails where the model cannot have
    /// that force model (no tets, a tet whose material has no Young's modulus).
    pub fn with_force_model(
        mut self,
        model: &PackedModel,
        kind: ForceModelKind,
    ) -> crate::Result<Self> {
        self.elements = kind.element_forces(model)?;
        Ok(self)
    }

    /// The name of the force model it steps.
    pub fn force_model_name(&self) -> &'static str {
        self.elements.as_ref().map_or("springs", |e| e.name())
    }

    /// The integrator's name.
    pub fn integrator_name(&self) -> &'static str {
        self.integrator.name()
    }
}

impl Engine for ReferenceEngine {
    fn step(&mut self, steps: u32) {
        let nodes = Nodes {
            mass: &self.model.mass,
            fixed: &self.model.fixed,
            gravity: self.model.gravity,
            mass_damping: self.model.mass_damping,
        };
        let springs = SpringForces::new(self.model.springs());
        let forces: &dyn ForceModel = match &self.elements {
            Some(e) => e,
            None => &springs,
        };
        for _ in 0..steps {
            self.integrator
                .step(forces, &nodes, self.dt, &mut self.state);
        }
    }

    fn elastic_energy(&self, model: &PackedModel, x: &[V3]) -> f64 {
        match &self.elements {
            Some(e) => e.potential_energy(x),
            None => model.elastic_energy(x),
        }
    }

    /// Springs: `None`, the simulation rebuilds the engine (serial and float64, it is the
    /// reference, not the fast path). A finite-element model is patched: the removed tets'
    /// shares subtracted and the added tets' added ([`ElementForces::patch`]), so that a cut's
    /// update is checked against a rebuild ([`Engine::differences_from_rebuild`]).
    fn patch(
        &mut self,
        model: &PackedModel,
        diff: &crate::model::ModelDiff,
    ) -> crate::Result<Option<super::PatchCost>> {
        let Some(elements) = &mut self.elements else {
            return Ok(None);
        };
        elements.patch(&model.rest, diff)?;
        super::grow_state(&model.rest, &mut self.state.x, &mut self.state.v, diff);
        self.model = model.clone();
        // Nodes that became fixed are held at rest, as a new engine holds them.
        for c in &diff.changed_nodes {
            let i = c.node as usize;
            if c.fixed {
                self.state.x[i] = model.rest[i];
                self.state.v[i] = [0.0; 3];
            }
        }
        let memory = self.memory();
        Ok(Some(super::PatchCost {
            uploaded_bytes: 0,
            copied_bytes: 0,
            buffers_grown: 0,
            layout_bytes: memory.stats.total,
            state_moves: diff.added_nodes.len(),
            reallocated: false,
        }))
    }

    fn differences_from_rebuild(&self, model: &PackedModel) -> crate::Result<Vec<String>> {
        match &self.elements {
            Some(e) => e.differences_from_rebuild(model),
            None => Ok(Vec::new()),
        }
    }

    fn set_contact_constraints(&mut self, constraints: &[crate::physics::NodeConstraint]) -> bool {
        self.integrator.set_contact_constraints(constraints)
    }

    fn contact_constraint_forces(&self) -> Vec<f64> {
        self.integrator.contact_constraint_forces()
    }

    fn positions(&self) -> Vec<V3> {
        self.state.x.clone()
    }

    fn velocities(&self) -> Vec<V3> {
        self.state.v.clone()
    }

    fn solver_stats(&self) -> Option<SolverStats> {
        self.integrator.solver_stats()
    }

    fn name(&self) -> String {
        "cpu-reference-f64".into()
    }

    fn memory(&self) -> super::EngineMemory {
        let (n, m) = (self.state.x.len() as u64, self.model.springs().len() as u64);
        let spring = std::mem::size_of::<crate::model::PackedSpring>() as u64;
        let v3 = std::mem::size_of::<V3>() as u64;
        let buffers = vec![
            ("springs".to_string(), m * spring),
            ("positions".to_string(), n * v3),
            ("velocities".to_string(), n * v3),
            ("forces".to_string(), n * v3),
            ("masses".to_string(), n * 8),
            ("fixed flags".to_string(), n),
        ];
        // A step reads the springs, masses and flags, and reads and writes positions, the
        // second state and the forces.
        let bytes_per_step = m * spring + n * (8 + 1) + 2 * 3 * n * v3;
        super::EngineMemory {
            stats: crate::layout::MemoryStats::new(buffers, 0, n as usize, m as usize),
            bytes_per_step,
        }
    }

    fn correct_positions(&mut self, nodes: &[u32], positions: &[V3]) -> crate::Result<()> {
        super::check_correction(nodes, positions, self.state.x.len())?;
        for (&i, &p) in nodes.iter().zip(positions) {
            let i = i as usize;
            if self.model.fixed[i] {
                continue;
            }
            // Both schemes turn the move into velocity: Verlet keeps its previous position
            // (`v = (x - x-) / h`), symplectic Euler adds `move / h`.
            let (x, v) = (self.state.x[i], self.state.v[i]);
            self.state.v[i] = [0, 1, 2].map(|c| v[c] + (p[c] - x[c]) / self.dt);
            self.state.x[i] = p;
        }
        Ok(())
    }

    fn set_time_step(&mut self, dt: f64) -> crate::Result<super::PatchCost> {
        // The state is positions and velocities for every scheme: exactly what an engine built
        // at `dt` and given this state holds.
        self.dt = dt;
        Ok(super::PatchCost::parameters_only(
            std::mem::size_of::<f64>() as u64,
            self.memory().stats.total,
        ))
    }

    fn set_state(&mut self, positions: &[V3], velocities: &[V3]) {
        for i in 0..self.state.x.len() {
            (self.state.x[i], self.state.v[i]) = if self.model.fixed[i] {
                (self.model.rest[i], [0.0; 3])
            } else {
                (positions[i], velocities[i])
            };
        }
    }
}

//! Changing a running simulation between steps: a model change (what a cut produces), checked
//! against the stable bound and given to the engine as a patch; the stable bound a change would
//! leave; a new time step, a parameter of the step.

use super::*;
use crate::physics::element_energy;

impl Simulation {
    /// Apply a change to the model between steps (what a cut produces): the GPU engine patches
    /// its layout and uploads only what changed, the fast CPU engine rewrites the rows of the
    /// touched nodes, the float64 reference engine is rebuilt with its state carried over. New nodes start with the state of the node they copy, or at rest. The
    /// stable time step is recomputed; a change that puts `dt` above it is refused (unless
    /// `allow_unstable`). A refused change (an invalid diff, an unstable step) leaves the model
    /// and engine as they were; a device failure while patching leaves the engine unusable.
    pub fn apply(&mut self, diff: &ModelDiff) -> Result<PatchCost> {
        self.apply_with(diff, self.config.allow_unstable)
    }

    /// [`Simulation::apply`], choosing whether a change that puts `dt` above the new stable
    /// bound is refused (`allow_unstable = false`) or applied anyway (a cut scene whose policy
    /// is to warn).
    pub fn apply_with(&mut self, diff: &ModelDiff, allow_unstable: bool) -> Result<PatchCost> {
        self.apply_inner(diff, allow_unstable, None)
    }

    /// [`Simulation::apply_with`], given the current positions (as [`Simulation::positions`]
    /// gave them, with no step since: what a cutter just read). The energy bookkeeping takes
    /// the positions of the touched springs' nodes from them instead of reading them back from
    /// the engine, which on the GPU is a round trip to the device per cut. Only those entries
    /// are read, so the positions of a cut that read only the nodes near its blade
    /// ([`crate::cut::ReadPositions::positions`]) will do. Positions of another length than
    /// the model's node count are an error, and nothing changes.
    pub fn apply_at(
        &mut self,
        diff: &ModelDiff,
        allow_unstable: bool,
        positions: &[[f64; 3]],
    ) -> Result<PatchCost> {
        let n = self.model.node_count();
        if positions.len() != n {
            return Err(Error::LengthMismatch {
                given: positions.len(),
                expected: n,
                message: format!(
                    "{} positions given for a model of {n} nodes: pass the positions read \
                     since the last step or change",
                    positions.len()
                ),
            });
        }
        self.apply_inner(diff, allow_unstable, Some(positions))
    }

    pub(super) fn apply_inner(
        &mut self,
        diff: &ModelDiff,
        allow_unstable: bool,
        positions: Option<&[[f64; 3]]>,
    ) -> Result<PatchCost> {
        // A finite-element model's bound follows the elements the diff removes and adds.
        let undo = self
            .config
            .force_model
            .update_bound(&mut self.bound, &self.model, diff)?;
        if self.config.dt > self.bound.dt
            && !allow_unstable
            && !self.config.integrator.is_implicit()
        {
            let err = Error::UnstableTimeStep {
                dt: self.config.dt,
                bound: self.bound.dt,
                node: self.bound.node,
            };
            self.bound.undo(undo);
            return Err(err);
        }
        let before = self.model.node_count();
        // Validates first: on error nothing has changed (the bound is put back).
        let energies = self
            .diff_elastic_energy(diff, positions)
            .and_then(|e| self.model.apply(diff).map(|()| e));
        let (elastic_before, elastic_after) = match energies {
            Ok(e) => e,
            Err(e) => {
                self.bound.undo(undo);
                return Err(e);
            }
        };
        let cost = match self.engine.patch(&self.model, diff)? {
            Some(cost) => cost,
            None => {
                let (mut x, mut v) = self.engine.state();
                let before = x.len();
                super::super::grow_state(&self.model.rest, &mut x, &mut v, diff);
                debug_assert_eq!(x.len(), before + diff.added_nodes.len());
                let (mut engine, _, _) =
                    make_engine(&self.model, self.kind, self.config, self.gpu, &self.host)?;
                engine.set_state(&x, &v);
                if let (Some(t), Some(d)) = (&self.surface, engine.device_mut()) {
                    d.set_surface(t)?;
                }
                let memory = engine.memory();
                self.engine = engine;
                #[cfg(feature = "gpu")]
                self.rebind_host()?;
                PatchCost {
                    uploaded_bytes: memory.stats.total,
                    copied_bytes: 0,
                    buffers_grown: 0,
                    layout_bytes: memory.stats.total,
                    state_moves: diff.added_nodes.len(),
                    reallocated: true,
                }
            }
        };
        debug_assert_eq!(self.model.node_count(), before + diff.added_nodes.len());
        self.node_springs = None;
        // Contact constraints name model nodes, which a change keeps: a rebuilt or patched
        // engine holds them again (a node that became fixed is skipped by the solve).
        self.resend_contact_constraints();
        // A replay from a state kept before would not make this change: none from here.
        self.changes += 1;
        if let Some(watch) = &mut self.watch {
            watch.touch(&diff.touched_nodes(before), self.model.node_count());
        }
        // The divergence reference follows the energy the change took out of or put into the
        // springs it touched (splitting a node shares its mass and keeps its velocity, so the
        // kinetic and gravitational energies do not change; carving only lowers them).
        let delta = elastic_after - elastic_before;
        self.start_energy += delta;
        self.base_energy += delta;
        Ok(cost)
    }

    /// Elastic energy, at the current positions, of the springs `diff` removes or changes (as
    /// they are) and of those it adds or changes (as they will be; a new node is displaced as
    /// the node it copies, or as the mix of the two it blends); under a finite-element force
    /// model, of the tets it removes and adds instead. Reads back only the existing nodes of
    /// those springs, tets and sources, once, unless `positions` (all nodes, current) are
    /// given.
    pub(super) fn diff_elastic_energy(
        &self,
        diff: &ModelDiff,
        positions: Option<&[[f64; 3]]>,
    ) -> Result<(f64, f64)> {
        let n = self.model.node_count() as u32;
        let old: Vec<crate::model::PackedSpring> = diff
            .removed_springs
            .iter()
            .map(|&[a, b]| (a, b))
            .chain(
                diff.changed_springs
                    .iter()
                    .map(|s| (s.nodes[0], s.nodes[1])),
            )
            .filter_map(|(a, b)| {
                self.model
                    .spring_index(a, b)
                    .map(|i| self.model.springs()[i])
            })
            .collect();
        let new: Vec<crate::model::PackedSpring> = diff
            .added_springs
            .iter()
            .chain(&diff.changed_springs)
            .copied()
            .collect();
        // An added node is displaced as its source is (mixed with its blend partner); one
        // without a source starts at rest. Existing nodes are their own source.
        let sources = |i: u32| -> [Option<u32>; 2] {
            if i < n {
                return [Some(i), None];
            }
            diff.added_nodes
                .get((i - n) as usize)
                .map_or([None, None], |a| [a.state_from, a.blend.map(|b| b.with)])
        };
        let kind = self.config.force_model;
        let (old_tets, new_tets) = if kind.is_finite_element() {
            ForceModelKind::diff_elements(&self.model, diff)?
        } else {
            (Vec::new(), Vec::new())
        };
        let mut nodes: Vec<u32> = old
            .iter()
            .chain(&new)
            .flat_map(|s| s.nodes)
            .chain(old_tets.iter().chain(&new_tets).flat_map(|e| e.nodes))
            .flat_map(sources)
            .flatten()
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        if nodes.is_empty() {
            return Ok((0.0, 0.0));
        }
        if let Some(&i) = nodes.last().filter(|&&i| i >= n) {
            // Validated again by `PackedModel::apply`; refused here before any position is
            // looked up.
            return Err(Error::NodeOutOfRange {
                node: i as u64,
                count: self.model.node_count(),
                message: format!(
                    "an added node starts from the state of node {i}, which does not exist yet"
                ),
            });
        }
        let x: Vec<[f64; 3]> = match positions {
            Some(p) => {
                let x: Vec<[f64; 3]> = nodes.iter().map(|&i| p[i as usize]).collect();
                // Positions read from a device that failed come back as NaN: refuse them
                // rather than carry NaN into the energy reference.
                if let Some((&i, _)) = nodes
                    .iter()
                    .zip(&x)
                    .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
                {
                    return Err(Error::Model(format!(
                        "the position given for node {i} is not finite; read the positions \
                         again, or apply without them"
                    )));
                }
                x
            }
            None => self.engine.node_positions(&nodes)?,
        };
        let read = |i: u32| x[nodes.binary_search(&i).expect("collected")];
        let at = |i: u32| -> [f64; 3] {
            if i < n {
                return read(i);
            }
            let a = &diff.added_nodes[(i - n) as usize];
            let d = a.start_value(|j| {
                let (p, r) = (read(j), self.model.rest[j as usize]);
                [0, 1, 2].map(|c| p[c] - r[c])
            });
            d.map_or(a.rest, |d| [0, 1, 2].map(|c| a.rest[c] + d[c]))
        };
        let energy = |springs: &[crate::model::PackedSpring]| -> f64 {
            springs
                .iter()
                .map(|s| {
                    let (a, b) = (at(s.nodes[0]), at(s.nodes[1]));
                    let l = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2))
                        .sqrt();
                    0.5 * s.stiffness * (l - s.rest_length).powi(2)
                })
                .sum()
        };
        if kind.is_finite_element() {
            let energy = |elements: &[crate::physics::TetElement]| -> f64 {
                elements
                    .iter()
                    .map(|e| element_energy(kind, e, e.nodes.map(at)))
                    .sum()
            };
            return Ok((energy(&old_tets), energy(&new_tets)));
        }
        Ok((energy(&old), energy(&new)))
    }

    /// Change the time step between steps, keeping the state (positions and velocities): a
    /// parameter of the step, so only the step parameters are written ([`Engine::set_time_step`]:
    /// no pipeline is rebuilt and no layout uploaded; Verlet's previous positions are moved
    /// where the state lives so that its velocity is kept). For an explicit integrator a step
    /// above the bound is refused unless `allow_unstable`, with nothing changed. Returns what it cost: the bytes of the
    /// engine's step parameters.
    pub fn set_time_step(&mut self, dt: f64) -> Result<PatchCost> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::InvalidParameter {
                name: "time step".into(),
                value: dt,
                requirement: "be finite and positive".into(),
            });
        }
        if dt > self.bound.dt
            && !self.config.allow_unstable
            && !self.config.integrator.is_implicit()
        {
            return Err(Error::UnstableTimeStep {
                dt,
                bound: self.bound.dt,
                node: self.bound.node,
            });
        }
        // The time reached so far is counted at the old step before it changes.
        self.time_at_dt_change = self.time();
        self.steps_at_dt_change = self.steps;
        let cost = self.engine.set_time_step(dt)?;
        self.config.dt = dt;
        self.changes += 1;
        self.reset_energy_reference();
        Ok(cost)
    }
}

//! The surface and what reads or moves nodes for contact: the boundary triangles, the broad
//! phases, reads of a few nodes, the nodes near a blade (read ahead with a step), position
//! corrections, and the contact constraints the implicit solve holds.

use super::*;
use crate::physics::NodeConstraint;

impl Simulation {
    /// Set the tissue's boundary triangles (dense model indices, e.g.
    /// `collide::broad::Surface::of(&mesh).triangles`) for [`Simulation::cull_tools`]; again
    /// whenever a cut changes the surface.
    pub fn set_surface(&mut self, triangles: Vec<[u32; 3]>) -> Result<()> {
        let n = self.model.node_count();
        if let Some(t) = triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            let node = t.iter().copied().find(|&i| i as usize >= n).unwrap_or(t[0]);
            return Err(Error::NodeOutOfRange {
                node: node as u64,
                count: n,
                message: format!("surface triangle {t:?} names a node past the model's {n} nodes"),
            });
        }
        if let Some(d) = self.engine.device_mut() {
            d.set_surface(&triangles)?;
        }
        // Built here, not at the first edit, so that the first cut does not pay for it.
        self.surface_slots = Some(
            triangles
                .iter()
                .enumerate()
                .map(|(i, t)| (surface_key(t), i as u32))
                .collect(),
        );
        self.surface = Some(triangles);
        self.surface_generation += 1;
        Ok(())
    }

    /// Apply a cut's change to the surface given to [`Simulation::set_surface`] in place: a
    /// removed triangle's slot takes the last triangle, added ones go at the end, so only a
    /// few slots change and the GPU engine writes only those. Triangle indices reported by
    /// [`Simulation::cull_tools`] refer to the edited list ([`Simulation::surface`]). On error
    /// (a removed triangle not on the surface, an added one already on it, a node out of range)
    /// nothing changes.
    pub fn edit_surface(&mut self, edit: &crate::collide::broad::SurfaceEdit) -> Result<()> {
        let n = self.model.node_count();
        let Some(triangles) = &mut self.surface else {
            return Err(Error::NoSurface(
                "no surface to edit: call set_surface with the boundary triangles first".into(),
            ));
        };
        if edit.is_empty() {
            return Ok(());
        }
        let key = surface_key;
        let slots = self.surface_slots.as_mut().expect("built with the surface");
        // Validate everything before changing anything.
        let mut gone = HashSet::new();
        for t in &edit.removed {
            if !slots.contains_key(&key(t)) || !gone.insert(key(t)) {
                return Err(Error::Model(format!(
                    "surface edit removes triangle {t:?}, which is not on the surface (or is \
                     removed twice)"
                )));
            }
        }
        let mut new = HashSet::new();
        for t in &edit.added {
            if let Some(&i) = t.iter().find(|&&i| i as usize >= n) {
                return Err(Error::NodeOutOfRange {
                    node: i as u64,
                    count: n,
                    message: format!(
                        "surface edit adds triangle {t:?}, whose node {i} is past the model's \
                         {n} nodes"
                    ),
                });
            }
            let k = key(t);
            if (slots.contains_key(&k) && !gone.contains(&k)) || !new.insert(k) {
                return Err(Error::Model(format!(
                    "surface edit adds triangle {t:?}, which is already on the surface"
                )));
            }
        }
        // Edited in place; undone the same way if the engine refuses the edit.
        let applied = surface_list::apply(triangles, slots, edit);
        if let Some(d) = self.engine.device_mut() {
            if let Err(e) = d.edit_surface(triangles, &applied.changed) {
                surface_list::undo(triangles, slots, edit, applied);
                return Err(e);
            }
        }
        self.surface_generation += 1;
        Ok(())
    }

    /// The surface given to [`Simulation::set_surface`].
    pub fn surface(&self) -> Option<&[[u32; 3]]> {
        self.surface.as_deref()
    }

    /// Broad phase, tool against tissue: (triangle, tool) pairs of the surface whose bounds
    /// overlap `boxes`. On the GPU engine the pass runs on the device and only the candidates
    /// come back; elsewhere it runs on the CPU over float64 positions. Either way no overlapping
    /// pair is missed.
    pub fn cull_tools(
        &mut self,
        boxes: &[crate::collide::broad::ToolBox],
    ) -> Result<Vec<crate::collide::broad::Candidate>> {
        let Some(triangles) = &self.surface else {
            return Err(Error::NoSurface(
                "no surface to cull: call set_surface with the boundary triangles first".into(),
            ));
        };
        if let Some(d) = self.engine.device_mut() {
            return d.cull_tools(boxes);
        }
        let exact: Vec<([f64; 3], [f64; 3])> = boxes
            .iter()
            .map(|b| {
                (
                    [b.lo[0] as f64, b.lo[1] as f64, b.lo[2] as f64],
                    [b.hi[0] as f64, b.hi[1] as f64, b.hi[2] as f64],
                )
            })
            .collect();
        Ok(crate::collide::broad::cull_exact(
            &self.engine.positions(),
            triangles,
            &exact,
        ))
    }

    /// Broad phase, tissue against itself: pairs of surface triangles (indices into the
    /// surface given to [`Simulation::set_surface`], t < u, sorted) that share no node and whose
    /// boxes, widened by `margin / 2` (m) on every side, overlap. On the GPU engine the spatial
    /// hash runs on the device and only the pairs come back; elsewhere its CPU twin
    /// ([`crate::twin::broad_self::self_pairs_cpu`]) runs over the current positions. Either
    /// way no pair the float64 brute force finds is missed.
    #[cfg(feature = "collide")]
    pub fn cull_self(&mut self, margin: f64) -> Result<Vec<[u32; 2]>> {
        use crate::collide::self_broad::GridParams;
        use crate::twin::broad_self::self_pairs_cpu;
        if !(margin.is_finite() && margin >= 0.0) {
            return Err(Error::Options(format!(
                "self-contact margin must be zero or positive and finite, got {margin} m"
            )));
        }
        let Some(triangles) = &self.surface else {
            return Err(Error::NoSurface(
                "no surface to cull: call set_surface with the boundary triangles first".into(),
            ));
        };
        if let Some(d) = self.engine.device_mut() {
            return d.cull_self(margin);
        }
        // The twin over float32 rest positions plus float32 displacements, as on the device.
        let rest = &self.model.rest;
        let x = self.engine.positions();
        let f4 = |p: [f64; 3]| [p[0] as f32, p[1] as f32, p[2] as f32, 0.0];
        let rest32: Vec<[f32; 4]> = rest.iter().map(|&r| f4(r)).collect();
        let disp32: Vec<[f32; 4]> = x
            .iter()
            .zip(rest)
            .map(|(p, r)| f4([p[0] - r[0], p[1] - r[1], p[2] - r[2]]))
            .collect();
        let mut grid = GridParams::for_surface(rest, triangles, margin);
        for _ in 0..40 {
            if let Some(pairs) = self_pairs_cpu(&grid, &rest32, &disp32, triangles) {
                return Ok(pairs);
            }
            // The surface stretched past the grid: coarser cells, as the device does.
            grid.inv_cell *= 0.5;
        }
        Err(Error::Diverged {
            step: self.steps,
            node: 0,
            reason: "the tissue surface stretched beyond any grid cell (non-finite or enormous \
                     positions)"
                .into(),
            found: None,
        })
    }

    /// Positions of a few nodes (model indices), m: on the GPU only those are read back.
    pub fn node_positions(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        self.engine.node_positions(nodes)
    }

    /// Read the nodes in the box `lo..=hi` (m) ahead, with the last step of the next
    /// [`Simulation::run`] (or [`Simulation::step_unchecked`]): on the GPU that step's
    /// submission ends with the pass that finds them and starts their readback, so that the
    /// cut after it ([`crate::cut::Cutter::cut_from`], whose box
    /// [`crate::cut::Cutter::reading_box_ahead`] bounds) reads them without a round trip of its
    /// own. A later read for a box that this one does not hold, or after the state changed
    /// again (a further step, a position correction, a patch), reads from the device as
    /// before; [`Simulation::near_reads`] counts which. The fast CPU engine scans for them
    /// after the step, on its threads, and the cut narrows that list instead of scanning every
    /// node itself; the reference engine ignores it.
    pub fn prefetch_near(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        self.near_ahead = Some((lo, hi));
    }

    /// How the engine served reads of nodes near a blade: from a read made ahead with a step,
    /// or with a round trip (a scan, on the fast CPU engine) of their own (zero on the reference
    /// engine).
    pub fn near_reads(&self) -> NearReads {
        self.near_reads
    }

    /// Give the engine the box to read ahead, for the step about to be submitted.
    pub(super) fn hand_prefetch(&mut self) {
        if let Some((lo, hi)) = self.near_ahead.take() {
            self.engine.prefetch_near(lo, hi);
        }
    }

    /// The nodes whose current position lies in the box `lo..=hi` (m), with their positions
    /// ([`Engine::nodes_near`]): on the GPU found on the device, and only they are read back.
    pub fn nodes_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        let before = self.engine.near_reads();
        let found = self.engine.nodes_near(lo, hi);
        let after = self.engine.near_reads();
        self.near_reads.ahead += after.ahead - before.ahead;
        self.near_reads.direct += after.direct - before.direct;
        found
    }

    /// Positions of a few nodes at the start of the last step (after the corrections made
    /// before it), m: with [`Simulation::node_positions`] they give each node's motion over the
    /// step, which friction needs. On the GPU only those nodes are read back.
    pub fn node_start_positions(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        self.engine.node_start_positions(nodes, self.config.dt)
    }

    /// Move nodes between steps (contact response by position correction); see
    /// [`Engine::correct_positions`].
    ///
    /// The move is work done on the tissue from outside (a tool's push, a self-contact
    /// separation), so the energy the divergence check compares against grows by that work:
    /// the change of the total energy the move makes, computed from the moved nodes alone (their
    /// positions and velocities before, and the springs at them with their other ends), with
    /// the velocity the integrator gives the move (`dx / dt`). The energy scale grows with the
    /// reference above where it was last taken from the state, so that the check's margin stays
    /// in proportion to the energy brought in; a later check that measures the total exactly
    /// lowers both again where the energy went (see [`Simulation::run`]). On the GPU only the
    /// moved nodes and their spring neighbours are read back, not the state.
    pub fn correct_positions(&mut self, nodes: &[u32], positions: &[[f64; 3]]) -> Result<()> {
        check_correction(nodes, positions, self.model.node_count())?;
        let work = self.correction_work(nodes, positions)?;
        self.engine.correct_positions(nodes, positions)?;
        self.changes += 1;
        self.start_energy += work;
        self.energy_scale = self.base_scale + (self.start_energy - self.base_energy).max(0.0);
        Ok(())
    }

    /// The change of total energy (kinetic, elastic, gravitational, as [`Simulation::energy`]
    /// counts them) that moving `nodes` to `positions` makes, J. Fixed nodes do not move; a
    /// node listed twice takes its last position, as the engines do.
    pub fn correction_work(&mut self, nodes: &[u32], positions: &[[f64; 3]]) -> Result<f64> {
        let m = &self.model;
        let mut to: std::collections::BTreeMap<u32, [f64; 3]> = Default::default();
        for (&i, &p) in nodes.iter().zip(positions) {
            if !m.fixed[i as usize] {
                to.insert(i, p);
            }
        }
        if to.is_empty() {
            return Ok(0.0);
        }
        let moved: Vec<u32> = to.keys().copied().collect();
        let node_springs = self.node_springs.get_or_insert_with(|| NodeSprings::of(m));
        let mut springs: Vec<u32> = moved
            .iter()
            .flat_map(|&i| node_springs.of_node(i).iter().copied())
            .collect();
        springs.sort_unstable();
        springs.dedup();
        let mut ends: Vec<u32> = springs
            .iter()
            .flat_map(|&s| m.springs()[s as usize].nodes)
            .chain(moved.iter().copied())
            .collect();
        ends.sort_unstable();
        ends.dedup();
        let x = self.engine.node_positions(&ends)?;
        let v = self.engine.node_velocities(&moved)?;
        let at = |i: u32| x[ends.binary_search(&i).expect("every end was read")];
        let g = m.gravity;
        let inv_h = 1.0 / self.config.dt;
        let mut work = 0.0;
        for (k, (&i, p)) in to.iter().enumerate() {
            let (old, mass) = (at(i), m.mass[i as usize]);
            let dx = [0, 1, 2].map(|c| p[c] - old[c]);
            let v1 = [0, 1, 2].map(|c| v[k][c] + dx[c] * inv_h);
            let sq = |a: [f64; 3]| a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
            work += 0.5 * mass * (sq(v1) - sq(v[k]));
            work -= mass * (dx[0] * g[0] + dx[1] * g[1] + dx[2] * g[2]);
        }
        let spring_energy = |s: &crate::model::PackedSpring, a: [f64; 3], b: [f64; 3]| {
            let l = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt();
            0.5 * s.stiffness * (l - s.rest_length).powi(2)
        };
        for &s in &springs {
            let s = &m.springs()[s as usize];
            let [a, b] = s.nodes;
            let after = |i: u32| to.get(&i).copied().unwrap_or_else(|| at(i));
            work += spring_energy(s, after(a), after(b)) - spring_energy(s, at(a), at(b));
        }
        Ok(work)
    }
}

/// Tool contact inside the implicit solve ([`crate::physics::contact_constraint`]).
impl Simulation {
    /// Hold `constraints`' nodes on their tools' planes inside the implicit solve from the next
    /// step on, replacing those set before (an empty list releases every node). Returns whether
    /// the engine takes them: backward Euler on the reference and fast engines does; the
    /// explicit schemes and the GPU engine do not (`false`, nothing set), and contact must
    /// correct positions instead. A node out of range, a normal that is not a finite unit
    /// vector or an offset that is not finite is an error, and nothing changes.
    pub fn set_contact_constraints(&mut self, constraints: &[NodeConstraint]) -> Result<bool> {
        let n = self.model.node_count();
        for (k, c) in constraints.iter().enumerate() {
            if c.node as usize >= n {
                return Err(crate::engine::bad_node(c.node, n));
            }
            if !c.is_valid() {
                return Err(Error::Options(format!(
                    "contact constraint {k} (node {}): its normal {:?} must be a finite unit \
                     vector and its offset {} finite",
                    c.node, c.normal, c.offset
                )));
            }
        }
        if !self.engine.set_contact_constraints(constraints) {
            return Ok(false);
        }
        self.contact_constraints = constraints.to_vec();
        Ok(true)
    }

    /// Whether the engine holds contact constraints inside its solve (see
    /// [`Simulation::set_contact_constraints`]): backward Euler on a CPU engine.
    pub fn takes_contact_constraints(&self) -> bool {
        self.config.integrator.is_implicit() && self.kind() != crate::engine::EngineKind::Gpu
    }

    /// The constraints set by [`Simulation::set_contact_constraints`].
    pub fn contact_constraints(&self) -> &[NodeConstraint] {
        &self.contact_constraints
    }

    /// The normal force each constraint put on its node in the last step, N (positive: the tool
    /// pushed the node along the constraint's normal), in the order they were set; the tool
    /// feels the opposite. Empty where none is set.
    pub fn contact_constraint_forces(&self) -> Vec<f64> {
        if self.contact_constraints.is_empty() {
            return Vec::new();
        }
        self.engine.contact_constraint_forces()
    }

    /// Give a new or patched engine the constraints again.
    pub(super) fn resend_contact_constraints(&mut self) {
        if !self.contact_constraints.is_empty()
            && !self
                .engine
                .set_contact_constraints(&self.contact_constraints)
        {
            self.contact_constraints.clear();
        }
    }

    /// The constrained nodes' positions before a run's steps (empty without constraints).
    pub(super) fn constrained_positions(&self) -> Result<Vec<[f64; 3]>> {
        if self.contact_constraints.is_empty() {
            return Ok(Vec::new());
        }
        let nodes: Vec<u32> = self.contact_constraints.iter().map(|c| c.node).collect();
        self.engine.node_positions(&nodes)
    }

    /// Count the work the constraints did on the tissue over the steps just taken (their last
    /// step's normal forces times each node's normal motion from `before`) into the divergence
    /// check's reference, as a position correction's work is counted: a tool pressing through
    /// the solve brings energy in.
    pub(super) fn count_constraint_work(&mut self, before: &[[f64; 3]]) -> Result<()> {
        if before.is_empty() {
            return Ok(());
        }
        let nodes: Vec<u32> = self.contact_constraints.iter().map(|c| c.node).collect();
        let after = self.engine.node_positions(&nodes)?;
        let forces = self.engine.contact_constraint_forces();
        let work: f64 = self
            .contact_constraints
            .iter()
            .zip(forces)
            .zip(before.iter().zip(&after))
            .map(|((c, f), (a, b))| f * (0..3).map(|k| c.normal[k] * (b[k] - a[k])).sum::<f64>())
            .sum();
        self.start_energy += work;
        self.energy_scale = self.base_scale + (self.start_energy - self.base_energy).max(0.0);
        Ok(())
    }
}

//! What every engine does, on the device: [`Engine`] for [`GpuEngine`]. A step records `n`
//! steps into one compute pass and submits once; reads of a few nodes copy only those entries
//! back.

use super::*;

impl Engine for GpuEngine {
    fn step(&mut self, steps: u32) {
        // Whatever was read ahead saw the state this step replaces.
        self.forget_ahead();
        let ahead = self.near_ahead.take();
        if self.implicit.is_some() {
            // The solve reads its status back between batches: no read is made ahead.
            return self.step_implicit(steps);
        }
        // A culler behind a patch is brought up to date before the pass reads its rest
        // positions; where that fails the read is not made ahead (a direct read will report it).
        let ahead = ahead.filter(|_| self.refresh_surface().is_ok());
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("steps"),
            });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("springs"),
                timestamp_writes: self.timer.as_ref().map(|t| t.writes()),
            });
            for _ in 0..steps {
                let d = self.dispatch;
                if let Some(c) = &self.corot {
                    c.record(&mut pass, self.phase, d.nodes);
                    self.phase = (self.phase + 1) % self.state.phases();
                    continue;
                }
                if let Some(t) = &self.tensor {
                    t.record(&mut pass, &self.passes, self.phase, d.springs, d.nodes);
                    self.phase = (self.phase + 1) % self.state.phases();
                    continue;
                }
                match &self.passes {
                    Passes::Connectivity(p) => p.record(&mut pass, self.phase, d.nodes),
                    Passes::Valence(p) => p.record(&mut pass, self.phase, d.nodes),
                    Passes::Edges(p) => p.record(&mut pass, self.phase, d.springs, d.nodes),
                    Passes::AtomicEdges(p) => p.record(&mut pass, self.phase, d.springs, d.nodes),
                }
                self.phase = (self.phase + 1) % self.state.phases();
            }
        }
        if let Some(t) = &self.timer {
            t.resolve(&mut enc);
        }
        let slots = self.layout.node_slots() as u32;
        let near = match (ahead, self.surface.as_mut()) {
            (Some((lo, hi)), Some(s)) => {
                let (lo32, hi32) = crate::engine::reading::float32_box(lo, hi);
                s.near
                    .record_ahead(&self.ctx, &mut enc, self.phase, slots, lo32, hi32);
                Some(&mut s.near)
            }
            _ => None,
        };
        let submitted = self.ctx.queue.submit([enc.finish()]);
        if let Some(near) = near {
            near.map_ahead(submitted.clone());
        }
        self.last_submission = Some(submitted);
    }

    fn solver_stats(&self) -> Option<crate::physics::SolverStats> {
        self.implicit_stats()
    }

    fn prefetch_near(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        self.near_ahead = Some((lo, hi));
    }

    fn near_reads(&self) -> NearReads {
        self.near_reads
    }

    fn positions(&self) -> Vec<[f64; 3]> {
        self.state_f64().0
    }

    fn velocities(&self) -> Vec<[f64; 3]> {
        self.state_f64().1
    }

    fn state(&self) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        self.state_f64()
    }

    fn set_time_step(&mut self, dt: f64) -> Result<PatchCost> {
        let h = dt as f32;
        let u = &mut self.uniform_data;
        u.rescale = (dt / self.config.dt) as f32;
        (u.h, u.h2, u.inv_h) = (h, h * h, 1.0 / h);
        self.config.dt = dt;
        if let Some(solver) = self.implicit.as_mut() {
            solver.set_time_step(&self.ctx, h);
        }
        let bytes = bytemuck::bytes_of(&self.uniform_data);
        self.ctx.queue.write_buffer(&self.uniform, 0, bytes);
        if let Some(pass) = &self.rescale {
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("time step"),
                });
            let b = self.state.bindings(self.phase);
            pass.record(&self.ctx, &mut enc, &self.uniform, &b, self.dispatch.nodes);
            self.last_submission = Some(self.ctx.queue.submit([enc.finish()]));
        }
        Ok(PatchCost::parameters_only(
            bytes.len() as u64,
            self.layout.upload_bytes(),
        ))
    }

    fn set_state(&mut self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) {
        self.forget_ahead();
        let n = self.layout.node_slots();
        let dt = self.config.dt;
        let mut cur = vec![[0.0f32; 4]; n];
        let mut second = vec![[0.0f32; 4]; n];
        for (new, old) in self.layout.order().pairs() {
            if self.fixed[old] {
                continue;
            }
            for c in 0..3 {
                let u = positions[old][c] - self.rest[old][c];
                cur[new][c] = u as f32;
                second[new][c] = match self.state.integrator {
                    Integrator::Verlet => (velocities[old][c] * dt) as f32,
                    Integrator::SymplecticEuler | Integrator::BackwardEuler => {
                        velocities[old][c] as f32
                    }
                };
            }
        }
        let b = self.state.bindings(self.phase);
        self.ctx
            .queue
            .write_buffer(b.cur, 0, bytemuck::cast_slice(&cur));
        self.ctx
            .queue
            .write_buffer(b.second_in, 0, bytemuck::cast_slice(&second));
    }

    fn differences_from_rebuild(&self, model: &PackedModel) -> Result<Vec<String>> {
        let mut out = self.layout.differences_from_rebuild(model)?;
        out.extend(self.device_differences()?);
        if let Some(t) = &self.tensor {
            out.extend(t.differences(&self.ctx, model, &self.layout)?);
        }
        if let Some(c) = &self.corot {
            out.extend(c.differences(&self.ctx, model, &self.layout)?);
            if let Some(b) = &self.corot_blocks {
                out.extend(b.differences(&self.ctx, c, &self.layout)?);
            }
        }
        Ok(out)
    }

    fn memory(&self) -> EngineMemory {
        // Counted when asked (a pass over the slot table), not at every patch.
        let mut m = layout_memory(&self.layout, self.config, self.accumulation);
        if let Some(t) = &self.tensor {
            // The tensor passes read the layout's tables as the springs' passes do, and their
            // blocks beside them.
            m.bytes_per_step += t.extra_bytes_per_step(&self.layout);
            let before = m.stats.total.max(1) as f64;
            for (name, bytes) in t.buffers() {
                m.stats.total += bytes;
                m.stats.buffers.push((name, bytes));
            }
            let grown = m.stats.total as f64 / before;
            m.stats.bytes_per_node *= grown;
            m.stats.bytes_per_spring *= grown;
        }
        if let Some(c) = &self.corot {
            // The element path reads no spring: its own traffic (the tet pass, the gather of
            // its corner forces) replaces the springs' passes'. Under backward Euler the block
            // pass follows it, and the solve reads the layout's tables and the blocks as the
            // tensor-mass solve does (counted as tensor-mass counts it: one product a step).
            let elements = c.bytes_per_step(self.layout.node_slots() as u64);
            m.bytes_per_step = match &self.corot_blocks {
                Some(b) => {
                    let used = crate::layout::tensor_blocks::slot_walk(&self.layout).len() as u64;
                    elements + b.bytes_per_step() + m.bytes_per_step + used * b.slot_bytes()
                }
                None => elements,
            };
            let before = m.stats.total.max(1) as f64;
            // Under backward Euler the block pass's pair lists and blocks are beside them.
            let blocks = self.corot_blocks.iter().flat_map(|b| b.buffers());
            for (name, bytes) in c.buffers().into_iter().chain(blocks) {
                m.stats.total += bytes;
                m.stats.buffers.push((name, bytes));
            }
            let grown = m.stats.total as f64 / before;
            m.stats.bytes_per_node *= grown;
            m.stats.bytes_per_spring *= grown;
        }
        m
    }

    fn name(&self) -> String {
        self.describe()
    }

    /// The finite elements' energy when the engine steps them (the float64 model its passes
    /// keep patched, in model indices), else the springs': the divergence check and a cut's
    /// energy bookkeeping must weigh the forces this engine applies.
    fn elastic_energy(&self, model: &PackedModel, x: &[[f64; 3]]) -> f64 {
        use crate::physics::ForceModel;
        if let Some(t) = &self.tensor {
            return t.model().potential_energy(x);
        }
        if let Some(c) = &self.corot {
            return c.model().potential_energy(x);
        }
        model.elastic_energy(x)
    }

    fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<Option<PatchCost>> {
        GpuEngine::patch(self, model, diff).map(Some)
    }

    fn node_positions(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        let n = self.rest.len();
        if let Some(&i) = nodes.iter().find(|&&i| i as usize >= n) {
            return Err(crate::engine::bad_node(i, n));
        }
        let rank = &self.layout.order().rank;
        let idx: Vec<u32> = nodes.iter().map(|&i| rank[i as usize]).collect();
        let cur = buffers::read_entries(&self.ctx, self.state.bindings(self.phase).cur, &idx)?;
        Ok(nodes
            .iter()
            .zip(cur)
            .map(|(&i, u)| {
                let r = self.rest[i as usize];
                if self.fixed[i as usize] {
                    r
                } else {
                    [0, 1, 2].map(|c| r[c] + u[c] as f64)
                }
            })
            .collect())
    }

    fn node_start_positions(&self, nodes: &[u32], dt: f64) -> Result<Vec<[f64; 3]>> {
        let n = self.rest.len();
        if let Some(&i) = nodes.iter().find(|&&i| i as usize >= n) {
            return Err(crate::engine::bad_node(i, n));
        }
        let rank = &self.layout.order().rank;
        let idx: Vec<u32> = nodes.iter().map(|&i| rank[i as usize]).collect();
        let b = self.state.bindings(self.phase);
        // The current displacement less the last step: Verlet keeps that step, symplectic
        // Euler the velocity (times dt).
        let second = buffers::read_entries(&self.ctx, b.second_in, &idx)?;
        let euler = self.state.integrator.keeps_velocity();
        let cur = buffers::read_entries(&self.ctx, b.cur, &idx)?;
        Ok(nodes
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let r = self.rest[i as usize];
                if self.fixed[i as usize] {
                    return r;
                }
                [0, 1, 2].map(|c| {
                    let u = if euler {
                        cur[k][c] as f64 - dt * second[k][c] as f64
                    } else {
                        cur[k][c] as f64 - second[k][c] as f64
                    };
                    r[c] + u
                })
            })
            .collect())
    }

    fn node_velocities(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        if nodes.is_empty() {
            return Ok(Vec::new());
        }
        let n = self.rest.len();
        if let Some(&i) = nodes.iter().find(|&&i| i as usize >= n) {
            return Err(crate::engine::bad_node(i, n));
        }
        let rank = &self.layout.order().rank;
        let idx: Vec<u32> = nodes.iter().map(|&i| rank[i as usize]).collect();
        let b = self.state.bindings(self.phase);
        let second = buffers::read_entries(&self.ctx, b.second_in, &idx)?;
        let dt = self.config.dt;
        Ok(nodes
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                if self.fixed[i as usize] {
                    return [0.0; 3];
                }
                [0, 1, 2].map(|c| match self.state.integrator {
                    Integrator::Verlet => second[k][c] as f64 / dt,
                    Integrator::SymplecticEuler | Integrator::BackwardEuler => second[k][c] as f64,
                })
            })
            .collect())
    }

    fn correct_positions(&mut self, nodes: &[u32], positions: &[[f64; 3]]) -> Result<()> {
        self.forget_ahead();
        crate::engine::check_correction(nodes, positions, self.rest.len())?;
        let rank = &self.layout.order().rank;
        let b = self.state.bindings(self.phase);
        // The move is added to the second state (to the velocity over dt for symplectic Euler,
        // to the step for Verlet), as if the step had made it: read the few old states.
        let moving: Vec<(u32, [f64; 3])> = nodes
            .iter()
            .zip(positions)
            .filter(|(&i, _)| !self.fixed[i as usize])
            .map(|(&i, &p)| (i, p))
            .collect();
        let idx: Vec<u32> = moving.iter().map(|&(i, _)| rank[i as usize]).collect();
        let euler = self.config.integrator.keeps_velocity();
        let old = buffers::read_entries(&self.ctx, b.cur, &idx)?;
        let vel = buffers::read_entries(&self.ctx, b.second_in, &idx)?;
        let inv_h = if euler { 1.0 / self.config.dt } else { 1.0 };
        for (k, &(i, p)) in moving.iter().enumerate() {
            let r = self.rest[i as usize];
            let u = [0, 1, 2].map(|c| p[c] - r[c]);
            let at = idx[k] as u64 * 16;
            let cur = [u[0] as f32, u[1] as f32, u[2] as f32, 0.0];
            self.ctx
                .queue
                .write_buffer(b.cur, at, bytemuck::bytes_of(&cur));
            let v =
                [0, 1, 2].map(|c| (vel[k][c] as f64 + (u[c] - old[k][c] as f64) * inv_h) as f32);
            let v = [v[0], v[1], v[2], 0.0];
            self.ctx
                .queue
                .write_buffer(b.second_in, at, bytemuck::bytes_of(&v));
        }
        Ok(())
    }

    fn device(&self) -> Option<&dyn DeviceEngine> {
        Some(self)
    }

    fn device_mut(&mut self) -> Option<&mut dyn DeviceEngine> {
        Some(self)
    }

    fn gpu_mut(&mut self) -> Option<&mut GpuEngine> {
        Some(self)
    }

    fn nodes_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        GpuEngine::nodes_near(self, lo, hi)
    }
}

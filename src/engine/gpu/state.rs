//! The node state on the device: its buffers and their rotation, and reading and writing it
//! whole.

use super::*;

/// Node state read back from the device: current displacements and the second state.
pub(super) type StatePair = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// The node-state buffers and their rotation: current and next displacements, current and
/// next second state (the last step `u - u_prev` for Verlet, the velocity for symplectic
/// Euler), swapped after each step.
pub struct StateBuffers {
    pub(super) integrator: Integrator,
    /// Displacements (two).
    pub(super) x: Vec<wgpu::Buffer>,
    /// Second states (two).
    pub(super) v: Vec<wgpu::Buffer>,
}

/// The buffers a pass binds in one phase of the rotation.
pub struct PhaseBindings<'a> {
    /// Verlet: last steps `u - u_prev`; symplectic Euler: velocities.
    pub second_in: &'a wgpu::Buffer,
    /// Current displacements.
    pub cur: &'a wgpu::Buffer,
    /// Next displacements (written).
    pub next: &'a wgpu::Buffer,
    /// Next second state (written).
    pub second_out: &'a wgpu::Buffer,
}

impl StateBuffers {
    pub(super) fn new(
        ctx: &GpuContext,
        n: usize,
        integrator: Integrator,
        sizing: Sizing,
    ) -> Result<Self> {
        let bytes = sizing.size(ctx, (n.max(1) * 16) as u64);
        buffers::check_binding(ctx, "node state", bytes)?;
        let make = |label: &str, size: u64| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let second = match integrator {
            Integrator::Verlet => "steps",
            Integrator::SymplecticEuler | Integrator::BackwardEuler => "velocities",
        };
        Ok(StateBuffers {
            integrator,
            x: (0..2).map(|_| make("displacements", bytes)).collect(),
            v: (0..2).map(|_| make(second, bytes)).collect(),
        })
    }

    /// Nodes the buffers have room for.
    pub fn capacity(&self) -> usize {
        (self.x[0].size() / 16) as usize
    }

    /// Every buffer that holds per-node state.
    pub(super) fn buffers(&self) -> Vec<&wgpu::Buffer> {
        self.x.iter().chain(&self.v).collect()
    }

    /// New buffers with room for `n` nodes (a size class), holding this state.
    pub(super) fn grown(&self, ctx: &GpuContext, n: usize) -> Result<Self> {
        let next = StateBuffers::new(ctx, n, self.integrator, Sizing::SizeClass)?;
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("grow node state"),
            });
        for (old, new) in self.buffers().into_iter().zip(next.buffers()) {
            enc.copy_buffer_to_buffer(old, 0, new, 0, old.size());
        }
        ctx.queue.submit([enc.finish()]);
        Ok(next)
    }

    /// Number of rotation phases.
    pub fn phases(&self) -> usize {
        self.x.len()
    }

    /// What a step in `phase` reads and writes.
    pub fn bindings(&self, phase: usize) -> PhaseBindings<'_> {
        PhaseBindings {
            second_in: &self.v[phase],
            cur: &self.x[phase],
            next: &self.x[1 - phase],
            second_out: &self.v[1 - phase],
        }
    }
}

impl GpuEngine {
    /// The raw device state in layout order (holes included): current displacements and the
    /// second state (last steps for Verlet, velocities for symplectic Euler).
    pub fn raw_state(&self) -> Result<StatePair> {
        let b = self.state.bindings(self.phase);
        let n = self.layout.node_slots();
        let mut cur = buffers::read_vec4(&self.ctx, b.cur)?;
        let mut second = buffers::read_vec4(&self.ctx, b.second_in)?;
        cur.truncate(n);
        second.truncate(n);
        Ok((cur, second))
    }

    /// Overwrite the raw device state (layout order, as [`GpuEngine::raw_state`] gives it).
    pub fn set_raw_state(&mut self, cur: &[[f32; 4]], second: &[[f32; 4]]) -> Result<()> {
        self.forget_ahead();
        let n = self.layout.node_slots();
        if cur.len() != n || second.len() != n {
            return Err(crate::Error::LengthMismatch {
                given: if cur.len() != n {
                    cur.len()
                } else {
                    second.len()
                },
                expected: n,
                message: format!(
                    "raw state of {} and {} entries for a layout of {n} node slots",
                    cur.len(),
                    second.len()
                ),
            });
        }
        let b = self.state.bindings(self.phase);
        self.ctx
            .queue
            .write_buffer(b.cur, 0, bytemuck::cast_slice(cur));
        self.ctx
            .queue
            .write_buffer(b.second_in, 0, bytemuck::cast_slice(second));
        Ok(())
    }

    /// Model-order positions and velocities from the device state; NaN if the device failed,
    /// which the simulation's divergence check then reports.
    pub(super) fn state_f64(&self) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let n = self.rest.len();
        let (cur, second) = match self.raw_state() {
            Ok(s) => s,
            Err(e) => {
                eprintln!("lancet: reading the GPU state failed: {e}");
                return (vec![[f64::NAN; 3]; n], vec![[f64::NAN; 3]; n]);
            }
        };
        let dt = self.config.dt;
        let mut x = vec![[0.0; 3]; n];
        let mut v = vec![[0.0; 3]; n];
        for (new, old) in self.layout.order().pairs() {
            for c in 0..3 {
                x[old][c] = self.rest[old][c] + cur[new][c] as f64;
                v[old][c] = match self.state.integrator {
                    Integrator::Verlet => second[new][c] as f64 / dt,
                    Integrator::SymplecticEuler | Integrator::BackwardEuler => {
                        second[new][c] as f64
                    }
                };
            }
            if self.fixed[old] {
                x[old] = self.rest[old];
            }
        }
        (x, v)
    }
}

//! The divergence check on the device: pairs with `shaders/health.wgsl`. Instead of reading the
//! whole state back every few steps, the simulation reads one vec4 per 64 nodes (kinetic energy
//! and change of gravitational energy per workgroup) and the first non-finite node. The twin is [`crate::twin::health`].

use super::buffers::{self, Sizing};
use super::{GpuContext, StateBuffers};
use crate::error::{Error, Result};

/// What the pass reads back; its twin is [`crate::twin::health::health_cpu`].
pub use crate::twin::health::HealthPartials;

const SOURCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/health.wgsl")
);

/// The pass with its output buffers and one bind group per rotation phase.
pub struct HealthPass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    bind_groups: Vec<wgpu::BindGroup>,
    partials: wgpu::Buffer,
    first_bad: wgpu::Buffer,
    /// Where the first bad node (first 16 bytes) and the partials are copied for the host to
    /// read: one submission and one map per probe.
    staging: wgpu::Buffer,
}

impl HealthPass {
    /// Build the pass over the node masses `inv_mass` and the node state, for up to `groups`
    /// workgroups.
    pub fn new(
        ctx: &GpuContext,
        inv_mass: &wgpu::Buffer,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
        groups: u32,
    ) -> Result<Self> {
        let partials = buffers::storage_buffer(
            ctx,
            "health partials",
            &vec![0u8; groups.max(1) as usize * 16],
            Sizing::Headroom,
        )?;
        let first_bad = buffers::storage_buffer(ctx, "first bad node", &[0u8; 4], Sizing::Exact)?;
        let staging = buffers::staging_buffer(ctx, 16 + partials.size());
        let layout = buffers::pass_layout(ctx, "health", &[true, true, true, false, false]);
        let pipeline = buffers::compute_pipeline(ctx, "health", SOURCE, &[&layout])?;
        let mut pass = HealthPass {
            pipeline,
            layout,
            bind_groups: Vec::new(),
            partials,
            first_bad,
            staging,
        };
        pass.rebind(ctx, inv_mass, uniform, state);
        Ok(pass)
    }

    /// Bind the pass to `inv_mass`, `uniform` and the node state afresh, keeping its pipeline
    /// and outputs (after a patch replaced the mass buffer by a larger one).
    pub fn rebind(
        &mut self,
        ctx: &GpuContext,
        inv_mass: &wgpu::Buffer,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) {
        self.bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("health"),
                    layout: &self.layout,
                    entries: &buffers::entries(&[
                        uniform,
                        inv_mass,
                        b.second_in,
                        b.cur,
                        &self.partials,
                        &self.first_bad,
                    ]),
                })
            })
            .collect();
    }

    /// Whether the pass has room for a node dispatch of `groups` workgroups.
    pub fn fits(&self, groups: (u32, u32)) -> bool {
        (groups.0 * groups.1) as u64 * 16 <= self.partials.size()
    }

    /// Run the check on the state of `phase` over `groups` workgroups (the node dispatch) and
    /// read back its few bytes.
    pub fn run(
        &self,
        ctx: &GpuContext,
        phase: usize,
        groups: (u32, u32),
    ) -> Result<HealthPartials> {
        let count = (groups.0 * groups.1) as u64;
        if count * 16 > self.partials.size() {
            return Err(Error::Gpu(format!(
                "the health check has room for {} workgroups, not {count}",
                self.partials.size() / 16
            )));
        }
        ctx.queue
            .write_buffer(&self.first_bad, 0, &u32::MAX.to_le_bytes());
        // The probe and the copies of its outputs in one submission.
        let mut enc = buffers::encode_dispatch(
            ctx,
            "health",
            &self.pipeline,
            &self.bind_groups[phase],
            groups,
        );
        enc.copy_buffer_to_buffer(&self.first_bad, 0, &self.staging, 0, 4);
        enc.copy_buffer_to_buffer(&self.partials, 0, &self.staging, 16, count * 16);
        let raw = buffers::submit_and_read(ctx, enc, &self.staging, 16 + count * 16)?;
        let floats: Vec<f32> = bytemuck::pod_collect_to_vec(&raw[16..]);
        let first = u32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]]);
        Ok(HealthPartials {
            partials: floats.chunks_exact(4).map(|c| [c[0], c[1]]).collect(),
            first_bad: (first != u32::MAX).then_some(first),
        })
    }
}

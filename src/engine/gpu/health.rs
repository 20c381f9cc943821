//! The divergence check on the device: pairs with `shaders/health.wgsl`. Instead of reading the
//! whole state back every few steps, the simulation reads one vec4 per 64 nodes (kinetic energy
//! and change of gravitational energy per workgroup) and the first non-finite node.

use super::buffers::{self, Sizing};
use super::{GpuContext, NodeState};
use crate::error::{Error, Result};
use crate::physics::{velocity, StepParams};

const SOURCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/health.wgsl")
);

/// What the check reads back: per-workgroup sums and the first non-finite node.
#[derive(Debug, Clone, PartialEq)]
pub struct HealthPartials {
    /// Per workgroup of 64 nodes: kinetic energy and change of gravitational energy, J.
    pub partials: Vec<[f32; 2]>,
    /// Lowest layout index whose displacement or second state is not finite.
    pub first_bad: Option<u32>,
}

impl HealthPartials {
    /// Total kinetic energy and change of gravitational energy, summed in float64.
    pub fn totals(&self) -> (f64, f64) {
        self.partials
            .iter()
            .fold((0.0, 0.0), |(k, g), p| (k + p[0] as f64, g + p[1] as f64))
    }
}

/// The check on the CPU exactly as `shaders/health.wgsl` computes it (the same pairwise tree in
/// each workgroup of 64 nodes).
pub fn health_cpu(
    p: &StepParams,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    second: &[[f32; 4]],
) -> HealthPartials {
    let n = cur.len();
    let finite = |v: &[f32; 4]| v[..3].iter().all(|x| x.is_finite());
    let mut first_bad = None;
    let mut partials = Vec::with_capacity(n.div_ceil(64));
    for start in (0..n.max(1)).step_by(64) {
        let mut k = [0.0f32; 64];
        let mut g = [0.0f32; 64];
        for l in 0..64 {
            let i = start + l;
            if i >= n {
                continue;
            }
            if !finite(&cur[i]) || !finite(&second[i]) {
                first_bad = first_bad.or(Some(i as u32));
            } else if inv_mass[i] > 0.0 {
                let m = 1.0 / inv_mass[i];
                let v = velocity(p, cur[i], second[i]);
                k[l] = 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
                let gu =
                    p.gravity[0] * cur[i][0] + p.gravity[1] * cur[i][1] + p.gravity[2] * cur[i][2];
                g[l] = -m * gu;
            }
        }
        let mut stride = 32;
        while stride > 0 {
            for l in 0..stride {
                k[l] += k[l + stride];
                g[l] += g[l + stride];
            }
            stride /= 2;
        }
        partials.push([k[0], g[0]]);
    }
    HealthPartials {
        partials,
        first_bad,
    }
}

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
        state: &NodeState,
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
        state: &NodeState,
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

//! Device-side timing of a step's compute pass with timestamp queries, on adapters with
//! `TIMESTAMP_QUERY`: the pass writes a timestamp at its start and end, the encoder resolves
//! both into a small buffer after the pass, and the host reads them back only when asked.
//! Wall-clock time of a step includes submission and the wait; this is the device's own time.

use super::{buffers, GpuContext};
use crate::error::Result;

/// Two timestamps around the last recorded step pass.
pub struct PassTimer {
    queries: wgpu::QuerySet,
    /// The resolved pair (2 x u64 nanosecond ticks).
    resolved: wgpu::Buffer,
    /// Nanoseconds per tick.
    period: f64,
}

impl PassTimer {
    /// A timer on devices opened with `TIMESTAMP_QUERY`; `None` on the others.
    pub fn new(ctx: &GpuContext) -> Option<Self> {
        if !ctx
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
        {
            return None;
        }
        let queries = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("step pass timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let resolved = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("resolved timestamps"),
            size: 16,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Some(PassTimer {
            queries,
            resolved,
            period: ctx.queue.get_timestamp_period() as f64,
        })
    }

    /// The timestamp writes of a step pass.
    pub fn writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }

    /// Record, after the pass, the resolution of its two timestamps.
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.queries, 0..2, &self.resolved, 0);
    }

    /// Seconds the device spent in the last resolved pass; `None` if the timestamps are not
    /// ordered (a device that does not advance them, or a counter that wrapped).
    pub fn last_seconds(&self, ctx: &GpuContext) -> Result<Option<f64>> {
        // The 16 bytes come back through the vec4 readback; the bits are what matter.
        let raw = buffers::read_vec4(ctx, &self.resolved)?;
        let Some(first) = raw.first() else {
            return Ok(None);
        };
        let [start, end]: [u64; 2] = bytemuck::cast(*first);
        Ok((end > start).then(|| (end - start) as f64 * self.period * 1e-9))
    }
}

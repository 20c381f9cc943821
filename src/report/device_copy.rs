//! The memory-bandwidth floor of a GPU: a compute pass that copies one array into another on
//! the device, measured in the same run as the benchmarks.
//!
//! A GPU step streams the spring data and node state from the device's own memory, so its floor
//! is what the device can copy, not what the host can stream (an H100 copies at about 3 TB/s,
//! its host at about 0.1 TB/s). On a CPU device (lavapipe) the two are the same memory.

#[cfg(feature = "gpu")]
use crate::engine::gpu::GpuContext;
#[cfg(feature = "gpu")]
use crate::error::{Error, Result};

/// Result of the device copy.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DeviceBandwidth {
    /// Best bytes per second over the timed submissions, counting each byte read and written
    /// (as STREAM's copy does).
    pub bytes_per_s: f64,
    /// Bytes per copy.
    pub bytes: u64,
    /// The device, as `GpuContext::describe` names it.
    pub device: String,
    /// The faster way of copying, which sets the floor: "compute pass" (one vec4 per
    /// invocation, as the steps move data; the faster on GPUs) or "buffer copy" (the copy
    /// command; the faster on a CPU device such as lavapipe, whose compute passes pay for each
    /// invocation).
    pub method: &'static str,
}

#[cfg(feature = "gpu")]
const SOURCE: &str = include_str!("../../shaders/device_copy.wgsl");

/// Seconds of copying before the timed submissions (see [`device_copy`]).
#[cfg(feature = "gpu")]
const WARM_UP_S: f64 = 0.5;

/// Copy an array of up to 256 MiB (far past any GPU cache; smaller where the device's bindings
/// are limited) into another, both with a compute pass that moves one vec4 per invocation (the
/// way the steps move their arrays) and with the copy command, and keep the faster: many copies
/// per submission so that submitting and waiting are a small part of the time, and the best of
/// five submissions. The copy command alone is not the floor of a GPU: on an H100 it read
/// 840 GB/s where the steps reached 1,700 GB/s.
#[cfg(feature = "gpu")]
pub fn device_copy(ctx: &GpuContext) -> Result<DeviceBandwidth> {
    use crate::engine::gpu::buffers;
    use wgpu::util::DeviceExt;
    // Engines dropped before this still hold their memory until the device is polled: free it
    // first, so that the arrays below are placed as on an idle device.
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu(format!("device copy: {e}")))?;
    let bytes = (256u64 << 20)
        .min(ctx.limits.max_buffer_size)
        .min(ctx.limits.max_storage_buffer_binding_size)
        & !4095;
    let vec4s = (bytes / 16) as u32;
    let storage = |label, usage| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | usage,
            mapped_at_creation: false,
        })
    };
    let src = storage("copy source", wgpu::BufferUsages::COPY_SRC);
    let dst = storage("copy destination", wgpu::BufferUsages::COPY_DST);
    let n = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("copy count"),
            contents: bytemuck::cast_slice(&[vec4s, 0, 0, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
    let (layout, pipeline) = copy_pass(ctx)?;
    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("device copy"),
        layout: &layout,
        entries: &buffers::entries(&[&n, &src, &dst]),
    });
    // The steps' workgroups and grid, so that the copy moves data as they do.
    let grid = crate::engine::gpu::dispatch_size(ctx, vec4s);
    // Each way of copying, timed alone.
    let timed = |copies: u32, pass: bool| -> Result<f64> {
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("copy"),
            });
        for _ in 0..copies {
            if pass {
                buffers::record_dispatch(&mut enc, "device copy", &pipeline, &group, grid);
            } else {
                enc.copy_buffer_to_buffer(&src, 0, &dst, 0, bytes);
            }
        }
        let t = std::time::Instant::now();
        ctx.queue.submit([enc.finish()]);
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("device copy: {e}")))?;
        Ok(t.elapsed().as_secs_f64())
    };
    let best_of = |pass: bool| -> Result<f64> {
        // The first copy pays for first touches (memory is committed on first use); the
        // second sets how many copies take about 50 ms.
        timed(1, pass)?;
        let once = timed(1, pass)?.max(1e-6);
        let copies = ((0.05 / once).ceil() as u32).clamp(1, 4096);
        // Half a second of copies first, for a GPU whose clock follows its load (an H100
        // idles at a third of its clock): on one, 2,734-2,735 GB/s with it against 2,689-2,695
        // without, alternated after the same light rows.
        let warm = std::time::Instant::now();
        while warm.elapsed().as_secs_f64() < WARM_UP_S {
            timed(copies, pass)?;
        }
        let mut best = f64::INFINITY;
        for _ in 0..5 {
            best = best.min(timed(copies, pass)? / copies as f64);
        }
        Ok(best)
    };
    let (pass, copy) = (best_of(true)?, best_of(false)?);
    let best = pass.min(copy);
    Ok(DeviceBandwidth {
        bytes_per_s: 2.0 * vec4s as f64 * 16.0 / best,
        bytes: vec4s as u64 * 16,
        device: ctx.describe(),
        method: if pass <= copy {
            "compute pass"
        } else {
            "buffer copy"
        },
    })
}

/// The copy pass: its bind-group layout and pipeline, shared by [`device_copy`] and
/// [`copy_on_device`].
#[cfg(feature = "gpu")]
fn copy_pass(ctx: &GpuContext) -> Result<(wgpu::BindGroupLayout, wgpu::ComputePipeline)> {
    use crate::engine::gpu::buffers;
    let layout = buffers::pass_layout(ctx, "device copy", &[true, false]);
    let pipeline = buffers::compute_pipeline(ctx, "device copy", SOURCE, &[&layout])?;
    Ok((layout, pipeline))
}

/// `data` copied by one dispatch of the pass [`device_copy`] times, in the grid it uses, and
/// read back: what its twin ([`crate::twin::device_copy`]) gives, every entry once. The
/// destination starts with every bit set (NaNs), so an entry the pass skips shows; a
/// measurement of a pass that copied only part of its array would overstate the floor.
#[cfg(feature = "gpu")]
pub fn copy_on_device(ctx: &GpuContext, data: &[[f32; 4]]) -> Result<Vec<[f32; 4]>> {
    use crate::engine::gpu::buffers;
    use wgpu::util::DeviceExt;
    if data.is_empty() {
        return Ok(Vec::new());
    }
    let n = u32::try_from(data.len())
        .map_err(|_| Error::Gpu(format!("device copy: {} entries past u32", data.len())))?;
    let bytes = 16 * data.len() as u64;
    let init = |label, contents: &[u8], usage| {
        ctx.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
    };
    let src = init(
        "copy source",
        bytemuck::cast_slice(data),
        wgpu::BufferUsages::STORAGE,
    );
    let dst = init(
        "copy destination",
        &vec![0xff; bytes as usize],
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    );
    let count = init(
        "copy count",
        bytemuck::cast_slice(&[n, 0, 0, 0]),
        wgpu::BufferUsages::UNIFORM,
    );
    let (layout, pipeline) = copy_pass(ctx)?;
    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("device copy"),
        layout: &layout,
        entries: &buffers::entries(&[&count, &src, &dst]),
    });
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("copy check"),
        });
    let grid = crate::engine::gpu::dispatch_size(ctx, n);
    buffers::record_dispatch(&mut enc, "device copy", &pipeline, &group, grid);
    let staging = buffers::staging_buffer(ctx, bytes);
    enc.copy_buffer_to_buffer(&dst, 0, &staging, 0, bytes);
    let raw = buffers::submit_and_read(ctx, enc, &staging, bytes)?;
    Ok(bytemuck::pod_collect_to_vec(&raw))
}

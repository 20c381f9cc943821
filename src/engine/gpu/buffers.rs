//! Small wgpu helpers shared by the passes: binding entries, pipelines built inside an error
//! scope, limit checks, and readback.

use super::GpuContext;
use crate::error::{Error, Result};

/// A storage-buffer binding visible to compute.
pub fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A uniform-buffer binding visible to compute.
pub fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// The layout every pass here uses: the step constants at binding 0, then one storage buffer
/// per entry of `read_only` (true for read-only) at bindings 1, 2, ...
pub fn pass_layout(ctx: &GpuContext, label: &str, read_only: &[bool]) -> wgpu::BindGroupLayout {
    let entries: Vec<_> = std::iter::once(uniform_entry(0))
        .chain(
            read_only
                .iter()
                .enumerate()
                .map(|(i, &r)| storage_entry(i as u32 + 1, r)),
        )
        .collect();
    ctx.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &entries,
        })
}

/// Bind-group entries binding `buffers[i]` whole at binding `i`.
pub fn entries<'a>(buffers: &[&'a wgpu::Buffer]) -> Vec<wgpu::BindGroupEntry<'a>> {
    buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect()
}

/// Compile `source` and build a compute pipeline with entry point `main`; a shader or
/// validation problem becomes an error instead of a panic.
pub fn compute_pipeline(
    ctx: &GpuContext,
    label: &str,
    source: &str,
    layouts: &[&wgpu::BindGroupLayout],
) -> Result<wgpu::ComputePipeline> {
    compute_pipeline_at(ctx, label, source, "main", layouts)
}

/// [`compute_pipeline`] with entry point `entry`, for a shader with several.
pub fn compute_pipeline_at(
    ctx: &GpuContext,
    label: &str,
    source: &str,
    entry: &str,
    layouts: &[&wgpu::BindGroupLayout],
) -> Result<wgpu::ComputePipeline> {
    let d = &ctx.device;
    let scope = d.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &layouts.iter().map(|l| Some(*l)).collect::<Vec<_>>(),
        immediate_size: 0,
    });
    let pipeline = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    match pollster::block_on(scope.pop()) {
        None => Ok(pipeline),
        Some(e) => Err(Error::Gpu(format!("pipeline {label}: {e}"))),
    }
}

/// Fail with a clear error when a buffer exceeds what one binding may hold on this device.
pub fn check_binding(ctx: &GpuContext, what: &str, bytes: u64) -> Result<()> {
    let max = ctx
        .limits
        .max_storage_buffer_binding_size
        .min(ctx.limits.max_buffer_size);
    if bytes > max {
        return Err(Error::Gpu(format!(
            "{what} needs {bytes} bytes but {} binds at most {max} bytes per buffer; use a \
             smaller mesh, a layout without padding (valence or edges), or the cpu engine",
            ctx.info.name
        )));
    }
    Ok(())
}

/// How much room a buffer gets beyond its data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sizing {
    /// Exactly the data.
    Exact,
    /// The data and an eighth more, at least [`MIN_HEADROOM`] bytes: the first upload, so that
    /// the first cuts (a few percent more nodes and springs on a large mesh, many percent on a
    /// small one) fit without reallocating.
    Headroom,
    /// The next power of two (after a patch outgrew a buffer: room for the next edits).
    SizeClass,
}

/// Least room a first upload leaves in a buffer: a small mesh grows by a large fraction of
/// itself at each cut, and reallocating means uploading everything again.
pub const MIN_HEADROOM: u64 = 16 << 10;

impl Sizing {
    /// Bytes to allocate for `bytes` of data on `ctx`: at least one element of the largest
    /// struct bound (32 bytes), since an empty binding is invalid; room is never made past the
    /// binding limit.
    pub fn size(self, ctx: &GpuContext, bytes: u64) -> u64 {
        let bytes = bytes.max(32);
        // Whole words: a buffer's size is rounded up to them, which must not pass the limit
        // that `check_binding` holds a request to.
        let max = ctx
            .limits
            .max_storage_buffer_binding_size
            .min(ctx.limits.max_buffer_size)
            & !3;
        match self {
            Sizing::Exact => bytes,
            // Never past the binding limit for the room alone.
            Sizing::Headroom => (bytes + (bytes / 8).max(MIN_HEADROOM))
                .min(max)
                .max(bytes)
                .next_multiple_of(16),
            Sizing::SizeClass => bytes.next_power_of_two().min(max).max(bytes),
        }
    }
}

/// A storage buffer holding `data` (which may be empty: bindings never are), sized by
/// `sizing`, writable by queue writes so patches can update it in place.
pub fn storage_buffer(
    ctx: &GpuContext,
    label: &str,
    data: &[u8],
    sizing: Sizing,
) -> Result<wgpu::Buffer> {
    let buffer = zeroed_storage(ctx, label, data.len() as u64, sizing)?;
    // New buffers are zeroed; the data (a whole number of 4-byte words) lands before the next
    // submission.
    if !data.is_empty() {
        ctx.queue.write_buffer(&buffer, 0, data);
    }
    Ok(buffer)
}

/// A zeroed storage buffer with room for `bytes` by `sizing`, a copy source and destination
/// (patches write it in place, a grown successor copies from it).
pub fn zeroed_storage(
    ctx: &GpuContext,
    label: &str,
    bytes: u64,
    sizing: Sizing,
) -> Result<wgpu::Buffer> {
    let size = sizing.size(ctx, bytes).next_multiple_of(4);
    check_binding(ctx, label, size)?;
    Ok(ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    }))
}

/// What replacing a buffer by a larger one cost.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Growth {
    /// Bytes written from the host.
    pub uploaded: u64,
    /// Bytes copied from the old buffer to the new one on the device.
    pub copied: u64,
}

impl std::ops::AddAssign for Growth {
    fn add_assign(&mut self, o: Growth) {
        self.uploaded += o.uploaded;
        self.copied += o.copied;
    }
}

/// A buffer of the next size class holding `data`, to replace `old`, which `data` outgrew and
/// which holds `data` as it was before a patch: equal to it outside the byte ranges `dirty`
/// (ascending, 4-byte aligned) up to the old buffer's end. Either the old buffer is copied
/// whole on the device and only the dirty ranges and the bytes past the old buffer are
/// written, or, where that would upload as much (a rewrite of the whole array), `data` is
/// written whole. Bytes between the old array's end and the old buffer's end are copied as
/// they lie: a caller whose old buffer holds stale bytes there names them in `dirty`.
pub fn grown(
    ctx: &GpuContext,
    label: &str,
    old: &wgpu::Buffer,
    data: &[u8],
    dirty: &[std::ops::Range<u64>],
) -> Result<(wgpu::Buffer, Growth)> {
    let len = data.len() as u64;
    // Bytes the device may keep: the old buffer, cut to the new array.
    let keep = old.size().min(len);
    let inside = |r: &std::ops::Range<u64>| r.start..r.end.min(keep);
    let stale: u64 = dirty
        .iter()
        .map(|r| inside(r).end.saturating_sub(r.start))
        .sum();
    if stale + (len - keep) >= len {
        let buffer = storage_buffer(ctx, label, data, Sizing::SizeClass)?;
        return Ok((
            buffer,
            Growth {
                uploaded: len,
                copied: 0,
            },
        ));
    }
    let buffer = zeroed_storage(ctx, label, len, Sizing::SizeClass)?;
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("grow buffer"),
        });
    enc.copy_buffer_to_buffer(old, 0, &buffer, 0, keep);
    // Queue writes land at the start of the next submission: after this copy.
    ctx.queue.submit([enc.finish()]);
    for r in dirty.iter().map(inside).filter(|r| r.start < r.end) {
        ctx.queue
            .write_buffer(&buffer, r.start, &data[r.start as usize..r.end as usize]);
    }
    if keep < len {
        ctx.queue
            .write_buffer(&buffer, keep, &data[keep as usize..]);
    }
    Ok((
        buffer,
        Growth {
            uploaded: stale + (len - keep),
            copied: keep,
        },
    ))
}

/// Bring `buffer` (whose contents are `host`) to `data`, writing only the runs of elements that
/// differ; a buffer too small is replaced by one of the next size class holding all of `data`.
/// Returns the bytes written and whether the buffer was replaced (bind groups must then be
/// rebuilt). Comparing on the host costs a pass over `data`, far less than uploading it.
pub fn write_changed<T: bytemuck::Pod + PartialEq>(
    ctx: &GpuContext,
    label: &str,
    buffer: &mut wgpu::Buffer,
    host: &mut Vec<T>,
    data: &[T],
) -> Result<(u64, bool)> {
    let elem = std::mem::size_of::<T>();
    let bytes = std::mem::size_of_val(data) as u64;
    if bytes > buffer.size() {
        *buffer = storage_buffer(ctx, label, bytemuck::cast_slice(data), Sizing::SizeClass)?;
        host.clear();
        host.extend_from_slice(data);
        return Ok((bytes, true));
    }
    let mut written = 0u64;
    for run in changed_runs(host, data, 16) {
        ctx.queue.write_buffer(
            buffer,
            (run.start * elem) as u64,
            bytemuck::cast_slice(&data[run.clone()]),
        );
        written += (run.len() * elem) as u64;
    }
    host.clear();
    host.extend_from_slice(data);
    Ok((written, false))
}

/// Write the elements `indices` of `host` (what `buffer` should hold everywhere) to `buffer`,
/// one write per run of indices less than [`super::WRITE_GAP`] bytes apart (the elements
/// between go too: each write has a cost of its own, a staging buffer, that a few hundred bytes
/// do not). Returns the bytes written.
pub fn write_slots<T: bytemuck::Pod>(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    host: &[T],
    indices: &mut Vec<u32>,
) -> u64 {
    indices.sort_unstable();
    indices.dedup();
    let elem = std::mem::size_of::<T>();
    let gap = (super::WRITE_GAP as usize / elem.max(1)).max(1);
    let mut written = 0;
    let mut k = 0;
    while k < indices.len() {
        let start = indices[k] as usize;
        let mut end = start + 1;
        while k + 1 < indices.len() && indices[k + 1] as usize <= end + gap {
            k += 1;
            end = indices[k] as usize + 1;
        }
        k += 1;
        ctx.queue.write_buffer(
            buffer,
            (start * elem) as u64,
            bytemuck::cast_slice(&host[start..end]),
        );
        written += ((end - start) * elem) as u64;
    }
    written
}

/// The element ranges where `data` differs from `old` (elements past the end of `old` differ),
/// ascending; runs separated by at most `gap` equal elements are merged into one (fewer,
/// larger copies).
pub fn changed_runs<T: PartialEq>(
    old: &[T],
    data: &[T],
    gap: usize,
) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    for (i, d) in data.iter().enumerate() {
        if old.get(i) == Some(d) {
            continue;
        }
        match runs.last_mut() {
            Some(r) if i - r.end <= gap => r.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    runs
}

/// Copy `src` into a mappable buffer and read it back as vec4s.
pub fn read_vec4(ctx: &GpuContext, src: &wgpu::Buffer) -> Result<Vec<[f32; 4]>> {
    Ok(bytemuck::pod_collect_to_vec(&read_bytes(
        ctx,
        src,
        src.size(),
    )?))
}

/// An encoder holding one dispatch of `pipeline` over `groups` workgroups (x, y) with
/// `bind_group`, for the passes that run alone between steps (culling, finding nodes, the
/// health probe): the copies that read their output back follow in the same submission.
pub fn encode_dispatch(
    ctx: &GpuContext,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    groups: (u32, u32),
) -> wgpu::CommandEncoder {
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    record_dispatch(&mut enc, label, pipeline, bind_group, groups);
    enc
}

/// Record one compute pass of a single dispatch into `enc` (after whatever it holds).
pub fn record_dispatch(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    groups: (u32, u32),
) {
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind_group, &[]);
    pass.dispatch_workgroups(groups.0, groups.1, 1);
}

/// Read back the vec4 entries `indices` of `src`: each is copied next to the others on the
/// device, so only `16 * indices.len()` bytes cross back.
pub fn read_entries(
    ctx: &GpuContext,
    src: &wgpu::Buffer,
    indices: &[u32],
) -> Result<Vec<[f32; 4]>> {
    if indices.is_empty() {
        return Ok(Vec::new());
    }
    let size = indices.len() as u64 * 16;
    let gathered = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("gathered entries"),
        size,
        usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("gather entries"),
        });
    for (k, &i) in indices.iter().enumerate() {
        enc.copy_buffer_to_buffer(src, i as u64 * 16, &gathered, k as u64 * 16, 16);
    }
    ctx.queue.submit([enc.finish()]);
    Ok(bytemuck::pod_collect_to_vec(&read_bytes(
        ctx, &gathered, size,
    )?))
}

/// Read back the first `size` bytes of `src` (a multiple of 4).
pub fn read_bytes(ctx: &GpuContext, src: &wgpu::Buffer, size: u64) -> Result<Vec<u8>> {
    let staging = staging_buffer(ctx, size);
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback"),
        });
    enc.copy_buffer_to_buffer(src, 0, &staging, 0, size);
    submit_and_read(ctx, enc, &staging, size)
}

/// A buffer the host can map to read `size` bytes copied into it.
pub fn staging_buffer(ctx: &GpuContext, size: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Submit `enc` (whose last command copies into `staging`), wait for it and read the first
/// `size` bytes of `staging` back: the work and its readback in one submission.
pub fn submit_and_read(
    ctx: &GpuContext,
    enc: wgpu::CommandEncoder,
    staging: &wgpu::Buffer,
    size: u64,
) -> Result<Vec<u8>> {
    let index = ctx.queue.submit([enc.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, ..size, move |r| {
        let _ = tx.send(r);
    });
    ctx.device
        .poll(wgpu::PollType::Wait {
            submission_index: Some(index),
            timeout: None,
        })
        .map_err(|e| Error::Gpu(format!("waiting for the device: {e}")))?;
    rx.recv()
        .map_err(|_| Error::Gpu("readback was never answered".into()))?
        .map_err(|e| Error::Gpu(format!("mapping the readback buffer: {e}")))?;
    let bytes = staging
        .get_mapped_range(..size)
        .map_err(|e| Error::Gpu(format!("reading the mapped buffer: {e}")))?
        .to_vec();
    staging.unmap();
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::changed_runs;
    use proptest::prelude::*;

    proptest! {
        /// Writing the runs over the old contents gives the new ones, runs are ascending and
        /// apart by more than the gap, and every run starts and ends on a changed element.
        #[test]
        fn runs_cover_exactly_the_changes(
            old in proptest::collection::vec(0u8..3, 0..80),
            new in proptest::collection::vec(0u8..3, 0..80),
            gap in 0usize..5,
        ) {
            let runs = changed_runs(&old, &new, gap);
            let mut copy = old.clone();
            copy.resize(new.len(), 255);
            for r in &runs {
                copy[r.clone()].copy_from_slice(&new[r.clone()]);
                prop_assert!(old.get(r.start) != Some(&new[r.start]));
                prop_assert!(old.get(r.end - 1) != Some(&new[r.end - 1]));
            }
            prop_assert_eq!(&copy[..], &new[..]);
            for w in runs.windows(2) {
                prop_assert!(w[1].start > w[0].end + gap);
            }
        }
    }
}

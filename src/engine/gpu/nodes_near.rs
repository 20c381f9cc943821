//! Nodes in a box on the device: pairs with `shaders/nodes_near.wgsl`. A cut needs the current
//! positions of the nodes near its blade only; this pass finds them where the state lives and
//! reads back just their displacements (16 bytes each, with the counter in the same buffer: one
//! round trip), instead of every node's state. Built with the surface culler, whose rest
//! positions it reads, so that a cut never waits for a pipeline to compile.
//!
//! The pass can also be recorded at the end of a step's commands, its output copied to a
//! buffer of its own that is mapped once the step is submitted ([`NodesNear::record_ahead`]):
//! the wait for the step then brings the read back too, and the cut that follows is served
//! from it ([`NodesNear::take_ahead`]) with no round trip of its own.

use bytemuck::{Pod, Zeroable};

use super::buffers::{self, Sizing};
use super::{dispatch_size, GpuContext, StateBuffers, WORKGROUP};
use crate::error::{Error, Result};

const SOURCE: &str = include_str!("../../../shaders/nodes_near.wgsl");

/// Mirrors `struct NearParams` in `shaders/nodes_near.wgsl` (48 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct NearParams {
    lo: [f32; 4],
    hi: [f32; 4],
    slots: u32,
    capacity: u32,
    row: u32,
    _pad: u32,
}

const _: () = assert!(std::mem::size_of::<NearParams>() == 48);

/// Bytes before the entries in the output buffer (the counter and its padding).
const HEADER: u64 = 16;

/// Entries the output holds at first: the nodes near a few-centimetre incision in centimetre
/// cells, with room; grown by size class when a cut finds more.
const FIRST_CAPACITY: u64 = 2048;

/// The pass and its output buffer.
pub struct NodesNear {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    found: wgpu::Buffer,
    /// Where `found` is copied for the host to read, kept from one cut to the next.
    staging: wgpu::Buffer,
    /// One bind group per rotation phase (the displacement buffer differs).
    bind_groups: Vec<wgpu::BindGroup>,
    /// Where a read made at the end of a step is copied (apart from `staging`, which a direct
    /// read may use while this one is mapped).
    ahead: wgpu::Buffer,
    /// A read made with the last step, until the state changes.
    read_ahead: Option<Ahead>,
}

/// One node found: its layout slot and its displacement.
pub type Found = (u32, [f32; 3]);

impl NodesNear {
    /// Compile the pass and bind it to `rest` (positions in layout order) and the node state.
    pub fn new(ctx: &GpuContext, rest: &wgpu::Buffer, state: &StateBuffers) -> Result<Self> {
        let params = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("nodes near params"),
            size: std::mem::size_of::<NearParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // rest, displacements (read); found (written).
        let layout = buffers::pass_layout(ctx, "nodes near", &[true, true, false]);
        let pipeline = buffers::compute_pipeline(ctx, "nodes near", SOURCE, &[&layout])?;
        let found = found_buffer(ctx, FIRST_CAPACITY)?;
        let staging = buffers::staging_buffer(ctx, found.size());
        let ahead = buffers::staging_buffer(ctx, found.size());
        let mut pass = NodesNear {
            pipeline,
            layout,
            params,
            found,
            staging,
            bind_groups: Vec::new(),
            ahead,
            read_ahead: None,
        };
        pass.rebind(ctx, rest, state);
        Ok(pass)
    }

    /// Rebuild the bind groups (after the rest positions, the node state or the output buffer
    /// was reallocated).
    pub fn rebind(&mut self, ctx: &GpuContext, rest: &wgpu::Buffer, state: &StateBuffers) {
        self.bind_groups = (0..state.phases())
            .map(|phase| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("nodes near"),
                    layout: &self.layout,
                    entries: &buffers::entries(&[
                        &self.params,
                        rest,
                        state.bindings(phase).cur,
                        &self.found,
                    ]),
                })
            })
            .collect();
    }

    /// The node slots among the first `slots` whose current position (rest + displacement, in
    /// float32) lies in `lo..=hi`, with their displacements, at the state of `phase`, in the
    /// order the device appended them (no order: sort them).
    #[allow(clippy::too_many_arguments)]
    pub fn find(
        &mut self,
        ctx: &GpuContext,
        rest: &wgpu::Buffer,
        state: &StateBuffers,
        phase: usize,
        slots: u32,
        lo: [f32; 3],
        hi: [f32; 3],
    ) -> Result<Vec<Found>> {
        loop {
            let capacity = self.record(ctx, slots, lo, hi);
            // The pass and the copy of its output in one submission: one round trip.
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("nodes near"),
                });
            self.encode(ctx, &mut enc, phase, slots, &self.staging);
            let size = self.found.size();
            let raw = buffers::submit_and_read(ctx, enc, &self.staging, size)?;
            if let Some(found) = entries(&raw, capacity)? {
                return Ok(found);
            }
            // More nodes than room: grow to hold them all and run again.
            let count = counter(&raw)?;
            self.found = found_buffer(ctx, count)?;
            self.staging = buffers::staging_buffer(ctx, self.found.size());
            self.rebind(ctx, rest, state);
        }
    }

    /// Record the pass for the box `lo..=hi` at the end of `enc` (a step's commands, so that it
    /// sees the state the step leaves, `phase`), its output copied to a buffer of its own; call
    /// [`NodesNear::map_ahead`] once `enc` is submitted. A later [`NodesNear::take_ahead`]
    /// then needs no round trip of its own: the read came back with the step.
    pub fn record_ahead(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        phase: usize,
        slots: u32,
        lo: [f32; 3],
        hi: [f32; 3],
    ) {
        self.forget_ahead();
        let size = self.found.size();
        if self.ahead.size() < size {
            self.ahead = buffers::staging_buffer(ctx, size);
        }
        self.record(ctx, slots, lo, hi);
        self.encode(ctx, enc, phase, slots, &self.ahead);
        self.read_ahead = Some(Ahead {
            lo,
            hi,
            size,
            state: AheadState::Recorded,
        });
    }

    /// Start mapping the read recorded by [`NodesNear::record_ahead`], whose commands have just
    /// been submitted as `submitted`; it completes at the device's next poll after the step.
    pub fn map_ahead(&mut self, submitted: wgpu::SubmissionIndex) {
        let Some(ahead) = self
            .read_ahead
            .as_mut()
            .filter(|a| matches!(a.state, AheadState::Recorded))
        else {
            return;
        };
        let (tx, rx) = std::sync::mpsc::channel();
        self.ahead
            .map_async(wgpu::MapMode::Read, ..ahead.size, move |r| {
                let _ = tx.send(r);
            });
        ahead.state = AheadState::Mapping(rx, submitted);
    }

    /// Drop a read made ahead (the state it saw has changed), leaving its buffer unmapped and
    /// free for the next one: a pending map is aborted, a failed one left alone (wgpu has
    /// already put the buffer back).
    pub fn forget_ahead(&mut self) {
        if let Some(Ahead {
            state: AheadState::Mapping(rx, _),
            ..
        }) = self.read_ahead.take()
        {
            if !matches!(rx.try_recv(), Ok(Err(_))) {
                self.ahead.unmap();
            }
        }
    }

    /// The nodes found ahead in a box holding `lo..=hi` (all of that box's, to be narrowed by
    /// the caller), waiting for the step that found them if it is still running; `None`
    /// where no read was made ahead, its box does not hold this one, or its output ran out of
    /// room (then [`NodesNear::find`] reads, and grows the output). The read stays until
    /// [`NodesNear::forget_ahead`], so several reads between two steps (several blades) are
    /// all served by it.
    pub fn take_ahead(
        &mut self,
        ctx: &GpuContext,
        lo: [f32; 3],
        hi: [f32; 3],
    ) -> Result<Option<Vec<Found>>> {
        let Some(ahead) = self.read_ahead.as_mut() else {
            return Ok(None);
        };
        if !(0..3).all(|c| ahead.lo[c] <= lo[c] && hi[c] <= ahead.hi[c]) {
            return Ok(None);
        }
        if let AheadState::Mapping(rx, submitted) = &ahead.state {
            let (raw, unmap) = read_mapped(ctx, &self.ahead, rx, submitted, ahead.size);
            if unmap {
                self.ahead.unmap();
            }
            match raw.and_then(|raw| entries(&raw, room(ahead.size))) {
                Ok(found) => ahead.state = AheadState::Read(found),
                Err(e) => {
                    self.read_ahead = None;
                    return Err(e);
                }
            }
        }
        Ok(match &ahead.state {
            AheadState::Read(found) => found.clone(),
            _ => None,
        })
    }

    /// Write the box and clear the counter (queued before the next submission); returns the
    /// output's room in entries.
    fn record(&self, ctx: &GpuContext, slots: u32, lo: [f32; 3], hi: [f32; 3]) -> u64 {
        let groups = dispatch_size(ctx, slots);
        let capacity = room(self.found.size());
        let params = NearParams {
            lo: [lo[0], lo[1], lo[2], 0.0],
            hi: [hi[0], hi[1], hi[2], 0.0],
            slots,
            capacity: capacity as u32,
            row: groups.0 * WORKGROUP,
            _pad: 0,
        };
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        ctx.queue.write_buffer(&self.found, 0, &[0u8; 4]);
        capacity
    }

    /// The pass over `slots` nodes at `phase`, then the copy of its output into `to`.
    fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        phase: usize,
        slots: u32,
        to: &wgpu::Buffer,
    ) {
        let groups = dispatch_size(ctx, slots);
        buffers::record_dispatch(
            enc,
            "nodes near",
            &self.pipeline,
            &self.bind_groups[phase],
            groups,
        );
        enc.copy_buffer_to_buffer(&self.found, 0, to, 0, self.found.size());
    }
}

/// A read recorded at the end of a step: the box it tested, the bytes of the output copied
/// then, and how far it has come.
struct Ahead {
    lo: [f32; 3],
    hi: [f32; 3],
    size: u64,
    state: AheadState,
}

/// Answers a map of a readback buffer.
type MapAnswer = std::sync::mpsc::Receiver<std::result::Result<(), wgpu::BufferAsyncError>>;

enum AheadState {
    /// In a step's commands, not yet submitted.
    Recorded,
    /// Submitted (as the index given); the buffer is being mapped (answered when the step has
    /// run).
    Mapping(MapAnswer, wgpu::SubmissionIndex),
    /// Read back and unmapped: the entries found (`None`: more than the output held).
    Read(Option<Vec<Found>>),
}

/// The first `size` bytes of `buffer`, whose map `answer` answers, waiting for the submission
/// `submitted` that wrote it if the map is still pending; and whether the caller must unmap the
/// buffer (it is mapped, or its map is still pending and unmapping aborts it; a failed map has
/// left it unmapped).
fn read_mapped(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    answer: &MapAnswer,
    submitted: &wgpu::SubmissionIndex,
    size: u64,
) -> (Result<Vec<u8>>, bool) {
    let answered = match answer.try_recv() {
        Ok(a) => Ok(a),
        // The step is still running: wait for it (the map completes with it), not for other
        // work on the shared device.
        Err(_) => ctx
            .device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(submitted.clone()),
                timeout: None,
            })
            .map_err(|e| Error::Gpu(format!("waiting for the device: {e}")))
            .and_then(|_| {
                answer
                    .recv()
                    .map_err(|_| Error::Gpu("read ahead was never answered".into()))
            }),
    };
    match answered {
        Ok(Ok(())) => {
            // Only the counter and the entries it counts (at most the buffer's room).
            let raw = buffer
                .get_mapped_range(..size)
                .map(|m| {
                    let used = counter(&m).map_or(HEADER, |n| HEADER + 16 * n).min(size);
                    m[..used as usize].to_vec()
                })
                .map_err(|e| Error::Gpu(format!("reading the read ahead: {e}")));
            (raw, true)
        }
        Ok(Err(e)) => (
            Err(Error::Gpu(format!("mapping the read ahead: {e}"))),
            false,
        ),
        // Never answered: the map is still pending, and unmapping aborts it.
        Err(e) => (Err(e), true),
    }
}

/// Entries an output buffer of `size` bytes has room for.
fn room(size: u64) -> u64 {
    (size - HEADER) / 16
}

/// The counter at the head of an output read back.
fn counter(raw: &[u8]) -> Result<u64> {
    raw.get(..4)
        .and_then(|b| b.try_into().ok())
        .map(|b: [u8; 4]| u32::from_le_bytes(b) as u64)
        .ok_or_else(|| Error::Gpu("nodes near: counter readback".into()))
}

/// The entries of an output read back, in the order the device appended them; `None` where
/// the pass found more than `capacity` (nothing past it was written).
fn entries(raw: &[u8], capacity: u64) -> Result<Option<Vec<Found>>> {
    let count = counter(raw)?;
    if count > capacity {
        return Ok(None);
    }
    let bytes = raw
        .get(HEADER as usize..(HEADER + 16 * count) as usize)
        .ok_or_else(|| Error::Gpu("nodes near: entries readback".into()))?;
    let entries: Vec<[u32; 4]> = bytemuck::pod_collect_to_vec(bytes);
    Ok(Some(
        entries
            .iter()
            .map(|e| (e[3], [0, 1, 2].map(|c| f32::from_bits(e[c]))))
            .collect(),
    ))
}

/// An output buffer with room for `capacity` entries (at least), by size class.
fn found_buffer(ctx: &GpuContext, capacity: u64) -> Result<wgpu::Buffer> {
    let bytes = vec![0u8; (HEADER + 16 * capacity) as usize];
    buffers::storage_buffer(ctx, "nodes near", &bytes, Sizing::SizeClass)
}

//! One patch's host-to-device writes gathered into one staging buffer and copied by one
//! command encoder.
//!
//! A queue write makes a staging buffer of its own (an allocation, fresh pages to fault in) and
//! is flushed at the next submission: a valence patch wrote 60-100 ranges that way, 2 µs each
//! on lavapipe before the flush. Here every range goes into one mapped buffer, and the copies
//! out of it are recorded into the encoder that carries the rest of the patch (the state
//! moves), so a patch is one submission; the staging buffers are kept and reused
//! ([`StagingPool`]).

use std::ops::Range;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;

use super::GpuContext;
use crate::error::{Error, Result};
use crate::layout::patch::{Dirty, LayoutArray};

/// Writes waiting to be recorded: their bytes back to back, and where each goes.
#[derive(Default)]
pub struct Upload {
    data: Vec<u8>,
    copies: Vec<Copy>,
}

struct Copy {
    dst: wgpu::Buffer,
    dst_offset: u64,
    src_offset: u64,
    size: u64,
}

impl Upload {
    /// Nothing to write yet, with room for `bytes` of writes: a patch knows its dirty bytes
    /// and state moves ahead, so the bytes are gathered without growing the buffer.
    pub fn with_capacity(bytes: usize) -> Self {
        Upload {
            data: Vec::with_capacity(bytes),
            copies: Vec::new(),
        }
    }

    /// Write `data` into `dst` at `offset` when recorded. Both must be multiples of four bytes
    /// (what a buffer copy allows); every array the engine uploads is made of 4-byte words.
    pub fn write(&mut self, dst: &wgpu::Buffer, offset: u64, data: &[u8]) {
        debug_assert!(offset.is_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT));
        debug_assert!((data.len() as u64).is_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT));
        if data.is_empty() {
            return;
        }
        self.copies.push(Copy {
            dst: dst.clone(),
            dst_offset: offset,
            src_offset: self.data.len() as u64,
            size: data.len() as u64,
        });
        self.data.extend_from_slice(data);
    }

    /// Bytes written so far.
    pub fn bytes(&self) -> u64 {
        self.data.len() as u64
    }

    /// Record the copies into `enc`, from a staging buffer of `pool` filled now. Returns the
    /// buffer, to hand back to the pool once `enc` is submitted ([`StagingPool::submitted`]);
    /// nothing is recorded (and no buffer taken) when there is nothing to write.
    pub fn record(
        self,
        ctx: &GpuContext,
        pool: &mut StagingPool,
        enc: &mut wgpu::CommandEncoder,
    ) -> Result<Option<wgpu::Buffer>> {
        if self.copies.is_empty() {
            return Ok(None);
        }
        let staging = pool.take(ctx, self.data.len() as u64);
        staging
            .get_mapped_range_mut(..self.data.len() as u64)
            .map_err(|e| Error::Gpu(format!("filling the patch's staging buffer: {e}")))?
            .copy_from_slice(&self.data);
        staging.unmap();
        for c in &self.copies {
            enc.copy_buffer_to_buffer(&staging, c.src_offset, &c.dst, c.dst_offset, c.size);
        }
        Ok(Some(staging))
    }
}

/// Staging buffers kept between patches, mapped again as soon as the device is done with
/// them.
///
/// A buffer made for each patch is memory the allocator gets from the driver and the host
/// faults in page by page (a queue write does the same): on lavapipe the page faults were a
/// fifth of a patch's writes, and on a virtual machine an allocation from the driver can take
/// milliseconds. A used buffer is mapped for writing again after its submission
/// (`map_async`, which completes once the device is done with it, seen at the engine's next
/// poll or submission); a patch takes a mapped one large enough, or makes one. Only buffers
/// up to [`KEPT_SIZE`] are kept: a patch that writes a whole large array (a repack, a
/// compaction) does not leave that much host-visible memory mapped for good.
#[derive(Default)]
pub struct StagingPool {
    /// Mapped and free.
    ready: Vec<wgpu::Buffer>,
    /// Submitted, waiting to be mapped again (the flag is set by the map's callback).
    mapping: Vec<(wgpu::Buffer, Arc<AtomicU8>)>,
    /// Buffers made so far.
    made: usize,
}

/// A buffer's map: still pending.
const PENDING: u8 = 0;
/// Mapped.
const MAPPED: u8 = 1;
/// Failed (the device was lost): the buffer is dropped.
const FAILED: u8 = 2;

/// Buffers kept at most: a patch uses one, and a few cover patches that come faster than the
/// device polls.
const KEPT: usize = 4;

/// Least size of a staging buffer: a local cut writes 2-40 kB.
const LEAST: u64 = 64 << 10;

/// Largest staging buffer kept for reuse.
pub const KEPT_SIZE: u64 = 1 << 20;

impl StagingPool {
    /// A mapped buffer of at least `size` bytes.
    fn take(&mut self, ctx: &GpuContext, size: u64) -> wgpu::Buffer {
        self.collect();
        if let Some(i) = self.ready.iter().position(|b| b.size() >= size) {
            return self.ready.swap_remove(i);
        }
        // Mappable for writing and a copy source: host memory the device copies from, the same
        // kind of buffer a queue write stages through.
        self.made += 1;
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("patch upload"),
            size: size.next_power_of_two().max(LEAST),
            usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: true,
        })
    }

    /// Take back `buffer` after the submission that copies from it: it is mapped again when
    /// the device is done with it.
    pub fn submitted(&mut self, buffer: wgpu::Buffer) {
        if buffer.size() > KEPT_SIZE {
            return;
        }
        let state = Arc::new(AtomicU8::new(PENDING));
        let set = state.clone();
        buffer.map_async(wgpu::MapMode::Write, .., move |r| {
            set.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
        });
        self.mapping.push((buffer, state));
        self.collect();
        // Past the few kept (the device has not been polled for a while), those still waiting
        // for their map go first, the oldest first: the mapped ones are ready for the next
        // patch.
        let over = (self.ready.len() + self.mapping.len()).saturating_sub(KEPT);
        let from_mapping = over.min(self.mapping.len());
        self.mapping.drain(..from_mapping);
        self.ready.drain(..over - from_mapping);
    }

    /// Move the buffers whose map completed to the ready ones; drop those whose map failed.
    fn collect(&mut self) {
        let mut i = 0;
        while i < self.mapping.len() {
            match self.mapping[i].1.load(Ordering::Acquire) {
                PENDING => i += 1,
                state => {
                    let (b, _) = self.mapping.remove(i);
                    if state == MAPPED {
                        self.ready.push(b);
                    }
                }
            }
        }
    }

    /// Buffers kept (mapped or being mapped).
    pub fn kept(&self) -> usize {
        self.ready.len() + self.mapping.len()
    }

    /// Buffers made so far (the rest of the patches reused one).
    pub fn made(&self) -> usize {
        self.made
    }
}

/// Dirty ranges of one array closer than this (bytes) are written as one, the bytes between
/// them included: the device holds the same bytes there as the host, and each range is a copy
/// command to record and encode, which costs more than copying a few hundred bytes (a valence
/// patch's masses and rows lie scattered through their buckets: 60-100 ranges a cut). Kept
/// below a slot row of most nodes, so that rows are not joined across unchanged rows.
pub const WRITE_GAP: u64 = 256;

/// `dirty` (ascending per array, as a patch gives it) with ranges of one array less than `gap`
/// bytes apart joined.
pub fn merged_ranges(dirty: &[Dirty], gap: u64) -> Vec<(LayoutArray, Range<u64>)> {
    let mut out: Vec<(LayoutArray, Range<u64>)> = Vec::with_capacity(dirty.len());
    for d in dirty {
        debug_assert!(
            out.last()
                .is_none_or(|(a, r)| *a != d.array || d.bytes.start >= r.start),
            "dirty ranges out of order"
        );
        match out.last_mut() {
            Some((a, r)) if *a == d.array && d.bytes.start <= r.end + gap => {
                r.end = r.end.max(d.bytes.end);
            }
            _ => out.push((d.array, d.bytes.clone())),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dirty(array: LayoutArray, bytes: Range<u64>) -> Dirty {
        Dirty { array, bytes }
    }

    #[test]
    fn ranges_closer_than_the_gap_join_within_an_array_only() {
        let d = [
            dirty(LayoutArray::Slots, 0..32),
            dirty(LayoutArray::Slots, 32 + 256..320 + 32),
            dirty(LayoutArray::Slots, 352 + 257..1000),
            dirty(LayoutArray::InvMass, 1000..1004),
            dirty(LayoutArray::InvMass, 1008..1012),
        ];
        assert_eq!(
            merged_ranges(&d, 256),
            vec![
                (LayoutArray::Slots, 0..352),
                (LayoutArray::Slots, 609..1000),
                (LayoutArray::InvMass, 1000..1012),
            ]
        );
        // No gap: only touching ranges join; every dirty byte is still covered.
        let exact = merged_ranges(&d, 0);
        assert_eq!(exact.len(), 5);
        for x in &d {
            assert!(exact
                .iter()
                .any(|(a, r)| *a == x.array && r.start <= x.bytes.start && x.bytes.end <= r.end));
        }
    }
}

//! A patch's state moves on the device: pairs with `shaders/move_state.wgsl`. Nodes that
//! change place in the layout take their state along, new nodes start from their source (or
//! between the two ends of the edge a cut put them on), and nodes that become fixed start at
//! rest, all without reading anything back.
//!
//! Two dispatches per state buffer, `gather` (every source into a scratch buffer) then
//! `scatter` (every destination from it), recorded into the patch's encoder. A copy per move
//! and buffer did the same, but a valence patch recorded about a hundred of them, and the
//! encoder's `finish` cost more than the rest of the patch's device work.

use bytemuck::{Pod, Zeroable};

use super::buffers::{self, Sizing};
use super::upload::Upload;
use super::GpuContext;
use crate::error::Result;
use crate::layout::patch::StateMove;

const SOURCE: &str = include_str!("../../../shaders/move_state.wgsl");

/// One move as the shader reads it (`struct Move`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct MoveRecord {
    /// Destination index.
    pub to: u32,
    /// Source index, or [`MoveRecord::NONE`] to start at zero.
    pub from: u32,
    /// Second source mixed in, or [`MoveRecord::NONE`].
    pub with: u32,
    /// Weight of the second source.
    pub t: f32,
}

impl MoveRecord {
    /// No source.
    pub const NONE: u32 = u32::MAX;

    /// The record of `m`.
    pub fn of(m: &StateMove) -> Self {
        // Without a source the node starts at zero whatever it would be mixed with, as
        // `StateMove::apply_to` says.
        let blend = m.blend.filter(|_| m.from.is_some());
        MoveRecord {
            to: m.to,
            from: m.from.unwrap_or(Self::NONE),
            with: blend.map_or(Self::NONE, |b| b.with),
            t: blend.map_or(0.0, |b| b.t),
        }
    }
}

/// Bytes before the first record: the count, padded to a record (`struct Moves`).
const HEADER: u64 = 16;

/// The two pipelines, built with the engine (compiling them at the first cut would stall it),
/// and the buffers of the moves and their staged sources, kept between patches.
pub struct MovePass {
    gather: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    records: wgpu::Buffer,
    temp: wgpu::Buffer,
    /// A bind group per state buffer moved into, kept while the buffers stay the same
    /// (creating them took a third of a patch's recording on lavapipe).
    groups: std::cell::RefCell<Vec<(wgpu::Buffer, wgpu::BindGroup)>>,
}

impl MovePass {
    /// Compile the pass, with buffers for a few moves.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let layout = ctx
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("state moves"),
                entries: &[
                    buffers::storage_entry(0, true),
                    buffers::storage_entry(1, false),
                    buffers::storage_entry(2, false),
                ],
            });
        let pipeline =
            |entry| buffers::compute_pipeline_at(ctx, "state moves", SOURCE, entry, &[&layout]);
        let (gather, scatter) = (pipeline("gather")?, pipeline("scatter")?);
        let records = buffers::storage_buffer(ctx, "state move records", &[], Sizing::Exact)?;
        let temp = buffers::storage_buffer(ctx, "state move sources", &[], Sizing::Exact)?;
        Ok(MovePass {
            gather,
            scatter,
            layout,
            records,
            temp,
            groups: Default::default(),
        })
    }

    /// Drop the bind groups of the state buffers moved into last: the state was replaced (grown),
    /// and the groups would keep the old buffers alive until the next patch with moves.
    pub fn forget_state(&mut self) {
        self.groups.get_mut().clear();
    }

    /// Queue the records of `moves` on `upload` (growing the buffers they and their sources
    /// need), then, once the upload is recorded into `enc`, call [`MovePass::record`] with
    /// the count this returns.
    pub fn stage(
        &mut self,
        ctx: &GpuContext,
        upload: &mut Upload,
        moves: &[StateMove],
    ) -> Result<u32> {
        if moves.is_empty() {
            return Ok(0);
        }
        let n = moves.len() as u64;
        let need = HEADER + n * 16;
        if self.records.size() < need {
            self.records =
                buffers::zeroed_storage(ctx, "state move records", need, Sizing::SizeClass)?;
            self.groups.get_mut().clear();
        }
        if self.temp.size() < 2 * n * 16 {
            self.temp =
                buffers::zeroed_storage(ctx, "state move sources", 2 * n * 16, Sizing::SizeClass)?;
            self.groups.get_mut().clear();
        }
        let (width, _) = super::dispatch_size(ctx, moves.len() as u32);
        let row = width * super::WORKGROUP;
        let mut bytes = Vec::with_capacity(need as usize);
        bytes.extend_from_slice(bytemuck::bytes_of(&[moves.len() as u32, row, 0, 0]));
        for m in moves {
            bytes.extend_from_slice(bytemuck::bytes_of(&MoveRecord::of(m)));
        }
        upload.write(&self.records, 0, &bytes);
        Ok(moves.len() as u32)
    }

    /// Record the `count` staged moves on every buffer of `state`, each read whole before any
    /// of it is written.
    pub fn record(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        state: &[&wgpu::Buffer],
        count: u32,
    ) {
        if count == 0 {
            return;
        }
        let mut groups = self.groups.borrow_mut();
        let current =
            groups.len() == state.len() && groups.iter().zip(state).all(|(g, s)| g.0 == **s);
        if !current {
            *groups = state
                .iter()
                .map(|&s| {
                    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("state moves"),
                        layout: &self.layout,
                        entries: &buffers::entries(&[&self.records, &self.temp, s]),
                    });
                    (s.clone(), group)
                })
                .collect();
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("state moves"),
            timestamp_writes: None,
        });
        let (x, y) = super::dispatch_size(ctx, count);
        // One buffer after the other: they share the scratch buffer, and each dispatch sees
        // the writes of the one before it.
        for (_, group) in groups.iter() {
            pass.set_bind_group(0, group, &[]);
            pass.set_pipeline(&self.gather);
            pass.dispatch_workgroups(x, y, 1);
            pass.set_pipeline(&self.scatter);
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::patch::MoveBlend;

    /// A move without a source starts at zero, as its CPU twin says, even when it names a
    /// blend partner: the shader must not mix the partner in.
    #[test]
    fn a_move_without_a_source_mixes_nothing_in() {
        let blend = Some(MoveBlend { with: 3, t: 0.5 });
        let lone = StateMove {
            to: 1,
            from: None,
            blend,
        };
        let r = MoveRecord::of(&lone);
        assert_eq!((r.from, r.with), (MoveRecord::NONE, MoveRecord::NONE));
        let old = [[1.0f32; 4], [2.0; 4], [3.0; 4], [4.0; 4]];
        assert_eq!(lone.apply_to(&old), [0.0; 4]);
        let mixed = MoveRecord::of(&StateMove {
            from: Some(2),
            ..lone
        });
        assert_eq!((mixed.from, mixed.with, mixed.t), (2, 3, 0.5));
    }
}

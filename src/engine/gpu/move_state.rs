//! A patch's state moves on the device: pairs with `shaders/move_state.wgsl`. Nodes that
//! change place in the layout take their state along, new nodes start from their source (or
//! between the two ends of the edge a cut put them on), and nodes that become fixed start at
//! rest, all without reading anything back.
//!
//! Every state buffer is bound in one group and moved by the same dispatch: one (`direct`)
//! where no move's destination is another's source (connectivity and edge patches append
//! nodes), else two, `gather` (every source into a scratch buffer) then `scatter` (every
//! destination from it). A copy per move and buffer did the same, but a valence patch recorded
//! about a hundred of them; then a gather and a scatter per buffer (six dispatches for the
//! Verlet state), whose encoding was an eighth of a valence patch's host time on lavapipe.

use bytemuck::{Pod, Zeroable};

use super::buffers::{self, Sizing};
use super::upload::Upload;
use super::GpuContext;
use crate::error::Result;
use crate::layout::patch::StateMove;

const SOURCE: &str = include_str!("../../../shaders/move_state.wgsl");

/// State buffers one dispatch moves (`MOST` in the shader): the Verlet state has three, the
/// symplectic Euler state four.
pub const MOST_BUFFERS: usize = 4;

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

/// Whether the moves can be made in place by one dispatch: no destination is another move's
/// source, so no invocation reads what another writes (each destination is named once).
pub fn in_place(moves: &[StateMove]) -> bool {
    let written: rustc_hash::FxHashSet<u32> = moves.iter().map(|m| m.to).collect();
    !moves.iter().any(|m| {
        let r = MoveRecord::of(m);
        written.contains(&r.from) || written.contains(&r.with)
    })
}

/// Moves staged on an upload, to record once it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Staged {
    count: u32,
    direct: bool,
}

/// Bytes before the first record: the count, padded to a record (`struct Moves`).
const HEADER: u64 = 16;

/// The three pipelines, built with the engine (compiling them at the first cut would stall
/// it), and the buffers of the moves and their staged sources, kept between patches.
pub struct MovePass {
    direct: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    records: wgpu::Buffer,
    temp: wgpu::Buffer,
    /// Bound where a state has fewer buffers than the shader's slots; never read or written.
    placeholder: wgpu::Buffer,
    /// The bind group of the state buffers moved into last, kept while they and the pass's
    /// buffers stay the same (creating groups took a third of a patch's recording on
    /// lavapipe).
    group: std::cell::RefCell<Option<(Vec<wgpu::Buffer>, wgpu::BindGroup)>>,
}

impl MovePass {
    /// Compile the pass, with buffers for a few moves.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let mut entries = vec![buffers::storage_entry(0, true)];
        entries.extend((1..2 + MOST_BUFFERS as u32).map(|b| buffers::storage_entry(b, false)));
        let layout = ctx
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("state moves"),
                entries: &entries,
            });
        let pipeline =
            |entry| buffers::compute_pipeline_at(ctx, "state moves", SOURCE, entry, &[&layout]);
        let (direct, gather, scatter) = (
            pipeline("direct")?,
            pipeline("gather")?,
            pipeline("scatter")?,
        );
        let records = buffers::storage_buffer(ctx, "state move records", &[], Sizing::Exact)?;
        let temp = buffers::storage_buffer(ctx, "state move sources", &[], Sizing::Exact)?;
        let placeholder =
            buffers::storage_buffer(ctx, "state move placeholder", &[], Sizing::Exact)?;
        Ok(MovePass {
            direct,
            gather,
            scatter,
            layout,
            records,
            temp,
            placeholder,
            group: Default::default(),
        })
    }

    /// Drop the bind group of the state buffers moved into last: the state was replaced
    /// (grown), and the group would keep the old buffers alive until the next patch with
    /// moves.
    pub fn forget_state(&mut self) {
        *self.group.get_mut() = None;
    }

    /// Queue the records of `moves` on `buffers` state buffers on `upload` (growing the
    /// buffers they and their sources need), then, once the upload is recorded into `enc`,
    /// call [`MovePass::record`] with what this returns.
    pub fn stage(
        &mut self,
        ctx: &GpuContext,
        upload: &mut Upload,
        moves: &[StateMove],
        buffers: usize,
    ) -> Result<Staged> {
        if moves.is_empty() {
            return Ok(Staged {
                count: 0,
                direct: true,
            });
        }
        if buffers > MOST_BUFFERS {
            return Err(crate::Error::Gpu(format!(
                "{buffers} state buffers to move, past the pass's {MOST_BUFFERS}"
            )));
        }
        let n = moves.len() as u64;
        let need = HEADER + n * 16;
        if self.records.size() < need {
            self.records =
                buffers::zeroed_storage(ctx, "state move records", need, Sizing::SizeClass)?;
            *self.group.get_mut() = None;
        }
        let direct = in_place(moves);
        // Two sources per move and state buffer.
        let scratch = 2 * buffers as u64 * n * 16;
        if !direct && self.temp.size() < scratch {
            self.temp =
                buffers::zeroed_storage(ctx, "state move sources", scratch, Sizing::SizeClass)?;
            *self.group.get_mut() = None;
        }
        let (width, _) = super::dispatch_size(ctx, moves.len() as u32);
        let row = width * super::WORKGROUP;
        let mut bytes = Vec::with_capacity(need as usize);
        bytes.extend_from_slice(bytemuck::bytes_of(&[
            moves.len() as u32,
            row,
            buffers as u32,
            0,
        ]));
        for m in moves {
            bytes.extend_from_slice(bytemuck::bytes_of(&MoveRecord::of(m)));
        }
        upload.write(&self.records, 0, &bytes);
        Ok(Staged {
            count: moves.len() as u32,
            direct,
        })
    }

    /// Record the `staged` moves on every buffer of `state` (as many as staged), each source
    /// read before any destination is written.
    pub fn record(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        state: &[&wgpu::Buffer],
        staged: Staged,
    ) {
        if staged.count == 0 {
            return;
        }
        let mut group = self.group.borrow_mut();
        let current = group.as_ref().is_some_and(|(bound, _)| {
            bound.len() == state.len() && bound.iter().zip(state).all(|(b, s)| b == *s)
        });
        if !current {
            let mut bound: Vec<&wgpu::Buffer> = vec![&self.records, &self.temp];
            bound.extend(state.iter().copied());
            bound.resize(2 + MOST_BUFFERS, &self.placeholder);
            let g = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("state moves"),
                layout: &self.layout,
                entries: &buffers::entries(&bound),
            });
            *group = Some((state.iter().map(|&s| s.clone()).collect(), g));
        }
        let (_, g) = group.as_ref().expect("made above");
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("state moves"),
            timestamp_writes: None,
        });
        let (x, y) = super::dispatch_size(ctx, staged.count);
        pass.set_bind_group(0, g, &[]);
        if staged.direct {
            pass.set_pipeline(&self.direct);
            pass.dispatch_workgroups(x, y, 1);
        } else {
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

    /// Moves go in place only where no destination is read by another move: appended nodes
    /// copying or blending old ones do; a node that a move writes and another reads (as its
    /// source or its blend partner) does not, nor does a permutation.
    #[test]
    fn moves_go_in_place_only_where_no_destination_is_read() {
        let copy = |to, from| StateMove {
            to,
            from: Some(from),
            blend: None,
        };
        let blended = |to, from, with| StateMove {
            to,
            from: Some(from),
            blend: Some(MoveBlend { with, t: 0.25 }),
        };
        let cleared = |to| StateMove {
            to,
            from: None,
            blend: None,
        };
        assert!(in_place(&[copy(10, 1), blended(11, 2, 3), cleared(4)]));
        assert!(!in_place(&[copy(10, 1), cleared(1)]));
        assert!(!in_place(&[blended(11, 2, 3), cleared(3)]));
        assert!(!in_place(&[copy(0, 1), copy(1, 0)]));
        // A partner without a source is never read.
        assert!(in_place(&[
            StateMove {
                to: 5,
                from: None,
                blend: Some(MoveBlend { with: 6, t: 0.5 }),
            },
            cleared(6),
        ]));
        assert!(in_place(&[]));
    }
}

//! What every layout pass shares about the buffers of layout arrays it owns: finding one, and
//! growing some in place (a larger buffer, the old contents copied on the device, the bind
//! groups rebuilt over it) while the pass keeps its compute pipelines.

use std::ops::Range;

use super::buffers::{self, Growth};
use super::{GpuContext, StateBuffers};
use crate::error::{Error, Result};
use crate::layout::patch::LayoutArray;

/// A layout array that outgrew its device buffer, as patched.
pub struct Outgrown<'a> {
    /// Which array.
    pub array: LayoutArray,
    /// Its bytes after the patch.
    pub data: &'a [u8],
    /// The byte ranges the patch changed, ascending.
    pub dirty: Vec<Range<u64>>,
}

/// A pass that owns the device buffers of some layout arrays and binds them.
pub trait LayoutBuffers {
    /// The device buffer of a layout array, if this pass holds it.
    fn buffer(&self, array: LayoutArray) -> Option<&wgpu::Buffer>;

    /// The same buffer, to replace.
    fn buffer_mut(&mut self, array: LayoutArray) -> Option<&mut wgpu::Buffer>;

    /// Rebuild the bind groups over the buffers the pass holds now, and any buffer sized from
    /// one of them (forces per spring, accumulators per node); the pipelines are kept.
    fn rebind(
        &mut self,
        ctx: &GpuContext,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) -> Result<()>;

    /// Replace the buffers of `arrays` by larger ones holding the arrays' new contents (see
    /// [`buffers::grown`]), then rebind once.
    fn grow(
        &mut self,
        ctx: &GpuContext,
        arrays: &[Outgrown<'_>],
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) -> Result<Growth> {
        let mut cost = Growth::default();
        for a in arrays {
            let old = self.buffer_mut(a.array).ok_or_else(|| {
                Error::Gpu(format!(
                    "no device buffer holds the {:?} array to grow",
                    a.array
                ))
            })?;
            let (new, g) = buffers::grown(ctx, label(a.array), old, a.data, &a.dirty)?;
            *old = new;
            cost += g;
        }
        if !arrays.is_empty() {
            self.rebind(ctx, uniform, state)?;
        }
        Ok(cost)
    }
}

/// The debug label of an array's device buffer.
pub fn label(array: LayoutArray) -> &'static str {
    match array {
        LayoutArray::Slots => "slots",
        LayoutArray::InvMass => "inverse masses",
        LayoutArray::Buckets => "valence buckets",
        LayoutArray::EdgeSprings => "edge springs",
        LayoutArray::IncidenceRows => "incidence rows",
        LayoutArray::Incidence => "incidence",
    }
}

//! Patching the device's layout in place after a model change: dirty ranges written through
//! one staging buffer, buffers grown by size class, node state moved on the device.

use super::*;

impl GpuEngine {
    /// Apply a change to the model between steps: `diff` has already been applied to `model`
    /// (the model after it, see [`PackedModel::apply`]). The layout is patched on the CPU and
    /// only its dirty byte ranges are written to the device; node state moves on the device
    /// (new nodes start from the state of the node they copy, or at rest). A buffer that
    /// outgrows its room is replaced by one of the next size class, its old contents copied on
    /// the device, and rebound; the passes keep their pipelines. Only a repack of a
    /// node-centric layout or node state outgrowing its buffers rebuilds the passes and
    /// uploads the layout whole.
    ///
    /// On an error (a diff that does not match the model) the engine is left inconsistent:
    /// build a new one.
    pub fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<PatchCost> {
        self.forget_ahead();
        self.patches += 1;
        let patch = self.layout.patch(model, diff)?;
        if patch.repacked {
            // A repack (or an edge compaction) made new arrays: room again for the next cuts.
            self.layout.reserve_room();
        }
        // A diff only appends nodes and changes the fixed flags it names: copy just those, not
        // the whole arrays (a local cut on a large mesh).
        let before = self.rest.len();
        self.rest.extend_from_slice(&model.rest[before..]);
        self.fixed.extend_from_slice(&model.fixed[before..]);
        for c in &diff.changed_nodes {
            self.fixed[c.node as usize] = model.fixed[c.node as usize];
        }
        debug_assert_eq!(self.fixed, model.fixed);
        let slots = self.layout.node_slots();
        // An edge-layout compaction rewrites only its two incidence arrays, both marked dirty
        // whole: written in place like any dirty range (or grown like any array), it keeps the
        // passes and their pipelines. A connectivity repack rebuilds them (its whole table is new;
        // a valence regroup packs only the buckets patches appended, written like any patch).
        let mut rebuild = patch.repacked && !matches!(self.layout, PackedLayout::Edges(_));
        let state_moved = slots > self.state.capacity();
        if state_moved {
            self.state = self.state.grown(&self.ctx, slots)?;
            self.mover.forget_state();
            rebuild = true;
        }
        self.update_fixed_point(model);
        self.dispatch = Dispatch::new(&self.ctx, slots as u32, spring_records(&self.layout));
        let uniform_before = self.uniform_data;
        self.uniform_data = constants(self.uniform_data, &self.layout, self.dispatch);
        // The first damped spring of an undamped model turns the damped step on (it reads the
        // neighbours' velocities); springs that lose their damping leave zeros, which the
        // damped step handles, so it stays on.
        if diff
            .added_springs
            .iter()
            .chain(&diff.changed_springs)
            .any(|s| s.damping != 0.0)
        {
            self.uniform_data.damped = 1;
        }
        let mut tensor_bytes = 0;
        if let Some(t) = self.tensor.as_mut() {
            tensor_bytes = t.patch(
                &self.ctx,
                model,
                diff,
                &self.layout,
                &patch.dirty,
                patch.repacked || rebuild,
            )?;
            // The blocks' stride follows the tets' damping, not the springs'.
            self.uniform_data.damped = t.damped() as u32;
        }
        if let Some(c) = self.corot.as_mut() {
            tensor_bytes = c.patch(&self.ctx, model, diff, &self.layout)?;
            self.uniform_data.damped = c.damped() as u32;
            if let Some(b) = self.corot_blocks.as_mut() {
                tensor_bytes += b.patch(
                    &self.ctx,
                    c,
                    &self.layout,
                    &patch.dirty,
                    patch.repacked || rebuild,
                    &diff.removed_tets,
                )?;
            }
        }
        let layout_bytes = self.layout.upload_bytes();
        let mut cost = PatchCost {
            uploaded_bytes: layout_bytes,
            copied_bytes: 0,
            buffers_grown: 0,
            layout_bytes,
            state_moves: patch.moves.len(),
            reallocated: rebuild,
        };
        // The dirty ranges and the state moves go up together: one staging buffer, one
        // submission.
        // Room for the dirty ranges, the move records (16 bytes each and a header) and the step
        // constants; ranges joined across small gaps may still grow it.
        let mut upload = upload::Upload::with_capacity(
            (patch.dirty_bytes() + 16 * patch.moves.len() as u64 + 256) as usize,
        );
        // With the patch's other writes (a queue write stages through a buffer of its own),
        // and only when the dispatch sizes changed.
        if bytemuck::bytes_of(&uniform_before) != bytemuck::bytes_of(&self.uniform_data) {
            upload.write(&self.uniform, 0, bytemuck::bytes_of(&self.uniform_data));
        }
        if rebuild {
            self.passes = build_passes(
                &self.ctx,
                &self.layout,
                self.accumulation,
                &self.uniform,
                &self.state,
                self.fixed_point,
                Sizing::SizeClass,
            )?;
        } else {
            let grown = self.outgrown();
            let growth = self.grow(&grown, &patch.dirty)?;
            let (written, tables) = self.write_dirty(&patch.dirty, &grown, &mut upload);
            cost.uploaded_bytes = growth.uploaded + written;
            cost.copied_bytes = growth.copied;
            cost.buffers_grown = grown.len() + tables;
        }
        // Submitted before anything else can fail: the host layout is patched already, and
        // the device must follow it even if the moves cannot be staged (the error says so).
        debug_assert!(
            patch
                .moves
                .iter()
                .all(|m| (m.to as usize) < self.state.capacity()),
            "a state move past the state buffers"
        );
        let state_buffers = self.state.buffers();
        let moves = self
            .mover
            .stage(&self.ctx, &mut upload, &patch.moves, state_buffers.len());
        // Nothing to write and no moves (the records are written too): nothing to submit.
        if upload.bytes() > 0 {
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("patch"),
                });
            let staging = upload.record(&self.ctx, &mut self.staging, &mut enc)?;
            if let Ok(staged) = moves {
                self.mover
                    .record(&self.ctx, &mut enc, &state_buffers, staged);
            }
            self.ctx.queue.submit([enc.finish()]);
            if let Some(b) = staging {
                self.staging.submitted(b);
            }
        }
        moves?;
        if rebuild || !self.health.fits(self.dispatch.nodes) {
            // Bound to new buffers, or grown with the node dispatch.
            self.health = health_pass(
                &self.ctx,
                &self.passes,
                &self.uniform,
                &self.state,
                self.dispatch,
            )?;
        } else if cost.buffers_grown > 0 {
            // The mass buffer may be a new one: the probe keeps its pipeline.
            let inv_mass = self
                .passes
                .buffer(LayoutArray::InvMass)
                .expect("every layout uploads inverse masses");
            self.health
                .rebind(&self.ctx, inv_mass, &self.uniform, &self.state);
        }
        // The solver binds the slot and mass buffers and the state, any of which may be new.
        self.rebind_implicit()?;
        if let Some(t) = self.tensor.as_mut() {
            t.rebind(&self.ctx, &self.passes, &self.uniform, &self.state)?;
            cost.uploaded_bytes += tensor_bytes;
        }
        if let Some(c) = self.corot.as_mut() {
            c.rebind(&self.ctx, &self.passes, &self.uniform, &self.state)?;
            cost.uploaded_bytes += tensor_bytes;
        }
        // Node indices and state buffers may have changed under the surface: the culler is
        // brought up to date when next used (a cut usually edits the surface right after).
        // Only the moved slots are stale, after a repack too (see `SurfaceSync`).
        self.note_surface_moves(&patch.moves, state_moved);
        Ok(cost)
    }

    /// The staging buffers patches upload through: how many are kept for reuse, and how many
    /// were made so far.
    pub fn staging_buffers(&self) -> (usize, usize) {
        (self.staging.kept(), self.staging.made())
    }

    /// Re-quantize the fixed-point accumulation (edge layout, atomic fixed point) only when the
    /// patched model's larger valence could wrap an accumulator: keeping the constants keeps
    /// the step bit-identical to before the patch otherwise.
    pub(super) fn update_fixed_point(&mut self, model: &PackedModel) {
        if let (PackedLayout::Edges(e), Accumulation::AtomicFixed) =
            (&self.layout, self.accumulation)
        {
            let fp = match &self.tensor {
                Some(t) => {
                    super::tensor_atomic::fixed_point(&self.layout, model, t, self.fixed_point)
                }
                None => e.fixed_point(model),
            };
            if fp.limit < self.fixed_point.limit {
                self.fixed_point = fp;
                if let Passes::AtomicEdges(p) = &self.passes {
                    p.set_fixed_point(&self.ctx, &fp);
                }
            }
        }
    }

    /// The layout arrays that outgrew their device buffers.
    pub(super) fn outgrown(&self) -> Vec<LayoutArray> {
        LayoutArray::ALL
            .into_iter()
            .filter(|&a| {
                self.passes
                    .buffer(a)
                    .is_some_and(|b| self.layout.array(a).len() as u64 > b.size())
            })
            .collect()
    }

    /// Replace the buffers of `arrays` by larger ones holding the patched arrays (`dirty`: the
    /// patch's ranges), rebinding the passes that use them.
    pub(super) fn grow(&mut self, arrays: &[LayoutArray], dirty: &[Dirty]) -> Result<Growth> {
        let grown: Vec<_> = arrays
            .iter()
            .map(|&array| layout_buffers::Outgrown {
                array,
                data: self.layout.array(array),
                dirty: dirty
                    .iter()
                    .filter(|d| d.array == array)
                    .map(|d| d.bytes.clone())
                    .collect(),
            })
            .collect();
        self.passes
            .layout_buffers_mut()
            .grow(&self.ctx, &grown, &self.uniform, &self.state)
    }

    /// Write the dirty ranges of every array but those in `skip` (grown: already written) in
    /// place through `upload`, and the valence bucket table when it changed. Returns the bytes
    /// written and how many tables outgrew their buffers on the way (the bucket table grows as
    /// it is written).
    pub(super) fn write_dirty(
        &mut self,
        dirty: &[Dirty],
        skip: &[LayoutArray],
        upload: &mut upload::Upload,
    ) -> (u64, usize) {
        let mut written = 0u64;
        for (array, bytes) in merged_ranges(dirty, WRITE_GAP) {
            if skip.contains(&array) {
                continue;
            }
            let Some(buf) = self.passes.buffer(array) else {
                continue;
            };
            let data = &self.layout.array(array)[bytes.start as usize..bytes.end as usize];
            upload.write(buf, bytes.start, data);
            written += data.len() as u64;
        }
        let mut grown = 0;
        if let (Passes::Valence(p), PackedLayout::Valence(v)) = (&mut self.passes, &self.layout) {
            if dirty.iter().any(|d| d.array == LayoutArray::Buckets) {
                let stage = |table: &wgpu::Buffer, bytes: &[u8]| upload.write(table, 0, bytes);
                grown += p.set_buckets(&self.ctx, &v.buckets, stage) as usize;
                written += crate::layout::valence::table_bytes(v.buckets.len());
            }
        }
        (written, grown)
    }

    /// Remember what a patch's `moves` changed under the surface, and whether it moved the node
    /// state to new buffers (`state_moved`).
    pub(super) fn note_surface_moves(
        &mut self,
        moves: &[crate::layout::patch::StateMove],
        state_moved: bool,
    ) {
        if self.surface.is_none() {
            return;
        }
        let (mut slots, rebind) =
            match std::mem::replace(&mut self.surface_sync, SurfaceSync::Current) {
                SurfaceSync::Current => (Vec::new(), false),
                SurfaceSync::Moved { slots, rebind } => (slots, rebind),
            };
        slots.extend(moves.iter().map(|m| m.to));
        self.surface_sync = SurfaceSync::Moved {
            slots,
            rebind: rebind || state_moved,
        };
    }
}

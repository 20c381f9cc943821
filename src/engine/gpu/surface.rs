//! The tissue surface on the device and the passes over it: the tool and self-contact broad
//! phases and the nodes near a blade, kept in step with the layout through patches and edits.

use super::*;
#[cfg(feature = "collide")]
use crate::collide::self_broad::GridParams;

/// What changed under the surface culler since it last saw the layout. A patch moves a node
/// to another layout index only with a state move to it (its state must follow it: a
/// connectivity repack or an edge compaction packs the same order anew, a valence regroup
/// moves every node of the buckets it packs anew), so the moves name every slot whose
/// triangles and rest position may be stale.
pub(super) enum SurfaceSync {
    /// Nothing: its triangles and rest positions match the layout.
    Current,
    /// The nodes at these layout slots moved there or were added (from patches' state moves);
    /// `rebind` when the node state moved to new buffers, which the culler's passes read.
    Moved { slots: Vec<u32>, rebind: bool },
}

/// The tissue surface on the device and the broad phases over it.
pub(super) struct SurfaceCulling {
    /// Boundary triangles, model order.
    pub(super) triangles: Vec<[u32; 3]>,
    /// The triangles at each model node.
    pub(super) at_nodes: surface_nodes::TrianglesAtNodes,
    pub(super) tool: broad_tool::ToolCuller,
    /// Nodes near a blade, over the culler's rest positions (built with it: a cut that reads
    /// them never waits for a pipeline).
    pub(super) near: nodes_near::NodesNear,
    /// The self-contact broad phase and the margin it culls at, once asked for. It shares
    /// `tool`'s triangles and rest positions and follows every edit of them.
    #[cfg(feature = "collide")]
    pub(super) self_contact: Option<(f64, broad_self::SelfCuller)>,
    /// Self-contact cullers built (pipelines compiled): one per engine, whatever the edits.
    pub(super) self_builds: usize,
}

/// The self-contact grid after an edit left `triangles` triangles: the same cell and margin,
/// a hash table of at least twice as many buckets as triangles (never smaller than before).
#[cfg(feature = "collide")]
fn edited_grid(grid: GridParams, triangles: usize) -> GridParams {
    let table = (2 * triangles).next_power_of_two().max(256) as u32;
    let table = table.max(grid.table);
    GridParams {
        triangles: triangles as u32,
        table,
        blocks: table / 256,
        ..grid
    }
}

/// The error for culling before a surface was given.
pub(super) fn no_surface() -> crate::Error {
    crate::Error::NoSurface(
        "no surface to cull: call set_surface with the boundary triangles first".into(),
    )
}

/// The error for a surface triangle `t` naming a node past the model's `n`.
pub(crate) fn surface_node_error(t: &[u32; 3], n: usize) -> crate::Error {
    let node = t.iter().copied().find(|&i| i as usize >= n).unwrap_or(t[0]);
    crate::Error::NodeOutOfRange {
        node: node as u64,
        count: n,
        message: format!("surface triangle {t:?} names a node past the model's {n} nodes"),
    }
}

impl GpuEngine {
    /// Give the engine the tissue's boundary triangles (dense model indices, as
    /// `collide::broad::Surface` makes them) for [`GpuEngine::cull_tools`]. The first call
    /// uploads them and the rest positions; later calls (a cut edited the surface, a patch
    /// renumbered or appended nodes) write only the triangles and positions that changed.
    pub fn set_surface(&mut self, triangles: &[[u32; 3]]) -> Result<()> {
        let n = self.rest.len();
        if let Some(t) = triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(surface_node_error(t, n));
        }
        let (tris, rest) = (self.in_layout_order(triangles), self.rest_f32());
        // A culler that exists keeps its pipeline: only what changed is written. On error the
        // old surface stays.
        match &mut self.surface {
            Some(s) => {
                s.tool.set_surface(&self.ctx, &tris, &rest, &self.state)?;
                s.near.rebind(&self.ctx, s.tool.rest(), &self.state);
                s.triangles = triangles.to_vec();
                s.at_nodes = surface_nodes::TrianglesAtNodes::of(triangles, n);
                // A whole new surface: the grid is made for it, the passes kept.
                #[cfg(feature = "collide")]
                if let Some((margin, culler)) = &mut s.self_contact {
                    let grid = GridParams::for_surface(&self.rest, triangles, *margin);
                    culler.regrid(&self.ctx, grid, &s.tool, &self.state)?;
                }
            }
            None => {
                let tool = broad_tool::ToolCuller::new(&self.ctx, &tris, &rest, &self.state)?;
                let near = nodes_near::NodesNear::new(&self.ctx, tool.rest(), &self.state)?;
                self.surface = Some(SurfaceCulling {
                    triangles: triangles.to_vec(),
                    at_nodes: surface_nodes::TrianglesAtNodes::of(triangles, n),
                    tool,
                    near,
                    #[cfg(feature = "collide")]
                    self_contact: None,
                    self_builds: 0,
                });
            }
        }
        self.surface_sync = SurfaceSync::Current;
        Ok(())
    }

    /// The surface after an edit: `triangles` is the whole new list (dense model indices), of
    /// which only the slots `changed` differ from the last one given (a cut swapped out the
    /// triangles it removed and appended those it added, as [`crate::Simulation::edit_surface`]
    /// does). Writes only those triangles, those at nodes a patch moved in the layout, and the
    /// rest positions of the moved and added nodes: a cut costs what it changed, not a pass
    /// over the surface and every node (a buffer the edit outgrows is grown by a copy on the
    /// device). A patch that moved the node state to new buffers costs a rebinding more.
    pub fn edit_surface(&mut self, triangles: &[[u32; 3]], changed: &[u32]) -> Result<()> {
        let (moved, rebind) = match &self.surface_sync {
            SurfaceSync::Moved { slots, rebind } => (slots.clone(), *rebind),
            SurfaceSync::Current => (Vec::new(), false),
        };
        let Some(surface) = self.surface.as_ref() else {
            return self.set_surface(triangles);
        };
        let known = surface.triangles.len();
        let n = self.rest.len();
        let mut slots: Vec<u32> = changed
            .iter()
            .copied()
            .filter(|&c| (c as usize) < triangles.len())
            .collect();
        // Appended slots are always written, named or not.
        slots.extend(known as u32..triangles.len() as u32);
        if let Some(t) = slots
            .iter()
            .map(|&c| &triangles[c as usize])
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(surface_node_error(t, n));
        }
        let order = &self.layout.order();
        // The model node at a layout slot (none at a hole).
        let node_at = |slot: u32| {
            order
                .order
                .get(slot as usize)
                .copied()
                .filter(|&o| o != crate::layout::NodeOrder::HOLE)
        };
        // Triangles at a node whose layout index changed hold stale indices. Those of the new
        // list are the ones at the node before the edit (the index is of the last list) that
        // the edit left alone, and changed ones, which are written anyway.
        for node in moved.iter().filter_map(|&slot| node_at(slot)) {
            slots.extend(
                surface
                    .at_nodes
                    .at(node)
                    .iter()
                    .copied()
                    .filter(|&i| (i as usize) < triangles.len()),
            );
        }
        slots.sort_unstable();
        slots.dedup();
        let tris: Vec<(u32, [u32; 3])> = slots
            .iter()
            .map(|&i| (i, triangles[i as usize].map(|k| order.rank[k as usize])))
            .collect();
        let slots_total = self.layout.node_slots();
        // Slots a shrinking patch dropped are no node's: nothing to write there.
        let rest: Vec<(u32, [f32; 4])> = moved
            .iter()
            .filter(|&&slot| (slot as usize) < slots_total)
            .map(|&slot| {
                let r = node_at(slot).map_or([0.0; 4], |old| {
                    let r = self.rest[old as usize];
                    [r[0] as f32, r[1] as f32, r[2] as f32, 0.0]
                });
                (slot, r)
            })
            .collect();
        let s = self.surface.as_mut().expect("checked above");
        let rest_moved = s.tool.edit(
            &self.ctx,
            triangles.len(),
            &tris,
            slots_total,
            &rest,
            &self.state,
        )?;
        if rebind {
            s.tool.rebind(&self.ctx, &self.state);
        }
        if rest_moved || rebind {
            s.near.rebind(&self.ctx, s.tool.rest(), &self.state);
        }
        // Dropped slots leave the index; changed and appended ones are put in it anew.
        for (i, t) in s.triangles.iter().enumerate().skip(triangles.len()) {
            s.at_nodes.remove(i as u32, t);
        }
        s.triangles.resize(triangles.len(), [u32::MAX; 3]);
        s.at_nodes.grow(n);
        for &i in &slots {
            let (old, new) = (s.triangles[i as usize], triangles[i as usize]);
            if old != new {
                s.at_nodes.remove(i, &old);
                s.at_nodes.add(i, &new);
                s.triangles[i as usize] = new;
            }
        }
        debug_assert_eq!(s.triangles, triangles, "the edit named every changed slot");
        debug_assert!(
            s.at_nodes
                .same_as(&surface_nodes::TrianglesAtNodes::of(triangles, n)),
            "the triangles at the nodes follow the edits"
        );
        // The self-contact culler reads the tool culler's buffers, which the edit wrote: it
        // follows the surface's size and binds afresh.
        #[cfg(feature = "collide")]
        if let Some((_, culler)) = &mut s.self_contact {
            let grid = edited_grid(culler.grid(), triangles.len());
            culler.regrid(&self.ctx, grid, &s.tool, &self.state)?;
        }
        self.surface_sync = SurfaceSync::Current;
        Ok(())
    }

    /// Bring the culler up to date after a patch (nodes appended or renumbered, state
    /// reallocated), before it is used.
    pub(super) fn refresh_surface(&mut self) -> Result<()> {
        if matches!(self.surface_sync, SurfaceSync::Current) {
            return Ok(());
        }
        if let Some(triangles) = self.surface.as_ref().map(|s| s.triangles.clone()) {
            self.edit_surface(&triangles, &[])?;
        }
        self.surface_sync = SurfaceSync::Current;
        Ok(())
    }

    /// Triangles of model nodes renumbered to layout indices.
    pub(super) fn in_layout_order(&self, triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
        let rank = &self.layout.order().rank;
        triangles
            .iter()
            .map(|t| t.map(|i| rank[i as usize]))
            .collect()
    }

    /// Rest positions in layout order as the passes see them (zero at holes).
    pub fn rest_f32(&self) -> Vec<[f32; 4]> {
        let mut rest = vec![[0.0f32; 4]; self.layout.node_slots()];
        for (new, old) in self.layout.order().pairs() {
            let r = self.rest[old];
            rest[new] = [r[0] as f32, r[1] as f32, r[2] as f32, 0.0];
        }
        rest
    }

    /// The surface triangles in layout order, as the culler holds them.
    pub fn surface_layout_order(&self) -> Option<Vec<[u32; 3]>> {
        self.surface
            .as_ref()
            .map(|s| self.in_layout_order(&s.triangles))
    }

    /// Broad phase against tool boxes on the device: the (triangle, tool) pairs whose boxes
    /// overlap at the current state, triangle indices into the surface given to
    /// [`GpuEngine::set_surface`]. Reads back only the candidate list.
    pub fn cull_tools(&mut self, boxes: &[ToolBox]) -> Result<broad_tool::CullResult> {
        self.refresh_surface()?;
        let Some(surface) = &mut self.surface else {
            return Err(no_surface());
        };
        surface.tool.cull(&self.ctx, &self.state, self.phase, boxes)
    }

    /// The nodes (model indices, ascending) whose current position lies in `lo..=hi` (m), with
    /// their positions as [`Engine::positions`] gives them, found on the device with one pass
    /// over the nodes; only those nodes are read back (16 bytes each). A few just outside the
    /// box may come too. Before a surface is given ([`GpuEngine::set_surface`]; the pass
    /// shares its rest positions) every position is read back and scanned instead.
    pub fn nodes_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        self.refresh_surface()?;
        let Some(surface) = &mut self.surface else {
            let x = self.state_f64().0;
            return crate::engine::reading::PositionSource::near(
                &mut crate::engine::reading::AllPositions(&x),
                lo,
                hi,
            );
        };
        let (lo32, hi32) = crate::engine::reading::float32_box(lo, hi);
        let (order, rest, fixed) = (&self.layout.order().order, &self.rest, &self.fixed);
        // The model node at a slot and its position as `state_f64` gives it (a cut reads what
        // a full readback gives), with its rest position; none at a hole.
        let node = |slot: u32, u: &[f32; 3]| {
            let old = *order.get(slot as usize)?;
            let r = *rest.get(old as usize)?;
            let x = if fixed[old as usize] {
                r
            } else {
                [0, 1, 2].map(|c| r[c] + u[c] as f64)
            };
            Some((old, x, r))
        };
        let mut out: Vec<(u32, [f64; 3])> = match surface.near.take_ahead(&self.ctx, lo32, hi32)? {
            Some(all) => {
                self.near_reads.ahead += 1;
                // In node order first (sorting 8-byte keys), so that the rest positions and
                // fixed flags are then read in ascending order, not at random, and the list
                // comes out sorted.
                let mut keys: Vec<u64> = all
                    .iter()
                    .enumerate()
                    .filter_map(|(i, (slot, _))| {
                        let old = *order.get(*slot as usize)?;
                        Some((u64::from(old) << 32) | i as u64)
                    })
                    .collect();
                keys.sort_unstable();
                // Narrowed to this box by the pass's own test (rest and displacement added
                // in float32), so the list is the one a read of its own would give.
                keys.iter()
                    .map(|k| &all[(k & 0xffff_ffff) as usize])
                    .filter_map(|(slot, u)| {
                        let (old, x, r) = node(*slot, u)?;
                        let x32 = [0, 1, 2].map(|c| r[c] as f32 + u[c]);
                        crate::twin::nodes_near::in_box(x32, lo32, hi32).then_some((old, x))
                    })
                    .collect()
            }
            None => {
                self.near_reads.direct += 1;
                surface
                    .near
                    .find(
                        &self.ctx,
                        surface.tool.rest(),
                        &self.state,
                        self.phase,
                        self.layout.node_slots() as u32,
                        lo32,
                        hi32,
                    )?
                    .iter()
                    .filter_map(|(slot, u)| node(*slot, u).map(|(old, x, _)| (old, x)))
                    .collect()
            }
        };
        crate::engine::reading::sort_by_node(&mut out);
        Ok(out)
    }

    /// Drop a read of nodes near a blade made ahead with a step: the state it saw is changing.
    pub(super) fn forget_ahead(&mut self) {
        if let Some(s) = &mut self.surface {
            s.near.forget_ahead();
        }
    }

    /// Broad phase of the tissue against itself on the device: pairs of surface triangles that
    /// share no node and whose boxes, widened by `margin / 2` (m), overlap at the current
    /// state. The passes are built at the first call; a new margin makes a new grid for the
    /// same passes, and surface edits (cuts) update the culler in place.
    #[cfg(feature = "collide")]
    pub fn cull_self(&mut self, margin: f64) -> Result<broad_self::SelfCullResult> {
        self.refresh_surface()?;
        let Some(s) = &mut self.surface else {
            return Err(no_surface());
        };
        match &mut s.self_contact {
            Some((m, _)) if *m == margin => {}
            Some((m, culler)) => {
                let grid = GridParams::for_surface(&self.rest, &s.triangles, margin);
                culler.regrid(&self.ctx, grid, &s.tool, &self.state)?;
                *m = margin;
            }
            None => {
                let grid = GridParams::for_surface(&self.rest, &s.triangles, margin);
                let culler = broad_self::SelfCuller::new(&self.ctx, grid, &s.tool, &self.state)?;
                s.self_contact = Some((margin, culler));
                s.self_builds += 1;
            }
        }
        let (_, culler) = s.self_contact.as_mut().expect("built above");
        culler.cull(&self.ctx, &s.tool, &self.state, self.phase)
    }

    /// Self-contact cullers this engine built (their pipelines compiled): 0 before the first
    /// [`GpuEngine::cull_self`], then 1 whatever the cuts and margins since.
    pub fn self_culler_builds(&self) -> usize {
        self.surface.as_ref().map_or(0, |s| s.self_builds)
    }
}

//! Cutting in a world step: after each step every cutting blade's sweep over the step goes to
//! the [`Cutter`]; a cut that changed something is applied to the simulation as a patch (only
//! its dirty ranges are uploaded), the surface is refreshed for the other tools, the time-step
//! policy decides what happens when the cut lowered the stable bound, and the invariants are
//! checked when asked. What each cut cost is kept for [`CutReport`].

use std::time::Instant;

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use crate::collide::broad::ToolBox;
use crate::collide::Tool;
use crate::cut::{CutMethod, Cutter, Sweep};
use crate::engine::{PatchCost, Simulation};
use crate::error::{Error, Result};
use crate::mesh::TetMesh;
use crate::model::{ModelDiff, SpringModel};

/// The fraction of the new stable bound a cut lowers the step to under
/// [`TimeStepPolicy::Substep`] unless the settings give another.
pub const DEFAULT_BOUND_FRACTION: f64 = 0.9;

/// What to do when a cut lowers the stable time step below the one in use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum TimeStepPolicy {
    /// Stop the run with an error naming the step, the node that limits the new bound, and
    /// the policies that go on instead.
    #[default]
    Stop,
    /// Go on at the same step and record a warning (the run may then diverge, and is stopped
    /// and reported if it does).
    Warn,
    /// Lower the step to [`CutSettings::bound_fraction`] of the new bound and go on.
    Substep,
}

/// How a [`World`](super::World) cuts.
#[derive(Debug, Clone, PartialEq)]
pub struct CutSettings {
    /// The cut method.
    pub method: CutMethod,
    /// Names of the tools that cut; empty for every tool of shape `Blade`. A tool that cuts
    /// passes through the tissue instead of pushing it.
    pub blades: Vec<String>,
    /// What a cut that lowers the stable bound below the time step does.
    pub time_step: TimeStepPolicy,
    /// Check the invariants after every cut, and the engine patched so far against one built
    /// from scratch (slow: for tests and `--check`).
    pub check: bool,
    /// The rest volume-length ratio below which subdividing makes no tet (see
    /// [`Cutter::with_quality_floor`]); 0 turns the floor off.
    pub quality_floor: f64,
    /// The fraction of the lowered bound [`TimeStepPolicy::Substep`] steps at.
    pub bound_fraction: f64,
}

impl Default for CutSettings {
    fn default() -> Self {
        CutSettings {
            method: CutMethod::default(),
            blades: Vec::new(),
            time_step: TimeStepPolicy::default(),
            check: false,
            quality_floor: crate::cut::subdivide::DEFAULT_QUALITY_FLOOR,
            bound_fraction: DEFAULT_BOUND_FRACTION,
        }
    }
}

impl CutSettings {
    /// Whether a tool named `name` of shape `shape` cuts under these settings.
    pub fn cuts_with(&self, name: &str, shape: &crate::collide::ToolShape) -> bool {
        matches!(shape, crate::collide::ToolShape::Blade { .. })
            && (self.blades.is_empty() || self.blades.iter().any(|b| b == name))
    }
}

/// What one cut did: a step at which a blade's sweep changed the mesh.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CutEvent {
    /// The step after which it cut (steps taken so far).
    pub step: u64,
    /// The blade that cut.
    pub blade: String,
    /// Tets removed or given new corners.
    pub tets_touched: usize,
    /// Tets removed.
    pub tets_removed: usize,
    /// Nodes created.
    pub nodes_added: usize,
    /// Springs removed, added or changed.
    pub springs_touched: usize,
    /// Bytes uploaded: the patch, plus `time_step_bytes` when the cut lowered the time step.
    pub bytes_uploaded: u64,
    /// Layout bytes a full rebuild would have uploaded.
    pub layout_bytes: u64,
    /// Bytes of step parameters written at a lowered time step (policy `Substep`), included
    /// in `bytes_uploaded`; 0 when the step did not change.
    pub time_step_bytes: u64,
    /// Whether the patch rebuilt the engine's passes and uploaded the layout whole (a repack,
    /// or node state outgrowing its buffers).
    pub passes_rebuilt: bool,
    /// Layout buffers the patch replaced by larger ones, the passes kept.
    pub buffers_grown: usize,
    /// Bytes those grown buffers took over on the device (copied, not uploaded).
    pub bytes_copied: u64,
    /// The stable bound this cut lowered below the time step, and what the policy did about
    /// it; `None` when the bound stayed at or above the step.
    pub time_step: Option<TimeStepChange>,
    /// Time taken (classify, edit, patch the engine, refresh the surface, change the time
    /// step), ms.
    pub ms: f64,
}

/// A cut that lowered the stable bound below the time step in use.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TimeStepChange {
    /// The stable bound after the cut, s.
    pub bound: f64,
    /// The node (dense index) that limits it.
    pub node: usize,
    /// The time step before the cut, s.
    pub dt_before: f64,
    /// The time step after it, s: the settings' bound fraction of `bound` under
    /// `Substep`, `dt_before` under `Warn` and `Stop`.
    pub dt_after: f64,
}

/// What giving one cut to the simulation did.
struct Applied {
    cost: PatchCost,
    /// Bytes of step parameters written at a new time step (0 if it did not change).
    time_step_bytes: u64,
    time_step: Option<TimeStepChange>,
    /// The error that ends the run once this cut is reported (policy `Stop`).
    stop: Option<Error>,
}

/// What the cuts of a run did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CutReport {
    /// The method used.
    pub method: String,
    /// Steps at which a cut changed the mesh.
    pub cuts: usize,
    /// Tets removed or given new corners, over all cuts.
    pub tets_touched: usize,
    /// Tets removed.
    pub tets_removed: usize,
    /// Nodes created.
    pub nodes_added: usize,
    /// Springs removed, added or changed.
    pub springs_touched: usize,
    /// Rest volume removed, as a fraction of the volume before cutting.
    pub volume_removed_fraction: f64,
    /// Bytes uploaded by all cuts, step parameters at a new time step included.
    pub bytes_uploaded: u64,
    /// Layout bytes a full rebuild would have uploaded at each cut, summed.
    pub bytes_full: u64,
    /// Of `bytes_uploaded`, the bytes of step parameters written at a new time step
    /// (`Substep`).
    pub bytes_time_step: u64,
    /// Cuts whose patch rebuilt the engine's passes and uploaded the layout whole.
    pub passes_rebuilt: usize,
    /// Layout buffers grown by patches (replaced by larger ones, the passes kept).
    pub buffers_grown: usize,
    /// Bytes grown buffers took over on the device (copied, not uploaded).
    pub bytes_copied: u64,
    /// Largest fraction of the layout one cut uploaded (above 1 for a cut after which the
    /// engine was rebuilt at a new time step).
    pub max_upload_fraction: f64,
    /// Time per cut (classify, edit, patch the engine, refresh the surface), ms: median.
    pub p50_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
    /// Largest, ms.
    pub max_ms: f64,
    /// Connected pieces at the end.
    pub fragments: usize,
    /// Largest distance between a node and a copy of it at the end, m: how far the incision
    /// opened (0 when no node was copied).
    pub max_opening: f64,
    /// Time-step changes and warnings caused by cuts.
    pub time_step_events: Vec<String>,
    /// The quality floor subdividing kept to (0: none).
    pub quality_floor: f64,
    /// The lowest rest volume-length ratio of a tet before the first cut.
    pub min_quality_uncut: f64,
    /// The lowest rest volume-length ratio of a tet at the end (no lower than the floor or the
    /// uncut mesh's lowest, whichever is lower; infinite when no tet is left).
    pub min_quality: f64,
    /// Invariant checks run.
    pub checks: usize,
    /// Invariant violations found, with the step.
    pub violations: Vec<String>,
    /// Each cut, in order (the totals above sum them).
    pub events: Vec<CutEvent>,
    /// How the cuts' reads of the nodes near the blades were served: with the step before
    /// them (the GPU engine reading ahead for a blade that touched the tissue at the step
    /// before) or with a round trip of their own (zero on the CPU engines).
    pub near_reads: crate::engine::NearReads,
}

/// A blade that cuts, and what is known of it between steps.
struct Blade {
    /// Its index among the world's tools.
    tool: usize,
    name: String,
    /// Whether it touched the tissue at the last step (it may be wholly inside now).
    touching: bool,
    /// Whether, moving on as it moved at the last step, it would reach the tissue's surface at
    /// the next (true before its first step): its first cut is then read ahead like the
    /// others.
    approaching: bool,
    /// Its strokes through the tissue since its last cut that changed no tet, kept for a
    /// render surface ([`CutMade::earlier`]) while [`Cutting::follow_cuts`] is on.
    unfollowed: Vec<Sweep>,
    /// Its strokes since it last touched the tissue, up to [`GAP_STEPS`] (`None` beyond):
    /// a carving can clear the material around the blade for a step or two, and a render
    /// surface needs those strokes too, or its sweep would have a gap there.
    outside: Option<Vec<Sweep>>,
}

/// How many steps out of touch with the tissue a blade's strokes are kept for a render surface
/// in case it touches again (beyond that, it left): a blade in the void a carving left goes
/// about twenty steps without touching in `surface_cut_box.ron`; a few hundred strokes are a
/// few hundred kilobytes at most.
const GAP_STEPS: usize = 256;

/// The cutting part of a world: the [`Cutter`] (which holds the mesh as cut so far), the
/// blades, and what the cuts did.
pub struct Cutting {
    cutter: Cutter,
    blades: Vec<Blade>,
    settings: CutSettings,
    volume_before: f64,
    /// The floor the invariant check holds the tets to: the settings', or the uncut mesh's
    /// worst tet where that is lower.
    check_floor: f64,
    latencies: Vec<f64>,
    /// Each node a cut created, with the node it copies (dense indices).
    copies: Vec<(u32, u32)>,
    /// What the cuts did so far.
    pub report: CutReport,
    /// The cuts a render surface has not yet followed ([`Cutting::follow_cuts`]); `None`
    /// when nothing follows them.
    made: Option<Vec<CutMade>>,
}

/// What one cut changed, for a render surface to follow ([`crate::surface::Rebinder`]).
///
/// A blade's strokes that changed no tet (separating opens a tet only once the blade is
/// through it; a blade moving within a cell) still cut the render surface where the mesh
/// opens later: they come with the blade's next cut as `earlier`, or, when the blade leaves
/// the tissue or stops with no further cut, or the run ends ([`Cutting::finish_strokes`]), as
/// a `CutMade` of their own with no tets and an empty `sweep`, so that the render surface is split along every stroke but only when the
/// mesh changed (or the blade left or stopped).
#[derive(Debug, Clone)]
pub struct CutMade {
    /// The tets it removed, gave new corners or made.
    pub tets: Vec<crate::mesh::TetKey>,
    /// The blade's swept surface over the step that cut.
    pub sweep: Sweep,
    /// The same blade's strokes through the tissue before it, since its last cut, that changed
    /// no tet, in order.
    pub earlier: Vec<Sweep>,
}

impl Cutting {
    /// Keep what each cut changed until [`Cutting::take_cuts`] (a render surface follows
    /// the cuts).
    pub fn follow_cuts(&mut self) {
        self.made.get_or_insert_with(Vec::new);
    }

    /// The cuts made since the last call, in order (empty unless [`Cutting::follow_cuts`]).
    /// At the end of a run call [`Cutting::finish_strokes`] (or [`World::finish_cuts`]) first,
    /// so that the strokes since each blade's last cut come too.
    ///
    /// [`World::finish_cuts`]: super::World::finish_cuts
    pub fn take_cuts(&mut self) -> Vec<CutMade> {
        self.made.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// The cutter: the mesh as cut so far and its adjacency.
    pub fn cutter(&self) -> &Cutter {
        &self.cutter
    }

    /// Cutting of `mesh` (whose model is `model`) under `settings`, with no blade yet.
    pub fn new(mesh: &TetMesh, model: &SpringModel, settings: CutSettings) -> Result<Self> {
        let min_quality_uncut = mesh.min_volume_length_ratio();
        let quality_floor = settings.quality_floor;
        // The cutter keeps to no floor at 0, below it or at NaN: neither does the check.
        let check_floor = if quality_floor > 0.0 {
            min_quality_uncut.min(quality_floor)
        } else {
            0.0
        };
        Ok(Cutting {
            cutter: Cutter::new(mesh.clone(), model.clone(), settings.method)?
                .with_quality_floor(quality_floor),
            blades: Vec::new(),
            volume_before: mesh.volume(),
            check_floor,
            latencies: Vec::new(),
            copies: Vec::new(),
            made: None,
            report: CutReport {
                method: settings.method.to_string(),
                quality_floor,
                min_quality_uncut,
                ..CutReport::default()
            },
            settings,
        })
    }

    /// The settings.
    pub fn settings(&self) -> &CutSettings {
        &self.settings
    }

    /// Cut with tool `tool` (its index among the world's tools), named `name`. Blades cut in
    /// the order they were added.
    pub(crate) fn add_blade(&mut self, tool: usize, name: &str) {
        self.blades.push(Blade {
            tool,
            name: name.to_string(),
            touching: false,
            unfollowed: Vec::new(),
            outside: None,
            // Nothing is known of the blade's motion before its first step: read ahead for it
            // then (it may start in contact).
            approaching: true,
        });
    }

    /// Whether tool `i` cuts (and so is not pushed against as a contact).
    pub fn cuts_with(&self, i: usize) -> bool {
        self.blades.iter().any(|b| b.tool == i)
    }

    /// The cut method.
    pub fn method(&self) -> CutMethod {
        self.cutter.method()
    }

    /// The mesh as cut so far.
    pub fn mesh(&self) -> &TetMesh {
        self.cutter.mesh()
    }

    /// Before a step (`tools` posed for its end): have the step read ahead what the cuts after
    /// it will read, the boxes of the sweeps of the blades that touched the tissue at the last
    /// step or were about to (one box holding them all), so that on the GPU those reads come
    /// back with the step.
    pub fn before_step(&self, sim: &mut Simulation, tools: &[Tool]) {
        let boxes = self
            .blades
            .iter()
            .filter(|b| b.touching || b.approaching)
            .filter_map(|b| {
                let tool = &tools[b.tool];
                let sweep = Sweep::of_blade(&tool.shape, tool.previous_pose(), tool.pose())?;
                self.cutter.reading_box(&sweep)
            });
        let union = boxes.reduce(|(lo, hi), (l, h)| {
            (
                [0, 1, 2].map(|c| lo[c].min(l[c])),
                [0, 1, 2].map(|c| hi[c].max(h[c])),
            )
        });
        if let Some((lo, hi)) = union {
            sim.prefetch_near(lo, hi);
        }
    }

    /// Cut with every cutting blade's sweep over the step just taken (`tools` at their new
    /// poses, remembering the previous ones), between steps.
    pub fn after_step(&mut self, sim: &mut Simulation, tools: &[Tool]) -> Result<()> {
        // By index: a cut is applied through `self` while the blades are walked.
        for slot in 0..self.blades.len() {
            let tool = &tools[self.blades[slot].tool];
            let Some(sweep) = Sweep::of_blade(&tool.shape, tool.previous_pose(), tool.pose())
            else {
                continue;
            };
            if sweep.is_empty() {
                // A blade that stopped: what it swept without cutting is followed now, out of
                // touch with the tissue too (in the void a carving left, or through and out).
                let blade = &mut self.blades[slot];
                if let Some(outside) = blade.outside.as_mut() {
                    blade.unfollowed.append(outside);
                }
                self.follow_unfollowed(slot);
            }
            // Only read the state back when the blade's bounds meet the surface, or met it at
            // the last step (a blade can be wholly inside the tissue). The same cull asks
            // whether the blade, moving on as it moved, would meet it at the next step.
            let b = tool.step_bounds(0.0);
            let next = tool.swept_aabb(tool.pose(), &extrapolated(tool), 0.0);
            let culled = sim.cull_tools(
                &[b, next].map(|b| ToolBox::containing(b.min.coords.into(), b.max.coords.into())),
            )?;
            let near = culled.iter().any(|&[_, k]| k == 0);
            self.blades[slot].approaching = culled.iter().any(|&[_, k]| k == 1);
            let was = std::mem::replace(&mut self.blades[slot].touching, near);
            if !(near || was) {
                // Out of the tissue: what it swept inside without cutting is followed now.
                self.follow_unfollowed(slot);
                let blade = &mut self.blades[slot];
                let follows = self.made.is_some() && !sweep.is_empty();
                if let (Some(outside), true) = (blade.outside.as_mut(), follows) {
                    outside.push(sweep);
                    if outside.len() > GAP_STEPS {
                        blade.outside = None;
                    }
                }
                continue;
            }
            // Back in touch within a few steps: the strokes in between go on the same cut.
            let blade = &mut self.blades[slot];
            let gap = blade.outside.replace(Vec::new()).unwrap_or_default();
            blade.unfollowed.extend(gap);
            let start = Instant::now();
            // The cutter reads back only the positions near the blade.
            let outcome = self.cutter.cut_from(&sweep, sim)?;
            if outcome.is_empty() {
                if self.made.is_some() && !sweep.is_empty() {
                    self.blades[slot].unfollowed.push(sweep);
                }
                continue;
            }
            self.blades[slot].touching = true;
            let first = sim.model().node_count() as u32;
            let applied = self.apply(sim, &outcome.diff)?;
            sim.edit_surface(&outcome.surface)?;
            if let Some(made) = self.made.as_mut() {
                made.push(CutMade {
                    tets: outcome.tets_changed.clone(),
                    sweep: sweep.clone(),
                    earlier: std::mem::take(&mut self.blades[slot].unfollowed),
                });
            }
            let seconds = start.elapsed().as_secs_f64();
            self.latencies.push(seconds);
            // Copies of a node (splitting) sit at its rest position; nodes a subdivision puts
            // on an edge do not, and are not openings.
            for (k, a) in outcome.diff.added_nodes.iter().enumerate() {
                if let Some(from) = a.state_from {
                    if sim.model().rest[from as usize] == a.rest {
                        self.copies.push((first + k as u32, from));
                    }
                }
            }
            let cost = &applied.cost;
            let uploaded = cost.uploaded_bytes + applied.time_step_bytes;
            let r = &mut self.report;
            r.events.push(CutEvent {
                step: sim.steps(),
                blade: self.blades[slot].name.clone(),
                tets_touched: outcome.tets_touched,
                tets_removed: outcome.tets_removed,
                nodes_added: outcome.nodes_added,
                springs_touched: outcome.springs_touched,
                bytes_uploaded: uploaded,
                layout_bytes: cost.layout_bytes,
                time_step_bytes: applied.time_step_bytes,
                passes_rebuilt: cost.reallocated,
                buffers_grown: cost.buffers_grown,
                bytes_copied: cost.copied_bytes,
                time_step: applied.time_step,
                ms: 1e3 * seconds,
            });
            r.cuts += 1;
            r.tets_touched += outcome.tets_touched;
            r.tets_removed += outcome.tets_removed;
            r.nodes_added += outcome.nodes_added;
            r.springs_touched += outcome.springs_touched;
            r.bytes_uploaded += uploaded;
            r.bytes_full += cost.layout_bytes;
            r.bytes_time_step += applied.time_step_bytes;
            r.passes_rebuilt += cost.reallocated as usize;
            r.buffers_grown += cost.buffers_grown;
            r.bytes_copied += cost.copied_bytes;
            r.max_upload_fraction = r
                .max_upload_fraction
                .max(uploaded as f64 / cost.layout_bytes.max(1) as f64);
            if self.settings.check {
                let inv = self
                    .cutter
                    .check_invariants(self.volume_before, self.check_floor);
                r.checks += 1;
                // The engine's patched structures (device buffers included) against a rebuild.
                let engine = sim.differences_from_rebuild()?;
                r.violations.extend(
                    inv.violations
                        .into_iter()
                        .chain(engine)
                        .map(|v| format!("after the cut at step {}: {v}", sim.steps())),
                );
            }
            if let Some(e) = applied.stop {
                return Err(e);
            }
        }
        Ok(())
    }

    /// End the run's cutting for a render surface: every blade's strokes since its last cut
    /// that changed no tet (a blade still moving inside the tissue when the run ends, or in
    /// the void a carving left) are handed over as a [`CutMade`] with no tets, as when a blade
    /// leaves the tissue or stops, so that the next [`Cutting::take_cuts`] gives the render
    /// surface the whole sweep. Without it those last strokes would wait for a cut, a leaving
    /// or a stop that never comes. Cutting may go on after it (it only empties what was kept);
    /// calling it again with no stroke since gives nothing.
    pub fn finish_strokes(&mut self) {
        for slot in 0..self.blades.len() {
            let blade = &mut self.blades[slot];
            if let Some(outside) = blade.outside.as_mut() {
                blade.unfollowed.append(outside);
            }
            self.follow_unfollowed(slot);
        }
    }

    /// Hand the strokes blade `slot` swept without cutting since its last cut to the render
    /// surface (a [`CutMade`] with no tets), if any and if one follows the cuts.
    fn follow_unfollowed(&mut self, slot: usize) {
        let mut earlier = std::mem::take(&mut self.blades[slot].unfollowed);
        earlier.retain(|s| !s.is_empty());
        if let (Some(made), false) = (self.made.as_mut(), earlier.is_empty()) {
            made.push(CutMade {
                tets: Vec::new(),
                sweep: Sweep::from_triangles(Vec::new()),
                earlier,
            });
        }
    }

    /// Give a cut's `diff` to the simulation (with the positions the cutter read), and when it
    /// lowers the stable bound below the time step, do what the settings' policy says.
    fn apply(&mut self, sim: &mut Simulation, diff: &ModelDiff) -> Result<Applied> {
        let positions = self.cutter.positions_read().positions();
        let dt = sim.config().dt;
        // Under every policy the simulation takes the cut (the bound is updated from the diff
        // once, with it): under `Stop` the run ends after it (no step is taken with it), but the
        // cutter already holds it, and the report must count it and measure a mesh and
        // positions that agree. Then the simulation's bound says whether the step must change.
        let cost = sim.apply_at(diff, true, positions)?;
        let (bound, node) = (sim.bound().dt, sim.bound().node);
        // The stable-bound policies are for explicit schemes: an implicit step is stable at
        // any step, so a cut never changes it.
        if dt <= bound || sim.config().integrator.is_implicit() {
            return Ok(Applied {
                cost,
                time_step_bytes: 0,
                time_step: None,
                stop: None,
            });
        }
        let step = sim.steps();
        let mut applied = Applied {
            cost,
            time_step_bytes: 0,
            time_step: None,
            stop: None,
        };
        let mut change = TimeStepChange {
            bound,
            node,
            dt_before: dt,
            dt_after: dt,
        };
        match self.settings.time_step {
            TimeStepPolicy::Stop => {
                applied.stop = Some(Error::CutLoweredTimeStep {
                    step,
                    dt,
                    bound,
                    node,
                });
            }
            TimeStepPolicy::Warn => self.report.time_step_events.push(format!(
                "step {step}: the cut lowered the stable bound to {bound:.4e} s (node {node}) \
                 below dt {dt:.4e} s; going on"
            )),
            TimeStepPolicy::Substep => {
                change.dt_after = self.settings.bound_fraction * bound;
                // A parameter of the step: the engine writes its step parameters (and Verlet's
                // previous positions move where the state lives), which the report counts with
                // the patch.
                applied.time_step_bytes = sim.set_time_step(change.dt_after)?.uploaded_bytes;
                self.report.time_step_events.push(format!(
                    "step {step}: the cut lowered the stable bound to {bound:.4e} s (node {node}); \
                     dt {dt:.4e} s -> {:.4e} s",
                    change.dt_after
                ));
            }
        }
        applied.time_step = Some(change);
        Ok(applied)
    }

    /// The report so far, finished (latency percentiles, fragments, opening at `positions`,
    /// the current node positions).
    pub fn report_at(&self, positions: &[[f64; 3]]) -> CutReport {
        let mut report = self.report.clone();
        let at = |i: u32| nalgebra::Point3::from(positions[i as usize]);
        report.max_opening = self
            .copies
            .iter()
            .map(|&(c, o)| (at(c) - at(o)).norm())
            .fold(0.0, f64::max);
        let mut l = self.latencies.clone();
        l.sort_by(f64::total_cmp);
        let pick = |q: f64| {
            if l.is_empty() {
                0.0
            } else {
                1e3 * l[((q * (l.len() - 1) as f64).round() as usize).min(l.len() - 1)]
            }
        };
        report.p50_ms = pick(0.5);
        report.p99_ms = pick(0.99);
        report.max_ms = l.last().map_or(0.0, |s| 1e3 * s);
        report.fragments = self.cutter.mesh().component_count();
        report.min_quality = self.cutter.mesh().min_volume_length_ratio();
        report.volume_removed_fraction = self.cutter.volume_removed() / self.volume_before;
        report
    }
}

/// Where `tool` would be after one more step moving as it moved over the last one (its last
/// motion applied again). A blade that strays from it reaches the tissue with a read of its
/// own, as without the prediction.
fn extrapolated(tool: &Tool) -> Isometry3<f64> {
    let motion = tool.pose() * tool.previous_pose().inverse();
    motion * tool.pose()
}

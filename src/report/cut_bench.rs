//! `lancet bench cut`: what a local incision costs as the mesh grows and as the cut lengthens.
//!
//! Each row cuts a box of 1 cm cells (6 tets each) with a blade drawn straight down into the
//! middle of its top, off the grid, to a depth of two cells, in steps of a fifth of a cell (one
//! cut event per step), and times every event from the state to the engine being ready for the
//! next step: reading the positions, classifying, editing the mesh and model, patching the
//! engine (only dirty ranges are uploaded on the GPU) and refreshing its surface. Reported per
//! row: latency percentiles and where the median goes, bytes uploaded against the whole layout,
//! nodes and springs added per square centimetre of cut, and the stable time step before and
//! after.

use std::time::Instant;

use serde::Serialize;

use nalgebra::Isometry3;

use crate::collide::ToolShape;
use crate::cut::{CutMethod, Cutter, Sweep};
use crate::engine::{EngineKind, SimConfig, Simulation};
use crate::error::{Error, Result};
use crate::layout::LayoutKind;
use crate::mesh::generate::BoxGrid;
use crate::model::{stable_time_step, Material, ModelConfig, SpringModel};

/// One row: a mesh, a cut length, a method and an engine.
#[derive(Debug, Clone, Serialize)]
pub struct CutRow {
    /// Tets before cutting.
    pub tets: usize,
    /// Nodes before cutting.
    pub nodes: usize,
    /// Cut length along the surface, m.
    pub length: f64,
    /// Cut method.
    pub method: String,
    /// Engine (with its device) and layout.
    pub engine: String,
    /// Cut events that changed the mesh.
    pub cuts: usize,
    /// Latency per cut event, ms: median, 99th percentile, largest.
    pub p50_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
    /// Largest, ms.
    pub max_ms: f64,
    /// Median of each part, ms: reading back the positions near the blade.
    pub read_ms: f64,
    /// Median nodes whose positions a cut event read back (of `nodes` and those added).
    pub nodes_read: f64,
    /// Cut events whose read came back with the step before them (GPU engines reading ahead,
    /// see [`crate::Simulation::prefetch_near`], from the blade's motion at the event before,
    /// or at an incision's first event from the motion it arrives with); the others waited for
    /// a read of their own.
    pub reads_ahead: usize,
    /// Median of the step before each cut event, waited for, ms (not part of the latency: the
    /// simulation steps anyway; it shows what reading ahead adds to the step).
    pub step_ms: f64,
    /// Median of [`QUIET_STEPS`] steps, each waited for, before the first incision, ms.
    pub quiet_step_before_ms: f64,
    /// The same after the last incision, ms: what the cuts did to the step itself (a larger
    /// model, a layout fragmented or regrouped by patches, overflow rows), against
    /// `quiet_step_before_ms`. No read is made ahead in either, unlike `step_ms`.
    pub quiet_step_after_ms: f64,
    /// The device's own time of those steps before the incisions (timestamps around the step
    /// pass), median, ms, where the engine measures it (a GPU adapter with timestamp queries):
    /// without the submission and the wait, which dominate a small step's wall time.
    pub quiet_device_before_ms: Option<f64>,
    /// The same after the last incision, ms.
    pub quiet_device_after_ms: Option<f64>,
    /// Classifying and editing (the cutter).
    pub cut_ms: f64,
    /// Patching the engine (diff applied, dirty ranges uploaded, time step re-checked).
    pub apply_ms: f64,
    /// Giving the engine the new surface.
    pub surface_ms: f64,
    /// Mean bytes uploaded per cut event.
    pub bytes_per_cut: f64,
    /// Bytes of the whole layout (a rebuild would upload this much per cut).
    pub layout_bytes: u64,
    /// Cut events whose patch rebuilt the engine's passes and uploaded the layout whole.
    pub passes_rebuilt: usize,
    /// Layout buffers grown by patches (replaced by larger ones, the passes kept).
    pub buffers_grown: usize,
    /// Cut area, cm^2.
    pub area_cm2: f64,
    /// Nodes added per cm^2 of cut.
    pub nodes_per_cm2: f64,
    /// Springs added per cm^2 of cut (net).
    pub springs_per_cm2: f64,
    /// Tets removed per cm^2 of cut.
    pub tets_removed_per_cm2: f64,
    /// Stable time step before the cut, s.
    pub dt_before: f64,
    /// Stable time step after it, s.
    pub dt_after: f64,
    /// The quality floor subdividing kept to (0: none; the other methods make no tets).
    pub quality_floor: f64,
    /// The lowest rest volume-length ratio of a tet after the cuts (the uncut boxes' is 0.657).
    pub min_quality: f64,
    /// Where the slowest cut event's time went: what sets `max_ms`, and with few events
    /// `p99_ms`.
    pub slowest: SlowestEvent,
}

/// The parts of one cut event, ms (the slowest of a row).
#[derive(Debug, Clone, Copy, Default, Serialize, PartialEq)]
pub struct SlowestEvent {
    /// Reading the positions near the blade.
    pub read_ms: f64,
    /// The cutter.
    pub cut_ms: f64,
    /// Patching the engine.
    pub apply_ms: f64,
    /// Giving the engine the new surface.
    pub surface_ms: f64,
    /// Whether the patch grew a buffer or rebuilt the passes.
    pub grew: bool,
}

impl SlowestEvent {
    /// The largest part, by name, and its time.
    pub fn largest(&self) -> (&'static str, f64) {
        [
            ("read", self.read_ms),
            ("cut", self.cut_ms),
            ("apply", self.apply_ms),
            ("surf", self.surface_ms),
        ]
        .into_iter()
        .fold(
            ("read", f64::NEG_INFINITY),
            |a, b| if b.1 > a.1 { b } else { a },
        )
    }
}

/// What `lancet bench cut` runs: one row per box, length, method, engine (GPU ones once per
/// layout) and, for subdividing, quality floor (the other methods make no tets: one row, at
/// the first floor).
#[derive(Debug, Clone)]
pub struct CutBench {
    /// Boxes of N x N x N/2 cells of 1 cm.
    pub cubes: Vec<usize>,
    /// Cut lengths, m.
    pub lengths: Vec<f64>,
    /// Cut methods.
    pub methods: Vec<CutMethod>,
    /// Engines.
    pub engines: Vec<EngineKind>,
    /// GPU layouts.
    pub layouts: Vec<LayoutKind>,
    /// Quality floors for subdividing.
    pub floors: Vec<f64>,
    /// Incisions per row, each two cells deep in 11 events (default [`INCISIONS`]): more
    /// give the percentiles more events to rest on and grow the mesh further, which is where
    /// a growing array or table would show as a pause.
    pub incisions: usize,
    /// Whether the step before each cut event reads ahead what the cut will read, predicting
    /// the blade's sweep from its motion at the event before
    /// ([`crate::cut::Cutter::reading_box_ahead`]): on the GPU the cut's read then comes back
    /// with the step instead of a round trip of its own, and the fast CPU engine scans for
    /// it after the step; the reference engine ignores it.
    pub read_ahead: bool,
}

impl CutBench {
    /// The rows.
    pub fn run(&self) -> Result<Vec<CutRow>> {
        let CutBench {
            cubes,
            lengths,
            methods,
            engines,
            layouts,
            floors,
            incisions,
            read_ahead,
        } = self;
        validate(cubes, lengths, floors, *incisions)?;
        if methods.is_empty() || engines.is_empty() || layouts.is_empty() {
            return Err(Error::Options(
                "give at least one cut method, one engine and one layout".into(),
            ));
        }
        let first = [floors
            .first()
            .copied()
            .unwrap_or(crate::cut::subdivide::DEFAULT_QUALITY_FLOOR)];
        let mut rows = Vec::new();
        for &n in cubes {
            for &length in lengths {
                for &method in methods {
                    for &engine in engines {
                        let per_layout = matches!(engine, EngineKind::Gpu | EngineKind::Auto);
                        let kinds = if per_layout {
                            layouts
                        } else {
                            &layouts[..1.min(layouts.len())]
                        };
                        let floors: &[f64] = if method == CutMethod::Subdivide && !floors.is_empty()
                        {
                            floors
                        } else {
                            &first
                        };
                        for &layout in kinds {
                            for &floor in floors {
                                let row = Row {
                                    n,
                                    length,
                                    method,
                                    engine,
                                    layout,
                                    floor,
                                    incisions: *incisions,
                                    read_ahead: *read_ahead,
                                };
                                rows.push(one(&row)?);
                            }
                        }
                    }
                }
            }
        }
        Ok(rows)
    }
}

/// Check the sizes of a [`CutBench`] before anything is built: every box must have room for
/// an incision, every length must be positive, every quality floor a volume-length ratio in
/// [0, 1) and the incisions at least one and as many as fit every box. Left unchecked, a box
/// with no room or a zero length cuts nothing and its row divides by a zero cut area; a floor
/// of 1 or more would refuse every split but a regular tet's.
pub fn validate(cubes: &[usize], lengths: &[f64], floors: &[f64], incisions: usize) -> Result<()> {
    if cubes.is_empty() || lengths.is_empty() {
        return Err(Error::Options(
            "give at least one cube and one cut length".into(),
        ));
    }
    if incisions == 0 {
        return Err(Error::Options(format!(
            "give at least one incision per row (the default is {INCISIONS})"
        )));
    }
    let smallest = smallest_cube();
    if let Some(&n) = cubes.iter().find(|&&n| n < smallest) {
        return Err(Error::Options(format!(
            "cube {n} is too small to cut: each incision runs at least a cell in from the box's \
             sides; give cubes of {smallest} cells or more ({} or more fit all {INCISIONS} \
             incisions)",
            cube_fitting_all_incisions()
        )));
    }
    if let Some(l) = lengths.iter().find(|l| !(l.is_finite() && **l > 0.0)) {
        return Err(Error::Options(format!(
            "cut length {l} m must be positive and finite (the default is 0.03 m, three cells)"
        )));
    }
    if let Some(f) = floors.iter().find(|f| !(0.0..1.0).contains(*f)) {
        return Err(Error::Options(format!(
            "quality floor {f} must be a volume-length ratio in [0, 1): 0 turns the floor off, \
             1 is a regular tet's, which no split keeps to (the default is {})",
            crate::cut::subdivide::DEFAULT_QUALITY_FLOOR
        )));
    }
    if incisions > INCISIONS {
        for &n in cubes {
            for &l in lengths {
                let fit = incision_sites(n, l / CELL, usize::MAX).len();
                if fit < incisions {
                    return Err(Error::Options(format!(
                        "{incisions} incisions of {l} m do not fit a box {n} cells across \
                         ({fit} do, two cells apart and a cell from its sides); give fewer \
                         incisions, a shorter cut or a larger box"
                    )));
                }
            }
        }
    }
    Ok(())
}

/// Cell size of the benchmark boxes, m.
const CELL: f64 = 0.01;

/// Where `count` incisions of `length` cells go in a box `n` cells across, as (x, y) of the
/// blade's centre in cells: first the planes of [`incision_planes`] at the middle of the box
/// (up to [`INCISIONS`] only those, as many as fit), then planes further out, then the same
/// planes at centres further along x (the length and two cells apart). Planes lie a cell from
/// the box's sides, and so do the incisions off the middle (one at the middle may be longer
/// than the box).
fn incision_sites(n: usize, length: f64, count: usize) -> Vec<(f64, f64)> {
    if count <= INCISIONS {
        let x = middle_cell(n);
        return incision_planes(n)
            .into_iter()
            .take(count)
            .map(|y| (x, y))
            .collect();
    }
    let half = 0.5 * length.min(n as f64);
    let fits_x = |x: f64| x - half >= 1.0 - 1e-9 && x + half <= n as f64 - 1.0 + 1e-9;
    let middle = middle_cell(n);
    let mut xs = vec![middle];
    let step = length + 2.0;
    for k in 1.. {
        let (a, b) = (middle - step * k as f64, middle + step * k as f64);
        if !fits_x(a) && !fits_x(b) {
            break;
        }
        xs.extend([a, b].into_iter().filter(|&x| fits_x(x)));
    }
    // Planes two cells apart: the default ones first, then outwards in turn.
    let mut ys = incision_planes(n);
    let (y_middle, first) = (middle_cell(n) + 0.3, 0.5 * (INCISIONS - 1) as f64);
    for k in 0..n {
        let reach = 2.0 * (first + 1.0 + k as f64);
        ys.extend(
            [y_middle - reach, y_middle + reach]
                .into_iter()
                .filter(|y| (1.0..=n as f64 - 1.0).contains(y)),
        );
    }
    let mut sites = Vec::new();
    for &x in &xs {
        for &y in &ys {
            if sites.len() == count {
                return sites;
            }
            sites.push((x, y));
        }
    }
    sites
}

/// The middle of the cell at the centre of a box `n` cells across (the centre itself for odd
/// `n`), in cells: incisions sit at the same place among the grid's cells in every box, so
/// that boxes of different sizes are cut alike and their latencies compare.
fn middle_cell(n: usize) -> f64 {
    (n / 2) as f64 + 0.5
}

/// Where the incisions go in a box `n` cells across: the `y` of each plane, in cells, that
/// lies at least a cell from both sides of the box. Two cells apart around the middle, off the
/// grid by 0.3 of a cell past the middle of a cell.
fn incision_planes(n: usize) -> Vec<f64> {
    let middle = middle_cell(n) + 0.3;
    (0..INCISIONS)
        .map(|j| middle + 2.0 * (j as f64 - 0.5 * (INCISIONS - 1) as f64))
        .filter(|y| (1.0..=n as f64 - 1.0).contains(y))
        .collect()
}

/// The smallest box (cells across) with room for an incision: smaller ones cannot cut.
pub fn smallest_cube() -> usize {
    (1..)
        .find(|&n| !incision_planes(n).is_empty())
        .expect("a large enough box has room for an incision")
}

/// The smallest box with room for all [`INCISIONS`] incisions.
pub fn cube_fitting_all_incisions() -> usize {
    (1..)
        .find(|&n| incision_planes(n).len() == INCISIONS)
        .expect("a large enough box has room for every incision")
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((q * (sorted.len() - 1) as f64).round() as usize).min(sorted.len() - 1)]
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    percentile(&v, 0.5)
}

/// Parallel incisions per row, each a blade going down two cells: enough cut events for the
/// percentiles to mean something (one incision made two to five; four make 8-27).
pub const INCISIONS: usize = 4;

/// One row's settings.
struct Row {
    n: usize,
    length: f64,
    method: CutMethod,
    engine: EngineKind,
    layout: LayoutKind,
    floor: f64,
    incisions: usize,
    read_ahead: bool,
}

/// How far, m, the bench lets a blade's sweep stray from the one predicted when reading ahead
/// (a millimetre: a tenth of a cell).
const PREDICTION_MARGIN: f64 = 1e-3;

/// Steps timed before the first incision and after the last ([`CutRow::quiet_step_before_ms`]).
pub const QUIET_STEPS: usize = 20;

/// The medians of `count` steps, each waited for, ms: wall time, and the device's own time
/// where the engine measures it (read after the wall time is taken).
fn quiet_steps(sim: &mut Simulation, count: usize) -> Result<(f64, Option<f64>)> {
    let (mut wall, mut device) = (Vec::with_capacity(count), Vec::with_capacity(count));
    for _ in 0..count {
        let t = Instant::now();
        sim.run(1)?;
        sim.wait();
        wall.push(t.elapsed().as_secs_f64() * 1e3);
        device.extend(sim.last_device_seconds().map(|s| s * 1e3));
    }
    let device = (device.len() == count).then(|| median(device));
    Ok((median(wall), device))
}

fn one(row: &Row) -> Result<CutRow> {
    let &Row {
        n,
        length,
        method,
        engine,
        layout,
        floor,
        incisions,
        read_ahead,
    } = row;
    let h = CELL;
    let nz = (n / 2).max(2);
    let mesh = BoxGrid::cube_cells([n, n, nz], h).build()?;
    let (tets, nodes) = (mesh.tet_count(), mesh.node_count());
    let mut config = ModelConfig::new(Material::elastic(5e3, 0.3, 1000.0));
    config.fixed = vec![crate::model::FixedSelector::Box {
        min: [-1.0; 3],
        max: [1.0, 1.0, 1e-9],
    }];
    let model = SpringModel::build(&mesh, &config)?;
    let packed = model.pack(&mesh)?;
    let before = stable_time_step(&packed);
    let sim_config = SimConfig {
        allow_unstable: true,
        ..SimConfig::new(0.5 * before.dt)
    };
    let mut sim = Simulation::with_gpu(packed, engine, sim_config, layout.into())?;
    let engine_name = sim.engine_name();
    let mut cutter = Cutter::new(mesh, model, method)?.with_quality_floor(floor);
    sim.set_surface(cutter.surface())?;
    let blade = ToolShape::Blade {
        width: length,
        length: 0.1,
        thickness: 2e-4,
    };
    // `incisions` sites (those that fit, see `incision_sites`), each in a plane y = const,
    // edge from just above the top down two cells, a fifth of a cell per step.
    let top = nz as f64 * h;
    let steps = 11;
    let (mut total, mut read, mut cutting, mut apply, mut surface) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut nodes_read, mut step) = (Vec::new(), Vec::new());
    let (mut bytes, mut added, mut springs, mut removed) = (0u64, 0usize, 0i64, 0usize);
    let mut layout_bytes = 0;
    let mut grew: Vec<bool> = Vec::new();
    let (mut passes_rebuilt, mut buffers_grown, mut reads_ahead) = (0, 0, 0);
    let sites = incision_sites(n, length / h, incisions);
    let (quiet_step_before_ms, quiet_device_before_ms) = quiet_steps(&mut sim, QUIET_STEPS)?;
    for (x, y) in sites.iter().map(|&(x, y)| (x * h, y * h)) {
        let pose = |z: f64| Isometry3::translation(x, y, z);
        // The blade arrives moving as it goes on to cut: a tracked tool's velocity is known
        // before it touches the tissue (the world's step extrapolates it the same way, see
        // `world::cutting::Cutting::after_step`), so an incision's first event is predicted
        // as well.
        let mut last_motion =
            Some(pose(top - 0.2 * h).translation.vector - pose(top).translation.vector);
        for k in 0..steps {
            let z0 = top + 0.1 * h - 0.2 * h * k as f64;
            let sweep =
                Sweep::of_blade(&blade, &pose(z0), &pose(z0 - 0.2 * h)).expect("a blade sweeps");
            // A simulator extrapolates the blade's motion and reads ahead, with the step, what
            // the cut after it will read: here the blade is predicted to move as it moved at
            // the last event; a sweep that strayed more than the margin from the prediction
            // would read with a round trip of its own.
            let predicted = last_motion.and_then(|d: nalgebra::Vector3<f64>| {
                let at = pose(z0);
                let to = Isometry3::from_parts((at.translation.vector + d).into(), at.rotation);
                Sweep::of_blade(&blade, &at, &to)
            });
            last_motion = Some(pose(z0 - 0.2 * h).translation.vector - pose(z0).translation.vector);
            if let Some(predicted) = predicted.filter(|_| read_ahead) {
                if let Some((lo, hi)) = cutter.reading_box_ahead(&predicted, PREDICTION_MARGIN) {
                    sim.prefetch_near(lo, hi);
                }
            }
            let t = Instant::now();
            sim.run(1)?;
            // The cut's latency, not the step's: on the GPU the step may still be running, and
            // the first readback would wait for it.
            sim.wait();
            let stepped = t.elapsed().as_secs_f64() * 1e3;
            let ahead_before = sim.near_reads().ahead;
            // The cutter reads only the positions near the blade, from the simulation.
            let t0 = Instant::now();
            let outcome = cutter.cut_from(&sweep, &mut sim)?;
            let t2 = Instant::now();
            if outcome.is_empty() {
                continue;
            }
            let positions = cutter.positions_read().positions();
            let cost = sim.apply_at(&outcome.diff, true, positions)?;
            let t3 = Instant::now();
            sim.edit_surface(&outcome.surface)?;
            let t4 = Instant::now();
            // A cut that made lighter nodes (subdividing, with a low quality floor) can lower
            // the stable bound below the step: follow it, as a scene's `Substep` policy does,
            // outside the cut's time (a rare event), so that the tissue does not diverge. The
            // engine is rebuilt for the new step: that upload is not in the row's bytes, and
            // the next cut reads without a read made ahead.
            if sim.config().dt > sim.bound().dt {
                sim.set_time_step(0.5 * sim.bound().dt)?;
            }
            total.push((t4 - t0).as_secs_f64() * 1e3);
            step.push(stepped);
            reads_ahead += (sim.near_reads().ahead > ahead_before) as usize;
            read.push(outcome.read_s * 1e3);
            cutting.push(((t2 - t0).as_secs_f64() - outcome.read_s) * 1e3);
            nodes_read.push(outcome.nodes_read as f64);
            apply.push((t3 - t2).as_secs_f64() * 1e3);
            surface.push((t4 - t3).as_secs_f64() * 1e3);
            bytes += cost.uploaded_bytes;
            layout_bytes = cost.layout_bytes;
            grew.push(cost.reallocated || cost.buffers_grown > 0);
            passes_rebuilt += cost.reallocated as usize;
            buffers_grown += cost.buffers_grown;
            added += outcome.nodes_added;
            removed += outcome.tets_removed;
            springs +=
                outcome.diff.added_springs.len() as i64 - outcome.diff.removed_springs.len() as i64;
        }
    }
    let (quiet_step_after_ms, quiet_device_after_ms) = quiet_steps(&mut sim, QUIET_STEPS)?;
    let cuts = total.len();
    if cuts == 0 {
        // A row without cuts would report latencies of nothing and zero growth as if measured.
        return Err(Error::Options(format!(
            "a {length} m blade made no cut in the box {n} cells across ({method}); lengthen \
             the cut (a cell is {h} m) or give a larger box"
        )));
    }
    let worst = (0..cuts)
        .max_by(|&a, &b| total[a].total_cmp(&total[b]))
        .expect("at least one cut");
    let slowest = SlowestEvent {
        read_ms: read[worst],
        cut_ms: cutting[worst],
        apply_ms: apply[worst],
        surface_ms: surface[worst],
        grew: grew[worst],
    };
    let mut sorted = total.clone();
    sorted.sort_by(f64::total_cmp);
    let area_cm2 = sites.len() as f64 * length.min(n as f64 * h) * 2.0 * h * 1e4;
    Ok(CutRow {
        tets,
        nodes,
        length,
        method: method.to_string(),
        engine: engine_name,
        cuts,
        p50_ms: percentile(&sorted, 0.5),
        p99_ms: percentile(&sorted, 0.99),
        max_ms: sorted.last().copied().unwrap_or(0.0),
        read_ms: median(read),
        nodes_read: median(nodes_read),
        reads_ahead,
        step_ms: median(step),
        quiet_step_before_ms,
        quiet_step_after_ms,
        quiet_device_before_ms,
        quiet_device_after_ms,
        cut_ms: median(cutting),
        apply_ms: median(apply),
        surface_ms: median(surface),
        bytes_per_cut: bytes as f64 / cuts.max(1) as f64,
        layout_bytes,
        passes_rebuilt,
        buffers_grown,
        area_cm2,
        nodes_per_cm2: added as f64 / area_cm2,
        springs_per_cm2: springs as f64 / area_cm2,
        tets_removed_per_cm2: removed as f64 / area_cm2,
        dt_before: before.dt,
        dt_after: sim.bound().dt,
        quality_floor: floor,
        min_quality: cutter.mesh().min_volume_length_ratio(),
        slowest,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const LENGTHS: [f64; 6] = [0.1, 0.3, 0.5, 1.0, 3.0, 7.5];

    #[test]
    fn the_largest_part_of_the_slowest_event_is_named() {
        let e = |read_ms, cut_ms, apply_ms, surface_ms| SlowestEvent {
            read_ms,
            cut_ms,
            apply_ms,
            surface_ms,
            grew: false,
        };
        assert_eq!(e(0.1, 0.3, 2.5, 0.05).largest(), ("apply", 2.5));
        assert_eq!(e(0.9, 0.3, 0.2, 0.05).largest(), ("read", 0.9));
        assert_eq!(e(0.1, 0.3, 0.2, 0.5).largest(), ("surf", 0.5));
        assert_eq!(e(0.1, 1.3, 0.2, 0.05).largest(), ("cut", 1.3));
    }

    /// Up to the default count, the incisions are the planes at the middle of the box, as
    /// many as fit: more only come when asked for.
    #[test]
    fn the_default_incisions_are_the_planes_at_the_middle() {
        for n in smallest_cube()..40 {
            for length in LENGTHS {
                let sites = incision_sites(n, length, INCISIONS);
                let planes: Vec<(f64, f64)> = incision_planes(n)
                    .into_iter()
                    .map(|y| (middle_cell(n), y))
                    .collect();
                assert_eq!(sites, planes, "n {n}, length {length}");
            }
        }
    }

    /// Boxes of every size are cut at the same places among their cells (measured against the
    /// cell at the centre), so that latencies against mesh size compare like with like: odd
    /// and even boxes once put the blade's ends on grid planes in one and mid-cell in the
    /// other, which cut twice as many tets.
    #[test]
    fn incisions_sit_alike_among_the_cells_of_every_box() {
        let relative = |n: usize| -> Vec<(f64, f64)> {
            let c = (n / 2) as f64;
            incision_sites(n, 3.0, INCISIONS)
                .into_iter()
                .map(|(x, y)| (x - c, y - c))
                .collect()
        };
        let first = cube_fitting_all_incisions();
        for n in first..60 {
            let (a, b) = (relative(n), relative(first));
            assert_eq!(a.len(), b.len(), "n {n}");
            for (p, q) in a.iter().zip(&b) {
                assert!(
                    (p.0 - q.0).abs() < 1e-9 && (p.1 - q.1).abs() < 1e-9,
                    "n {n}: {a:?}"
                );
            }
        }
    }

    /// However many are asked for, incisions do not overlap: those in one plane are two cells
    /// apart along x, planes two cells apart; off the middle they stay a cell from the sides.
    #[test]
    fn incisions_keep_apart_and_off_the_sides() {
        for n in smallest_cube()..40 {
            for length in LENGTHS {
                let sites = incision_sites(n, length, usize::MAX);
                assert!(sites.len() >= incision_planes(n).len());
                let half = 0.5 * length.min(n as f64);
                for (i, &(x, y)) in sites.iter().enumerate() {
                    assert!((1.0..=n as f64 - 1.0).contains(&y), "n {n}: plane {y}");
                    if x != middle_cell(n) {
                        assert!(x - half >= 1.0 - 1e-9 && x + half <= n as f64 - 1.0 + 1e-9);
                    }
                    for &(x2, y2) in &sites[i + 1..] {
                        let apart = if y == y2 {
                            (x - x2).abs() - 2.0 * half >= 2.0 - 1e-9
                        } else {
                            (y - y2).abs() >= 2.0 - 1e-9
                        };
                        assert!(apart, "n {n}, length {length}: ({x}, {y}) and ({x2}, {y2})");
                    }
                }
            }
        }
    }
}

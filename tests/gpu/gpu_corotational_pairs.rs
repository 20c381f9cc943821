//! The GPU's corotational backward Euler through cuts: the block pass's per-slot pair lists
//! (`layout::tet_pairs`) are patched where a cut reached them, not rebuilt and uploaded whole.
//! After random cut sequences by every method on every layout the patched lists, host and
//! device, equal a rebuild's, the blocks the device then forms equal its twin's on a rebuild's
//! lists, and the engine steps as one built afresh; a one-tet cut uploads as many bytes on a
//! large mesh as on a small one. The engine's memory report counts the block pass's buffers
//! and traffic.

use crate::gpu_corotational::{config, jittered_box};
use crate::models::Rng;
use crate::{common, cut_box};
use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Sweep};
use lancet::engine::gpu::corotational_implicit::PairsUpload;
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, ForceModelKind, Integrator, SimConfig};
use lancet::layout::tensor_blocks::slot_walk;
use lancet::layout::tet_pairs::TetPairs;
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{Material, ModelConfig, PackedModel, SpringModel};
use lancet::twin::corotational_implicit as twin;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rstest::rstest;

const BLADE: ToolShape = ToolShape::Blade {
    width: 0.1,
    length: 0.1,
    thickness: 1e-4,
};

/// `strokes` random strokes of an upright blade through the 5 x 4 x 3 cm box of
/// `cut_box`: each in its own plane (turned about z by up to 0.6 rad and tilted by up to 0.3
/// rad, at a random height across the box), moving down from above the box to a random depth
/// in three sweeps.
fn random_strokes(seed: u64, strokes: usize) -> Vec<Sweep> {
    let mut rng = Rng(seed);
    let mut out = Vec::new();
    for _ in 0..strokes {
        let y = 0.006 + 0.028 * rng.next();
        let x = 0.015 + 0.02 * rng.next();
        let turn = (rng.next() - 0.5) * 1.2;
        let tilt = (rng.next() - 0.5) * 0.6;
        let bottom = -0.01 + 0.03 * rng.next();
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), tilt);
        let at = |z: f64| Isometry3::from_parts(Translation3::new(x, y, z), rotation);
        let top = 0.045;
        for k in 0..3 {
            let z0 = top + (bottom - top) * k as f64 / 3.0;
            let z1 = top + (bottom - top) * (k + 1) as f64 / 3.0;
            if let Some(s) = Sweep::of_blade(&BLADE, &at(z0), &at(z1)) {
                out.push(s);
            }
        }
    }
    out
}

/// A state turned by 0.3 rad about z with random displacements, so that the rotations the
/// block pass reads are not the identity.
fn turned_state(model: &PackedModel, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    crate::gpu_corotational::random_state(model, seed, 1e-3, 0.3)
}

/// After every cut of a random sequence (three strokes, by `method`, on `kind`), with a step
/// between cuts: the engine's checks find nothing (the patched pair lists, host and device,
/// list each slot's tets as a rebuild does; the tet table and layout as before); a cut
/// uploads the lists whole only where the tet table was rebuilt or a buffer grew (the small
/// box grows by a large share of itself at each subdividing cut), and some cuts patch. At the
/// end the blocks the device forms
/// equal its twin's on a rebuild's lists and the device's rotations (bit for bit on lavapipe),
/// and the engine steps as one built afresh from the cut model (to float32 rounding and the
/// solver's tolerance: its rotations kept, the fresh one's cold).
#[rstest]
fn patched_pair_lists_equal_a_rebuild_after_random_cuts(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
) {
    let Some(ctx) = common::gpu() else { return };
    let what = format!("{kind:?} {method}");
    let mut cutter = cut_box::cutter(method);
    let mut model = cutter.model().pack(cutter.mesh()).unwrap();
    let config = config(&model, Integrator::BackwardEuler, 4.0);
    let mut gpu = GpuEngine::with_context(ctx.clone(), &model, config, kind).unwrap();
    let (x, v) = turned_state(&model, 3);
    gpu.set_state(&x, &v);
    gpu.step(1);
    let seed = what
        .bytes()
        .fold(17u64, |h, b| h.wrapping_mul(31).wrapping_add(u64::from(b)));
    let (mut cuts, mut patched, mut compacted) = (0, 0, 0);
    for sweep in random_strokes(seed, 3) {
        let (outcome, _) = cut_box::cut_once(&mut cutter, &sweep, None);
        if outcome.diff.removed_tets.is_empty() && outcome.diff.added_tets.is_empty() {
            continue;
        }
        model.apply(&outcome.diff).unwrap();
        let sizes = |gpu: &GpuEngine| gpu.corotational_blocks().unwrap().buffers();
        let before = sizes(&gpu);
        let cost = gpu.patch(&model, &outcome.diff).unwrap();
        cuts += 1;
        let (bytes, how) = gpu.corotational_blocks().unwrap().last_patch();
        // Whole only where the layout or the tet table was rebuilt, a buffer had to grow, or
        // holes filled half the pairs; each reason as the engine saw it.
        let grew = sizes(&gpu).iter().zip(&before).any(|(a, b)| a.1 > b.1);
        let table_rebuilt = gpu.corotational().unwrap().last_patch().1;
        match how {
            PairsUpload::Patched => {
                patched += 1;
                let all = gpu.corotational_blocks().unwrap().pairs().bytes();
                assert!(bytes < all, "{what}: {bytes} of {all} bytes for a patch");
                assert!(!grew, "{what}: a buffer grew under a patch");
            }
            PairsUpload::Outgrown => assert!(grew, "{what}: cut {cuts}"),
            PairsUpload::TableRebuilt => assert!(table_rebuilt, "{what}: cut {cuts}"),
            PairsUpload::LayoutRebuilt => assert!(cost.reallocated, "{what}: cut {cuts}"),
            PairsUpload::Compacted => compacted += 1,
            PairsUpload::StrideChanged => panic!("{what}: the box's tets are all undamped"),
        }
        assert_eq!(
            gpu.differences_from_rebuild(&model).unwrap(),
            Vec::<String>::new(),
            "{what}: cut {cuts}"
        );
        gpu.step(1);
    }
    assert!(cuts >= 3, "{what}: {cuts} cuts");
    assert!(patched >= 1, "{what}: none of {cuts} cuts patched");
    eprintln!("{what}: {patched} of {cuts} cuts patched, {compacted} compacted");
    let device = gpu.corotational_block_values().unwrap().expect("blocks");
    let table = gpu.corotational().unwrap().table().clone();
    let fresh_pairs = TetPairs::new(&table, gpu.layout());
    let rotations = gpu.tet_rotations().unwrap();
    let want = twin::blocks_cpu(&table, &fresh_pairs, &rotations, device.damped);
    let scale = want
        .rows
        .iter()
        .flat_map(|r| r.map(f32::abs))
        .fold(0.0, f32::max);
    let off = device
        .rows
        .iter()
        .zip(&want.rows)
        .flat_map(|(a, b)| (0..4).map(move |c| (a[c] - b[c]).abs()))
        .fold(0.0, f32::max);
    assert_eq!(device.rows.len(), want.rows.len(), "{what}");
    if common::rounds_like_cpu() {
        assert_eq!(off, 0.0, "{what}: device blocks and a rebuild's differ");
    } else {
        assert!(off <= 1e-6 * scale, "{what}: {off:e} of {scale:e}");
    }
    // Stepped beside an engine built from the cut model, from one state.
    let (x, v) = (gpu.positions(), gpu.velocities());
    let mut fresh = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
    fresh.set_state(&x, &v);
    gpu.set_state(&x, &v);
    gpu.step(5);
    fresh.step(5);
    let (a, b) = (gpu.positions(), fresh.positions());
    let largest = |p: &[[f64; 3]], q: &[[f64; 3]]| {
        p.iter()
            .zip(q)
            .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
            .fold(0.0, f64::max)
    };
    let (motion, worst) = (largest(&a, &x), largest(&a, &b));
    assert!(motion > 1e-6, "{what}: the cut box moves ({motion:e})");
    assert!(
        worst <= 1e-4 * motion,
        "{what}: cut and fresh engines differ by {worst:e} (motion {motion:e})"
    );
}

/// A one-tet cut (tet 0 re-cornered onto a copy of its first corner: removed, the last tet
/// moved into its place, a new one appended) patches the pair lists of the slots it reached:
/// the bytes uploaded are the same few hundred on boxes of 2^3 and 8^3 cells (48 and 3,072
/// tets; a count, not a timing), far below the large box's lists, which equal a rebuild's on
/// the host and the device, in every layout.
#[rstest]
fn a_one_tet_cut_uploads_what_it_reached_not_the_lists(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some(ctx) = common::gpu() else { return };
    let mut uploads = Vec::new();
    for cells in [2, 8] {
        let mesh = BoxGrid::cube_cells([cells; 3], 0.01).build().unwrap();
        let mc = ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0));
        let mut model = SpringModel::build(&mesh, &mc).unwrap().pack(&mesh).unwrap();
        let config = config(&model, Integrator::BackwardEuler, 4.0);
        let mut gpu = GpuEngine::with_context(ctx.clone(), &model, config, kind).unwrap();
        let (x, v) = turned_state(&model, 7);
        gpu.set_state(&x, &v);
        gpu.step(1);
        let diff = crate::fem_cut::recorner_first_tet(&model);
        model.apply(&diff).unwrap();
        gpu.patch(&model, &diff).unwrap();
        let blocks = gpu.corotational_blocks().unwrap();
        let (bytes, how) = blocks.last_patch();
        assert_eq!(how, PairsUpload::Patched, "{kind:?}, {cells} cells");
        assert_eq!(
            gpu.differences_from_rebuild(&model).unwrap(),
            Vec::<String>::new(),
            "{kind:?}, {cells} cells"
        );
        let all = blocks.pairs().bytes();
        eprintln!("{kind:?}, {cells} cells: {bytes} bytes uploaded of {all} bytes of lists");
        uploads.push((bytes, all));
    }
    let ((small, _), (large, all)) = (uploads[0], uploads[1]);
    assert!(
        bytes_flat(small, large),
        "{kind:?}: {small} bytes, then {large}"
    );
    assert!(large * 50 < all, "{kind:?}: {large} of {all} bytes");
}

/// Whether `large` (bytes a cut uploads on a large mesh) is no more than half again `small`
/// (the same cut on a small one).
fn bytes_flat(small: u64, large: u64) -> bool {
    large <= small + small / 2
}

/// The memory report of the GPU's corotational backward Euler, in every layout, damped and
/// not: its buffers name the block pass's pair rows, pairs and blocks, each holding at least
/// the host's lists (and a block per record), and sum to the total; a step's bytes are the
/// explicit corotational step's (tet pass, gather), the spring layout's read once (the
/// solve's product, as the springs' implicit engine counts it), each slot's blocks read, and
/// the block pass counted here: per record its range and blocks, per pair the pair and its
/// tet's shape and rotation.
#[rstest]
fn the_corotational_implicit_step_reports_its_buffers_and_bytes(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values(true, false)] damped: bool,
) {
    let Some(ctx) = common::gpu() else { return };
    let what = format!("{kind:?} damped={damped}");
    let model = jittered_box(5, damped, 0.1);
    let implicit = config(&model, Integrator::BackwardEuler, 4.0);
    let engine = |config: SimConfig| GpuEngine::with_context(ctx.clone(), &model, config, kind);
    let gpu = engine(implicit).unwrap();
    let m = gpu.memory();
    let pairs = gpu.corotational_blocks().unwrap().pairs().clone();
    let stride: u64 = if damped { 6 } else { 3 };
    let records = pairs.rows.len() as u64;
    let size = |name: &str| {
        m.stats
            .buffers
            .iter()
            .find(|(n, _)| n == name)
            .map(|&(_, b)| b)
            .unwrap_or_else(|| panic!("{what}: no {name} in {:?}", m.stats.buffers))
    };
    assert!(size("corotational pair rows") >= 8 * records, "{what}");
    assert!(
        size("corotational pairs") >= 4 * pairs.pairs.len() as u64,
        "{what}"
    );
    assert!(
        size("corotational blocks") >= 16 * stride * records,
        "{what}"
    );
    let sum: u64 = m.stats.buffers.iter().map(|&(_, b)| b).sum();
    assert_eq!(m.stats.total, sum, "{what}");

    let explicit = engine(config(&model, Integrator::Verlet, 0.5)).unwrap();
    let springs = engine(SimConfig {
        force_model: ForceModelKind::Springs,
        ..implicit
    })
    .unwrap();
    let used = slot_walk(gpu.layout()).len() as u64;
    let block_pass = records * (8 + 16 * stride) + pairs.pairs.len() as u64 * (4 + 48 + 16);
    let want = explicit.memory().bytes_per_step
        + springs.memory().bytes_per_step
        + used * 16 * stride
        + block_pass;
    assert_eq!(m.bytes_per_step, want, "{what}");
}

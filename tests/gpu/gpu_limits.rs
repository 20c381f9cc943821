//! Device limits are respected: a mesh whose arrays exceed what one storage binding may hold
//! on the device is refused with an error that names the buffer, the sizes and what to do,
//! never a validation panic; the same mesh fits a device with the full limits. Dispatches past
//! the workgroups a dimension allows fold into rows, and step as unfolded ones do.

use crate::{common, models};
use lancet::engine::gpu::{GpuContext, GpuEngine};
use lancet::engine::SimConfig;
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::Material;
use lancet::{Error, ModelConfig, SpringModel};
use rstest::rstest;

/// The spring model of a box of `cells`^3 cells of 1 cm.
fn box_model(cells: usize) -> lancet::model::PackedModel {
    let mesh = BoxGrid::cube_cells([cells; 3], 0.01).build().unwrap();
    SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(1e4, 0.3, 1e3)))
        .unwrap()
        .pack(&mesh)
        .unwrap()
}

/// A device allowing only 10 workgroups per dimension: every pass of a few thousand nodes or
/// springs folds into rows.
fn narrow_device() -> GpuContext {
    GpuContext::with_limits(|l| l.max_compute_workgroups_per_dimension = 10).unwrap()
}

/// Float bits, for comparisons that must be exact.
fn bits(v: &[[f32; 4]]) -> Vec<[u32; 4]> {
    v.iter().map(|x| x.map(f32::to_bits)).collect()
}

#[rstest]
fn a_mesh_past_the_binding_limit_is_refused_with_a_clear_error(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    // 9,261 nodes and 59,660 springs: about 3.8 MB of slots or spring records.
    let model = box_model(20);
    let limit = 1u64 << 20;
    let small = GpuContext::with_limits(|l| {
        l.max_storage_buffer_binding_size = limit;
        l.max_buffer_size = limit;
    })
    .unwrap();
    let config = SimConfig::new(1e-5);
    match GpuEngine::with_context(small, &model, config, kind) {
        Err(Error::Gpu(msg)) => {
            assert!(msg.contains(&limit.to_string()), "{msg}");
            assert!(msg.contains("cpu engine"), "says what to do: {msg}");
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a {kind:?} layout of 60k springs fit in 1 MiB bindings"),
    }
    assert!(GpuEngine::with_context(GpuContext::new().unwrap(), &model, config, kind).is_ok());
}

/// Dispatches past the device's workgroups per dimension fold into rows of equal width, within
/// the limit, covering every invocation with less than a workgroup per row to spare.
#[test]
fn dispatches_fold_into_equal_rows_within_the_limit() {
    if common::gpu().is_none() {
        return;
    }
    let max = 7;
    let ctx = GpuContext::with_limits(|l| l.max_compute_workgroups_per_dimension = max).unwrap();
    let w = lancet::engine::gpu::WORKGROUP;
    for n in 1..=w * max * max {
        let (x, y) = lancet::engine::gpu::dispatch_size(&ctx, n);
        let groups = n.div_ceil(w);
        assert!(x <= max && y <= max, "{n}: ({x}, {y})");
        assert!(x * y >= groups, "{n}: ({x}, {y}) misses invocations");
        assert!(
            x * y - groups < y,
            "{n}: ({x}, {y}) leaves a row's worth idle"
        );
    }
}

/// An engine on a device allowing 10 workgroups per dimension (its node and spring passes
/// folded into several rows) steps bit for bit like one on the full device, in every layout.
#[rstest]
fn folded_dispatches_step_like_unfolded_ones(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    use lancet::engine::Engine;
    if common::gpu().is_none() {
        return;
    }
    // 1,000 nodes (16 workgroups) and about 6,000 springs (94): both fold at 10.
    let model = box_model(9);
    assert!(model.springs().len() > 64 * 90);
    let narrow = narrow_device();
    let config = SimConfig::new(2e-4);
    let run = |ctx: GpuContext| {
        let mut e = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
        // Moving: a stretch along x.
        let x: Vec<[f64; 3]> = model
            .rest
            .iter()
            .map(|r| [r[0] * 1.05, r[1], r[2]])
            .collect();
        e.set_state(&x, &vec![[0.0; 3]; x.len()]);
        e.step(20);
        e.raw_state().unwrap()
    };
    let (a, b) = (run(narrow), run(GpuContext::new().unwrap()));
    assert_eq!(bits(&a.0), bits(&b.0));
    assert_eq!(bits(&a.1), bits(&b.1));
    assert!(a.0.iter().any(|p| p[0] != 0.0), "the nodes moved");
}

/// A patch with more state moves than ten workgroups hold (700 new nodes, every other one
/// blended between two existing nodes) moves them on a device allowing 10 workgroups per
/// dimension exactly as on the full device, in every layout: the move pass folds its
/// dispatch like the step's passes.
#[rstest]
fn folded_state_moves_match_unfolded_ones(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    use lancet::engine::Engine;
    use lancet::model::StateBlend;
    if common::gpu().is_none() {
        return;
    }
    // 729 nodes and 700 more; about 5,000 springs after the patch: within the 100 workgroups
    // two folded dimensions of 10 hold.
    let model = box_model(8);
    let n = model.node_count();
    let mut diff = models::floating_ring(&model, 700, 1);
    assert!(model.springs().len() + 700 < 64 * 100);
    for (k, a) in diff
        .added_nodes
        .iter_mut()
        .enumerate()
        .filter(|(k, _)| k % 2 == 1)
    {
        a.blend = Some(StateBlend {
            with: ((k * 7) % n) as u32,
            t: 0.25,
        });
    }
    let mut next = model.clone();
    next.apply(&diff).unwrap();
    let narrow = narrow_device();
    let config = SimConfig::new(2e-4);
    let run = |ctx: GpuContext| {
        let mut e = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
        // Every node displaced and moving differently, so each move carries its own state.
        let x: Vec<[f64; 3]> = model
            .rest
            .iter()
            .enumerate()
            .map(|(i, r)| [r[0] * 1.05, r[1] + 1e-4 * (i % 7) as f64, r[2]])
            .collect();
        let v: Vec<[f64; 3]> = (0..n).map(|i| [0.0, 0.0, 1e-3 * (i % 5) as f64]).collect();
        e.set_state(&x, &v);
        e.step(3);
        e.patch(&next, &diff).unwrap();
        let (x, v) = e.state();
        e.step(3);
        (x, v, e.raw_state().unwrap())
    };
    let (a, b) = (run(narrow), run(GpuContext::new().unwrap()));
    assert_eq!(a.0.len(), n + 700);
    assert_eq!((&a.0, &a.1), (&b.0, &b.1), "state right after the patch");
    assert_eq!(bits(&a.2 .0), bits(&b.2 .0));
    assert_eq!(bits(&a.2 .1), bits(&b.2 .1));
    // The blended nodes started between their two sources, not at either (the source's
    // displacement along y differs from the partner's for these).
    let y = |p: &[f64; 3], i: usize| p[1] - model.rest[i % n][1];
    let k = 1;
    let (from, with) = (k % n, (k * 7) % n);
    let got = a.0[n + k][1] - diff.added_nodes[k].rest[1];
    let want = 0.75 * y(&a.0[from], from) + 0.25 * y(&a.0[with], with);
    assert!(
        (got - want).abs() < 1e-7,
        "blended start {got} against {want}"
    );
}

/// The bandwidth floor's copy pass (`report::device_copy`) copies every entry once, as its twin
/// says, in the grid it is timed in: on the full device and on one allowing 10 workgroups per
/// dimension (the grid folds into rows, the last one partly idle), for counts that end inside
/// a workgroup. A pass that skipped entries would time less work than it counts.
#[test]
fn the_device_copy_copies_every_entry_once_folded_or_not() {
    use lancet::report::device_copy::copy_on_device;
    use lancet::twin::device_copy::device_copy_cpu;
    let Some(full) = common::gpu() else { return };
    let narrow = narrow_device();
    let mut rng = models::Rng(17);
    for n in [1, 63, 65, 640, 5_001, 6_399] {
        let data: Vec<[f32; 4]> = (0..n)
            .map(|_| [0; 4].map(|_| (rng.next() - 0.5) as f32 * 1e3))
            .collect();
        let want = bits(&device_copy_cpu(&data));
        for (name, ctx) in [("full", &full), ("narrow", &narrow)] {
            let got = copy_on_device(ctx, &data).unwrap();
            assert_eq!(bits(&got), want, "{name} device, {n} entries");
        }
        let (x, y) = lancet::engine::gpu::dispatch_size(&narrow, n as u32);
        assert!(
            n <= 640 || y > 1,
            "{n} entries fold on the narrow device ({x}, {y})"
        );
    }
}

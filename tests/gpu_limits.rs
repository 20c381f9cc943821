//! Device limits are respected: a mesh whose arrays exceed what one storage binding may hold
//! on the device is refused with an error that names the buffer, the sizes and what to do,
//! never a validation panic; the same mesh fits a device with the full limits. Dispatches past
//! the workgroups a dimension allows fold into rows, and step as unfolded ones do.

mod common;

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
    assert!(model.springs.len() > 64 * 90);
    let narrow = GpuContext::with_limits(|l| l.max_compute_workgroups_per_dimension = 10).unwrap();
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
    let bits =
        |v: &[[f32; 4]]| -> Vec<[u32; 4]> { v.iter().map(|x| x.map(f32::to_bits)).collect() };
    assert_eq!(bits(&a.0), bits(&b.0));
    assert_eq!(bits(&a.1), bits(&b.1));
    assert!(a.0.iter().any(|p| p[0] != 0.0), "the nodes moved");
}

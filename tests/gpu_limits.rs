//! Device limits are respected: a mesh whose arrays exceed what one storage binding may hold
//! on the device is refused with an error that names the buffer, the sizes and what to do,
//! never a validation panic; the same mesh fits a device with the full limits.

mod common;

use lancet::engine::gpu::{GpuContext, GpuEngine};
use lancet::engine::SimConfig;
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::Material;
use lancet::{Error, ModelConfig, SpringModel};
use rstest::rstest;

#[rstest]
fn a_mesh_past_the_binding_limit_is_refused_with_a_clear_error(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    // 9,261 nodes and 59,660 springs: about 3.8 MB of slots or spring records.
    let mesh = BoxGrid::cube_cells([20; 3], 0.01).build().unwrap();
    let model = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(1e4, 0.3, 1e3)))
        .unwrap()
        .pack(&mesh)
        .unwrap();
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

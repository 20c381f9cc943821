//! The process-wide device: engines made with `GpuContext::new` share one device, a context
//! with lowered limits has its own, and a lost shared device is replaced at the next call.
//! One test in its own binary (the only test outside the area binaries), since it destroys
//! the shared device that every other GPU test of a binary uses.

mod common;

use lancet::engine::gpu::{GpuContext, GpuEngine};
use lancet::engine::{Engine, SimConfig};
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::Material;
use lancet::{ModelConfig, SpringModel};

#[test]
fn contexts_share_one_device_until_it_is_lost() {
    let Some(first) = common::gpu() else { return };
    let second = GpuContext::new().unwrap();
    assert!(first.same_device(&second), "one device per process");
    let own = GpuContext::with_limits(|_| {}).unwrap();
    assert!(
        !own.same_device(&first),
        "lowered limits get a device of their own"
    );

    // An engine on the shared device steps; then the device is lost (destroyed here, as a
    // driver reset would) and the next context is a new device that works.
    let mesh = BoxGrid::cube_cells([3; 3], 0.01).build().unwrap();
    let model = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(1e4, 0.3, 1e3)))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let config = SimConfig::new(1e-5);
    let mut engine =
        GpuEngine::with_context(second, &model, config, LayoutKind::Connectivity).unwrap();
    engine.step(3);
    assert!(!first.is_lost());
    first.device.destroy();
    let _ = first.device.poll(wgpu::PollType::wait_indefinitely());
    assert!(first.is_lost(), "the lost callback marks every clone");
    assert!(
        !own.is_lost(),
        "a device of its own is not lost with the shared one"
    );
    let third = GpuContext::new().unwrap();
    assert!(
        !third.same_device(&first),
        "a lost device is not handed out again"
    );
    assert!(!third.is_lost());
    let mut engine =
        GpuEngine::with_context(third, &model, config, LayoutKind::Connectivity).unwrap();
    engine.step(3);
    assert!(engine.positions().iter().flatten().all(|x| x.is_finite()));
}

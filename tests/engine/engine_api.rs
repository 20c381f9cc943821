//! What a caller can act on without reading messages: the device capabilities an engine has
//! (asked once, through `Engine::device`), and the typed errors of bad indices, lengths and
//! parameters, which carry the numbers a program needs.

use crate::{common, models};
use lancet::engine::fast::FastEngine;
use lancet::engine::reference::ReferenceEngine;
use lancet::engine::{Engine, EngineKind, GpuOptions, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::model::stable_time_step;
use lancet::Error;
use models::random_model;

/// The CPU engines have no device; the GPU engine has one, which waits and culls. A
/// simulation on either culls the same surface.
#[test]
fn only_the_gpu_engine_has_a_device() {
    let model = random_model(71, true);
    let config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    let mut fast = FastEngine::new(&model, config);
    let mut reference = ReferenceEngine::new(&model, config);
    assert!(fast.device().is_none() && fast.device_mut().is_none());
    assert!(reference.device().is_none() && reference.device_mut().is_none());
    let Some(ctx) = common::gpu() else { return };
    let mut gpu =
        lancet::engine::gpu::GpuEngine::with_context(ctx, &model, config, LayoutKind::Valence)
            .unwrap();
    assert_eq!(gpu.options(), GpuOptions::from(LayoutKind::Valence));
    let device = gpu.device_mut().expect("the GPU engine has a device");
    device.wait();
    // A surface of one triangle, culled against a box holding the whole model.
    device.set_surface(&[[0, 1, 2]]).unwrap();
    let everywhere = lancet::collide::broad::ToolBox {
        lo: [-1e3; 4],
        hi: [1e3; 4],
    };
    assert_eq!(device.cull_tools(&[everywhere]).unwrap(), vec![[0, 0]]);
}

/// A node past the model, a correction with fewer positions than nodes, and a time step that
/// is not positive each come back as their own variant, with the numbers in it.
#[test]
fn bad_indices_lengths_and_parameters_are_typed() {
    let model = random_model(72, true);
    let n = model.node_count();
    let dt = 0.5 * stable_time_step(&model).dt;
    for kind in [EngineKind::Reference, EngineKind::Fast] {
        let mut sim = Simulation::new(model.clone(), kind, SimConfig::new(dt)).unwrap();
        match sim.node_positions(&[0, n as u32 + 3]) {
            Err(Error::NodeOutOfRange { node, count, .. }) => {
                assert_eq!((node, count), (n as u64 + 3, n), "{kind:?}")
            }
            other => panic!("{kind:?}: {other:?}"),
        }
        match sim.correct_positions(&[0, 1], &[model.rest[0]]) {
            Err(Error::LengthMismatch {
                given, expected, ..
            }) => assert_eq!((given, expected), (1, 2), "{kind:?}"),
            other => panic!("{kind:?}: {other:?}"),
        }
    }
    match Simulation::new(model.clone(), EngineKind::Fast, SimConfig::new(-dt)) {
        Err(e @ Error::InvalidParameter { .. }) => {
            let Error::InvalidParameter { name, value, .. } = &e else {
                unreachable!()
            };
            assert_eq!((name.as_str(), *value), ("time step", -dt));
            assert!(e.to_string().contains("time step"), "{e}");
        }
        other => panic!("{:?}", other.err()),
    }
}

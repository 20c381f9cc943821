//! A 1 kHz haptic loop on one thread while the simulation steps at its own rate on another.
//!
//! The haptic thread stands in for a device driver: every millisecond it reads the device's
//! pose (here a scripted hand pressing a probe 2 mm into a block and holding it), hands it to
//! the simulation, and renders the virtual coupling's force from the latest proxy the
//! simulation published: `F = k (x_proxy - x_device) + b (v_proxy - v_device)`, so the force it
//! sends changes smoothly at 1 kHz however fast the simulation runs and whatever the contact
//! does at a step. The simulation thread takes the latest device pose, steps the world and
//! publishes the proxy. The two share one small mutex-guarded handoff, held only to copy.
//!
//! `cargo run --release --example haptic_loop`

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use lancet::collide::ToolShape;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{FixedSelector, Material};
use lancet::world::{ProxyState, VirtualCoupling, WorldBuilder};
use lancet::{EngineKind, Integrator, ModelConfig, SimConfig};
use nalgebra::{Isometry3, Vector3};

/// What the two threads hand each other: the latest of each, nothing queued.
struct Handoff {
    device: Isometry3<f64>,
    device_velocity: Vector3<f64>,
    proxy: ProxyState,
    steps: u64,
}

const COUPLING: VirtualCoupling = VirtualCoupling {
    stiffness: 200.0,
    damping: 4.0,
    proxy_mass: 0.02,
};

/// The scripted hand: from 3 mm above the block's top (2 cm) to 2 mm into it over 0.3 s,
/// starting and stopping smoothly, then held; position and velocity at time `t`.
fn hand(t: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (start, depth, time) = (0.02 + 0.005 + 0.003, 0.005, 0.3);
    let u = (t / time).clamp(0.0, 1.0);
    let travel = depth * u * u * (3.0 - 2.0 * u);
    let v = -depth * 6.0 * u * (1.0 - u) / time;
    (
        Vector3::new(0.02, 0.02, start - travel),
        Vector3::new(0.0, 0.0, v),
    )
}

/// The world: a 4 x 4 x 2 cm block on a fixed base, and the probe coupled to the device.
fn world(
    start: Isometry3<f64>,
) -> lancet::Result<(lancet::world::World, lancet::world::ToolHandle)> {
    let mesh = BoxGrid {
        cells: [4, 4, 2],
        size: [0.04, 0.04, 0.02],
        origin: [0.0; 3],
        split: Default::default(),
    }
    .build()?;
    let mut model = ModelConfig::new(Material::elastic(2e4, 0.3, 1000.0));
    model.mass_damping = 20.0;
    model.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    }];
    // Backward Euler at 1 ms: the simulation's own step, stable at any stiffness.
    let config = SimConfig {
        integrator: Integrator::BackwardEuler,
        ..SimConfig::new(1e-3)
    };
    let mut world = WorldBuilder::new(mesh, &model, config)?
        .engine(EngineKind::Fast)
        .build()?;
    let probe = world.add_tool("probe", ToolShape::Sphere { radius: 0.005 }, start)?;
    world.couple(probe, COUPLING)?;
    Ok((world, probe))
}

fn main() -> lancet::Result<()> {
    let (x0, _) = hand(0.0);
    let start = Isometry3::translation(x0.x, x0.y, x0.z);
    let shared = Arc::new(Mutex::new(Handoff {
        device: start,
        device_velocity: Vector3::zeros(),
        proxy: ProxyState::at_rest(x0),
        steps: 0,
    }));
    let stop = Arc::new(AtomicBool::new(false));

    // The simulation thread, which owns the world: as fast as it goes, no faster than real
    // time.
    let sim = {
        let (shared, stop) = (shared.clone(), stop.clone());
        thread::spawn(move || -> lancet::Result<u64> {
            let (mut world, probe) = world(start)?;
            let began = Instant::now();
            while !stop.load(Ordering::Relaxed) {
                let ahead = world.sim().time() - began.elapsed().as_secs_f64();
                if ahead > 0.0 {
                    thread::sleep(Duration::from_secs_f64(ahead));
                }
                let (device, velocity) = {
                    let h = shared.lock().expect("no thread panicked");
                    (h.device, h.device_velocity)
                };
                world.set_device_pose(probe, device, velocity)?;
                let report = world.step()?;
                let mut h = shared.lock().expect("no thread panicked");
                h.proxy = report.tools[probe.index()].proxy.expect("coupled");
                h.steps = report.step;
            }
            Ok(world.sim().steps())
        })
    };

    // The haptic thread (this one): 1 kHz for 0.6 s.
    let period = Duration::from_millis(1);
    let began = Instant::now();
    let (mut ticks, mut last, mut largest_change) = (0u32, Vector3::zeros(), 0.0f64);
    let mut force = Vector3::zeros();
    while ticks < 600 {
        let t = began.elapsed().as_secs_f64();
        let (x, v) = hand(t);
        let device = Isometry3::translation(x.x, x.y, x.z);
        let proxy = {
            let mut h = shared.lock().expect("no thread panicked");
            h.device = device;
            h.device_velocity = v;
            h.proxy
        };
        // The force sent to the device at this tick.
        force = COUPLING.force(&proxy, &device, &v);
        if ticks > 0 {
            largest_change = largest_change.max((force - last).norm());
        }
        last = force;
        ticks += 1;
        let next = period * ticks;
        if let Some(wait) = next.checked_sub(began.elapsed()) {
            thread::sleep(wait);
        }
    }
    stop.store(true, Ordering::Relaxed);
    let steps = sim.join().expect("the simulation thread ran")?;
    println!(
        "{ticks} haptic ticks in {:.3} s, {steps} simulation steps; force now {:.4} N \
         (z {:.4} N), largest change between ticks {:.4} N",
        began.elapsed().as_secs_f64(),
        force.norm(),
        force.z,
        largest_change
    );
    Ok(())
}

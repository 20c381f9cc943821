//! A probe driven at 1 kHz into a tissue block through a virtual coupling: the force sent to
//! the device changes from step to step by no more than the coupling allows (at first contact,
//! in a steady press and in a drag), and in a steady press it converges to the tissue's
//! reaction, measured independently as the force the block's fixed base holds it with.
//!
//! The block: 4 x 4 x 2 cm, 20 kPa, 1000 kg/m^3, its base (z = 0) fixed, no gravity, stepped by
//! backward Euler at h = 1 ms (the haptic rate) on the float64 reference engine. The probe: a
//! 5 mm sphere, coupled by k = 200 N/m, b = 4 N s/m (about critical for the proxy's 20 g).

use lancet::collide::ToolShape;
use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::model::{FixedSelector, Material};
use lancet::world::{StepReport, ToolHandle, VirtualCoupling, World, WorldBuilder};
use lancet::{EngineKind, Integrator, ModelConfig, SimConfig};
use nalgebra::{Isometry3, Vector3};

const H: f64 = 1e-3;
const TOP: f64 = 0.02;
const RADIUS: f64 = 0.005;
/// Device speed pressing in, m/s.
const PRESS_SPEED: f64 = 0.2;
/// Device speed dragging sideways, m/s.
const DRAG_SPEED: f64 = 0.02;
/// How far below the undeformed top the device's sphere bottom goes, m.
const INDENT: f64 = 0.002;

pub const COUPLING: VirtualCoupling = VirtualCoupling {
    stiffness: 200.0,
    damping: 4.0,
    proxy_mass: 0.02,
};

fn block() -> WorldBuilder {
    let mesh = BoxGrid {
        cells: [4, 4, 2],
        size: [0.04, 0.04, TOP],
        origin: [0.0; 3],
        split: TetSplit::Six,
    }
    .build()
    .unwrap();
    let mut model = ModelConfig::new(Material::elastic(2e4, 0.3, 1000.0));
    model.mass_damping = 20.0;
    model.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    }];
    let config = SimConfig {
        integrator: Integrator::BackwardEuler,
        ..SimConfig::new(H)
    };
    WorldBuilder::new(mesh, &model, config)
        .unwrap()
        .engine(EngineKind::Reference)
}

/// The device's pose and velocity at step `n` (the pose for the end of the step): down at
/// `PRESS_SPEED` from 3 mm above the block until the sphere's bottom is `INDENT` below the top,
/// held for 1.5 s, then dragged along x at `DRAG_SPEED` for 0.3 s.
pub fn device(n: u64) -> (Vector3<f64>, Vector3<f64>) {
    let start = TOP + RADIUS + 0.003;
    let end = TOP + RADIUS - INDENT;
    let press = ((start - end) / (PRESS_SPEED * H)).round() as u64;
    let hold = press + 1500;
    let drag = hold + 300;
    let c = 0.02;
    if n <= press {
        let z = start - PRESS_SPEED * H * n as f64;
        (Vector3::new(c, c, z), Vector3::new(0.0, 0.0, -PRESS_SPEED))
    } else if n <= hold {
        (Vector3::new(c, c, end), Vector3::zeros())
    } else {
        let x = c + DRAG_SPEED * H * (n.min(drag) - hold) as f64;
        let v = if n <= drag { DRAG_SPEED } else { 0.0 };
        (Vector3::new(x, c, end), Vector3::new(v, 0.0, 0.0))
    }
}

pub fn sphere(world: &mut World) -> ToolHandle {
    let (x, _) = device(0);
    world
        .add_tool(
            "probe",
            ToolShape::Sphere { radius: RADIUS },
            Isometry3::translation(x.x, x.y, x.z),
        )
        .unwrap()
}

/// The load the block puts on its fixed base, N: the springs' force on the fixed nodes. The
/// block's internal forces sum to zero, so at rest with no gravity the base holds the block
/// against whatever else pushes it (here the probe): this is the probe's push, measured at
/// the other end of the block, by the elastic forces alone.
fn base_load(world: &World) -> Vector3<f64> {
    let model = world.model();
    let x = world.positions();
    let mut f = Vector3::zeros();
    for s in model.springs() {
        let [a, b] = s.nodes.map(|n| n as usize);
        let d = Vector3::from(x[b]) - Vector3::from(x[a]);
        let l = d.norm();
        // The spring's force on a; its opposite on b.
        let on_a = s.stiffness * (l - s.rest_length) * d / l;
        if model.fixed[a] {
            f += on_a;
        }
        if model.fixed[b] {
            f -= on_a;
        }
    }
    f
}

/// One step's device state and report.
struct Sample {
    device: (Vector3<f64>, Vector3<f64>),
    report: StepReport,
}

/// Steps `steps` of the device's path, the probe coupled (`true`) or posed straight at the
/// device (`false`, as before the coupling).
fn drive(
    world: &mut World,
    probe: ToolHandle,
    coupled: bool,
    steps: std::ops::RangeInclusive<u64>,
) -> Vec<Sample> {
    steps
        .map(|n| {
            let (x, v) = device(n);
            let pose = Isometry3::translation(x.x, x.y, x.z);
            if coupled {
                world.set_device_pose(probe, pose, v).unwrap();
            } else {
                world.set_tool_pose(probe, pose).unwrap();
            }
            Sample {
                device: (x, v),
                report: world.step().unwrap(),
            }
        })
        .collect()
}

fn press_steps() -> u64 {
    ((0.003 + INDENT) / (PRESS_SPEED * H)).round() as u64
}

/// The step at which the probe first touches, and the largest step-to-step change of `force`
/// from then until the device stops pressing (its own stop changes the damping force by
/// `b dv`, which the coupling allows but is no contact).
fn first_contact_jump(trace: &[Sample], force: impl Fn(&Sample) -> Vector3<f64>) -> (usize, f64) {
    let first = trace
        .iter()
        .position(|s| s.report.contacts > 0)
        .expect("the probe touches the block");
    let jump = (first.max(1)..press_steps() as usize)
        .map(|n| (force(&trace[n]) - force(&trace[n - 1])).norm())
        .fold(0.0, f64::max);
    (first, jump)
}

#[test]
fn rendered_force_increments_stay_within_the_coupling_and_converge_to_the_tissue_reaction() {
    let hold_end = press_steps() + 1500;
    let mut world = block().build().unwrap();
    let probe = sphere(&mut world);
    world.couple(probe, COUPLING).unwrap();
    let mut trace = drive(&mut world, probe, true, 1..=hold_end);

    // Steady press: the proxy is at rest against the tissue, the spring balances the contact,
    // and the force on the device is the tissue's reaction: the load the probe puts through
    // the block onto its base, measured from the springs alone. (Backward Euler's step is a
    // little softer than the springs' static response, which the position correction then
    // measures: 2% here.)
    let held = trace.last().unwrap().report.tools[0].clone();
    let (rendered, proxy) = (held.rendered.unwrap(), held.proxy.unwrap());
    let load = base_load(&world);
    assert!(proxy.velocity.norm() < 1e-6, "{proxy:?}");
    // Equal to the implicit solve's tolerance (1e-5 of the residual): the warm-started CG
    // stops at a slightly different state from step to step.
    assert!(
        (rendered - held.force).norm() < 1e-5 * held.force.norm(),
        "{rendered:?} {:?}",
        held.force
    );
    assert!(
        load.z < -0.05,
        "the probe does not press the block: {load:?}"
    );
    assert!(
        (rendered + load).norm() < 0.05 * load.norm(),
        "rendered {rendered:?} against the base's load {load:?}"
    );

    trace.extend(drive(
        &mut world,
        probe,
        true,
        hold_end + 1..=hold_end + 300,
    ));
    // Every step, first contact, press and drag alike: the force changes by no more than
    // the coupling allows for how far and how fast the device and the proxy moved, and the
    // proxy moves continuously (no faster than half as fast again as the device's top speed):
    // the contact never throws it.
    let top = PRESS_SPEED.max(DRAG_SPEED);
    for n in 1..trace.len() {
        let (r0, r1) = (&trace[n - 1].report.tools[0], &trace[n].report.tools[0]);
        let (p0, p1) = (r0.proxy.unwrap(), r1.proxy.unwrap());
        let (d0, d1) = (trace[n - 1].device, trace[n].device);
        let moved = (p1.position - p0.position).norm();
        let bound = COUPLING.increment_bound(
            (d1.0 - d0.0).norm(),
            (d1.1 - d0.1).norm(),
            moved,
            (p1.velocity - p0.velocity).norm(),
        );
        let df = (r1.rendered.unwrap() - r0.rendered.unwrap()).norm();
        assert!(
            df <= bound * (1.0 + 1e-9) + 1e-12,
            "step {n}: |dF| {df:e} > {bound:e}"
        );
        assert!(
            moved <= 1.5 * top * H,
            "step {n}: the proxy jumped {moved:e} m"
        );
    }

    // At first contact the coupled force rises smoothly; the raw position-correction force of
    // a probe posed straight at the device along the same path jumps (what a device was sent
    // before the coupling).
    let (_, coupled) = first_contact_jump(&trace, |s| s.report.tools[0].rendered.unwrap());
    let mut world = block().build().unwrap();
    let probe = sphere(&mut world);
    let raw = drive(&mut world, probe, false, 1..=press_steps() + 50);
    let (_, jump) = first_contact_jump(&raw, |s| s.report.tools[0].force);
    assert!(
        coupled < jump / 3.0,
        "coupled {coupled:e} N a step against {jump:e} N raw"
    );
}

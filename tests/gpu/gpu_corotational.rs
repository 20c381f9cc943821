//! The corotational force model on the GPU: one per-tet pass (rotation by a warm-started
//! float32 polar decomposition, corner forces into per-tet records) and a per-node gather,
//! whatever the layout. The passes equal their CPU twin (`twin::corotational`) to float32
//! rounding on a jittered box (flat tets included) with a random state, rotations included
//! (not bit for bit: on lavapipe the rotation's iteration, once its update is rounding noise,
//! rounds its last bits differently from the twin, for a reason not found yet; every tet whose
//! iteration stops early agrees bit for bit); the
//! engine follows the float64 reference; a rigid rotation of 90 degrees stores no force where
//! the linear model's ghost force is large; an inverted tet is pushed back, finitely; a cut
//! engine equals a rebuilt one.

use crate::{common, models};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, EngineKind, ForceModelKind, Integrator, SimConfig, Simulation};
use lancet::layout::tet_table::{TetTable, IDENTITY};
use lancet::layout::{LayoutKind, PackedLayout};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{Material, ModelConfig, PackedModel, SpringModel};
use models::{random_box, Rng};
use rstest::rstest;

/// [`random_box`] with every free node's rest position moved by up to `jitter` of a cell, and
/// two nodes pulled towards a neighbour so that a few tets are slivers (a tenth of a cell's
/// height or less).
pub(crate) fn jittered_box(seed: u64, damped: bool, jitter: f64) -> PackedModel {
    let mut model = random_box(seed, damped);
    let mut rng = Rng(seed ^ 0x5151);
    for (r, fixed) in model.rest.iter_mut().zip(&model.fixed) {
        if !fixed {
            for c in r.iter_mut() {
                *c += (rng.next() - 0.5) * 2.0 * jitter * 0.01;
            }
        }
    }
    model
}

pub(crate) fn config(model: &PackedModel, integrator: Integrator, fraction: f64) -> SimConfig {
    let kind = ForceModelKind::Corotational;
    SimConfig {
        integrator,
        force_model: kind,
        ..SimConfig::new(fraction * kind.stable_time_step(model).unwrap().dt)
    }
}

/// Random displacements of `scale` (m) on top of a rotation of `angle` (rad) about z through
/// the box's base corner, and random velocities.
pub(crate) fn random_state(
    model: &PackedModel,
    seed: u64,
    scale: f64,
    angle: f64,
) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = Rng(seed);
    let mut v = |s: f64| [0, 1, 2].map(|_| (rng.next() - 0.5) * s);
    let (c, s) = (angle.cos(), angle.sin());
    let x = model
        .rest
        .iter()
        .map(|r| {
            let d = v(scale);
            [
                c * r[0] - s * r[1] + d[0],
                s * r[0] + c * r[1] + d[1],
                r[2] + d[2],
            ]
        })
        .collect();
    let vel = model.rest.iter().map(|_| v(0.05)).collect();
    (x, vel)
}

pub(crate) fn inv_mass(layout: &PackedLayout) -> Vec<f32> {
    match layout {
        PackedLayout::Connectivity(c) => c.nodes.inv_mass.clone(),
        PackedLayout::Valence(v) => v.nodes.inv_mass.clone(),
        PackedLayout::Edges(e) => e.nodes.inv_mass.clone(),
    }
}

/// The per-tet pass and the node gather equal their CPU twin within float32 rounding (1e-5 of
/// the twin's motion per step, the bar `common::assert_twin` holds devices that round unlike
/// the CPU to), after 1 and after 20 steps, state and rotations: damped under
/// Verlet (velocity gradients read) and undamped under symplectic Euler, from a state turned
/// by 0.5 rad (the rotation iterates from a cold start) with large random displacements (some
/// tets inverted), on a box jittered by up to 25% of a cell (flat tets among them).
#[rstest]
fn corotational_passes_equal_their_cpu_twin(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values((Integrator::Verlet, true), (Integrator::SymplecticEuler, false))] scheme: (
        Integrator,
        bool,
    ),
) {
    let Some(ctx) = common::gpu() else { return };
    let (integrator, damped) = scheme;
    let model = jittered_box(7, damped, 0.25);
    let mut gpu =
        GpuEngine::with_context(ctx, &model, config(&model, integrator, 0.5), kind).unwrap();
    let (x, v) = random_state(&model, 11, 6e-3, 0.5);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let corot = gpu.corotational().expect("a corotational engine");
    assert_eq!(corot.damped(), damped);
    let table: TetTable = corot.table().clone();
    assert_eq!(table.len(), model.tets.len());
    let layout = gpu.layout().clone();
    let masses = inv_mass(&layout);
    let p = gpu.step_params();
    assert_eq!(p.damped, damped);
    let mut rotations = vec![IDENTITY; table.len()];
    let mut twin = start.clone();
    for steps in [1usize, 19] {
        twin = lancet::twin::steps(&p, twin, steps, |p, u, s| {
            table.step_cpu(p, &masses, u, s, &mut rotations)
        });
        gpu.step(steps as u32);
        let got = gpu.raw_state().unwrap();
        let what = format!("{kind:?} {integrator:?} damped={damped} after {steps}");
        // Within float32 rounding of the twin's motion per step (the rotation's iteration
        // rounds its last bits differently on lavapipe; see the module documentation).
        for (got, want, start) in [(&got.0, &twin.0, &start.0), (&got.1, &twin.1, &start.1)] {
            let d = common::relative_difference(got, want, start);
            assert!(
                d <= 1e-5 * steps as f64,
                "{what}: device and twin differ by {d:e}"
            );
        }
        let device = gpu.tet_rotations().unwrap();
        let off = device
            .iter()
            .zip(&rotations)
            .flat_map(|(a, b)| (0..4).map(move |c| (a[c] - b[c]).abs()))
            .fold(0.0f32, f32::max);
        assert!(off < 1e-5, "{what}: rotations differ by {off:e}");
    }
    // Rotations turned about z by about the state's 0.5 rad (q.z = sin 0.25 = 0.247) away from
    // the fixed base, and the state moved.
    let turned = rotations.iter().filter(|q| q[2].abs() > 0.2).count();
    assert!(
        turned > rotations.len() / 5,
        "{turned} of {}",
        rotations.len()
    );
    assert!(twin.0 != start.0);
}

/// The GPU engine in every layout follows the float64 reference engine's corotational run
/// (200 steps at 0.8 of the bound, damped, under gravity, from a random state turned by 0.3
/// rad) within float32 rounding, the bar the tensor-mass passes hold; the linear (tensor-mass)
/// model, stepped the same, is far off: the rotation is what is stepped.
#[rstest]
fn gpu_corotational_follows_the_float64_reference(
    #[values(LayoutKind::Connectivity, LayoutKind::Edges)] layout: LayoutKind,
) {
    let Some(_) = common::gpu() else { return };
    let model = jittered_box(3, true, 0.08);
    let config = config(&model, Integrator::Verlet, 0.8);
    let (x, v) = random_state(&model, 5, 1e-3, 0.3);
    let (err, apart) = crate::fem_gpu_checks::against_the_reference(
        &model,
        config,
        (&x, &v),
        layout,
        200,
        ForceModelKind::TensorMass,
    );
    assert!(err < 1e-3, "{layout:?}: relative L2 error {err:e}");
    assert!(
        apart > 100.0 * err.max(1e-6),
        "linear {apart:e}, gpu {err:e}"
    );
}

/// A free box (no fixed node, no gravity, no damping) turned rigidly by 90 degrees about an
/// oblique axis and left at rest: one symplectic Euler step on the GPU gives every node a
/// velocity `h f / m` of float32 rounding only, where the linear model's ghost force of the
/// same state is large; the tets' rotations are the box's (a cold start converges within the
/// step). Connectivity layout (the element path is the same in every layout).
#[test]
fn a_rigid_rotation_of_ninety_degrees_stores_no_force_on_the_gpu() {
    let Some(ctx) = common::gpu() else { return };
    let mesh = BoxGrid::cube_cells([3, 2, 2], 0.01).build().unwrap();
    let mut mc = ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0));
    mc.gravity = [0.0; 3];
    mc.mass_damping = 0.0;
    let model = SpringModel::build(&mesh, &mc).unwrap().pack(&mesh).unwrap();
    // 90 degrees about the unit axis n: R = n n^T + [n]_x (cos = 0, sin = 1).
    let n = [1.0f64 / 3.0f64.sqrt(); 3];
    let r = [0, 1, 2].map(|i| {
        [0, 1, 2].map(|j| {
            let cross = match (i, j) {
                (0, 1) => -n[2],
                (0, 2) => n[1],
                (1, 0) => n[2],
                (1, 2) => -n[0],
                (2, 0) => -n[1],
                (2, 1) => n[0],
                _ => 0.0,
            };
            n[i] * n[j] + cross
        })
    });
    let x: Vec<[f64; 3]> = model
        .rest
        .iter()
        .map(|p| [0, 1, 2].map(|i| (0..3).map(|j| r[i][j] * p[j]).sum()))
        .collect();
    let still = vec![[0.0; 3]; x.len()];
    let speed = |force_model: ForceModelKind| {
        let config = SimConfig {
            integrator: Integrator::SymplecticEuler,
            force_model,
            ..SimConfig::new(0.5 * force_model.stable_time_step(&model).unwrap().dt)
        };
        let mut gpu =
            GpuEngine::with_context(ctx.clone(), &model, config, LayoutKind::Connectivity).unwrap();
        gpu.set_state(&x, &still);
        gpu.step(1);
        let fastest = gpu
            .velocities()
            .iter()
            .flat_map(|v| v.map(f64::abs))
            .fold(0.0, f64::max);
        (fastest, gpu.tet_rotations().unwrap())
    };
    let (corotational, rotations) = speed(ForceModelKind::Corotational);
    let (linear, _) = speed(ForceModelKind::TensorMass);
    assert!(
        linear > 1e-3,
        "the linear model's ghost force moves the box ({linear:e} m/s)"
    );
    assert!(
        corotational < 1e-5 * linear,
        "corotational {corotational:e} m/s against the linear model's {linear:e} m/s"
    );
    // Every rotation is the box's: q = (n sin 45, cos 45) (or its negative).
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let want = [n[0] * h, n[1] * h, n[2] * h, h];
    for q in &rotations {
        let sign = if q[3] < 0.0 { -1.0 } else { 1.0 };
        let off = (0..4)
            .map(|c| (sign * q[c] as f64 - want[c]).abs())
            .fold(0.0, f64::max);
        assert!(off < 1e-5, "rotation {q:?}, want {want:?}");
    }
}

/// A tet turned inside out (one free corner pushed through the opposite face, 30% of the
/// corner's height beyond it) gets a finite force on that corner that points back through the
/// face; the float64 reference computes the same force to float32 rounding.
#[test]
fn an_inverted_tet_gets_a_finite_restoring_force_on_the_gpu() {
    let Some(ctx) = common::gpu() else { return };
    let mut model = random_box(9, false);
    model.gravity = [0.0; 3];
    model.mass_damping = 0.0;
    // A tet with a free corner: push that corner through the plane of the other three.
    let (tet, corner) = model
        .tets
        .iter()
        .enumerate()
        .find_map(|(t, tet)| {
            (0..4)
                .find(|&a| !model.fixed[tet.nodes[a] as usize])
                .map(|a| (t, a))
        })
        .expect("a tet with a free corner");
    let nodes = model.tets[tet].nodes;
    let i = nodes[corner] as usize;
    let others: Vec<[f64; 3]> = (0..4)
        .filter(|&a| a != corner)
        .map(|a| model.rest[nodes[a] as usize])
        .collect();
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let (e1, e2) = (sub(others[1], others[0]), sub(others[2], others[0]));
    let normal = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let len = normal.iter().map(|c| c * c).sum::<f64>().sqrt();
    let normal = normal.map(|c| c / len);
    let rest = model.rest[i];
    let height: f64 = (0..3).map(|c| (rest[c] - others[0][c]) * normal[c]).sum();
    let mut x = model.rest.clone();
    x[i] = [0, 1, 2].map(|c| rest[c] - 1.3 * height * normal[c]);
    let still = vec![[0.0; 3]; x.len()];
    let config = SimConfig {
        integrator: Integrator::SymplecticEuler,
        ..config(&model, Integrator::SymplecticEuler, 0.5)
    };
    let mut gpu = GpuEngine::with_context(ctx, &model, config, LayoutKind::Valence).unwrap();
    gpu.set_state(&x, &still);
    gpu.step(1);
    let v = gpu.velocities();
    assert!(v.iter().flatten().all(|c| c.is_finite()));
    // Back through the face: towards the side the corner rests on.
    let back: f64 = (0..3).map(|c| v[i][c] * normal[c] * height.signum()).sum();
    assert!(back > 0.0, "velocity {:?} of the pushed corner", v[i]);
    let mut reference = Simulation::new(model.clone(), EngineKind::Reference, config).unwrap();
    reference.set_state(&x, &still).unwrap();
    reference.run(1).unwrap();
    let want = reference.velocities();
    let scale = want.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
    let worst = v
        .iter()
        .zip(&want)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-4 * scale,
        "GPU and reference differ by {worst:e} of {scale:e}"
    );
}

/// Cuts through a corotational model on the GPU: after every cut the engine's float64
/// elements equal a rebuild from the cut mesh and its tet table (host and device) a fresh one
/// in the patched layout's node order (the world's checks, through
/// `Engine::differences_from_rebuild`); the cut engine then steps as a GPU engine built afresh
/// from the cut model does, to float32 rounding (the rotations it kept against a rebuild's
/// cold start).
#[rstest]
#[case(LayoutKind::Connectivity, lancet::cut::CutMethod::Separate)]
#[case(LayoutKind::Valence, lancet::cut::CutMethod::Separate)]
#[case(LayoutKind::Edges, lancet::cut::CutMethod::Subdivide)]
fn a_cut_gpu_corotational_model_equals_a_rebuilt_one(
    #[case] layout: LayoutKind,
    #[case] method: lancet::cut::CutMethod,
) {
    crate::fem_gpu_checks::cut_model_equals_a_rebuilt_one(
        ForceModelKind::Corotational,
        layout,
        method,
        Integrator::Verlet,
    );
}

/// A cut patches the corotational tet table where it changed: one tet re-cornered onto a copy
/// of its first corner (what separating does to a tet: removed, the last tet moved into its
/// place, a new one appended) uploads the same few hundred bytes on a box of 2 x 2 x 2 cells
/// and on one of 8 x 8 x 8 (48 and 3,072 tets), nothing read back, far below the large
/// table's size; the patched table, host and device, equals a rebuild's, and the rotations the
/// device kept went with their tets (the engine steps as before the patch wherever the cut
/// did not reach).
#[test]
fn a_cut_uploads_the_tets_it_changed_not_the_table() {
    let Some(ctx) = common::gpu() else { return };
    let mut uploads = Vec::new();
    for cells in [2, 8] {
        let mesh = BoxGrid::cube_cells([cells; 3], 0.01).build().unwrap();
        let config = ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0));
        let mut model = SpringModel::build(&mesh, &config)
            .unwrap()
            .pack(&mesh)
            .unwrap();
        let kind = ForceModelKind::Corotational;
        let sim = SimConfig {
            force_model: kind,
            ..SimConfig::new(0.5 * kind.stable_time_step(&model).unwrap().dt)
        };
        let mut engine =
            GpuEngine::with_context(ctx.clone(), &model, sim, LayoutKind::Connectivity).unwrap();
        // A turned state, so that the rotations kept are not the identity.
        let x: Vec<[f64; 3]> = model
            .rest
            .iter()
            .map(|p| [p[0] - 0.3 * p[1], p[1] + 0.3 * p[0], p[2]])
            .collect();
        engine.set_state(&x, &vec![[0.0; 3]; x.len()]);
        engine.step(3);
        let diff = crate::fem_cut::recorner_first_tet(&model);
        let before = engine.corotational().unwrap().rotations(&ctx).unwrap();
        model.apply(&diff).unwrap();
        engine.patch(&model, &diff).unwrap();
        let corot = engine.corotational().unwrap();
        let (bytes, rebuilt) = corot.last_patch();
        assert!(!rebuilt, "{cells} cells: the table was rebuilt");
        let table_bytes = corot.table().bytes();
        // The last tet took tet 0's place with its rotation; the new tet starts from the
        // identity; every other rotation stayed.
        let after = corot.rotations(&ctx).unwrap();
        let last = before.len() - 1;
        assert_eq!(after.len(), before.len());
        assert_eq!(after[0], before[last]);
        assert_eq!(after[last], IDENTITY);
        assert_eq!(after[1..last], before[1..last]);
        assert_ne!(before[last], IDENTITY, "the rotations kept are not trivial");
        assert_eq!(
            engine.differences_from_rebuild(&model).unwrap(),
            Vec::<String>::new()
        );
        eprintln!("{cells} cells: {bytes} bytes uploaded of a {table_bytes}-byte table");
        uploads.push((bytes, table_bytes));
    }
    let ((small, _), (large, large_table)) = (uploads[0], uploads[1]);
    assert!(large <= small + small / 2, "{small} bytes, then {large}");
    assert!(large * 50 < large_table, "{large} of {large_table} bytes");
}

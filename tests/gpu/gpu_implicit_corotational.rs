//! Backward Euler with the corotational force model on the GPU layouts: each step the tet pass
//! (rotations, corner forces), the block pass (`R K R^T` per slot, `shaders/corotational_blocks.wgsl`)
//! and the tensor-mass solve on those blocks with the corner forces as its force. The block
//! pass equals its twin given the device's rotations; under a rigid rotation its blocks are
//! the float64 tensor-mass assembly turned by the rotation; the step equals its twin to
//! float32 rounding, follows the float64 reference engine's backward Euler step where the
//! linear model does not, and goes on through cuts as an engine built afresh.

use crate::common;
use crate::gpu_corotational::{config, inv_mass, jittered_box, random_state};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, ForceModelKind, Integrator, SimConfig};
use lancet::layout::tensor_blocks::TensorBlocks;
use lancet::layout::tet_table::IDENTITY;
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{Material, ModelConfig, SpringModel};
use lancet::physics::{ElementForces, StepParams};
use lancet::twin::corotational_implicit as twin;
use rstest::rstest;

/// The largest entry of a set of block rows.
fn largest(rows: &[[f32; 4]]) -> f64 {
    rows.iter()
        .flat_map(|r| r.map(|x| f64::from(x).abs()))
        .fold(0.0, f64::max)
}

/// The largest difference between two sets of block rows.
fn apart(a: &[[f32; 4]], b: &[[f32; 4]]) -> f64 {
    assert_eq!(a.len(), b.len(), "as many rows");
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..4).map(move |c| (f64::from(x[c]) - f64::from(y[c])).abs()))
        .fold(0.0, f64::max)
}

/// The pair lists name, for every slot in use, the tets holding its two nodes with the
/// corners they are: 12 pairs per tet on the node-centric layouts (each of a tet's 6 edges
/// seen from both ends), 6 on the edge layout (one record per edge), none missing.
#[test]
fn each_slot_lists_the_tets_of_its_pair_of_nodes() {
    use lancet::layout::tensor_blocks::slot_walk;
    use lancet::layout::tet_pairs::TetPairs;
    use lancet::layout::tet_table::TetTable;
    use lancet::layout::{NodeOrder, PackedLayout};
    let model = jittered_box(2, false, 0.25);
    let Some(ElementForces::Corotational(c)) =
        ElementForces::new(ForceModelKind::Corotational, &model).unwrap()
    else {
        panic!("a corotational model")
    };
    for kind in [
        LayoutKind::Connectivity,
        LayoutKind::Valence,
        LayoutKind::Edges,
    ] {
        let order = NodeOrder::identity(model.rest.len());
        let layout = PackedLayout::pack(&model, kind, order).unwrap();
        let table = TetTable::new(c.elements(), &layout.order().rank, layout.node_slots());
        let pairs = TetPairs::new(&table, &layout);
        let per_tet = if kind == LayoutKind::Edges { 6 } else { 12 };
        assert_eq!(pairs.pairs.len(), per_tet * table.len(), "{kind:?}");
        for (i, slot, j) in slot_walk(&layout) {
            let [s, e] = pairs.rows[slot];
            assert!(e > s, "{kind:?}: slot {slot} lists no tet");
            for &p in &pairs.pairs[s as usize..e as usize] {
                let (t, a, b) = ((p / 16) as usize, (p / 4 % 4) as usize, (p % 4) as usize);
                assert_eq!(
                    (table.corners[t][a], table.corners[t][b]),
                    (i, j),
                    "{kind:?}"
                );
            }
        }
    }
}

/// After one backward Euler step in each layout, the blocks the device solved with equal the
/// twin's block pass on the device's own rotations, bit for bit where the device rounds as
/// the CPU (within 1e-6 of the largest entry elsewhere), damped (the `C` blocks too) and
/// undamped, on a box jittered by a quarter of a cell (slivers among its tets) turned by 0.5
/// rad with large random displacements. The rotations matter: the same pass with every
/// rotation the identity gives blocks far from these.
#[rstest]
fn the_corotational_block_pass_equals_its_twin(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values(true, false)] damped: bool,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = jittered_box(7, damped, 0.25);
    let config = config(&model, Integrator::BackwardEuler, 10.0);
    let mut gpu = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
    let (x, v) = random_state(&model, 11, 6e-3, 0.5);
    gpu.set_state(&x, &v);
    gpu.step(1);
    let what = format!("{kind:?} damped={damped}");
    let device = gpu.corotational_block_values().unwrap().expect("blocks");
    assert_eq!(device.damped, damped, "{what}");
    let table = gpu.corotational().unwrap().table().clone();
    let pairs = gpu.corotational_blocks().unwrap().pairs().clone();
    let rotations = gpu.tet_rotations().unwrap();
    let want = twin::blocks_cpu(&table, &pairs, &rotations, damped);
    let scale = largest(&want.rows);
    let off = apart(&device.rows, &want.rows);
    if common::rounds_like_cpu() {
        assert_eq!(off, 0.0, "{what}: device and twin blocks differ");
    } else {
        assert!(off <= 1e-6 * scale, "{what}: {off:e} of {scale:e}");
    }
    let unturned = twin::blocks_cpu(&table, &pairs, &vec![IDENTITY; table.len()], damped);
    assert!(
        apart(&unturned.rows, &want.rows) > 0.1 * scale,
        "{what}: the rotations change the blocks"
    );
}

/// A free box turned rigidly by 0.8 rad about an oblique axis: every tet's rotation is the
/// box's `R`, so each slot's block is `R K_ij R^T` of the linear model's `K_ij`, assembled in
/// float64 by `physics::TensorMass` (another path: per-tet 12x12 stiffness matrices), within
/// float32 rounding (1e-5 of the largest entry), in every layout; `K_ij` itself is far off.
#[test]
fn under_a_rigid_rotation_the_blocks_are_the_linear_blocks_turned() {
    let Some(ctx) = common::gpu() else { return };
    let mesh = BoxGrid::cube_cells([3, 2, 2], 0.01).build().unwrap();
    let mut mc = ModelConfig::new(Material::elastic(1e4, 0.3, 1000.0));
    mc.gravity = [0.0; 3];
    let model = SpringModel::build(&mesh, &mc).unwrap().pack(&mesh).unwrap();
    // Rodrigues: R = cos I + sin [n]_x + (1 - cos) n n^T.
    let n = [
        1.0f64 / 14f64.sqrt(),
        2.0 / 14f64.sqrt(),
        3.0 / 14f64.sqrt(),
    ];
    let (c, s) = (0.8f64.cos(), 0.8f64.sin());
    let cross = [[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]];
    let r: [[f64; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            f64::from(u8::from(i == j)) * c + s * cross[i][j] + (1.0 - c) * n[i] * n[j]
        })
    });
    let x: Vec<[f64; 3]> = model
        .rest
        .iter()
        .map(|p| [0, 1, 2].map(|i| (0..3).map(|j| r[i][j] * p[j]).sum()))
        .collect();
    let still = vec![[0.0; 3]; x.len()];
    let Some(ElementForces::TensorMass(tm)) =
        ElementForces::new(ForceModelKind::TensorMass, &model).unwrap()
    else {
        panic!("a tensor-mass model")
    };
    for kind in [
        LayoutKind::Connectivity,
        LayoutKind::Valence,
        LayoutKind::Edges,
    ] {
        let config = config(&model, Integrator::BackwardEuler, 4.0);
        let mut gpu = GpuEngine::with_context(ctx.clone(), &model, config, kind).unwrap();
        gpu.set_state(&x, &still);
        gpu.step(1);
        let device = gpu.corotational_block_values().unwrap().expect("blocks");
        let linear = TensorBlocks::new(gpu.layout(), &tm, false);
        let turned: Vec<[f32; 4]> = linear
            .rows
            .chunks(3)
            .flat_map(|k| {
                // R K R^T, row by row.
                let rk: [[f64; 3]; 3] = std::array::from_fn(|i| {
                    std::array::from_fn(|j| (0..3).map(|m| r[i][m] * f64::from(k[m][j])).sum())
                });
                (0..3).map(move |i| {
                    let e = |j: usize| (0..3).map(|m| rk[i][m] * r[j][m]).sum::<f64>() as f32;
                    [e(0), e(1), e(2), 0.0]
                })
            })
            .collect();
        let scale = largest(&turned);
        let off = apart(&device.rows, &turned);
        assert!(off <= 1e-5 * scale, "{kind:?}: {off:e} of {scale:e}");
        assert!(
            apart(&device.rows, &linear.rows) > 0.1 * scale,
            "{kind:?}: the turned blocks are not the linear ones"
        );
    }
}

/// Each layout's corotational implicit step equals its twin stepper (tet pass, block pass,
/// the tensor-mass solve with the gathered forces) over 4 steps at ten times the explicit
/// bound, damped, from a state turned by 0.5 rad: within float32 rounding of the twin's
/// motion per step (the bar the explicit corotational passes hold: on lavapipe the rotation's
/// iteration rounds its last bits unlike the twin, see `gpu_corotational.rs`); each solve
/// iterated.
#[rstest]
fn the_corotational_implicit_step_equals_its_twin(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = jittered_box(13, true, 0.25);
    let mut gpu = GpuEngine::with_context(
        ctx,
        &model,
        config(&model, Integrator::BackwardEuler, 10.0),
        kind,
    )
    .unwrap();
    let (x, v) = random_state(&model, 17, 2e-3, 0.5);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let solve = gpu.solve_params().expect("an implicit engine");
    let p: StepParams = gpu.step_params();
    assert!(p.damped && solve.damped, "the damped tets reach the solve");
    let table = gpu.corotational().unwrap().table().clone();
    let pairs = gpu.corotational_blocks().unwrap().pairs().clone();
    let (layout, masses) = (gpu.layout().clone(), inv_mass(gpu.layout()));
    let mut rotations = vec![IDENTITY; table.len()];
    let (mut cur, mut vel) = start.clone();
    let mut iterations = Vec::new();
    let steps = 4;
    for _ in 0..steps {
        let (next, v, s) = twin::implicit_step_cpu(
            &p,
            &solve,
            &table,
            &pairs,
            &layout,
            &masses,
            (&cur, &vel),
            &mut rotations,
        );
        (cur, vel) = (next, v);
        iterations.push(s.iterations);
    }
    gpu.step(steps as u32);
    let got = gpu.raw_state().unwrap();
    for (got, want, start) in [(&got.0, &cur, &start.0), (&got.1, &vel, &start.1)] {
        let d = common::relative_difference(got, want, start);
        assert!(
            d <= 1e-5 * steps as f64,
            "{kind:?}: device and twin differ by {d:e}"
        );
    }
    assert_eq!(gpu.solver_stats().unwrap().solves, steps as u64);
    assert!(iterations.iter().all(|&i| i > 1), "{iterations:?}");
    assert!(cur != start.0, "the state moved");
}

/// The GPU's corotational backward Euler in every layout follows the float64 reference
/// engine's (10 steps at ten times the explicit bound, damped, under gravity, from a state
/// turned by 0.6 rad with random displacements and velocities) within the solvers' tolerance
/// (relative residual 1e-5 each) and float32 rounding (the device's rotations converge to
/// 1e-6 rad, the reference's SVD to float64): relative L2 error below 1e-4 (3.3e-5 on lavapipe
/// in each layout; 1.2e-5 after 20 steps, where the settling motion outgrows the first
/// steps' error). The linear model stepped the same (what the step would be with every
/// rotation the identity) is far off (0.27): the rotations are what is solved with. The
/// reference runs once for the three layouts.
#[test]
fn gpu_corotational_backward_euler_follows_the_float64_reference() {
    use lancet::engine::{EngineKind, Simulation};
    use lancet::report::bench::relative_l2;
    let Some(_) = common::gpu() else { return };
    let model = jittered_box(3, true, 0.08);
    let config = config(&model, Integrator::BackwardEuler, 10.0);
    let (x, v) = random_state(&model, 5, 1e-3, 0.6);
    let run = |kind: EngineKind, config: SimConfig, layout: LayoutKind| {
        let mut sim = Simulation::with_gpu(model.clone(), kind, config, layout.into()).unwrap();
        sim.set_state(&x, &v).unwrap();
        sim.run(10).unwrap();
        sim.positions()
    };
    let reference = run(EngineKind::Reference, config, LayoutKind::Connectivity);
    let linear = SimConfig {
        force_model: ForceModelKind::TensorMass,
        ..config
    };
    let apart = relative_l2(
        &model.rest,
        &run(EngineKind::Reference, linear, LayoutKind::Connectivity),
        &reference,
    );
    for layout in [
        LayoutKind::Connectivity,
        LayoutKind::Valence,
        LayoutKind::Edges,
    ] {
        let gpu = run(EngineKind::Gpu, config, layout);
        let err = relative_l2(&model.rest, &gpu, &reference);
        eprintln!("{layout:?}: gpu {err:e}, linear {apart:e}");
        assert!(err < 1e-4, "{layout:?}: relative L2 error {err:e}");
        assert!(
            apart > 100.0 * err.max(1e-6),
            "linear {apart:e}, gpu {err:e}"
        );
    }
}

/// Cuts through a corotational model under backward Euler on the GPU (valence layout,
/// separating): the world's checks after every cut, then the cut engine steps as one built
/// afresh from the cut model (`fem_gpu_checks::cut_model_equals_a_rebuilt_one`): the tet
/// table patched, the pair lists and blocks rebuilt beside the patched layout, the solve
/// rebound. One layout: the block pass is the same in every layout, and an implicit cut run
/// costs ten times an explicit one.
#[test]
fn a_cut_gpu_corotational_implicit_engine_equals_a_rebuilt_one() {
    crate::fem_gpu_checks::cut_model_equals_a_rebuilt_one(
        ForceModelKind::Corotational,
        LayoutKind::Valence,
        lancet::cut::CutMethod::Separate,
        Integrator::BackwardEuler,
    );
}

/// The corotational implicit step does not run on the edge layout's fixed-point variant, as no
/// implicit step does (the float-atomic one runs it, `gpu_implicit_atomic_fem.rs`): refused
/// with the reason and what to use.
#[test]
fn corotational_backward_euler_on_atomic_edges_is_refused_with_a_reason() {
    let Some(ctx) = common::gpu() else { return };
    let model = jittered_box(1, false, 0.0);
    let config = SimConfig {
        force_model: ForceModelKind::Corotational,
        ..config(&model, Integrator::BackwardEuler, 4.0)
    };
    let options = lancet::engine::GpuOptions {
        layout: LayoutKind::Edges,
        accumulation: lancet::layout::edges::Accumulation::AtomicFixed,
    };
    let err = GpuEngine::with_context(ctx, &model, config, options)
        .err()
        .expect("refused");
    assert!(
        matches!(&err, lancet::Error::Unsupported(m) if m.contains("gather")),
        "{err}"
    );
}

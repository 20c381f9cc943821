//! The GPU layouts: each pass equals its CPU twin on random inputs, and the GPU engine in each
//! layout agrees with the float64 reference and with the other layouts.

use crate::{common, models};
use lancet::engine::gpu::{step_params, GpuEngine};
use lancet::engine::{Engine, EngineKind, Integrator, SimConfig, Simulation};
use lancet::layout::connectivity::ConnectivityLayout;
use lancet::layout::edges::{EdgeLayout, B_END};
use lancet::layout::valence::ValenceLayout;
use lancet::layout::{LayoutKind, NodeOrder};
use lancet::model::{
    stable_time_step, FixedSelector, Material, ModelConfig, PackedModel, SpringModel,
};
use lancet::physics::StepParams;
use lancet::report::bench::relative_l2;
use lancet::Error;
use models::{random_box as random_model, Rng};
use rstest::rstest;

/// Random displacements of about 5% of a cell and random velocities, in layout order.
fn random_state(n: usize, seed: u64) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let mut rng = Rng(seed);
    let mut v = |s: f64| {
        [
            (rng.next() - 0.5) * s,
            (rng.next() - 0.5) * s,
            (rng.next() - 0.5) * s,
        ]
    };
    let cur = (0..n)
        .map(|_| {
            let a = v(1e-3);
            [a[0] as f32, a[1] as f32, a[2] as f32, 0.0]
        })
        .collect();
    let second = (0..n)
        .map(|_| {
            let a = v(1e-3);
            [a[0] as f32, a[1] as f32, a[2] as f32, 0.0]
        })
        .collect();
    (cur, second)
}

/// The CPU twin of a layout's pass, and the node order it packs in.
type Twin = Box<dyn Fn(&StepParams, &[[f32; 4]], &[[f32; 4]]) -> (Vec<[f32; 4]>, Vec<[f32; 4]>)>;

fn twin(layout: LayoutKind, model: &PackedModel) -> (NodeOrder, Twin) {
    let base = NodeOrder::locality(model);
    match layout {
        LayoutKind::Connectivity => {
            let l = ConnectivityLayout::new(model, base, None).unwrap();
            (
                l.order.clone(),
                Box::new(move |p, u, s| l.step_cpu(p, u, s)),
            )
        }
        LayoutKind::Valence => {
            let l = ValenceLayout::new(model, &base);
            (
                l.order.clone(),
                Box::new(move |p, u, s| l.step_cpu(p, u, s)),
            )
        }
        LayoutKind::Edges => {
            let l = EdgeLayout::new(model, base);
            (
                l.order.clone(),
                Box::new(move |p, u, s| l.step_cpu(p, u, s)),
            )
        }
    }
}

#[rstest]
fn layout_pass_equals_its_cpu_twin_on_random_inputs(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(false, true)] damped: bool,
    #[values(1, 50)] steps: u32,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = random_model(7, damped);
    let dt = 0.5 * stable_time_step(&model).dt;
    let config = SimConfig {
        integrator,
        ..SimConfig::new(dt)
    };
    let (order, step_twin) = twin(kind, &model);
    let p = step_params(&model, config);
    // Start both from the same random state (positions and velocities in model order).
    let (cur, second) = random_state(model.node_count(), 11);
    let mut engine = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
    let order = &order;
    let to_model = |u: &[[f32; 4]]| -> Vec<[f64; 3]> {
        let mut x = vec![[0.0; 3]; u.len()];
        for (new, &old) in order.order.iter().enumerate() {
            for c in 0..3 {
                x[old as usize][c] = model.rest[old as usize][c] + u[new][c] as f64;
            }
        }
        x
    };
    // The engine takes velocities; derive them exactly as the twin's second state means them.
    let vel: Vec<[f64; 3]> = {
        let mut v = vec![[0.0; 3]; cur.len()];
        for (new, &old) in order.order.iter().enumerate() {
            for c in 0..3 {
                v[old as usize][c] = match integrator {
                    Integrator::Verlet => second[new][c] as f64 / dt,
                    Integrator::SymplecticEuler | Integrator::BackwardEuler => {
                        second[new][c] as f64
                    }
                };
            }
        }
        v
    };
    engine.set_state(&to_model(&cur), &vel);
    // The engine rounds the state to float32 on upload; start the twin from what it stored.
    let (mut u, mut s) = (cur.clone(), second.clone());
    for (new, &old) in order.order.iter().enumerate() {
        if model.fixed[old as usize] {
            u[new] = [0.0; 4];
            s[new] = [0.0; 4];
        } else if integrator == Integrator::Verlet {
            for c in 0..3 {
                s[new][c] = (vel[old as usize][c] * dt) as f32;
            }
        }
    }
    let (u, _) = lancet::twin::steps(&p, (u, s), steps as usize, &step_twin);
    engine.step(steps);
    let gpu = engine.positions();
    let cpu = to_model(&u);
    // Both sides run the same float32 operations in the same order; a GPU may still contract
    // a multiply-add or round a square root differently, so allow a few float32 ulps of the
    // motion, accumulated over the steps.
    let motion = cpu
        .iter()
        .zip(&model.rest)
        .map(|(x, r)| (0..3).map(|c| (x[c] - r[c]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    let worst = gpu
        .iter()
        .zip(&cpu)
        .map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    eprintln!(
        "{kind:?} {integrator:?} damped={damped} steps={steps}: worst {worst:e}, motion {motion:e}"
    );
    assert!(
        motion > 1e-5,
        "the inputs must move the nodes (motion {motion:e})"
    );
    assert!(
        worst <= 1e-5 * motion * steps as f64,
        "gpu and cpu twin differ by {worst:e} (motion {motion:e})"
    );
}

#[rstest]
fn gpu_engine_agrees_with_the_float64_reference(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let Some(_) = common::gpu() else { return };
    let model = random_model(3, true);
    let dt = 0.8 * stable_time_step(&model).dt;
    let config = SimConfig {
        integrator,
        ..SimConfig::new(dt)
    };
    let mut gpu =
        Simulation::with_gpu(model.clone(), EngineKind::Gpu, config, layout.into()).unwrap();
    let mut reference = Simulation::new(model.clone(), EngineKind::Reference, config).unwrap();
    gpu.run(300).unwrap();
    reference.run(300).unwrap();
    let err = relative_l2(&model.rest, &gpu.positions(), &reference.positions());
    // Same bar as the float32 CPU engine (tests/engine_agreement.rs).
    assert!(err < 1e-3, "relative L2 displacement error {err:e}");
    let name = format!("gpu-{layout:?}").to_lowercase();
    assert!(
        gpu.engine_name().starts_with(&name),
        "{}",
        gpu.engine_name()
    );
}

#[rstest]
fn gpu_engine_runs_a_real_mesh_like_the_reference(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
) {
    let Some(_) = common::gpu() else { return };
    let Some(dir) = std::env::var_os("LANCET_MESH_DIR") else {
        eprintln!("skipped: LANCET_MESH_DIR is not set");
        return;
    };
    let mesh = lancet::mesh::io::read(std::path::Path::new(&dir).join("sofa/liver.msh"))
        .unwrap()
        .mesh;
    let mut config = ModelConfig::new(Material::elastic(3e3, 0.25, 1000.0));
    config.gravity = [0.0, -9.81, 0.0];
    config.mass_damping = 2.0;
    let ymax = mesh.bounds().unwrap().1.y;
    config.fixed.push(FixedSelector::HalfSpace {
        point: [0.0, ymax - 0.5, 0.0],
        normal: [0.0, -1.0, 0.0],
        tolerance: 0.0,
    });
    let model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let dt = 0.9 * stable_time_step(&model).dt;
    let config = SimConfig::new(dt);
    let mut gpu =
        Simulation::with_gpu(model.clone(), EngineKind::Gpu, config, layout.into()).unwrap();
    let mut reference =
        Simulation::new(model.clone(), EngineKind::Reference, SimConfig::new(dt)).unwrap();
    gpu.run(200).unwrap();
    reference.run(200).unwrap();
    let err = relative_l2(&model.rest, &gpu.positions(), &reference.positions());
    assert!(
        err < 1e-3,
        "relative L2 displacement error {err:e} on the liver"
    );
}

/// Rows narrower than their nodes continue in overflow rows: on the device, a table of three
/// slots per row (most nodes a chain of several rows) steps bit for bit like its CPU twin and
/// like a table wide enough for every node. One slot per row is an error.
#[rstest]
fn rows_that_continue_step_on_the_gpu_like_full_rows(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = random_model(1, true);
    let order = NodeOrder::locality(&model);
    match ConnectivityLayout::new(&model, order.clone(), Some(1)) {
        Err(Error::LayoutCapacity(msg)) => assert!(msg.contains("at least 2 slots"), "{msg}"),
        other => panic!("expected a capacity error, got {other:?}"),
    }
    let Some(ctx) = common::gpu() else { return };
    let narrow = ConnectivityLayout::new(&model, order.clone(), Some(3)).unwrap();
    let wide = ConnectivityLayout::new(&model, order, None).unwrap();
    assert!(narrow.overflow_rows() > narrow.node_count());
    assert!(
        (0..model.node_count()).all(|i| narrow.row(i) == wide.row(i)),
        "the same slots in the same order"
    );
    let config = SimConfig {
        integrator,
        ..SimConfig::new(0.5 * stable_time_step(&model).dt)
    };
    let (cur, second) = random_state(model.node_count(), 3);
    let run = |layout: &ConnectivityLayout| {
        let ctx = common::gpu().unwrap();
        let mut e = GpuEngine::with_layout(
            ctx,
            &model,
            config,
            lancet::layout::PackedLayout::Connectivity(layout.clone()),
            lancet::layout::edges::Accumulation::Gather,
        )
        .unwrap();
        e.set_raw_state(&cur, &second).unwrap();
        e.step(20);
        e.raw_state().unwrap()
    };
    drop(ctx);
    let (a, b) = (run(&narrow), run(&wide));
    let bits =
        |v: &[[f32; 4]]| -> Vec<[u32; 4]> { v.iter().map(|x| x.map(f32::to_bits)).collect() };
    assert_eq!(bits(&a.0), bits(&b.0));
    assert_eq!(bits(&a.1), bits(&b.1));
    // And the twin, from the same raw state.
    let p = step_params(&model, config);
    let (u, _) = lancet::twin::steps(&p, (cur.clone(), second.clone()), 20, |p, u, s| {
        narrow.step_cpu(p, u, s)
    });
    let moved = u.iter().flatten().any(|&x| x.abs() > 1e-7);
    assert!(moved, "the nodes move");
    common::assert_twin(&a.0, &u, &cur, 20, "continued rows");
}

#[test]
fn padding_is_the_share_of_empty_slots() {
    let model = random_model(1, false);
    let layout = ConnectivityLayout::new(&model, NodeOrder::locality(&model), Some(20)).unwrap();
    let (stats, _) = layout.memory(Integrator::Verlet);
    let empty = (20 * model.node_count() - 2 * model.springs().len()) as u64;
    assert_eq!(stats.padding, empty * 32);
    // Each spring appears once in each end's row.
    let used = layout.slots.iter().filter(|s| s.other != u32::MAX).count();
    assert_eq!(used, 2 * model.springs().len());
}

#[test]
fn auto_engine_uses_the_gpu_when_there_is_one() {
    let Some(_) = common::gpu() else { return };
    let model = random_model(5, false);
    let dt = 0.5 * stable_time_step(&model).dt;
    let sim = Simulation::new(model, EngineKind::Auto, SimConfig::new(dt)).unwrap();
    assert_eq!(sim.kind(), EngineKind::Gpu);
    assert!(sim.engine_note().is_none());
}

#[test]
fn layouts_on_the_gpu_agree_with_each_other() {
    let Some(_) = common::gpu() else { return };
    let model = random_model(9, true);
    let dt = 0.8 * stable_time_step(&model).dt;
    let run = |layout: LayoutKind| {
        let config = SimConfig::new(dt);
        let mut sim =
            Simulation::with_gpu(model.clone(), EngineKind::Gpu, config, layout.into()).unwrap();
        sim.run(200).unwrap();
        sim.positions()
    };
    let base = run(LayoutKind::Connectivity);
    // Every layout computes each spring force with the same float32 operations (an edge force
    // seen from its other end is the exact negation) and sums a node's springs in ascending
    // neighbour order; only the node numbering differs. Allow rounding-level differences
    // should a device reorder anything.
    for other in [LayoutKind::Valence, LayoutKind::Edges] {
        let err = relative_l2(&model.rest, &run(other), &base);
        assert!(err < 1e-5, "{other:?} and connectivity differ by {err:e}");
    }
}

#[test]
fn valence_buckets_cover_every_node_without_padding() {
    let model = random_model(2, false);
    let layout = ValenceLayout::new(&model, &NodeOrder::locality(&model));
    let n = model.node_count();
    // The permutation and its inverse are inverse.
    for (new, &old) in layout.order.order.iter().enumerate() {
        assert_eq!(layout.order.rank[old as usize] as usize, new);
    }
    // Buckets are contiguous, in increasing valence, and cover all nodes.
    let mut next_node = 0;
    let mut next_slot = 0;
    for pair in layout.buckets.windows(2) {
        assert!(pair[0].valence < pair[1].valence);
    }
    for b in &layout.buckets {
        assert_eq!(b.first, next_node);
        assert_eq!(b.offset, next_slot);
        next_node += b.count;
        next_slot += b.count * b.valence;
    }
    assert_eq!(next_node as usize, n);
    // Exactly two slots per spring, none empty: no padding.
    assert_eq!(layout.slots.len(), 2 * model.springs().len());
    assert!(layout.slots.iter().all(|s| s.other != u32::MAX));
    // Each node's table lists exactly its springs' other ends.
    let mut expected: Vec<Vec<u32>> = vec![Vec::new(); n];
    for s in model.springs() {
        let (a, b) = (
            layout.order.rank[s.nodes[0] as usize],
            layout.order.rank[s.nodes[1] as usize],
        );
        expected[a as usize].push(b);
        expected[b as usize].push(a);
    }
    for b in &layout.buckets {
        for local in 0..b.count {
            let i = (b.first + local) as usize;
            let at = (b.offset + local * b.valence) as usize;
            let mut got: Vec<u32> = layout.slots[at..at + b.valence as usize]
                .iter()
                .map(|s| s.other)
                .collect();
            got.sort();
            expected[i].sort();
            assert_eq!(got, expected[i], "node {i}");
        }
    }
    let (stats, _) = layout.memory(Integrator::Verlet);
    assert_eq!(stats.padding, 0);
    assert_eq!(
        stats.total,
        stats.buffers.iter().map(|(_, b)| b).sum::<u64>()
    );
}

#[test]
fn edge_incidence_lists_every_spring_once_from_each_end() {
    let model = random_model(4, false);
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    assert_eq!(layout.springs.len(), model.springs().len());
    let mut seen = vec![(0u32, 0u32); layout.springs.len()];
    for i in 0..layout.node_count() {
        let [lo, hi] = layout.incidence_rows[i];
        for &e in &layout.incidence[lo as usize..hi as usize] {
            let s = &layout.springs[(e & !B_END) as usize];
            if e & B_END != 0 {
                assert_eq!(s.b as usize, i);
                seen[(e & !B_END) as usize].1 += 1;
            } else {
                assert_eq!(s.a as usize, i);
                seen[(e & !B_END) as usize].0 += 1;
            }
        }
    }
    assert!(seen.iter().all(|&c| c == (1, 1)));
    // Each spring stored once with a < b, and its rest vector points from a to b.
    for s in &layout.springs {
        assert!(s.a < s.b);
        let (a, b) = (
            layout.order.order[s.a as usize] as usize,
            layout.order.order[s.b as usize] as usize,
        );
        for c in 0..3 {
            let want = (model.rest[b][c] - model.rest[a][c]) as f32;
            assert_eq!(s.edge[c], want);
        }
    }
}

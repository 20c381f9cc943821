//! The edge layout on the CPU: the records and the incidence table are complete and consistent,
//! the gather twin steps like the float32 CPU engine and the float64 reference, and the
//! fixed-point twin is deterministic and as accurate as its resolution.

use crate::models;
use lancet::engine::fast::FastEngine;
use lancet::engine::gpu::step_params;
use lancet::engine::reference::ReferenceEngine;
use lancet::engine::{Engine, Integrator, SimConfig};
use lancet::layout::edges::{Accumulation, EdgeLayout, FixedPoint, B_END};
use lancet::layout::NodeOrder;
use lancet::model::{stable_time_step, PackedModel};
use lancet::physics::StepParams;
use lancet::report::bench::relative_l2;
use models::{random_box as random_model, Rng};
use rstest::rstest;

/// Random displacements (about 5% of a cell) and velocities of the free nodes, model order.
fn random_state(model: &PackedModel, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = Rng(seed);
    let mut x = model.rest.clone();
    let mut v = vec![[0.0; 3]; x.len()];
    for i in 0..x.len() {
        if model.fixed[i] {
            continue;
        }
        for c in 0..3 {
            x[i][c] += (rng.next() - 0.5) * 1e-3;
            v[i][c] = (rng.next() - 0.5) * 1e-2;
        }
    }
    (x, v)
}

/// The twin's float32 state (layout order) for model-order positions and velocities, as the
/// engines store it: displacements, and last steps `h v` (Verlet) or velocities.
fn to_layout(
    model: &PackedModel,
    order: &NodeOrder,
    config: &SimConfig,
    x: &[[f64; 3]],
    v: &[[f64; 3]],
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let n = x.len();
    let (mut cur, mut second) = (vec![[0.0f32; 4]; n], vec![[0.0f32; 4]; n]);
    for (new, &old) in order.order.iter().enumerate() {
        let old = old as usize;
        if model.fixed[old] {
            continue;
        }
        for c in 0..3 {
            let u = x[old][c] - model.rest[old][c];
            cur[new][c] = u as f32;
            second[new][c] = match config.integrator {
                Integrator::Verlet => (v[old][c] * config.dt) as f32,
                Integrator::SymplecticEuler | Integrator::BackwardEuler => v[old][c] as f32,
            };
        }
    }
    (cur, second)
}

/// Model-order positions of layout-order displacements.
fn to_model(model: &PackedModel, order: &NodeOrder, u: &[[f32; 4]]) -> Vec<[f64; 3]> {
    let mut x = model.rest.clone();
    for (new, &old) in order.order.iter().enumerate() {
        for c in 0..3 {
            x[old as usize][c] += u[new][c] as f64;
        }
    }
    x
}

/// Run a CPU twin `steps` steps from `(cur, second)` through the shared twin stepper; the
/// current displacements it ends with.
fn run(
    p: &StepParams,
    steps: usize,
    state: (Vec<[f32; 4]>, Vec<[f32; 4]>),
    step: impl Fn(&StepParams, &[[f32; 4]], &[[f32; 4]]) -> (Vec<[f32; 4]>, Vec<[f32; 4]>),
) -> Vec<[f32; 4]> {
    lancet::twin::steps(p, state, steps, step).0
}

fn config(model: &PackedModel, integrator: Integrator) -> SimConfig {
    SimConfig {
        integrator,
        ..SimConfig::new(0.8 * stable_time_step(model).dt)
    }
}

#[test]
fn each_spring_appears_once_with_its_ends_and_rest_vector() {
    let model = random_model(4, true);
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let order = &layout.order;
    let mut expected: Vec<(u32, u32)> = model
        .springs()
        .iter()
        .map(|s| {
            let (a, b) = (s.nodes[0].min(s.nodes[1]), s.nodes[0].max(s.nodes[1]));
            (a, b)
        })
        .collect();
    let mut got: Vec<(u32, u32)> = layout
        .springs
        .iter()
        .map(|s| {
            let (a, b) = (order.order[s.a as usize], order.order[s.b as usize]);
            // The rest vector points from a to b.
            for c in 0..3 {
                let e = model.rest[b as usize][c] - model.rest[a as usize][c];
                assert!((s.edge[c] as f64 - e).abs() <= 1e-7 * e.abs().max(1e-3));
            }
            assert!(s.a < s.b, "records store a < b in layout order");
            (a.min(b), a.max(b))
        })
        .collect();
    expected.sort();
    got.sort();
    assert_eq!(got.len(), model.springs().len());
    assert_eq!(got, expected);
    // Records stream by their ends in layout order.
    assert!(layout
        .springs
        .windows(2)
        .all(|w| (w[0].a, w[0].b) < (w[1].a, w[1].b)));
}

#[test]
fn incidence_lists_every_spring_exactly_twice_with_the_sign_of_its_end() {
    let model = random_model(5, false);
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let n = layout.node_count();
    assert_eq!(layout.incidence_rows.len(), n);
    assert_eq!(layout.incidence.len(), 2 * layout.springs.len());
    // A fresh packing is compact: each row starts where the previous one ends, with no room.
    assert_eq!(layout.incidence_rows.first().map(|r| r[0]), Some(0));
    assert!(layout.incidence_rows.windows(2).all(|w| w[0][1] == w[1][0]));
    assert_eq!(layout.holes(), 0);
    let mut ends = vec![(0u32, 0u32); layout.springs.len()];
    for i in 0..n {
        let [lo, hi] = layout.incidence_rows[i];
        let row = &layout.incidence[lo as usize..hi as usize];
        assert_eq!(row, layout.row(i), "no room in a fresh packing");
        for &e in row {
            let s = &layout.springs[(e & !B_END) as usize];
            if e & B_END != 0 {
                assert_eq!(s.b as usize, i, "a B_END entry is the spring's b end");
                ends[(e & !B_END) as usize].1 += 1;
            } else {
                assert_eq!(s.a as usize, i, "an unmarked entry is the spring's a end");
                ends[(e & !B_END) as usize].0 += 1;
            }
        }
        // Each row lists its springs in record order (the deterministic gather order).
        assert!(row.windows(2).all(|w| (w[0] & !B_END) < (w[1] & !B_END)));
    }
    assert!(ends.iter().all(|&e| e == (1, 1)), "once from each end");
}

#[rstest]
fn gather_twin_steps_like_the_fast_engine_and_the_float64_reference(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = random_model(7, true);
    let config = config(&model, integrator);
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let p = step_params(&model, config);
    let (x, v) = random_state(&model, 3);
    let steps = 200;
    let u = run(
        &p,
        steps,
        to_layout(&model, &layout.order, &config, &x, &v),
        |p, u, s| layout.step_cpu(p, u, s),
    );
    let twin = to_model(&model, &layout.order, &u);
    let mut fast = FastEngine::new(&model, config);
    let mut reference = ReferenceEngine::new(&model, config);
    for e in [&mut fast as &mut dyn Engine, &mut reference] {
        e.set_state(&x, &v);
        e.step(steps as u32);
    }
    let vs_fast = relative_l2(&model.rest, &twin, &fast.positions());
    let vs_reference = relative_l2(&model.rest, &twin, &reference.positions());
    eprintln!("{integrator:?}: vs fast {vs_fast:e}, vs float64 reference {vs_reference:e}");
    // Both float32 with the same force law; only the summation order differs.
    assert!(vs_fast < 1e-5, "gather twin vs fast engine: {vs_fast:e}");
    // The float32 bar of tests/engine_agreement.rs.
    assert!(
        vs_reference < 1e-3,
        "gather twin vs reference: {vs_reference:e}"
    );
}

#[rstest]
fn fixed_point_twin_is_bitwise_identical_when_the_spring_order_is_shuffled(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = random_model(8, true);
    let config = config(&model, integrator);
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let fp = layout.fixed_point(&model);
    let mut shuffled = layout.clone();
    let mut rng = Rng(99);
    let mut perm: Vec<u32> = (0..layout.springs.len() as u32).collect();
    for i in (1..perm.len()).rev() {
        perm.swap(i, (rng.next() * (i + 1) as f64) as usize);
    }
    shuffled.permute_springs(&perm);
    assert_ne!(shuffled.springs, layout.springs);
    let p = step_params(&model, config);
    let (x, v) = random_state(&model, 5);
    let start = to_layout(&model, &layout.order, &config, &x, &v);
    let step = |l: &EdgeLayout| {
        let l = l.clone();
        move |p: &StepParams, u: &[[f32; 4]], s: &[[f32; 4]]| {
            let (u, s, overflow) = l.step_fixed_cpu(p, &fp, u, s);
            assert!(!overflow);
            (u, s)
        }
    };
    let a = run(&p, 100, start.clone(), step(&layout));
    let b = run(&p, 100, start.clone(), step(&shuffled));
    let bits = |u: &[[f32; 4]]| -> Vec<u32> { u.iter().flatten().map(|x| x.to_bits()).collect() };
    assert_eq!(bits(&a), bits(&b));
    // The float atomics twin in the shuffled order is not (the control for this test).
    let fa = run(&p, 100, start.clone(), |p, u, s| {
        layout.step_float_cpu(p, u, s)
    });
    let fb = run(&p, 100, start, |p, u, s| shuffled.step_float_cpu(p, u, s));
    assert_ne!(
        bits(&fa),
        bits(&fb),
        "float sums should depend on the order"
    );
}

#[test]
fn fixed_point_scale_is_a_power_of_two_that_leaves_headroom() {
    let model = random_model(1, false);
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let fp = layout.fixed_point(&model);
    assert_eq!(fp.scale.log2().fract(), 0.0);
    assert_eq!(fp.limit.log2().fract(), 0.0);
    assert_eq!(fp.scale * fp.inv_scale, 1.0);
    // A node's sum of saturated springs still fits in an i32.
    assert!(fp.limit as f64 * layout.max_valence() as f64 <= i32::MAX as f64);
    // The range covers HEADROOM times the larger spring force k * L and node weight, but not
    // twice that (the scale is as fine as the range allows).
    let kl = layout
        .springs
        .iter()
        .map(|s| (s.k * s.rest) as f64)
        .fold(0.0, f64::max);
    let weight = model.mass.iter().fold(0.0f64, |w, m| w.max(m * 9.81));
    let bound = FixedPoint::HEADROOM * kl.max(weight);
    assert!(fp.max_force() >= bound && fp.max_force() < 2.0 * bound);
    eprintln!(
        "scale 2^{}, resolution {:e} N, range {:e} N, k L {kl:e} N, weight {weight:e} N",
        fp.scale.log2(),
        fp.resolution(),
        fp.max_force()
    );
    // Rounding is half to even, as WGSL round.
    assert_eq!(fp.quantize(2.5 * fp.inv_scale), (2, false));
    assert_eq!(fp.quantize(-3.5 * fp.inv_scale), (-4, false));
    // Beyond the range a force saturates and raises the flag.
    let big = 3.0 * fp.max_force() as f32;
    assert_eq!(fp.quantize(big), (fp.limit as i32, true));
    assert_eq!(fp.quantize(-big), (-(fp.limit as i32), true));
    assert!(fp.quantize(f32::NAN).1);
    let forces = vec![[big, 0.0, 0.0, 0.0]; layout.springs.len()];
    let (acc, overflow) = layout.accumulate_fixed_cpu(&fp, &forces);
    assert!(overflow);
    // Saturated sums never wrap: each node's sum is (a-count - b-count) * limit.
    for (i, sum) in acc.iter().enumerate() {
        let net: i64 = layout
            .row(i)
            .iter()
            .map(|e| if e & B_END != 0 { -1 } else { 1 })
            .sum();
        assert_eq!(sum[0] as i64, net * fp.limit as i64);
    }
}

#[rstest]
fn fixed_point_twin_agrees_with_the_gather_within_its_resolution(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = random_model(6, true);
    let config = config(&model, integrator);
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let fp = layout.fixed_point(&model);
    let p = step_params(&model, config);
    let (x, v) = random_state(&model, 9);
    let (cur, second) = to_layout(&model, &layout.order, &config, &x, &v);
    // One spring pass: each node's force is within half a unit per spring of the float32
    // gather (plus the gather's own float32 rounding, a few ulps of the summed magnitudes).
    let forces = layout.spring_forces_cpu(&p, &cur, &second);
    let gathered = layout.gather_forces_cpu(&forces);
    let (acc, overflow) = layout.accumulate_fixed_cpu(&fp, &forces);
    assert!(!overflow);
    let fixed = EdgeLayout::fixed_forces(&fp, &acc);
    let mut worst = 0.0f64;
    for i in 0..layout.node_count() {
        let valence = layout.row(i).len() as f64;
        let magnitude: f64 = layout
            .row(i)
            .iter()
            .map(|e| {
                let f = forces[(e & !B_END) as usize];
                (0..3).map(|c| (f[c] as f64).abs()).fold(0.0, f64::max)
            })
            .sum();
        let bound = valence * 0.5 * fp.resolution() + valence * magnitude * f32::EPSILON as f64;
        for c in 0..3 {
            let d = (fixed[i][c] as f64 - gathered[i][c] as f64).abs();
            assert!(d <= bound, "node {i}: {d:e} > {bound:e}");
            worst = worst.max(d / fp.resolution());
        }
    }
    eprintln!("worst force difference: {worst:.2} units");
    // After many steps the states stay close: the force errors are below the float32 rounding
    // of the engines' agreement bar.
    let start = (cur, second);
    let steps = 200;
    let a = run(&p, steps, start.clone(), |p, u, s| layout.step_cpu(p, u, s));
    let b = run(&p, steps, start, |p, u, s| {
        layout.step_variant_cpu(Accumulation::AtomicFixed, p, &fp, u, s)
    });
    let err = relative_l2(
        &model.rest,
        &to_model(&model, &layout.order, &b),
        &to_model(&model, &layout.order, &a),
    );
    eprintln!("{integrator:?}: fixed vs gather after {steps} steps: {err:e}");
    assert!(err < 1e-4, "fixed point vs gather: {err:e}");
}

#[test]
fn memory_stats_sum_their_buffers_for_every_variant() {
    let model = random_model(2, false);
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let (n, m) = (model.node_count() as u64, model.springs().len() as u64);
    for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
        // Two displacement buffers and two of the second state (Verlet's last step,
        // symplectic Euler's velocity).
        let state = 4 * 16 * n;
        for acc in [
            Accumulation::Gather,
            Accumulation::AtomicFixed,
            Accumulation::AtomicFloat,
        ] {
            let (stats, per_step) = layout.memory(integrator, acc);
            let sum: u64 = stats.buffers.iter().map(|(_, b)| b).sum();
            assert_eq!(stats.total, sum);
            assert_eq!(stats.padding, 0);
            let expected = 32 * m
                + 4 * n
                + state
                + match acc {
                    // Forces, one [start, end) record per node, two entries per spring.
                    Accumulation::Gather => 16 * m + 8 * n + 4 * 2 * m,
                    Accumulation::AtomicFixed => 12 * n + 32,
                    Accumulation::AtomicFloat => 12 * n,
                };
            assert_eq!(stats.total, expected, "{integrator:?} {acc:?}");
            assert!((stats.bytes_per_node - sum as f64 / n as f64).abs() < 1e-9);
            assert!((stats.bytes_per_spring - sum as f64 / m as f64).abs() < 1e-9);
            assert!(per_step >= 32 * m + state);
        }
    }
}

/// Each node's row as the gather sums it: the spring records (with the end it is) in order.
/// Two layouts that agree here sum the same forces in the same order, wherever their records
/// and rows sit.
fn rows_by_record(layout: &EdgeLayout) -> Vec<Vec<(lancet::layout::edges::EdgeSpring, bool)>> {
    (0..layout.node_count())
        .map(|i| {
            layout
                .row(i)
                .iter()
                .map(|&e| (layout.springs[(e & !B_END) as usize], e & B_END != 0))
                .collect()
        })
        .collect()
}

/// `steps` gather steps of the CPU twin (as `shaders/gather_edges.wgsl` takes them) from a
/// random layout-order state, as raw bits.
fn gather_steps(layout: &EdgeLayout, model: &PackedModel, seed: u64) -> Vec<[u32; 4]> {
    let p = step_params(model, SimConfig::new(2e-5));
    let mut rng = Rng(seed);
    let mut cur = vec![[0.0f32; 4]; layout.node_count()];
    for (t, u) in cur.iter_mut().enumerate() {
        if !model.fixed[layout.order.order[t] as usize] {
            for x in u.iter_mut().take(3) {
                *x = ((rng.next() - 0.5) * 1e-4) as f32;
            }
        }
    }
    let prev: Vec<[f32; 4]> = cur.iter().map(|u| u.map(|x| x * 0.99)).collect();
    let (cur, _) = lancet::twin::steps(&p, (cur, prev), 25, |p, u, s| layout.step_cpu(p, u, s));
    assert!(cur.iter().flatten().any(|&x| x != 0.0), "the state moved");
    cur.iter().map(|u| u.map(f32::to_bits)).collect()
}

/// Patch `layout` (of `model`) with `diff` and check it against a fresh packing of the changed
/// model in the same node order: the same rows, record for record, and the same 25 steps, bit
/// for bit (byte equality does not hold: patched rows move and keep room). Every changed byte
/// lies in a dirty range. Returns the patch and the changed model.
fn patch_and_compare(
    layout: &mut EdgeLayout,
    model: &PackedModel,
    diff: &lancet::model::ModelDiff,
) -> (lancet::layout::patch::LayoutPatch, PackedModel) {
    use lancet::layout::PackedLayout;
    let mut next = model.clone();
    next.apply(diff).unwrap();
    let before = PackedLayout::Edges(layout.clone());
    let patch = layout.patch(&next, diff).unwrap();
    let after = PackedLayout::Edges(layout.clone());
    for a in lancet::layout::patch::LayoutArray::ALL {
        let (old, new) = (before.array(a), after.array(a));
        for (i, byte) in new.iter().enumerate() {
            if old.get(i) != Some(byte) {
                assert!(
                    patch
                        .dirty
                        .iter()
                        .any(|d| d.array == a && d.bytes.contains(&(i as u64))),
                    "{a:?} byte {i} changed outside the dirty ranges"
                );
            }
        }
    }
    let fresh = EdgeLayout::new(&next, layout.order.clone());
    assert!(
        rows_by_record(layout) == rows_by_record(&fresh),
        "rows differ"
    );
    assert_eq!(
        gather_steps(layout, &next, 3),
        gather_steps(&fresh, &next, 3)
    );
    (patch, next)
}

/// Bytes of all the arrays of `layout` a device holds.
fn layout_bytes(layout: &EdgeLayout) -> u64 {
    let l = lancet::layout::PackedLayout::Edges(layout.clone());
    lancet::layout::patch::LayoutArray::ALL
        .iter()
        .map(|&a| l.array(a).len() as u64)
        .sum()
}

#[test]
fn a_row_that_outgrows_its_room_moves_alone_to_the_end() {
    let mut model = random_model(8, true);
    let mut layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    // An inner node (free, many neighbours).
    let node = (0..model.node_count() as u32)
        .filter(|&i| !model.fixed[i as usize])
        .max_by_key(|&i| {
            model
                .springs()
                .iter()
                .filter(|s| s.nodes.contains(&i))
                .count()
        })
        .unwrap();
    let r = layout.order.rank[node as usize] as usize;
    // Round 0: a fresh packing has no room, so one new spring moves both ends' rows. Round 1:
    // the moved row has room now; one spring more than it has outgrows it again.
    for round in 0..2 {
        let [lo, hi] = layout.incidence_rows[r];
        let free = (hi - lo) as usize - layout.row(r).len();
        assert_eq!(free == 0, round == 0, "round {round}: {free} free entries");
        let diff = models::join_nearest(&model, node, free + 1);
        let old = layout.clone();
        let (patch, next) = patch_and_compare(&mut layout, &model, &diff);
        model = next;
        assert!(!patch.repacked, "round {round}");
        let touched: std::collections::BTreeSet<usize> = diff
            .added_springs
            .iter()
            .flat_map(|s| s.nodes)
            .map(|t| layout.order.rank[t as usize] as usize)
            .collect();
        // The overfull row moved past the old table, with room; every other row that did not
        // overflow stays where it was.
        let [start, end] = layout.incidence_rows[r];
        assert!(start as usize >= old.incidence.len(), "round {round}");
        assert!((end - start) as usize >= layout.row(r).len() + 4);
        let mut moved_room = 0;
        for i in 0..layout.node_count() {
            let (o, n) = (old.incidence_rows[i], layout.incidence_rows[i]);
            if o != n {
                assert!(
                    touched.contains(&i),
                    "round {round}: untouched row {i} moved"
                );
                assert!(n[0] as usize >= old.incidence.len());
                moved_room += (o[1] - o[0]) as usize;
            } else if !touched.contains(&i) {
                let range = o[0] as usize..o[1] as usize;
                assert_eq!(layout.incidence[range.clone()], old.incidence[range]);
            }
        }
        assert_eq!(layout.holes(), old.holes() + moved_room, "round {round}");
        // Only the moved rows, their records and the new spring records are dirty: a few
        // hundred bytes of a layout of tens of kilobytes.
        let total = layout_bytes(&layout);
        assert!(
            patch.dirty_bytes() * 20 < total,
            "round {round}: {} of {total} bytes dirty",
            patch.dirty_bytes()
        );
    }
}

#[test]
fn enough_growth_compacts_the_table_and_still_steps_the_same() {
    let mut model = random_model(9, false);
    let mut layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let free_nodes: Vec<u32> = (0..model.node_count() as u32)
        .filter(|&i| !model.fixed[i as usize])
        .collect();
    let mut moves_before = 0;
    for round in 0..40 {
        // Outgrow one more row each round, nodes spread over the box.
        let node = free_nodes[(round * 37 + 5) % free_nodes.len()];
        let r = layout.order.rank[node as usize] as usize;
        let [lo, hi] = layout.incidence_rows[r];
        let free = (hi - lo) as usize - layout.row(r).len();
        let diff = models::join_nearest(&model, node, free + 1);
        let (patch, next) = patch_and_compare(&mut layout, &model, &diff);
        model = next;
        if !patch.repacked {
            // Holes wait until they pass a quarter of the table.
            assert!(layout.holes() > 0 && layout.holes() * 4 <= layout.incidence.len());
            moves_before += 1;
            continue;
        }
        // Compacted: rows contiguous in node order, each with at least four free entries.
        assert_eq!(layout.holes(), 0);
        assert_eq!(layout.incidence_rows[0][0], 0);
        assert!(layout.incidence_rows.windows(2).all(|w| w[0][1] == w[1][0]));
        assert_eq!(
            layout.incidence_rows.last().unwrap()[1] as usize,
            layout.incidence.len()
        );
        for i in 0..layout.node_count() {
            let [lo, hi] = layout.incidence_rows[i];
            assert!((hi - lo) as usize >= layout.row(i).len() + 4, "row {i}");
        }
        // Amortized: several rounds moved rows before one compaction paid for them.
        assert!(moves_before >= 2, "compacted after {moves_before} rounds");
        return;
    }
    panic!("40 rounds of growth never compacted the table");
}

//! Incremental patches on the device: after cut-like random edits, each layout's engine holds
//! exactly the patched arrays and moved state (it steps like the CPU twin of the patched layout:
//! bit for bit on a device that rounds like the CPU, `common::assert_twin`), and steps bit for bit like an engine built from scratch on the changed model
//! in the same arrangement, while uploading only a part of the layout.

use crate::{common, models};
use lancet::engine::gpu::{merged_ranges, GpuEngine, WRITE_GAP};
use lancet::engine::{Engine, GpuOptions, Integrator, SimConfig};
use lancet::layout::edges::Accumulation;
use lancet::layout::patch::LayoutArray;
use lancet::layout::{LayoutKind, PackedLayout};
use lancet::twin::move_state::move_state_cpu;
use models::{floating_ring, fresh, random_diff, random_model, random_state, widen_node_0};
use rstest::rstest;
use std::collections::BTreeSet;

type Raw = (Vec<[f32; 4]>, Vec<[f32; 4]>);

fn bits(v: &[[f32; 4]]) -> Vec<[u32; 4]> {
    v.iter().map(|x| x.map(f32::to_bits)).collect()
}

/// `steps` steps of the patched layout's CPU twin from raw state (layout order).
fn twin(engine: &GpuEngine, accumulation: Accumulation, raw: Raw, steps: usize) -> Raw {
    let p = engine.step_params();
    engine
        .layout()
        .steps_cpu(&p, accumulation, &engine.fixed_point(), raw, steps)
}

/// `steps` steps of an engine built from scratch on `model` in `engine`'s arrangement (a fresh
/// packing of its layout), from raw state `raw`.
fn rebuilt_steps(
    engine: &GpuEngine,
    model: &lancet::model::PackedModel,
    config: SimConfig,
    raw: &Raw,
    steps: u32,
) -> Raw {
    let ctx = common::gpu().unwrap();
    let mut rebuilt = GpuEngine::with_layout(
        ctx,
        model,
        config,
        fresh(model, engine.layout()),
        engine.options().accumulation,
    )
    .unwrap();
    rebuilt.set_raw_state(&raw.0, &raw.1).unwrap();
    rebuilt.step(steps);
    rebuilt.raw_state().unwrap()
}

/// Step the patched `engine` 13 times from the state its patch left: bit for bit what its CPU
/// twin does, and (except in fixed point, whose constants a rebuild may choose anew) what an
/// engine built from scratch in the same arrangement does from that state.
fn steps_like_twin_and_rebuild(
    engine: &mut GpuEngine,
    model: &lancet::model::PackedModel,
    config: SimConfig,
    accumulation: Accumulation,
    round: impl std::fmt::Display,
) {
    // The state the device must now hold, from the layout's own moves.
    let want = engine.raw_state().unwrap();
    let expect_twin = twin(engine, accumulation, want.clone(), 13);
    engine.step(13);
    let got = engine.raw_state().unwrap();
    common::assert_twin(
        &got.0,
        &expect_twin.0,
        &want.0,
        13,
        &format!("round {round}: the patched layout"),
    );
    common::assert_twin(
        &got.1,
        &expect_twin.1,
        &want.1,
        13,
        &format!("round {round}: second buffer"),
    );
    if accumulation != Accumulation::AtomicFixed {
        let r = rebuilt_steps(engine, model, config, &want, 13);
        assert_eq!(
            bits(&r.0),
            bits(&got.0),
            "round {round}: patched != rebuilt"
        );
    }
    assert!(got.0.iter().flatten().all(|x| x.is_finite()));
}

#[rstest]
#[case::connectivity(LayoutKind::Connectivity, Accumulation::Gather, Integrator::Verlet)]
#[case::connectivity_euler(
    LayoutKind::Connectivity,
    Accumulation::Gather,
    Integrator::SymplecticEuler
)]
#[case::valence(LayoutKind::Valence, Accumulation::Gather, Integrator::Verlet)]
#[case::valence_euler(LayoutKind::Valence, Accumulation::Gather, Integrator::SymplecticEuler)]
#[case::edges(LayoutKind::Edges, Accumulation::Gather, Integrator::Verlet)]
#[case::edges_fixed_point(LayoutKind::Edges, Accumulation::AtomicFixed, Integrator::Verlet)]
fn patched_engine_steps_like_its_twin_and_like_a_rebuild(
    #[case] kind: LayoutKind,
    #[case] accumulation: Accumulation,
    #[case] integrator: Integrator,
) {
    let Some(ctx) = common::gpu() else { return };
    let mut model = random_model(41, true);
    let mut config = SimConfig::new(2e-5);
    config.integrator = integrator;
    let options = GpuOptions {
        layout: kind,
        accumulation,
    };
    let mut engine = GpuEngine::with_context(ctx, &model, config, options).unwrap();
    let (x, v) = random_state(&model, 41);
    engine.set_state(&x, &v);
    engine.step(7);
    let mut partial = false;
    for round in 0..4 {
        let diff = random_diff(&model, 100 + round);
        let mut next = model.clone();
        next.apply(&diff).unwrap();
        let report = engine.patch(&next, &diff).unwrap();
        model = next;
        partial |= !report.reallocated && report.uploaded_bytes < report.layout_bytes;
        assert!(report.uploaded_bytes <= report.layout_bytes);
        steps_like_twin_and_rebuild(&mut engine, &model, config, accumulation, round);
    }
    assert!(
        partial,
        "at least one patch uploaded only part of the layout"
    );
    // The device was polled between patches (each round reads the state back): each patch
    // reused the staging buffer the one before it used.
    let (kept, made) = engine.staging_buffers();
    assert_eq!((kept, made), (1, 1), "staging buffers kept and made");
}

/// A cut that gives a node more springs than the connectivity table's rows hold continues its
/// row in an overflow row: the device gets that row and the continuation, not a repacked
/// table, and steps like the patched layout's twin; cuts that add nodes afterwards move the
/// overflow rows up, and the device follows.
#[test]
fn a_connectivity_row_that_outgrows_its_capacity_continues_on_the_device() {
    let Some(ctx) = common::gpu() else { return };
    let mut model = random_model(43, true);
    let config = SimConfig::new(2e-5);
    let mut engine =
        GpuEngine::with_context(ctx, &model, config, LayoutKind::Connectivity).unwrap();
    let (x, v) = random_state(&model, 43);
    engine.set_state(&x, &v);
    engine.step(3);
    let PackedLayout::Connectivity(c) = engine.layout() else {
        unreachable!()
    };
    let k = c.capacity;
    for round in 0..3 {
        let diff = if round == 0 {
            widen_node_0(&model, k, k)
        } else {
            random_diff(&model, 200 + round)
        };
        let mut next = model.clone();
        next.apply(&diff).unwrap();
        let report = engine.patch(&next, &diff).unwrap();
        model = next;
        let PackedLayout::Connectivity(c) = engine.layout() else {
            unreachable!()
        };
        assert_eq!(c.capacity, k, "round {round}: not repacked");
        assert!(c.overflow_rows() >= 2, "round {round}");
        // The widening rewrites the rows of node 0 and its k new neighbours and writes two
        // overflow rows (a repack would send all of it); random cuts on this small model touch
        // more, and added nodes move the overflow rows.
        let share = if round == 0 { 4 } else { 1 };
        assert!(
            report.uploaded_bytes * share < report.layout_bytes,
            "round {round}: uploaded {} of {}",
            report.uploaded_bytes,
            report.layout_bytes
        );
        let want = engine.raw_state().unwrap();
        let expect = twin(&engine, Accumulation::Gather, want.clone(), 11);
        engine.step(11);
        let got = engine.raw_state().unwrap();
        common::assert_twin(&got.0, &expect.0, &want.0, 11, &format!("round {round}"));
    }
}

/// The device's raw state `after` a patch is `before` moved by the patch's moves, in the
/// first `slots` entries: copies exactly, blends up to the device's fused multiply-adds, every
/// entry no move names unchanged.
fn assert_moved(
    after: &Raw,
    before: &Raw,
    patch: &lancet::layout::patch::LayoutPatch,
    slots: usize,
    what: &str,
) {
    for (got, was) in [(&after.0, &before.0), (&after.1, &before.1)] {
        let want = move_state_cpu(was, &patch.moves, slots);
        assert!(
            got.len() >= slots,
            "{what}: {} entries for {slots} slots",
            got.len()
        );
        // Slots a shrinking patch dropped lie past `slots`: they show as zeros when later
        // patches lay holes there again.
        for mv in patch.moves.iter().filter(|m| (m.to as usize) < slots) {
            let (g, w) = (got[mv.to as usize], want[mv.to as usize]);
            if let (Some(f), Some(blend)) = (mv.from, mv.blend) {
                let (f, b) = (f as usize, blend.with as usize);
                for c in 0..4 {
                    let scale = was[f][c].abs() + was[b][c].abs();
                    let tol = 4.0 * f32::EPSILON * scale;
                    assert!(
                        (g[c] - w[c]).abs() <= tol,
                        "{what}: blend to {}: {g:?} vs {w:?}",
                        mv.to
                    );
                }
            } else {
                assert_eq!(bits(&[g]), bits(&[w]), "{what}: move to {}", mv.to);
            }
        }
        let moved: std::collections::HashSet<u32> = patch.moves.iter().map(|m| m.to).collect();
        for i in (0..slots).filter(|i| !moved.contains(&(*i as u32))) {
            assert_eq!(
                bits(&[got[i]]),
                bits(&[want[i]]),
                "{what}: entry {i} changed"
            );
        }
    }
}

/// A patch that adds the first damped spring to an undamped model turns the device's damped
/// step on: the patched engine then steps like an engine built from scratch on the changed
/// model (which reads the neighbours' velocities), in every layout.
#[rstest]
fn the_first_damped_spring_damps_the_device_step(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = random_model(5, false);
    assert!(model.springs().iter().all(|s| s.damping == 0.0));
    let config = SimConfig::new(2e-5);
    let mut engine = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
    let (x, v) = random_state(&model, 5);
    engine.set_state(&x, &v);
    engine.step(3);
    let diff = random_diff(&model, 5);
    assert!(diff.added_springs.iter().any(|s| s.damping > 0.0));
    let mut next = model.clone();
    next.apply(&diff).unwrap();
    engine.patch(&next, &diff).unwrap();
    assert!(engine.step_params().damped, "the step is not damped");
    steps_like_twin_and_rebuild(
        &mut engine,
        &next,
        config,
        Accumulation::Gather,
        format!("{kind:?}"),
    );
}

/// Buckets of a valence layout that are dispatched (hold nodes or holes).
fn dispatched_buckets(layout: &lancet::layout::PackedLayout) -> usize {
    let lancet::layout::PackedLayout::Valence(v) = layout else {
        unreachable!("packed as valence")
    };
    v.buckets.iter().filter(|b| b.count > 0).count()
}

/// Cut-like patches on the valence engine, built on a fragmented layout (more buckets than its
/// bound, `fragmented_valence`), so that its first patch regroups (packs the buckets after the
/// packing's anew by valence, their nodes renumbered): the device follows every node's
/// state through each patch, holds every layout buffer as the host does, steps after a
/// regroup like its CPU twin and like an engine built from scratch, and its surface
/// culler, given before the run and brought up to date only through the patches'
/// moves, holds what an upload from scratch would after every patch and culls as the float64
/// brute force does over the renumbered nodes.
#[test]
fn a_valence_regroup_on_the_device_keeps_every_node_its_state_and_surface() {
    use lancet::collide::broad::{cull_exact, ToolBox};
    let Some(ctx) = common::gpu() else { return };
    let mut model = random_model(21, false);
    let config = SimConfig::new(2e-5);
    let fragmented = models::fragmented_valence(&model, &config.node_order.order(&model));
    let mut engine = GpuEngine::with_layout(
        ctx,
        &model,
        config,
        PackedLayout::Valence(fragmented),
        Accumulation::Gather,
    )
    .unwrap();
    let (x, v) = random_state(&model, 21);
    engine.set_state(&x, &v);
    engine.step(3);
    let n = model.node_count() as u32;
    let triangles: Vec<[u32; 3]> = (0..n - 2).step_by(2).map(|i| [i, i + 1, i + 2]).collect();
    engine.set_surface(&triangles).unwrap();
    let mut regrouped = 0;
    for round in 0..100 {
        let diff = random_diff(&model, 21 * 1009 + round);
        let mut next = model.clone();
        next.apply(&diff).unwrap();
        let before = engine.raw_state().unwrap();
        let mut cpu = engine.layout().clone();
        let dispatched_before = dispatched_buckets(&cpu);
        let patch = cpu.patch(&next, &diff).unwrap();
        engine.patch(&next, &diff).unwrap();
        let after = engine.raw_state().unwrap();
        assert_moved(
            &after,
            &before,
            &patch,
            cpu.node_slots(),
            &format!("round {round}"),
        );
        // Nothing else lowers the buckets dispatched: a node that leaves one leaves a hole.
        let regroup = dispatched_buckets(&cpu) < dispatched_before;
        regrouped += usize::from(regroup);
        if regroup {
            steps_like_twin_and_rebuild(&mut engine, &next, config, Accumulation::Gather, round);
        }
        // Every layout buffer, the bucket table and its count as the host holds them.
        let differences = engine.device_differences().unwrap();
        assert!(differences.is_empty(), "round {round}: {differences:?}");
        // The culler catches up at its next use, each round: through shrinking and growing
        // node slots its buffers equal an upload from scratch.
        let everywhere = ToolBox::containing([-1.0; 3], [1.0; 3]);
        engine.cull_tools(&[everywhere]).unwrap();
        let diffs = engine.surface_differences().unwrap();
        assert!(diffs.is_empty(), "round {round}: {diffs:?}");
        model = next;
    }
    assert!(regrouped > 0, "no patch regrouped the layout");
    let x = engine.positions();
    let lo = x
        .iter()
        .fold([f64::MAX; 3], |a, p| [0, 1, 2].map(|c| a[c].min(p[c])));
    let hi = x
        .iter()
        .fold([f64::MIN; 3], |a, p| [0, 1, 2].map(|c| a[c].max(p[c])));
    let mid = [0, 1, 2].map(|c| 0.5 * (lo[c] + hi[c]));
    let exact_boxes = [
        (lo, mid),
        (mid, hi),
        ([lo[0], mid[1], lo[2]], [mid[0], hi[1], mid[2]]),
    ];
    let boxes: Vec<ToolBox> = exact_boxes
        .iter()
        .map(|&(a, b)| ToolBox::containing(a, b))
        .collect();
    let got = engine.cull_tools(&boxes).unwrap().candidates;
    let diffs = engine.surface_differences().unwrap();
    assert!(diffs.is_empty(), "{diffs:?}");
    let exact = cull_exact(&x, &triangles, &exact_boxes);
    assert!(exact.len() > 10, "the boxes met {} triangles", exact.len());
    // Float32 rounding may add triangles within a micrometre of a box, never more.
    let grown: Vec<([f64; 3], [f64; 3])> = exact_boxes
        .iter()
        .map(|(a, b)| (a.map(|v| v - 1e-6), b.map(|v| v + 1e-6)))
        .collect();
    let loose = cull_exact(&x, &triangles, &grown);
    let (got, exact, loose): (BTreeSet<_>, BTreeSet<_>, BTreeSet<_>) = (
        got.into_iter().collect(),
        exact.into_iter().collect(),
        loose.into_iter().collect(),
    );
    assert!(exact.is_subset(&got), "missed {:?}", exact.difference(&got));
    assert!(got.is_subset(&loose), "found {:?}", got.difference(&loose));
}

#[rstest]
fn state_moves_on_the_device_follow_the_nodes(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = random_model(43, false);
    let config = SimConfig::new(2e-5);
    let mut engine = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
    let (x, v) = random_state(&model, 43);
    engine.set_state(&x, &v);
    engine.step(3);
    let before = engine.raw_state().unwrap();
    let diff = random_diff(&model, 77);
    let mut next = model.clone();
    next.apply(&diff).unwrap();
    let mut cpu = engine.layout().clone();
    let patch = cpu.patch(&next, &diff).unwrap();
    engine.patch(&next, &diff).unwrap();
    let after = engine.raw_state().unwrap();
    assert_moved(&after, &before, &patch, cpu.node_slots(), "");
    // Positions read back in model order: old nodes where they were, copies on their source.
    let x0 = engine.positions();
    let old = {
        let mut e = GpuEngine::with_context(common::gpu().unwrap(), &model, config, kind).unwrap();
        e.set_raw_state(&before.0, &before.1).unwrap();
        e.positions()
    };
    for (i, p) in old.iter().enumerate() {
        if model.fixed[i] == next.fixed[i] {
            assert_eq!(x0[i], *p, "node {i} moved");
        }
    }
    let mut blended = 0;
    for (k, a) in diff.added_nodes.iter().enumerate() {
        let src = a.state_from.unwrap() as usize;
        let got = x0[model.node_count() + k];
        match a.blend {
            None if !next.fixed[src] && !a.fixed => {
                assert_eq!(got, old[src], "copy {k} of node {src}");
            }
            // On the deformed edge, at the rest edge's parameter (float32 state).
            Some(b) if !next.fixed[src] && !next.fixed[b.with as usize] => {
                let w = old[b.with as usize];
                let want = [0, 1, 2].map(|c| old[src][c] + b.t * (w[c] - old[src][c]));
                let off = (0..3).map(|c| (got[c] - want[c]).abs()).fold(0.0, f64::max);
                assert!(
                    off < 1e-6,
                    "node {k} on edge {src}-{}: {off:e} m off",
                    b.with
                );
                blended += 1;
            }
            _ => {}
        }
    }
    assert!(blended > 0, "the diff puts a node on an edge");
}

#[test]
fn an_edge_row_outgrowing_its_room_moves_alone_and_steps_like_a_rebuild_on_the_device() {
    let Some(ctx) = common::gpu() else { return };
    let mut model = random_model(45, true);
    let config = SimConfig::new(2e-5);
    let mut engine = GpuEngine::with_context(ctx, &model, config, LayoutKind::Edges).unwrap();
    let (x, v) = random_state(&model, 45);
    engine.set_state(&x, &v);
    engine.step(5);
    let free_nodes: Vec<u32> = (0..model.node_count() as u32)
        .filter(|&i| !model.fixed[i as usize])
        .collect();
    let (mut moved_alone, mut compacted) = (0, false);
    for round in 0..40 {
        // One row more than its room each round, until the holes it leaves compact the table.
        let node = free_nodes[(round * 37 + 5) % free_nodes.len()];
        let PackedLayout::Edges(e) = engine.layout() else {
            unreachable!("an edge engine")
        };
        let r = e.order.rank[node as usize] as usize;
        let [lo, hi] = e.incidence_rows[r];
        let diff = models::join_nearest(&model, node, (hi - lo) as usize - e.row(r).len() + 1);
        let mut next = model.clone();
        next.apply(&diff).unwrap();
        let mut cpu = engine.layout().clone();
        let patch = cpu.patch(&next, &diff).unwrap();
        let report = engine.patch(&next, &diff).unwrap();
        model = next;
        assert!(
            engine.layout() == &cpu,
            "round {round}: engine and CPU layouts differ"
        );
        if patch.repacked {
            compacted = true;
        } else if !report.reallocated {
            // Only the moved rows, their records and the new springs went up (ranges a few
            // hundred bytes apart in one write, the unchanged bytes between them included).
            let merged: u64 = merged_ranges(&patch.dirty, WRITE_GAP)
                .iter()
                .map(|(_, r)| r.end - r.start)
                .sum();
            assert_eq!(report.uploaded_bytes, merged);
            assert!(merged >= patch.dirty_bytes());
            assert!(
                report.uploaded_bytes * 20 < report.layout_bytes,
                "round {round}: {} of {} bytes",
                report.uploaded_bytes,
                report.layout_bytes
            );
            moved_alone += 1;
        }
        let want = engine.raw_state().unwrap();
        let expect_twin = twin(&engine, Accumulation::Gather, want.clone(), 13);
        engine.step(13);
        let got = engine.raw_state().unwrap();
        let what = format!("round {round}: twin");
        common::assert_twin(&got.0, &expect_twin.0, &want.0, 13, &what);
        common::assert_twin(&got.1, &expect_twin.1, &want.1, 13, &what);
        let r = rebuilt_steps(&engine, &model, config, &want, 13);
        assert_eq!(
            bits(&r.0),
            bits(&got.0),
            "round {round}: patched != rebuilt"
        );
        assert!(got.0.iter().flatten().any(|&x| x != 0.0));
        if compacted {
            break;
        }
    }
    assert!(
        moved_alone >= 1,
        "no patch moved a row without a full upload"
    );
    assert!(compacted, "40 rounds of growth never compacted the table");
}

/// The layout arrays whose device buffers `engine` would outgrow by patching in `diff` (whose
/// model after it is `next`), found on a copy of its layout.
fn outgrown_by(
    engine: &GpuEngine,
    next: &lancet::model::PackedModel,
    diff: &lancet::model::ModelDiff,
) -> Vec<LayoutArray> {
    let mut layout = engine.layout().clone();
    layout.patch(next, diff).unwrap();
    LayoutArray::ALL
        .into_iter()
        .filter(|&a| {
            engine
                .buffer_size(a)
                .is_some_and(|room| layout.array(a).len() as u64 > room)
        })
        .collect()
}

/// The smallest floating ring (each node joined to the next `reach`) whose nodes make some
/// array outgrow its device buffer, with the model after it and the arrays that outgrow.
fn smallest_outgrowing_ring(
    engine: &GpuEngine,
    model: &lancet::model::PackedModel,
    reach: usize,
) -> (
    lancet::model::ModelDiff,
    lancet::model::PackedModel,
    Vec<LayoutArray>,
) {
    for n in 2 * reach + 1..2000 {
        let diff = floating_ring(model, n, reach);
        let mut next = model.clone();
        next.apply(&diff).unwrap();
        let outgrown = outgrown_by(engine, &next, &diff);
        if !outgrown.is_empty() {
            return (diff, next, outgrown);
        }
    }
    panic!("no ring of up to 2000 nodes outgrows a buffer");
}

/// A patch that makes layout arrays outgrow their device buffers grows those buffers alone: the
/// passes keep their pipelines (not `reallocated`), the old contents are copied on the device
/// and only the dirty ranges and the new tails go up (less than the layout), the device then
/// holds exactly the layout, and the engine steps like its CPU twin and like one built from
/// scratch; so does it after a random cut-like patch on top (which the valence layout's
/// appended buckets may make grow again). The ring's `reach` sets which
/// arrays outgrow first: one (the edge layout's springs alone with `reach` 2), or, for the
/// edge gather with `reach` 1, its springs and incidence at once.
#[rstest]
#[case::connectivity(LayoutKind::Connectivity, Accumulation::Gather, 1, 1)]
#[case::valence(LayoutKind::Valence, Accumulation::Gather, 1, 1)]
#[case::edges(LayoutKind::Edges, Accumulation::Gather, 2, 1)]
#[case::edges_two_at_once(LayoutKind::Edges, Accumulation::Gather, 1, 2)]
#[case::edges_fixed_point(LayoutKind::Edges, Accumulation::AtomicFixed, 1, 1)]
fn buffers_outgrown_by_a_patch_grow_alone_and_the_passes_are_kept(
    #[case] kind: LayoutKind,
    #[case] accumulation: Accumulation,
    #[case] reach: usize,
    #[case] arrays: usize,
) {
    let Some(ctx) = common::gpu() else { return };
    let mut model = random_model(47, true);
    let config = SimConfig::new(2e-5);
    let options = GpuOptions {
        layout: kind,
        accumulation,
    };
    let mut engine = GpuEngine::with_context(ctx, &model, config, options).unwrap();
    let (x, v) = random_state(&model, 47);
    engine.set_state(&x, &v);
    engine.step(5);
    let capacity = engine.state_capacity();
    let (ring, next, outgrown) = smallest_outgrowing_ring(&engine, &model, reach);
    assert_eq!(outgrown.len(), arrays, "{kind:?}: {outgrown:?} outgrow");
    let rooms: Vec<u64> = outgrown
        .iter()
        .map(|&a| engine.buffer_size(a).unwrap())
        .collect();
    for (round, diff) in [ring, random_diff(&next, 300)].into_iter().enumerate() {
        let mut after = model.clone();
        after.apply(&diff).unwrap();
        let cost = engine.patch(&after, &diff).unwrap();
        model = after;
        assert_eq!(engine.state_capacity(), capacity, "the node state had room");
        assert!(!cost.reallocated, "round {round}: the passes were rebuilt");
        assert!(
            cost.uploaded_bytes < cost.layout_bytes,
            "round {round}: uploaded {} of {}",
            cost.uploaded_bytes,
            cost.layout_bytes
        );
        if round == 0 {
            for (&a, &room) in outgrown.iter().zip(&rooms) {
                assert!(engine.buffer_size(a).unwrap() > room, "{a:?} grew");
            }
            assert_eq!(cost.buffers_grown, arrays, "{outgrown:?} alone grew");
            assert!(
                cost.copied_bytes > 0,
                "the old contents moved on the device"
            );
        }
        assert_eq!(engine.device_differences().unwrap(), Vec::<String>::new());
        steps_like_twin_and_rebuild(&mut engine, &model, config, accumulation, round);
    }
}

/// A change of time step on the device: the step parameters change and, under Verlet, the
/// last steps become `d h'/h` (the velocity kept), bit for bit as
/// the pass's CPU twin computes it where the device rounds like the CPU; the current
/// displacements and symplectic Euler's state do not change. Afterwards the engine steps like
/// its twin and bit for bit like an engine built at the new step from the same raw state: the
/// step reads nothing of the old one. Nothing but the 64-byte uniform is uploaded.
#[rstest]
fn a_time_step_change_rescales_like_its_twin_and_steps_like_a_rebuild(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = random_model(62, true);
    let mut config = SimConfig::new(2e-5);
    config.integrator = integrator;
    let mut engine = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
    let (x, v) = random_state(&model, 62);
    engine.set_state(&x, &v);
    engine.step(7);
    for (round, dt) in [7.4e-6, 1.9e-5].into_iter().enumerate() {
        let (cur, mut second) = engine.raw_state().unwrap();
        let before = second.clone();
        let rescale = (dt / config.dt) as f32;
        let cost = engine.set_time_step(dt).unwrap();
        assert_eq!(cost.uploaded_bytes, 64);
        assert_eq!(engine.step_params().h, dt as f32);
        let (cur_after, second_after) = engine.raw_state().unwrap();
        assert_eq!(
            bits(&cur_after),
            bits(&cur),
            "round {round}: displacements moved"
        );
        if integrator == Integrator::Verlet {
            lancet::physics::rescale_previous(&cur, &mut second, rescale);
            assert_ne!(
                bits(&second),
                bits(&before),
                "round {round}: nothing to rescale"
            );
        }
        common::assert_twin(
            &second_after,
            &second,
            &before,
            1,
            &format!("round {round}: the rescaled second state"),
        );
        config.dt = dt;
        steps_like_twin_and_rebuild(&mut engine, &model, config, Accumulation::Gather, round);
    }
}

//! Reading ahead (`Engine::prefetch_near`, `Simulation::prefetch_near`): the step before a cut
//! finds the nodes in a box as its last pass and starts reading them back, so that the cut's
//! read needs no round trip of its own. A read served that way must be the read a round trip
//! gives, bit for bit, in every layout and after cut-like patches; it must never be served
//! once the state has changed (a further step, a position correction, a patch) or for a box
//! the read ahead does not hold; and a cut that reads ahead must cut exactly as one that does
//! not.

use crate::{common, models, read_ahead};
use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, EngineKind, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{Material, ModelConfig, PackedModel, SpringModel};
use models::{boxes_near, random_diff, random_model, random_state, Rng};
use nalgebra::Isometry3;
use read_ahead::{holds_the_box, reads_ahead_as_on_its_own, Found};
use rstest::rstest;

fn engine_on(model: &PackedModel, kind: LayoutKind) -> Option<GpuEngine> {
    let ctx = common::gpu()?;
    let mut engine = GpuEngine::with_context(ctx, model, SimConfig::new(2e-5), kind).unwrap();
    let (x, v) = random_state(model, 7);
    engine.set_state(&x, &v);
    engine.set_surface(&[[0, 1, 2]]).unwrap();
    Some(engine)
}

#[rstest]
fn a_read_ahead_gives_what_a_read_of_its_own_gives(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let model = random_model(7, false);
    let Some(mut engine) = engine_on(&model, kind) else {
        return;
    };
    reads_ahead_as_on_its_own(&mut engine, model, 5);
}

/// The nodes in `inner`, read with a round trip of their own (no read ahead served), checked
/// against a full readback.
fn read_afresh(engine: &mut GpuEngine, inner: [[f64; 3]; 2]) -> Found {
    let before = engine.near_reads();
    let got = engine.nodes_near(inner[0], inner[1]).unwrap();
    assert_eq!(
        engine.near_reads().ahead,
        before.ahead,
        "a stale read was served"
    );
    holds_the_box(engine, inner, &got);
    got
}

#[test]
fn a_read_ahead_is_not_served_once_the_state_changed_or_for_a_box_it_does_not_hold() {
    let model = random_model(9, false);
    let Some(mut engine) = engine_on(&model, LayoutKind::Valence) else {
        return;
    };
    let mut rng = Rng(17);
    let (inner, outer) = boxes_near(&mut rng, &engine.positions());

    // A second step: the read ahead saw the state before it.
    engine.prefetch_near(outer[0], outer[1]);
    engine.step(1);
    engine.step(1);
    read_afresh(&mut engine, inner);

    // A position correction after the step: a node moved into the box must be found.
    let x = engine.positions();
    let inside = |p: &[f64; 3]| (0..3).all(|c| p[c] >= inner[0][c] && p[c] <= inner[1][c]);
    let outside = (0..x.len() as u32)
        .find(|&i| !inside(&x[i as usize]) && !model.fixed[i as usize])
        .expect("a free node outside the box");
    let centre = [0, 1, 2].map(|c| 0.5 * (inner[0][c] + inner[1][c]));
    engine.prefetch_near(outer[0], outer[1]);
    engine.step(1);
    engine.correct_positions(&[outside], &[centre]).unwrap();
    let got = read_afresh(&mut engine, inner);
    assert!(
        got.iter().any(|e| e.0 == outside),
        "the moved node is found"
    );

    // The state replaced after the step (set_state, set_raw_state): a read must see the new
    // state.
    let (x, v) = random_state(&model, 23);
    engine.prefetch_near(outer[0], outer[1]);
    engine.step(1);
    engine.set_state(&x, &v);
    read_afresh(&mut engine, inner);
    let raw = engine.raw_state().unwrap();
    engine.prefetch_near(outer[0], outer[1]);
    engine.step(3);
    engine.set_raw_state(&raw.0, &raw.1).unwrap();
    read_afresh(&mut engine, inner);

    // A patch after the step.
    let diff = random_diff(&model, 41);
    let mut next = model.clone();
    next.apply(&diff).unwrap();
    engine.prefetch_near(outer[0], outer[1]);
    engine.step(1);
    engine.patch(&next, &diff).unwrap();
    read_afresh(&mut engine, inner);

    // A box the read ahead does not hold: the outer box read ahead, the inner one's
    // neighbour asked for.
    engine.prefetch_near(inner[0], inner[1]);
    engine.step(1);
    let before = engine.near_reads();
    let got = engine.nodes_near(outer[0], outer[1]).unwrap();
    assert_eq!(
        engine.near_reads().ahead,
        before.ahead,
        "a box it does not hold"
    );
    assert_eq!(engine.near_reads().direct, before.direct + 1);
    holds_the_box(&engine, outer, &got);
}

/// The box from the benchmark's blade, a 14-cell box fixed at its base.
fn cutting(method: CutMethod, kind: EngineKind, layout: LayoutKind) -> (Simulation, Cutter) {
    let mesh = BoxGrid::cube_cells([14, 14, 7], 0.01).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(5e3, 0.3, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.fixed = vec![lancet::model::FixedSelector::Box {
        min: [-1.0; 3],
        max: [1.0, 1.0, 1e-9],
    }];
    let model = SpringModel::build(&mesh, &config).unwrap();
    let packed = model.pack(&mesh).unwrap();
    let dt = 0.5 * lancet::model::stable_time_step(&packed).dt;
    let sim_config = SimConfig {
        check_every: 3,
        ..SimConfig::new(dt)
    };
    let mut sim = Simulation::with_gpu(packed, kind, sim_config, layout.into()).unwrap();
    let cutter = Cutter::new(mesh, model, method).unwrap();
    sim.set_surface(cutter.surface()).unwrap();
    (sim, cutter)
}

/// A blade drawn 4 cm down into the sagging box in ten events, ten steps (four checked chunks)
/// before each: reading ahead with the steps cuts exactly as reading after them, and every
/// read but none is served by the steps.
#[rstest]
fn a_cut_that_reads_ahead_cuts_as_one_that_does_not(
    #[values(CutMethod::Separate, CutMethod::Subdivide, CutMethod::Remove)] method: CutMethod,
) {
    if common::gpu().is_none() {
        return;
    }
    let blade = ToolShape::Blade {
        width: 0.03,
        length: 0.1,
        thickness: 2e-4,
    };
    let pose = |z: f64| Isometry3::translation(0.064, 0.073, z);
    let (mut a, mut cut_a) = cutting(method, EngineKind::Gpu, LayoutKind::Edges);
    let (mut b, mut cut_b) = cutting(method, EngineKind::Gpu, LayoutKind::Edges);
    let mut changed = 0;
    for k in 0..10 {
        let z = 0.071 - 0.004 * k as f64;
        let sweep = Sweep::of_blade(&blade, &pose(z), &pose(z - 0.004)).unwrap();
        let (lo, hi) = cut_a.reading_box_ahead(&sweep, 1e-3).unwrap();
        a.prefetch_near(lo, hi);
        a.run(10).unwrap();
        b.run(10).unwrap();
        let oa = cut_a.cut_from(&sweep, &mut a).unwrap();
        let ob = cut_b.cut_from(&sweep, &mut b).unwrap();
        assert_eq!(oa.diff, ob.diff, "event {k}: the same change");
        assert_eq!(oa.surface, ob.surface, "event {k}: the same surface edit");
        if !oa.is_empty() {
            changed += 1;
            a.apply_at(&oa.diff, true, cut_a.positions_read().positions())
                .unwrap();
            b.apply_at(&ob.diff, true, cut_b.positions_read().positions())
                .unwrap();
            a.edit_surface(&oa.surface).unwrap();
            b.edit_surface(&ob.surface).unwrap();
        }
    }
    assert!(changed >= 3, "the blade cut in {changed} of 10 events");
    assert_eq!(a.near_reads().ahead, 10, "every read came with the steps");
    assert_eq!(b.near_reads().ahead, 0);
    assert_eq!(cut_a.mesh().tet_count(), cut_b.mesh().tet_count());
}

/// A read ahead that finds more nodes than the output holds is not served (nothing is
/// dropped): the read of its own grows the output, and the next read ahead, with the room
/// that made, is served whole.
#[test]
fn a_read_ahead_past_the_output_room_reads_again_and_the_next_one_fits() {
    // 19^3 = 6,859 nodes: more than the pass first has room for (2,048 entries, rounded up
    // to a size class: 4,095).
    let mesh = BoxGrid::cube_cells([18, 18, 18], 0.01).build().unwrap();
    let model = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(5e3, 0.3, 1e3)))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let Some(mut engine) = engine_on(&model, LayoutKind::Connectivity) else {
        return;
    };
    let all = [[-1.0; 3], [1.0; 3]];
    for round in 0..2 {
        engine.prefetch_near(all[0], all[1]);
        engine.step(1);
        let before = engine.near_reads();
        let got = engine.nodes_near(all[0], all[1]).unwrap();
        assert_eq!(holds_the_box(&engine, all, &got), model.rest.len());
        assert_eq!(got.len(), model.rest.len());
        let after = engine.near_reads();
        if round == 0 {
            assert_eq!(
                (after.ahead, after.direct),
                (before.ahead, before.direct + 1)
            );
        } else {
            assert_eq!(
                (after.ahead, after.direct),
                (before.ahead + 1, before.direct)
            );
        }
    }
}

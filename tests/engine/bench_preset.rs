//! `lancet bench --preset`: the mass-spring benchmark of Warp, Newton and Taichi users, built
//! as their `add_soft_grid` builds it, so that `benches/peers/` times the same model.

use lancet::mesh::generate::TetSplit;
use lancet::model::stable_time_step;
use lancet::report::bench::{BenchMesh, BenchOptions, Preset};
use lancet::EngineKind;

/// The small preset grid's model, as the bench builds it.
fn small(preset: Preset) -> lancet::PackedModel {
    let BenchMesh::Grid { cells, cell, split } = Preset::meshes(TetSplit::Five)[0].clone() else {
        panic!("the preset's meshes are grids");
    };
    let mesh = lancet::mesh::generate::BoxGrid {
        split,
        ..lancet::mesh::generate::BoxGrid::cube_cells(cells, cell)
    }
    .build()
    .unwrap();
    preset.model(&mesh).unwrap()
}

#[test]
fn the_preset_is_warps_soft_grid_with_the_peers_parameters() {
    let model = small(Preset::Damped);
    // Warp's add_soft_grid on 40 x 20 x 20 cells: 41 * 21 * 21 nodes, and 102,080 unique tet
    // edges (the count its builder gives, and `benches/peers/peers.py` rebuilds in numpy).
    assert_eq!(model.node_count(), 41 * 21 * 21);
    assert_eq!(model.springs().len(), 102_080);
    // Every spring holds the whole stiffness and damping, whatever number of tets share it.
    for s in model.springs() {
        assert!(
            (s.stiffness - Preset::STIFFNESS).abs() < 1e-9 * Preset::STIFFNESS,
            "{s:?}"
        );
        assert!((s.damping - Preset::DAMPING).abs() < 1e-12, "{s:?}");
    }
    for &m in &model.mass {
        assert!((m - Preset::MASS).abs() < 1e-12, "{m}");
    }
    // The face x = 0 is fixed: 21 * 21 nodes.
    assert_eq!(model.fixed.iter().filter(|&&f| f).count(), 21 * 21);
    // The peers' step is stable for this model, so the bench does not refuse it.
    assert!(Preset::DT < stable_time_step(&model).dt);
    let undamped = small(Preset::Undamped);
    assert!(undamped.springs().iter().all(|s| s.damping == 0.0));
}

#[test]
fn the_preset_bench_runs_the_peers_step_and_agrees_with_the_reference() {
    let opts = BenchOptions {
        engines: vec![EngineKind::Reference, EngineKind::Fast],
        steps: 20,
        chunk: 10,
        integrator: lancet::Integrator::SymplecticEuler,
        preset: Some(Preset::Damped),
        ..Default::default()
    };
    let mesh = BenchMesh::Grid {
        cells: [8, 4, 4],
        cell: Preset::CELL,
        split: TetSplit::Five,
    };
    let bw = lancet::report::bandwidth::stream_triad(1 << 16, 1);
    let report = lancet::report::bench::run_bench(&[mesh], &opts, &bw, || None).unwrap();
    assert_eq!(report.rows.len(), 2);
    assert_eq!(report.rows[0].mesh, "8x4x4-5tet");
    // Float32 against float64 after the same 20 steps of the sagging, damped grid.
    let fast = &report.rows[1];
    assert!(fast.error_vs_reference < 1e-4, "{fast:?}");
}

//! What a cut does to the motion: nothing jumps. Tissue under a uniform stretch, expanding at a
//! uniform rate, is cut by subdividing; every node the cut makes (on an edge, or a copy) must
//! start where the deformed tissue puts it, so every spring, old or new, still has the
//! stretch's strain, and every node still has the expansion's velocity. A node started with the
//! state of the nearer end of its edge is off by up to half an edge times the strain, which
//! these checks see.

use crate::common;
use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::engine::{EngineKind, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, Material, ModelConfig, SpringModel};
use nalgebra::Isometry3;
use rstest::rstest;

/// Stretch of every direction.
const STRAIN: f64 = 0.05;
/// Expansion rate, 1/s: the velocity at `x` is `RATE * (x - CENTRE)` (rest coordinates).
const RATE: f64 = 2.0;
const CENTRE: [f64; 3] = [0.02, 0.02, 0.02];

fn affine(p: [f64; 3], scale: f64) -> [f64; 3] {
    [0, 1, 2].map(|c| CENTRE[c] + scale * (p[c] - CENTRE[c]))
}

fn cut_stretched_box(kind: EngineKind, layout: LayoutKind) {
    let mesh = BoxGrid::cube_cells([4, 4, 4], 0.01).build().unwrap();
    let config = ModelConfig::new(Material::elastic(3e3, 0.3, 1000.0));
    let model = SpringModel::build(&mesh, &config).unwrap();
    let packed = model.pack(&mesh).unwrap();
    let sim_config = SimConfig {
        allow_unstable: true,
        ..SimConfig::new(0.4 * stable_time_step(&packed).dt)
    };
    let mut sim = Simulation::with_gpu(packed, kind, sim_config, layout.into()).unwrap();
    let rest = sim.model().rest.clone();
    let x: Vec<[f64; 3]> = rest.iter().map(|&p| affine(p, 1.0 + STRAIN)).collect();
    let v: Vec<[f64; 3]> = rest
        .iter()
        .map(|&p| [0, 1, 2].map(|c| RATE * (p[c] - CENTRE[c])))
        .collect();
    sim.set_state(&x, &v).unwrap();
    let mut cutter = Cutter::new(mesh, model, CutMethod::Subdivide).unwrap();

    // An upright blade off the grid, drawn down through the whole box (stretched), then a
    // second one across it: nodes on edges, and copies of them where faces open.
    let blade = ToolShape::Blade {
        width: 0.1,
        length: 0.1,
        thickness: 1e-4,
    };
    let sweeps = [
        Sweep::of_blade(
            &blade,
            &Isometry3::translation(0.02, 0.0237, 0.07),
            &Isometry3::translation(0.02, 0.0237, -0.03),
        ),
        Sweep::of_blade(
            &blade,
            &Isometry3::new([0.0163, 0.02, 0.07].into(), [0.0, 0.0, 0.5].into()),
            &Isometry3::new([0.0163, 0.02, -0.03].into(), [0.0, 0.0, 0.5].into()),
        ),
    ];
    let (mut blended, mut copies) = (0, 0);
    for sweep in sweeps {
        let positions = sim.positions();
        let outcome = cutter.cut(&sweep.unwrap(), &positions).unwrap();
        assert!(
            outcome.nodes_added > 0,
            "{kind:?} {layout:?}: the blade cut"
        );
        blended += outcome
            .diff
            .added_nodes
            .iter()
            .filter(|a| a.blend.is_some())
            .count();
        copies += outcome
            .diff
            .added_nodes
            .iter()
            .filter(|a| a.blend.is_none())
            .count();
        sim.apply_at(&outcome.diff, true, &positions).unwrap();
    }
    assert!(
        blended > 0 && copies > 0,
        "{blended} on edges, {copies} copies"
    );

    let m = sim.model();
    let (x, v) = (sim.positions(), sim.velocities());
    // Float32 engines hold displacements of about 1 mm to 1e-10 m.
    let tol = if kind == EngineKind::Reference {
        1e-9
    } else {
        1e-5
    };
    let mut worst = 0.0f64;
    for s in m.springs() {
        let [a, b] = s.nodes.map(|i| x[i as usize]);
        let l = (0..3).map(|c| (b[c] - a[c]).powi(2)).sum::<f64>().sqrt();
        worst = worst.max((l / s.rest_length - 1.0 - STRAIN).abs());
    }
    assert!(
        worst < tol,
        "{kind:?} {layout:?}: a spring's strain is {worst:e} off the stretch's {STRAIN}"
    );
    // The velocity the expansion gives each node's rest point; float32 Verlet velocities are
    // differences of displacements, good to about 1e-5 m/s here.
    let speed = RATE * 0.02 * 3f64.sqrt();
    let off = (0..m.node_count())
        .map(|i| {
            let want = [0, 1, 2].map(|c| RATE * (m.rest[i][c] - CENTRE[c]));
            (0..3)
                .map(|c| (v[i][c] - want[c]).abs())
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    assert!(
        off < 1e-3 * speed,
        "{kind:?} {layout:?}: a node's velocity is {off:e} m/s off the expansion's"
    );
}

#[rstest]
fn subdivided_nodes_start_on_the_deformed_tissue_on_the_cpu(
    #[values(EngineKind::Reference, EngineKind::Fast)] kind: EngineKind,
) {
    cut_stretched_box(kind, LayoutKind::Connectivity);
}

#[rstest]
fn subdivided_nodes_start_on_the_deformed_tissue_on_the_gpu(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    cut_stretched_box(EngineKind::Gpu, layout);
}

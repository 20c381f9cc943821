//! Random sequences of cuts, on generated boxes (both tet splits) and the liver, with every
//! method and every layout: after each cut all invariants hold, the packed model kept up to date
//! by diffs equals the cutter's spring model, every layout patched by the diffs equals (or steps
//! like) a fresh packing, and the same sequence gives the same topology twice. Nothing panics.

#[path = "common/models.rs"]
mod models;

use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::engine::gpu::step_params;
use lancet::engine::SimConfig;
use lancet::layout::{LayoutKind, NodeOrder, PackedLayout};
use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::model::{Material, ModelConfig, PackedModel, SpringModel};
use lancet::TetMesh;
use models::{fresh, Rng};
use nalgebra::{Isometry3, Point3, Vector3};
use rstest::rstest;

fn random_box(rng: &mut Rng) -> TetMesh {
    let cells = [
        3 + (rng.next() * 3.0) as usize,
        3 + (rng.next() * 3.0) as usize,
        3,
    ];
    BoxGrid {
        cells,
        size: [0.03 + 0.02 * rng.next(), 0.03 + 0.02 * rng.next(), 0.03],
        origin: [rng.next() * 0.01, -0.02, 0.1],
        split: if rng.next() < 0.5 {
            TetSplit::Five
        } else {
            TetSplit::Six
        },
    }
    .build()
    .unwrap()
}

/// A random blade pose crossing the mesh's bounds, and where it moves in 1 to 3 steps: along
/// its own -z (edge first) from outside the bounds to a random depth, sometimes sideways too.
fn random_strokes(rng: &mut Rng, lo: Point3<f64>, hi: Point3<f64>) -> Vec<Isometry3<f64>> {
    let size = (hi - lo).norm();
    let axis = Vector3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5);
    let rotation = axis.normalize() * (rng.next() * 3.0);
    let centre = lo + (hi - lo).component_mul(&Vector3::new(rng.next(), rng.next(), rng.next()));
    let start = Isometry3::new(Vector3::zeros(), rotation);
    let down = start * Vector3::z();
    let side = start * Vector3::x();
    // Edge starts a body size above the centre, along the blade's own axis.
    let from = centre.coords + down * size;
    let depth = size * (0.5 + 1.5 * rng.next());
    let slide = if rng.next() < 0.3 {
        size * (rng.next() - 0.5)
    } else {
        0.0
    };
    let steps = 1 + (rng.next() * 3.0) as usize;
    (0..=steps)
        .map(|k| {
            let s = k as f64 / steps as f64;
            Isometry3::new(from - down * depth * s + side * slide * s, rotation)
        })
        .collect()
}

/// Current positions: rest plus a smooth random deformation (a tenth of the size at most).
fn deformed(mesh: &TetMesh, rng: &mut Rng) -> Vec<[f64; 3]> {
    let (lo, hi) = mesh.bounds().unwrap();
    let size = (hi - lo).norm();
    let a = Vector3::new(rng.next(), rng.next(), rng.next()) * 0.05;
    mesh.nodes()
        .map(|(_, n)| {
            let p = n.rest;
            let q = (p - lo) / size;
            let d = Vector3::new(
                (q.y * 3.0).sin() * a.x,
                (q.z * 3.0).sin() * a.y,
                (q.x * 3.0).sin() * a.z,
            );
            (p + d * size).coords.into()
        })
        .collect()
}

/// The packed model kept by diffs carries exactly the cutter's springs and masses.
fn assert_packed_matches(packed: &PackedModel, cutter: &Cutter) {
    let model = cutter.model();
    assert_eq!(packed.springs.len(), model.spring_count());
    for (_, s) in model.springs() {
        let (a, b) = (
            cutter.dense_index(s.nodes[0]).unwrap(),
            cutter.dense_index(s.nodes[1]).unwrap(),
        );
        let i = packed.spring_index(a, b).expect("every spring is packed");
        let p = packed.springs[i];
        assert_eq!(
            (p.rest_length, p.stiffness, p.damping),
            (s.rest_length, s.stiffness, s.damping)
        );
    }
    for (k, _) in cutter.mesh().nodes() {
        let i = cutter.dense_index(k).unwrap() as usize;
        match model.mass(k) {
            Some(m) => {
                assert_eq!(packed.mass[i], m);
                assert_eq!(packed.fixed[i], model.is_fixed(k));
            }
            // Retired (carved away): kept fixed, without springs.
            None => assert!(packed.fixed[i]),
        }
    }
}

/// The tets as dense corner indices, for comparing topologies.
fn topology(cutter: &Cutter) -> Vec<[u32; 4]> {
    cutter
        .mesh()
        .tets()
        .map(|(_, t)| t.nodes.map(|k| cutter.dense_index(k).unwrap()))
        .collect()
}

/// Run a random sequence of cuts, checking every invariant after each (no tet below `floor`
/// among them). Returns the cutter and how many cuts changed the mesh.
fn run_sequence(seed: u64, method: CutMethod, mesh: TetMesh, floor: f64) -> (Cutter, usize) {
    let mut rng = Rng(seed);
    let volume = mesh.volume();
    let mut config = ModelConfig::new(Material::elastic(3e3, 0.3, 1000.0));
    config.fixed = vec![lancet::model::FixedSelector::Box {
        min: [-1e9; 3],
        max: [1e9, 1e9, mesh.bounds().unwrap().0.z + 1e-9],
    }];
    let model = SpringModel::build(&mesh, &config).unwrap();
    let mut packed = model.pack(&mesh).unwrap();
    let mut layouts: Vec<PackedLayout> = [
        LayoutKind::Connectivity,
        LayoutKind::Valence,
        LayoutKind::Edges,
    ]
    .into_iter()
    .map(|k| PackedLayout::pack(&packed, k, NodeOrder::locality(&packed)).unwrap())
    .collect();
    let (lo, hi) = mesh.bounds().unwrap();
    let mut cutter = Cutter::new(mesh, model, method)
        .unwrap()
        .with_quality_floor(floor);
    let size = (hi - lo).norm();
    let blade = ToolShape::Blade {
        width: size * (0.2 + 0.8 * rng.next()),
        length: 4.0 * size,
        thickness: 1e-3 * size,
    };
    let mut cuts = 0;
    for _ in 0..4 {
        let poses = random_strokes(&mut rng, lo, hi);
        for w in poses.windows(2) {
            let positions = deformed(cutter.mesh(), &mut Rng(seed));
            let sweep = Sweep::of_blade(&blade, &w[0], &w[1]).unwrap();
            let outcome = cutter.cut(&sweep, &positions).unwrap();
            if outcome.is_empty() {
                continue;
            }
            cuts += 1;
            packed.apply(&outcome.diff).unwrap();
            assert_packed_matches(&packed, &cutter);
            let report = cutter.check_invariants(volume, floor);
            assert!(report.passed(), "seed {seed} {method}: {report:#?}");
            for layout in &mut layouts {
                layout.patch(&packed, &outcome.diff).unwrap();
                match layout {
                    PackedLayout::Edges(_) => {
                        // The spring pool keeps dead records: step both and compare.
                        let rebuilt = fresh(&packed, layout);
                        let p = step_params(&packed, SimConfig::new(1e-5));
                        let mut r = Rng(seed ^ 7);
                        let state: Vec<[f32; 4]> = (0..layout.node_slots())
                            .map(|_| [1e-4 * r.next() as f32, 1e-4 * r.next() as f32, 0.0, 0.0])
                            .collect();
                        let (a, _) = layout.step_cpu(&p, &state, &state);
                        let (b, _) = rebuilt.step_cpu(&p, &state, &state);
                        for (x, y) in a.iter().zip(&b) {
                            for c in 0..3 {
                                assert!((x[c] - y[c]).abs() <= 1e-6 * y[c].abs().max(1e-6));
                            }
                        }
                    }
                    _ => assert!(*layout == fresh(&packed, layout), "{method} seed {seed}"),
                }
            }
        }
    }
    (cutter, cuts)
}

#[rstest]
fn random_cut_sequences_keep_every_invariant(
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
    #[values(1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)] seed: u64,
) {
    let mesh = random_box(&mut Rng(seed * 977));
    let (a, cuts) = run_sequence(seed, method, mesh.clone(), 0.0);
    // The same sequence again gives the same topology, node for node.
    let (b, _) = run_sequence(seed, method, mesh, 0.0);
    assert_eq!(topology(&a), topology(&b));
    eprintln!(
        "seed {seed} {method}: {cuts} cuts, {} tets, {} fragments",
        a.mesh().tet_count(),
        a.mesh().component_count()
    );
}

#[rstest]
fn random_cuts_of_the_liver_keep_every_invariant(
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
    #[values(31, 32, 33)] seed: u64,
) {
    let Some(dir) = std::env::var_os("LANCET_MESH_DIR") else {
        eprintln!("skipped: LANCET_MESH_DIR is not set");
        return;
    };
    let path = std::path::Path::new(&dir).join("sofa/liver.msh");
    let mesh = lancet::mesh::io::read(&path).unwrap().mesh;
    let (cutter, cuts) = run_sequence(seed, method, mesh, 0.0);
    assert!(cuts > 0, "seed {seed}: no stroke met the liver");
    assert!(cutter.mesh().tet_count() > 0 || method == CutMethod::Remove);
}

#[rstest]
fn random_subdividing_of_the_liver_keeps_to_a_quality_floor(#[values(31, 32, 33)] seed: u64) {
    let Some(dir) = std::env::var_os("LANCET_MESH_DIR") else {
        eprintln!("skipped: LANCET_MESH_DIR is not set");
        return;
    };
    let path = std::path::Path::new(&dir).join("sofa/liver.msh");
    let mesh = lancet::mesh::io::read(&path).unwrap().mesh;
    // The liver has tets below FLOOR of its own: a floor just under its worst.
    let worst = mesh.min_volume_length_ratio();
    let (_, cuts) = run_sequence(seed, CutMethod::Subdivide, mesh, 0.9 * worst);
    assert!(cuts > 0, "seed {seed}: no stroke met the liver");
}

/// Counted over all seeds, the sequences cut something: the test is not vacuous.
#[test]
fn random_sequences_do_cut() {
    let total: usize = (1..=12)
        .map(|seed| {
            run_sequence(
                seed,
                CutMethod::Separate,
                random_box(&mut Rng(seed * 977)),
                0.0,
            )
            .1
        })
        .sum();
    assert!(total >= 12, "only {total} cuts in 12 sequences");
}

/// The smallest rest volume-length ratio subdividing may make in the sequences below (0.3 is
/// tried too); the generated boxes' own tets are all above 0.35.
const FLOOR: f64 = 0.2;

/// Nodes at rest positions `uncut` has no node at: the nodes splitting made.
fn made_nodes(uncut: &TetMesh, cutter: &Cutter) -> usize {
    let key = |p: &Point3<f64>| [p.x, p.y, p.z].map(f64::to_bits);
    let old: std::collections::BTreeSet<[u64; 3]> =
        uncut.nodes().map(|(_, n)| key(&n.rest)).collect();
    let made: std::collections::BTreeSet<[u64; 3]> = cutter
        .mesh()
        .nodes()
        .map(|(_, n)| key(&n.rest))
        .filter(|k| !old.contains(k))
        .collect();
    made.len()
}

#[rstest]
fn random_subdivide_sequences_keep_to_the_quality_floor(
    #[values(1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)] seed: u64,
    #[values(FLOOR, 0.3)] floor: f64,
) {
    let mesh = random_box(&mut Rng(seed * 977));
    let uncut = mesh.clone();
    // Every invariant after every cut, the floor among them.
    let (a, cuts) = run_sequence(seed, CutMethod::Subdivide, mesh.clone(), floor);
    let (b, _) = run_sequence(seed, CutMethod::Subdivide, mesh.clone(), floor);
    assert_eq!(topology(&a), topology(&b));
    let (without, _) = run_sequence(seed, CutMethod::Subdivide, mesh, 0.0);
    let quality = |c: &Cutter| c.check_invariants(uncut.volume(), 0.0).min_quality;
    eprintln!(
        "seed {seed}, floor {floor}: {cuts} cuts; lowest quality {:.3} with the floor, {:.3} \
         without; nodes \
         made {} with, {} without; {} and {} fragments",
        quality(&a),
        quality(&without),
        made_nodes(&uncut, &a),
        made_nodes(&uncut, &without),
        a.mesh().component_count(),
        without.mesh().component_count()
    );
}

/// The floor is not vacuous: without it, the same sequences make tets below it.
#[test]
fn without_the_floor_random_subdivide_sequences_go_below_it() {
    let lowest = (1..=12)
        .map(|seed| {
            let mesh = random_box(&mut Rng(seed * 977));
            let volume = mesh.volume();
            let (c, _) = run_sequence(seed, CutMethod::Subdivide, mesh, 0.0);
            c.check_invariants(volume, 0.0).min_quality
        })
        .fold(f64::INFINITY, f64::min);
    assert!(lowest < FLOOR, "lowest quality without the floor {lowest}");
}

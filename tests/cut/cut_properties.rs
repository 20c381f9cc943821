//! Random sequences of cuts, on generated boxes (both tet splits) and the liver, with every
//! method and every layout: after each cut all invariants hold, the packed model kept up to date
//! by diffs equals the cutter's spring model, every layout patched by the diffs equals (or steps
//! like) a fresh packing, and the same sequence gives the same topology twice. Nothing panics.
//!
//! The first sequences classify every cut at one deformation. The others move the tissue
//! between sweeps (a smooth displacement of a few percent of a cell, new for each sweep, now
//! and then a large one), as a simulation would give the positions, with the quality floor
//! users get; they sweep earlier strokes again, tremble the blade at a stroke's end and repeat
//! every sweep at once, which must cut nothing new. The defects those sequences found are kept
//! fixed by `cut_blade_defects.rs`.

use crate::models;
use std::collections::BTreeSet;

use lancet::collide::ToolShape;
use lancet::cut::subdivide::DEFAULT_QUALITY_FLOOR;
use lancet::cut::{CutMethod, CutOutcome, Cutter, Sweep};
use lancet::engine::gpu::step_params;
use lancet::engine::SimConfig;
use lancet::layout::{LayoutKind, NodeOrder, PackedLayout};
use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::mesh::quality::tet_quality;
use lancet::model::{Material, ModelConfig, ModelDiff, PackedModel, SpringModel};
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

/// A smooth random displacement: three sine waves of wavelength one to two body sizes, along
/// random directions, their amplitudes summing to `amplitude` (so no node moves further, and
/// the displacement gradient stays below `2 pi amplitude / size`).
struct Field([(Vector3<f64>, Vector3<f64>, f64); 3]);

impl Field {
    fn random(rng: &mut Rng, size: f64, amplitude: f64) -> Self {
        let unit = |rng: &mut Rng| loop {
            let v = Vector3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5);
            if v.norm() > 0.1 {
                break v.normalize();
            }
        };
        Field([(); 3].map(|_| {
            let wave = unit(rng) * (std::f64::consts::TAU / (size * (1.0 + rng.next())));
            let along = unit(rng) * (amplitude / 3.0);
            (wave, along, std::f64::consts::TAU * rng.next())
        }))
    }

    fn at(&self, p: &Point3<f64>) -> Vector3<f64> {
        self.0
            .iter()
            .map(|(k, a, phase)| a * (k.dot(&p.coords) + phase).sin())
            .sum()
    }
}

/// Current positions, dense order, of tissue displaced by `field`: fixed nodes (the base, and
/// nodes carving left without tets) stay at rest, as the engines hold them.
fn displaced(packed: &PackedModel, field: &Field) -> Vec<[f64; 3]> {
    packed
        .rest
        .iter()
        .zip(&packed.fixed)
        .map(|(r, &fixed)| {
            let p = Point3::from(*r);
            if fixed {
                *r
            } else {
                (p + field.at(&p)).coords.into()
            }
        })
        .collect()
}

/// `positions` with the nodes `diff` added appended where the engines start them: at their rest
/// position displaced as their source node is (mixed with its blend partner's), so that a copy
/// sits on its original and a node made on an edge sits on the deformed edge. `rest` holds every
/// node's rest position, the added ones included.
fn extended(positions: &[[f64; 3]], rest: &[[f64; 3]], diff: &ModelDiff) -> Vec<[f64; 3]> {
    let mut x = positions.to_vec();
    for a in &diff.added_nodes {
        let p = match a.state_from {
            Some(s) => {
                let s = s as usize;
                let (w, t) = a.blend.map_or((s, 0.0), |b| (b.with as usize, b.t));
                [0, 1, 2].map(|c| {
                    let (u, v) = (x[s][c] - rest[s][c], x[w][c] - rest[w][c]);
                    a.rest[c] + (1.0 - t) * u + t * v
                })
            }
            None => a.rest,
        };
        x.push(p);
    }
    x
}

/// The packed model kept by diffs carries exactly the cutter's springs and masses.
fn assert_packed_matches(packed: &PackedModel, cutter: &Cutter) {
    let model = cutter.model();
    assert_eq!(packed.springs().len(), model.spring_count());
    for (_, s) in model.springs() {
        let (a, b) = (
            cutter.dense_index(s.nodes[0]).unwrap(),
            cutter.dense_index(s.nodes[1]).unwrap(),
        );
        let i = packed.spring_index(a, b).expect("every spring is packed");
        let p = packed.springs()[i];
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

/// The rest positions of the nodes, dense order, as bits.
fn rest_bits(cutter: &Cutter) -> Vec<[u64; 3]> {
    cutter
        .mesh()
        .nodes()
        .map(|(_, n)| [n.rest.x, n.rest.y, n.rest.z].map(f64::to_bits))
        .collect()
}

/// What a sequence does besides its random strokes.
#[derive(Debug, Clone, Copy)]
struct Setup {
    /// The cutter's quality floor; `None` keeps the one [`Cutter::new`] starts with, what users
    /// get. The invariants are checked against it.
    floor: Option<f64>,
    /// The tissue moves between sweeps (a new smooth displacement for each, now and then a
    /// large one), rather than holding one deformation throughout.
    moving: bool,
    /// Earlier strokes are swept again (either way along them), the blade trembles at a
    /// stroke's end, and every sweep is repeated at once, at the same positions.
    revisits: bool,
    /// How many random strokes.
    strokes: usize,
}

impl Setup {
    /// One deformation throughout, no revisits.
    fn still(floor: f64) -> Self {
        Setup {
            floor: Some(floor),
            moving: false,
            revisits: false,
            strokes: 4,
        }
    }

    /// Moving tissue and revisits.
    fn moving(floor: Option<f64>) -> Self {
        Setup {
            floor,
            moving: true,
            revisits: true,
            strokes: 8,
        }
    }
}

/// What happened in a sequence.
#[derive(Debug, Clone, Default, PartialEq)]
struct Tally {
    /// Sweeps that changed the mesh.
    cuts: usize,
    /// Sweeps repeated at once at the same poses and positions.
    repeats: usize,
    /// Moves of a trembling blade.
    trembles: usize,
    /// Repeats and trembles held to cutting nothing new (all of them), and of those trembles.
    held: usize,
    trembles_held: usize,
    /// Repeats and trembles that cut something new (none of those held).
    cut_again: usize,
    /// Sweeps of strokes swept before, and how many of them cut (the tissue had moved).
    revisited: usize,
    revisit_cuts: usize,
    /// Sweeps at a large displacement, and how many of them cut.
    large: usize,
    large_cuts: usize,
}

/// Sorted rest corners of a tet, as bits: the same for a tet and its copies.
fn rest_corners(mesh: &TetMesh, nodes: [lancet::mesh::NodeKey; 4]) -> [[u64; 3]; 4] {
    let mut c = nodes.map(|k| {
        let p = mesh.rest(k);
        [p.x, p.y, p.z].map(f64::to_bits)
    });
    c.sort();
    c
}

/// Whether `sweep` has a triangle of rounding-level area (below 1e-12 of `size` squared):
/// a blade side moving along itself, which `Sweep::of_blade` leaves out.
fn has_slivers(sweep: &Sweep, size: f64) -> bool {
    sweep
        .triangles
        .iter()
        .any(|t| 0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm() < 1e-12 * size * size)
}

/// A sequence under way: the cutter, the packed model and layouts kept by its diffs, and what
/// every cut is checked against.
struct Run {
    seed: u64,
    method: CutMethod,
    cutter: Cutter,
    packed: PackedModel,
    layouts: Vec<PackedLayout>,
    volume: f64,
    /// The diagonal of the uncut mesh's bounds.
    size: f64,
    /// The floor the invariants are checked against (the cutter's, or the uncut mesh's worst
    /// quality where that is lower).
    check_floor: f64,
    /// The cutter's floor, which every tet a cut made (rest corners no uncut tet has) keeps to.
    made_floor: f64,
    uncut: BTreeSet<[[u64; 3]; 4]>,
}

impl Run {
    fn new(seed: u64, method: CutMethod, mesh: TetMesh, floor: Option<f64>) -> Self {
        let volume = mesh.volume();
        let mut config = ModelConfig::new(Material::elastic(3e3, 0.3, 1000.0));
        config.fixed = vec![lancet::model::FixedSelector::Box {
            min: [-1e9; 3],
            max: [1e9, 1e9, mesh.bounds().unwrap().0.z + 1e-9],
        }];
        let model = SpringModel::build(&mesh, &config).unwrap();
        let packed = model.pack(&mesh).unwrap();
        let layouts: Vec<PackedLayout> = [
            LayoutKind::Connectivity,
            LayoutKind::Valence,
            LayoutKind::Edges,
        ]
        .into_iter()
        .map(|k| PackedLayout::pack(&packed, k, NodeOrder::locality(&packed)).unwrap())
        .collect();
        let worst = mesh.min_volume_length_ratio();
        let (lo, hi) = mesh.bounds().unwrap();
        let uncut = mesh
            .tets()
            .map(|(_, t)| rest_corners(&mesh, t.nodes))
            .collect();
        let mut cutter = Cutter::new(mesh, model, method).unwrap();
        match floor {
            Some(f) => cutter = cutter.with_quality_floor(f),
            None => assert_eq!(cutter.quality_floor(), DEFAULT_QUALITY_FLOOR),
        }
        let made_floor = cutter.quality_floor().max(0.0);
        Run {
            seed,
            method,
            cutter,
            packed,
            layouts,
            volume,
            size: (hi - lo).norm(),
            check_floor: made_floor.min(worst),
            made_floor,
            uncut,
        }
    }

    /// Sweep the blade from `from` to `to`, classifying at `positions`, and check everything
    /// after a cut. Returns the outcome and the positions of every node after it, the nodes it
    /// added where the engines start them.
    fn sweep(&mut self, sweep: &Sweep, positions: &[[f64; 3]]) -> (CutOutcome, Vec<[f64; 3]>) {
        let outcome = self.cutter.cut(sweep, positions).unwrap();
        if !outcome.is_empty() {
            self.check(&outcome);
        }
        let positions = extended(positions, &self.packed.rest, &outcome.diff);
        assert_eq!(positions.len(), self.cutter.mesh().node_count());
        (outcome, positions)
    }

    /// `sweep` again at `positions`, where it, or a sweep whose band holds its band, has just
    /// been swept: it cuts nothing new (no diff, no surface change, no new crack front).
    /// Returns whether it was held to cutting nothing, whether it cut, and the positions after
    /// it.
    fn again(
        &mut self,
        sweep: &Sweep,
        positions: Vec<[f64; 3]>,
        trembling: bool,
    ) -> (bool, bool, Vec<[f64; 3]>) {
        let (seed, method) = (self.seed, self.method);
        let what = if trembling {
            "a trembling blade"
        } else {
            "the same sweep repeated"
        };
        let state = |c: &Cutter| (c.mesh().node_count(), c.mesh().tet_count(), c.crack_front());
        let before = state(&self.cutter);
        // A blade moved along its own axis has no leading side there: no sweep triangle of
        // rounding-level area, which would cut what its long edges pass.
        assert!(
            !has_slivers(sweep, self.size),
            "seed {seed} {method}: {what} kept a side moving along itself"
        );
        let outcome = self.cutter.cut(sweep, &positions).unwrap();
        let after = state(&self.cutter);
        assert!(
            outcome.is_empty() && after == before,
            "seed {seed} {method}: {what} cut again: (nodes, tets, crack front) {before:?} -> \
             {after:?}, {} tets touched, {} faces cut, {} nodes added",
            outcome.tets_touched,
            outcome.faces_cut,
            outcome.nodes_added
        );
        (true, false, positions)
    }

    /// After a cut: the packed model and every layout patched by its diff agree with a rebuild,
    /// every invariant holds (the floor among them), and every tet made keeps to the floor.
    fn check(&mut self, outcome: &CutOutcome) {
        let (seed, method) = (self.seed, self.method);
        self.packed.apply(&outcome.diff).unwrap();
        assert_packed_matches(&self.packed, &self.cutter);
        let report = self.cutter.check_invariants(self.volume, self.check_floor);
        assert!(report.passed(), "seed {seed} {method}: {report:#?}");
        if self.made_floor > 0.0 {
            let mesh = self.cutter.mesh();
            for (_, t) in mesh.tets() {
                if !self.uncut.contains(&rest_corners(mesh, t.nodes)) {
                    let q = tet_quality(&mesh.tet_points(t)).volume_length_ratio;
                    assert!(
                        q >= self.made_floor,
                        "seed {seed} {method}: a tet of quality {q} made, floor {}",
                        self.made_floor
                    );
                }
            }
        }
        for layout in &mut self.layouts {
            layout.patch(&self.packed, &outcome.diff).unwrap();
            let differences = layout.differences_from_rebuild(&self.packed).unwrap();
            assert!(
                differences.is_empty(),
                "seed {seed} {method}: the patched layout differs from a rebuild: \
                 {differences:#?}"
            );
            if let PackedLayout::Edges(_) = layout {
                // The spring pool keeps dead records: step both and compare.
                let rebuilt = fresh(&self.packed, layout);
                let p = step_params(&self.packed, SimConfig::new(1e-5));
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
            } else {
                assert!(
                    *layout == fresh(&self.packed, layout),
                    "{method} seed {seed}"
                );
            }
        }
    }
}

/// Run a random sequence of cuts (`setup.strokes` random strokes; with `setup.revisits`,
/// trembles, repeats and earlier strokes again besides), checking everything after each cut.
/// Returns the cutter and what happened. The strokes and the blade are the same whatever the
/// setup.
fn run(seed: u64, method: CutMethod, mesh: TetMesh, setup: Setup) -> (Cutter, Tally) {
    let mut rng = Rng(seed);
    // Separate generators for the motion and the revisits, so the strokes stay the same.
    let mut motion = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let mut moves = Rng(seed.wrapping_mul(0xbf58_476d_1ce4_e5b9) | 1);
    let (lo, hi) = mesh.bounds().unwrap();
    let size = (hi - lo).norm();
    let mut run = Run::new(seed, method, mesh, setup.floor);
    // The cell: the mean rest edge.
    let model = run.cutter.model();
    let cell =
        model.springs().map(|(_, s)| s.rest_length).sum::<f64>() / model.spring_count() as f64;
    let blade = ToolShape::Blade {
        width: size * (0.2 + 0.8 * rng.next()),
        length: 4.0 * size,
        thickness: 1e-3 * size,
    };
    let mut tally = Tally::default();
    let mut history: Vec<Vec<Isometry3<f64>>> = Vec::new();
    // Sweeps `poses` step by step (each step repeated with `setup.revisits`); returns the
    // positions after the last step.
    let mut stroke = |run: &mut Run, tally: &mut Tally, poses: &[Isometry3<f64>], revisit: bool| {
        let mut last = Vec::new();
        for w in poses.windows(2) {
            let (positions, large) = if setup.moving {
                let large = motion.next() < 0.125;
                let amplitude = if large {
                    cell * (0.2 + 0.3 * motion.next())
                } else {
                    cell * (0.01 + 0.04 * motion.next())
                };
                let field = Field::random(&mut motion, size, amplitude);
                (displaced(&run.packed, &field), large)
            } else {
                (deformed(run.cutter.mesh(), &mut Rng(seed)), false)
            };
            let sweep = Sweep::of_blade(&blade, &w[0], &w[1]).unwrap();
            let (outcome, mut after) = run.sweep(&sweep, &positions);
            let cut = !outcome.is_empty() as usize;
            tally.cuts += cut;
            if revisit {
                tally.revisited += 1;
                tally.revisit_cuts += cut;
            }
            if large {
                tally.large += 1;
                tally.large_cuts += cut;
            }
            if setup.revisits {
                let (held, cut, positions) = run.again(&sweep, after, false);
                tally.repeats += 1;
                tally.held += held as usize;
                tally.cut_again += cut as usize;
                after = positions;
            }
            last = after;
        }
        last
    };
    for _ in 0..setup.strokes {
        let poses = random_strokes(&mut rng, lo, hi);
        let mut positions = stroke(&mut run, &mut tally, &poses, false);
        if !setup.revisits {
            continue;
        }
        // Trembling at the end: back up along its own axis by a little (at most a third of
        // how far the last step took the edge down) and down again, at the positions of that
        // step. Its sides move along themselves, so only its edge cuts, within the band the
        // last step has just cut. (Back along a step that also slid, a side would lead and
        // sweep past the band's end.)
        if moves.next() < 0.5 {
            let (a, b) = (poses[poses.len() - 2], poses[poses.len() - 1]);
            let axis = b.rotation * Vector3::z();
            let depth = (a.translation.vector - b.translation.vector).dot(&axis);
            for _ in 0..1 + (moves.next() * 3.0) as usize {
                let mut back = b;
                back.translation.vector += axis * depth * (0.02 + 0.3 * moves.next());
                for (p, q) in [(b, back), (back, b)] {
                    let sweep = Sweep::of_blade(&blade, &p, &q).unwrap();
                    let (held, cut, after) = run.again(&sweep, positions, true);
                    tally.trembles += 1;
                    tally.held += held as usize;
                    tally.trembles_held += held as usize;
                    tally.cut_again += cut as usize;
                    positions = after;
                }
            }
        }
        history.push(poses);
        // An earlier stroke again (this one too), either way along it.
        if moves.next() < 0.5 {
            let k = ((moves.next() * history.len() as f64) as usize).min(history.len() - 1);
            let mut poses = history[k].clone();
            if moves.next() < 0.5 {
                poses.reverse();
            }
            stroke(&mut run, &mut tally, &poses, true);
        }
    }
    (run.cutter, tally)
}

/// Run a random sequence of cuts at one deformation, checking every invariant after each (no
/// tet below `floor` among them). Returns the cutter and how many cuts changed the mesh.
fn run_sequence(seed: u64, method: CutMethod, mesh: TetMesh, floor: f64) -> (Cutter, usize) {
    let (cutter, tally) = run(seed, method, mesh, Setup::still(floor));
    (cutter, tally.cuts)
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

/// Tissue moving between sweeps (now and then by a large displacement), earlier strokes swept
/// again, a trembling blade and every sweep repeated, with the floor users get: every invariant
/// after every cut (that floor among them), every layout patched equals a rebuild, a repeat or a
/// tremble cuts nothing new, and the same sequence twice gives the same mesh, bit for bit.
#[rstest]
fn random_sequences_in_moving_tissue_at_the_default_floor_keep_every_invariant(
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
    #[values(
        1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25,
        26, 27, 28, 29, 30, 31, 32
    )]
    seed: u64,
) {
    let mesh = random_box(&mut Rng(seed * 977));
    let (a, tally) = run(seed, method, mesh.clone(), Setup::moving(None));
    let (b, again) = run(seed, method, mesh, Setup::moving(None));
    assert_eq!(tally, again, "seed {seed} {method}");
    assert_eq!(topology(&a), topology(&b), "seed {seed} {method}");
    assert_eq!(rest_bits(&a), rest_bits(&b), "seed {seed} {method}");
    eprintln!(
        "seed {seed} {method}: {tally:?}; {} tets, {} fragments",
        a.mesh().tet_count(),
        a.mesh().component_count()
    );
}

/// The same moving sequences subdivided without a floor (the parameter rule alone).
#[rstest]
fn random_subdividing_of_moving_tissue_without_a_floor_keeps_every_invariant(
    #[values(
        1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25,
        26, 27, 28, 29, 30, 31, 32
    )]
    seed: u64,
) {
    let mesh = random_box(&mut Rng(seed * 977));
    let (a, tally) = run(
        seed,
        CutMethod::Subdivide,
        mesh.clone(),
        Setup::moving(Some(0.0)),
    );
    let (b, _) = run(seed, CutMethod::Subdivide, mesh, Setup::moving(Some(0.0)));
    assert_eq!(topology(&a), topology(&b), "seed {seed}");
    assert_eq!(rest_bits(&a), rest_bits(&b), "seed {seed}");
    eprintln!("seed {seed}: {tally:?}");
}

/// The liver, moving, at the default floor: it has tets below that floor of its own, which
/// stay as they are; every tet a cut makes keeps to it.
#[rstest]
fn random_cuts_of_the_moving_liver_at_the_default_floor_keep_every_invariant(
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
    #[values(31, 32, 33, 34, 35, 36)] seed: u64,
) {
    let Some(dir) = std::env::var_os("LANCET_MESH_DIR") else {
        eprintln!("skipped: LANCET_MESH_DIR is not set");
        return;
    };
    let path = std::path::Path::new(&dir).join("sofa/liver.msh");
    let mesh = lancet::mesh::io::read(&path).unwrap().mesh;
    assert!(mesh.min_volume_length_ratio() < DEFAULT_QUALITY_FLOOR);
    let (_, tally) = run(seed, method, mesh, Setup::moving(None));
    assert!(tally.cuts > 0, "seed {seed}: no stroke met the liver");
    eprintln!("seed {seed} {method}: {tally:?}");
}

/// Counted over the seeds, the moving sequences cut, repeat, tremble and revisit, large
/// displacements cut, and revisits of strokes in moved tissue cut something new: none of the
/// checks above is vacuous, and the positions given to the cutter matter.
#[test]
fn random_sequences_in_moving_tissue_do_every_move() {
    let mut total = Tally::default();
    for seed in 1..=32 {
        let mesh = random_box(&mut Rng(seed * 977));
        let (_, t) = run(seed, CutMethod::Separate, mesh, Setup::moving(None));
        total.cuts += t.cuts;
        total.repeats += t.repeats;
        total.trembles += t.trembles;
        total.held += t.held;
        total.trembles_held += t.trembles_held;
        total.cut_again += t.cut_again;
        total.revisited += t.revisited;
        total.revisit_cuts += t.revisit_cuts;
        total.large += t.large;
        total.large_cuts += t.large_cuts;
    }
    eprintln!("{total:?}");
    assert!(total.cuts >= 32, "{total:?}");
    assert!(total.repeats >= total.cuts, "{total:?}");
    assert!(total.trembles_held > 0 && total.revisited > 0, "{total:?}");
    assert!(total.large_cuts > 0 && total.revisit_cuts > 0, "{total:?}");
}

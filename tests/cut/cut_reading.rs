//! A cut reads only the positions near its blade (`Cutter::cut_from`): the nodes in a box
//! around the sweep, then those of the tets around its candidates that the box missed. Reading
//! every node instead must give the same cut, in undeformed, bent and strongly stretched
//! tissue (where the box misses nodes and they are fetched), by every method; a cut on a
//! large mesh reads a small part of it; and the CPU engines find the nodes in a box exactly.

use crate::models;
use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, CutOutcome, Cutter, PositionSource, Sweep};
use lancet::engine::{EngineKind, SimConfig, Simulation};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{Material, ModelConfig, SpringModel};
use lancet::Result;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rstest::rstest;

const H: f64 = 0.01;
const BLADE: ToolShape = ToolShape::Blade {
    width: 0.03,
    length: 0.1,
    thickness: 1e-4,
};

/// Every node's position, whatever the box: the reference.
struct Everything<'a>(&'a [[f64; 3]]);

impl PositionSource for Everything<'_> {
    fn near(&mut self, _: [f64; 3], _: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        Ok(self
            .0
            .iter()
            .enumerate()
            .map(|(i, &p)| (i as u32, p))
            .collect())
    }
    fn of(&mut self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        panic!("asked for {} nodes after giving every node", nodes.len())
    }
}

/// The nodes in the box only, counting what is read.
struct Counting<'a> {
    x: &'a [[f64; 3]],
    fetched: usize,
}

impl PositionSource for Counting<'_> {
    fn near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        lancet::cut::AllPositions(self.x).near(lo, hi)
    }
    fn of(&mut self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        self.fetched += nodes.len();
        lancet::cut::AllPositions(self.x).of(nodes)
    }
}

/// The tissue's deformations: none, a bend of a few millimetres, and a stretch to three times
/// its length along x about the box's centre (edges past the box's room around the sweep).
#[derive(Debug, Clone, Copy)]
enum Deform {
    None,
    Bend,
    Stretch,
}

fn deformed(cutter: &Cutter, d: Deform, c: f64) -> Vec<[f64; 3]> {
    cutter
        .mesh()
        .nodes()
        .map(|(_, n)| {
            let r = n.rest;
            match d {
                Deform::None => [r.x, r.y, r.z],
                Deform::Bend => [r.x, r.y + 0.004 * (r.x / c - 1.0).powi(2), r.z],
                Deform::Stretch => [c + 3.0 * (r.x - c), r.y, r.z],
            }
        })
        .collect()
}

fn same(a: &CutOutcome, b: &CutOutcome) {
    assert_eq!(a.diff, b.diff);
    assert_eq!(a.surface, b.surface);
    assert_eq!(
        (a.tets_touched, a.faces_cut, a.nodes_added, a.tets_removed),
        (b.tets_touched, b.faces_cut, b.nodes_added, b.tets_removed)
    );
}

#[rstest]
fn reading_near_the_blade_cuts_as_reading_everything(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
    #[values(Deform::None, Deform::Bend, Deform::Stretch)] deform: Deform,
) {
    let cells = 14;
    let mesh = BoxGrid::cube_cells([cells, cells, cells], H)
        .build()
        .unwrap();
    let model =
        SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(3e3, 0.3, 1e3))).unwrap();
    let mut near = Cutter::new(mesh, model, method).unwrap();
    let mut all = near.clone();
    let c = 0.5 * cells as f64 * H;
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3);
    let (mut cuts, mut fetched, mut read, mut nodes) = (0, 0, 0, 0);
    // A turned blade drawn down and along, a few millimetres a step (further in the stretched
    // box: with the quality floor, a subdivision waits for the blade to finish a tet, or snaps
    // where finishing it would make a tet below the floor, and stretched tets are large).
    let steps = if matches!(deform, Deform::Stretch) {
        14
    } else {
        8
    };
    for k in 0..steps {
        let pose = |k: f64| {
            let at = Translation3::new(c - 0.01 + 0.003 * k, c + 0.0013, 0.143 - 0.004 * k);
            Isometry3::from_parts(at, turn)
        };
        let sweep = Sweep::of_blade(&BLADE, &pose(k as f64), &pose(k as f64 + 1.0)).unwrap();
        let x = deformed(&near, deform, c);
        let mut counting = Counting { x: &x, fetched: 0 };
        let a = near.cut_from(&sweep, &mut counting).unwrap();
        let b = all.cut_from(&sweep, &mut Everything(&x)).unwrap();
        same(&a, &b);
        cuts += usize::from(!a.is_empty());
        fetched += counting.fetched;
        read += a.nodes_read;
        nodes += x.len();
    }
    // Cells stretched to three centimetres are crossed by fewer sweeps.
    let least = if matches!(deform, Deform::Stretch) {
        1
    } else {
        2
    };
    assert!(cuts >= least, "the blade cut only {cuts} times");
    match deform {
        // The box around the sweep holds every node a cut reads.
        Deform::None | Deform::Bend => assert_eq!(fetched, 0),
        // Edges three times their rest length leave nodes of the tets around the candidates
        // outside it: they were fetched, and the cut is the same.
        Deform::Stretch => assert!(fetched > 0, "the stretch left nothing to fetch"),
    }
    assert!(
        read < nodes / 2,
        "the cuts read {read} positions of {nodes}: most of the mesh"
    );
}

/// Every CPU engine's `nodes_near` finds exactly the nodes the float64 scan of its positions
/// finds, with those positions bit for bit, before and after cut-like patches (appended
/// nodes). The GPU engine's is tested in `gpu_nodes_near.rs`.
#[rstest]
fn cpu_engines_find_the_nodes_in_a_box(
    #[values(EngineKind::Reference, EngineKind::Fast)] kind: EngineKind,
) {
    let mut model = models::random_model(5, true);
    let config = SimConfig {
        allow_unstable: true,
        ..SimConfig::new(2e-5)
    };
    let mut sim = Simulation::new(model.clone(), kind, config).unwrap();
    let (x, v) = models::random_state(&model, 5);
    sim.set_state(&x, &v).unwrap();
    let mut rng = models::Rng(17);
    let mut found = 0;
    for round in 0..4 {
        sim.run(3).unwrap();
        for _ in 0..10 {
            let x = sim.positions();
            let c = x[(rng.next() * x.len() as f64) as usize];
            let half = [0, 1, 2].map(|_| 2e-3 + 2e-2 * rng.next());
            let (lo, hi) = (
                [0, 1, 2].map(|k| c[k] - half[k]),
                [0, 1, 2].map(|k| c[k] + half[k]),
            );
            let got = sim.nodes_near(lo, hi).unwrap();
            let want: Vec<(u32, [f64; 3])> = x
                .iter()
                .enumerate()
                .filter(|(_, p)| (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k]))
                .map(|(i, &p)| (i as u32, p))
                .collect();
            let bits = |v: &[(u32, [f64; 3])]| -> Vec<(u32, [u64; 3])> {
                v.iter().map(|&(i, p)| (i, p.map(f64::to_bits))).collect()
            };
            assert_eq!(bits(&got), bits(&want), "round {round}");
            found += want.len();
        }
        let diff = models::random_diff(&model, 40 + round);
        sim.apply(&diff).unwrap();
        model.apply(&diff).unwrap();
    }
    assert!(
        found > 100,
        "the boxes held too few nodes to test ({found})"
    );
}

/// The energy bookkeeping of a cut applied with the positions the cut read near its blade
/// (`Simulation::apply_at` with `Cutter::positions_read`) equals the one a full readback gives
/// (`Simulation::apply`), in strained, moving tissue, by every method: every node it needs was
/// read (one that was not holds NaN and would show).
#[rstest]
fn the_energy_reference_follows_the_cut_from_what_it_read(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    let mesh = BoxGrid::cube_cells([6, 6, 4], H).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(3e3, 0.3, 1e3));
    config.gravity = [0.0, 0.0, -9.81];
    let model = SpringModel::build(&mesh, &config).unwrap();
    let packed = model.pack(&mesh).unwrap();
    let sim_config = SimConfig {
        allow_unstable: true,
        ..SimConfig::new(0.4 * lancet::model::stable_time_step(&packed).dt)
    };
    let start = |packed: lancet::model::PackedModel| {
        let mut sim = Simulation::new(packed, EngineKind::Fast, sim_config).unwrap();
        // A smooth stretch and swirl, so that the springs a cut touches hold energy.
        let x: Vec<[f64; 3]> = mesh
            .nodes()
            .map(|(_, n)| {
                let r = n.rest;
                [r.x * 1.03 + 0.002 * r.z, r.y - 0.001 * r.x, r.z * 0.98]
            })
            .collect();
        let v = vec![[0.01, -0.02, 0.005]; x.len()];
        sim.set_state(&x, &v).unwrap();
        sim.run(3).unwrap();
        sim
    };
    let (mut near, mut all) = (start(packed.clone()), start(packed));
    let mut cutter = Cutter::new(mesh.clone(), model, method).unwrap();
    let mut cuts = 0;
    for k in 0..6 {
        let pose = |z: f64| Isometry3::translation(0.03, 0.0313, z);
        let z0 = 0.05 - 0.006 * k as f64;
        let sweep = Sweep::of_blade(&BLADE, &pose(z0), &pose(z0 - 0.006)).unwrap();
        let outcome = cutter.cut_from(&sweep, &mut near).unwrap();
        if outcome.is_empty() {
            continue;
        }
        cuts += 1;
        near.apply_at(&outcome.diff, true, cutter.positions_read().positions())
            .unwrap();
        all.apply_with(&outcome.diff, true).unwrap();
        let (a, b) = (near.energy_reference(), all.energy_reference());
        assert!(a.0.is_finite(), "cut {cuts}: {a:?}");
        assert!(
            (a.0 - b.0).abs() <= 1e-12 * b.0.abs().max(b.1),
            "cut {cuts}: {a:?} from what the cut read, {b:?} from every position"
        );
        near.run(2).unwrap();
        all.run(2).unwrap();
    }
    assert!(cuts >= 2, "the blade cut only {cuts} times");
}

/// Carving tissue stretched to three and five times its length: every tet a small sweep meets
/// (the exact test over every tet at the stretched positions) is carved. The candidates are
/// the tets with any corner within the longest rest edge of the sweep plus how far apart the
/// displacements read near it are; a scan that listed each tet only at one fixed corner lost
/// a sixth of them at four times, and one that left the displacements out misses some at five.
#[rstest]
fn carving_strongly_stretched_tissue_misses_no_tet_the_sweep_meets(
    #[values(3.0, 5.0)] stretch: f64,
) {
    let mesh = BoxGrid::cube_cells([8, 4, 4], H).build().unwrap();
    let model =
        SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(3e3, 0.3, 1e3))).unwrap();
    let base = Cutter::new(mesh, model, CutMethod::Remove).unwrap();
    let c = 4.0 * H;
    let x: Vec<[f64; 3]> = base
        .mesh()
        .nodes()
        .map(|(_, n)| [c + stretch * (n.rest.x - c), n.rest.y, n.rest.z])
        .collect();
    let mut rng = models::Rng(12345);
    let mut met = 0;
    for _ in 0..60 {
        let p = nalgebra::Point3::new(
            c + stretch * (rng.next() - 0.5) * 6.0 * H,
            (0.5 + 3.0 * rng.next()) * H,
            (0.5 + 3.0 * rng.next()) * H,
        );
        let d = 0.05 * H;
        let tri = [
            p,
            p + Vector3::new(d, 0.0, 0.0),
            p + Vector3::new(0.0, d, d),
        ];
        let mut cutter = base.clone();
        let want = cutter
            .mesh()
            .tets()
            .filter(|(_, t)| {
                let q = t
                    .nodes
                    .map(|k| nalgebra::Point3::from(x[cutter.dense_index(k).unwrap() as usize]));
                lancet::cut::exact::triangle_meets_tet(&tri, &q)
            })
            .count();
        let got = cutter
            .cut(&Sweep::from_triangles(vec![tri]), &x)
            .unwrap()
            .tets_removed;
        assert_eq!(got, want, "stretched {stretch} times: a sweep at {p:?}");
        met += want;
    }
    assert!(met > 30, "the sweeps met only {met} tets");
}

/// Carving next to a node pulled far out of tissue otherwise at rest (a grasper's pull: the
/// node's tets become a tent over the surface), after a first cut near rest that leaves the
/// smallest box: every tet a small sweep in the tent meets is carved, as long as it has a
/// corner in the box the cut reads. Such a tet's corners on the surface lie further from the
/// sweep than the scan's reach (the longest rest edge and the spread of the displacements
/// read), and where the box holds only the pulled node, so does that node: before the cut
/// looked at the tets of the nodes read beyond its reach, it missed tets in both cases (and
/// the fixed reach of twice the longest rest edge it replaced missed some too). A tet with no
/// corner in the box (a sweep in the air halfway up a tent taller than two boxes) is beyond
/// any cut that reads near its blade; those sweeps are counted apart.
#[rstest]
fn carving_next_to_a_pulled_node_misses_no_tet_the_sweep_meets(
    #[values(0.0, 1.0, 2.0)] width: f64,
    #[values(4.0, 6.0, 9.0)] height: f64,
) {
    let mesh = BoxGrid::cube_cells([12, 12, 4], H).build().unwrap();
    let model =
        SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(3e3, 0.3, 1e3))).unwrap();
    let mut base = Cutter::new(mesh, model, CutMethod::Remove).unwrap();
    let top = nalgebra::Point3::new(8.0 * H, 8.0 * H, 4.0 * H);
    let lift = height * H;
    // The pulled node alone (width 0), or a bump a rest edge or two wide around it.
    let x: Vec<[f64; 3]> = base
        .mesh()
        .nodes()
        .map(|(_, n)| {
            let d2 = (n.rest - top).norm_squared();
            let up = if d2 < 1e-12 {
                lift
            } else if width > 0.0 {
                lift * (-d2 / (width * H).powi(2)).exp()
            } else {
                0.0
            };
            [n.rest.x, n.rest.y, n.rest.z + up]
        })
        .collect();
    let small = |p: nalgebra::Point3<f64>| {
        let d = 0.05 * H;
        [
            p,
            p + Vector3::new(d, 0.0, 0.0),
            p + Vector3::new(0.0, d, d),
        ]
    };
    // A first cut near rest, far enough from the pull that it reads none of it.
    let first = base
        .cut(
            &Sweep::from_triangles(vec![small(nalgebra::Point3::new(
                1.3 * H,
                1.2 * H,
                0.45 * H,
            ))]),
            &x,
        )
        .unwrap();
    assert!(first.tets_removed > 0);
    let mut rng = models::Rng(777);
    let (mut met, mut beyond) = (0, 0);
    for _ in 0..40 {
        let t = 0.2 + 0.7 * rng.next();
        let s = 1.0 - t;
        let p = nalgebra::Point3::new(
            top.x + s * (rng.next() - 0.5) * H,
            top.y + s * (rng.next() - 0.5) * H,
            top.z + t * lift,
        );
        let sweep = Sweep::from_triangles(vec![small(p)]);
        let mut cutter = base.clone();
        let (lo, hi) = cutter.reading_box(&sweep).unwrap();
        let (mut want, mut in_box) = (0, 0);
        for (_, tet) in cutter.mesh().tets() {
            let q = tet
                .nodes
                .map(|k| nalgebra::Point3::from(x[cutter.dense_index(k).unwrap() as usize]));
            if lancet::cut::exact::triangle_meets_tet(&sweep.triangles[0], &q) {
                want += 1;
                let inside =
                    |q: &nalgebra::Point3<f64>| (0..3).all(|c| q[c] >= lo[c] && q[c] <= hi[c]);
                in_box += usize::from(q.iter().any(inside));
            }
        }
        let got = cutter.cut(&sweep, &x).unwrap().tets_removed;
        let at = format!("pulled {height} cells up, {width} wide: a sweep at {p:?}");
        assert!(got <= want, "{at}: {got} tets carved of {want} met");
        if in_box == want {
            assert_eq!(got, want, "{at}");
            met += want;
        } else {
            beyond += 1;
        }
    }
    assert!(
        met > 20,
        "the sweeps met only {met} tets with a corner in the box"
    );
    // Only where the box holds no node: the tallest tent of the pulled node alone.
    assert!(
        beyond == 0 || (width == 0.0 && height == 9.0),
        "{beyond} sweeps met tets with no corner in the box"
    );
}

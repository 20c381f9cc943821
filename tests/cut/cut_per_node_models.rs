//! Cuts of models given per node and per spring (`Mass::PerNode`, `Stiffness::Spring`,
//! `SpringDamping::Absolute`, the way spring-network users configure them), with every
//! method: mass is conserved, node by node where it can be said what each node must hold, and
//! each spring keeps what the tets holding its edge were given.
//!
//! A node of mass `m` held by `n` tets gets `m / n` from each, and an edge of stiffness `k` held
//! by `n` tets `k / n` from each, so the shares differ from corner to corner and edge to edge
//! (unlike a density's): moving one corner's or edge's share in place of another's shows. What
//! the uncut mesh gives, worked out here from its rest geometry alone:
//!
//! - a tet of the cut mesh at the rest corners of an uncut tet (untouched, or given copies of
//!   its nodes by separating) gives each corner and edge what the uncut tet gave it;
//! - a tet made by subdividing lies in one uncut tet and carries that tet's mass per rest
//!   volume, `rho V / 4` to each corner, and its springs' `sum k l^2` per rest volume,
//!   `kappa = sum k l^2 / (6 V)`, as `kappa V / l^2` to each edge of rest length `l`:
//!   subdividing passes each parent's mass, and the energy a uniform stretch stores in its
//!   springs, to its sub-tets.
//!
//! So every spring is checked, and the total `sum k l^2` is the uncut mesh's less what carving
//! removed. (Before that rule a sub-tet gave a per-spring edge `k / n`, `n` the tets holding it
//! when the sub-tet was added: one subdividing cut through the 64-node box below left 88 of
//! 371 springs stiffer than `k`, the stiffest 2.45 `k`, and raised `sum k l^2` by 41%.)

use crate::incisions::{blade_push, small_box};
use crate::models;
use std::collections::HashMap;

use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::mesh::TetMesh;
use lancet::model::{Material, ModelConfig, SpringDamping, SpringModel};
use models::Rng;
use nalgebra::{Isometry3, Point3, Vector3};
use rstest::rstest;

/// Spring stiffness, N/m, damping, N s/m, and node mass, kg.
const K: f64 = 40.0;
const C: f64 = 0.3;
const M: f64 = 0.01;

type Bits = [u64; 3];

fn bits(p: &Point3<f64>) -> Bits {
    [p.x, p.y, p.z].map(f64::to_bits)
}

fn sorted<const N: usize>(mut a: [Bits; N]) -> [Bits; N] {
    a.sort_unstable();
    a
}

/// What the uncut mesh gives, by rest position.
struct Uncut {
    /// Tets holding each rest node position and each rest edge.
    at_node: HashMap<Bits, usize>,
    at_edge: HashMap<[Bits; 2], usize>,
    /// Each tet's rest corners, sorted, and its corner points.
    tets: Vec<([Bits; 4], [Point3<f64>; 4])>,
}

impl Uncut {
    fn of(mesh: &TetMesh) -> Self {
        let mut at_node = HashMap::new();
        let mut at_edge = HashMap::new();
        let mut tets = Vec::new();
        for (_, t) in mesh.tets() {
            let p = mesh.tet_points(t);
            let b = p.map(|x| bits(&x));
            for c in b {
                *at_node.entry(c).or_insert(0) += 1;
            }
            for i in 0..4 {
                for j in i + 1..4 {
                    *at_edge.entry(sorted([b[i], b[j]])).or_insert(0) += 1;
                }
            }
            tets.push((sorted(b), p));
        }
        Uncut {
            at_node,
            at_edge,
            tets,
        }
    }

    /// The uncut tet at these rest corners, if one is.
    fn is_uncut(&self, corners: [Bits; 4]) -> bool {
        self.tets.iter().any(|(b, _)| *b == sorted(corners))
    }

    /// The `sum k l^2` an uncut tet's edges hold, at its rest corners `b` and points `q` (in the
    /// same order).
    fn kl2(&self, b: &[Bits; 4], q: &[Point3<f64>; 4]) -> f64 {
        let mut sum = 0.0;
        for i in 0..4 {
            for j in i + 1..4 {
                let l2 = (q[i] - q[j]).norm_squared();
                sum += K / self.at_edge[&sorted([b[i], b[j]])] as f64 * l2;
            }
        }
        sum
    }

    /// The mass and the `sum k l^2 / 6` per rest volume of the uncut tet holding `p` (inside it
    /// or on its boundary).
    fn density_at(&self, p: &Point3<f64>) -> (f64, f64) {
        let volume = |a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>, d: &Point3<f64>| {
            (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0
        };
        let (b, q) = self
            .tets
            .iter()
            .find(|(_, q)| {
                let v = volume(&q[0], &q[1], &q[2], &q[3]);
                let parts = [
                    volume(p, &q[1], &q[2], &q[3]),
                    volume(&q[0], p, &q[2], &q[3]),
                    volume(&q[0], &q[1], p, &q[3]),
                    volume(&q[0], &q[1], &q[2], p),
                ];
                parts.iter().all(|w| w / v > -1e-9)
            })
            .expect("every sub-tet lies in an uncut tet");
        let mass: f64 = b.iter().map(|c| M / self.at_node[c] as f64).sum();
        let v = volume(&q[0], &q[1], &q[2], &q[3]).abs();
        (mass / v, self.kl2(&q.map(|x| bits(&x)), q) / (6.0 * v))
    }

    /// The `sum k l^2` of the whole uncut mesh.
    fn total_kl2(&self) -> f64 {
        // The stored corners are sorted; the points are in corner order.
        self.tets
            .iter()
            .map(|(_, q)| self.kl2(&q.map(|x| bits(&x)), q))
            .sum()
    }
}

/// A 3 cm box of 1 cm cells (a random tet split) on a model of springs `K` and nodes `M`.
fn per_node_box(rng: &mut Rng) -> (TetMesh, SpringModel) {
    let mesh = small_box(rng);
    let material = Material::springs(K, M).with_damping(SpringDamping::Absolute(C));
    let model = SpringModel::build(&mesh, &ModelConfig::new(material)).unwrap();
    (mesh, model)
}

/// [`blade_push`]'s sweep.
fn stroke(rng: &mut Rng) -> Sweep {
    let (blade, from, to) = blade_push(rng);
    Sweep::of_blade(&blade, &from, &to).unwrap()
}

/// What was checked over a sequence.
#[derive(Debug, Default)]
struct Checked {
    /// Tets made by subdividing, and nodes whose mass differs from `M` (shares moved).
    sub_tets: usize,
    nodes_not_m: usize,
    /// Springs held only by tets at uncut rest corners, and of those, stiffnesses below `K`
    /// (an edge whose tets were parted).
    springs: usize,
    springs_parted: usize,
    /// Springs a sub-tet holds.
    springs_of_sub_tets: usize,
}

impl Checked {
    fn add(&mut self, c: &Checked) {
        self.sub_tets += c.sub_tets;
        self.nodes_not_m += c.nodes_not_m;
        self.springs += c.springs;
        self.springs_parted += c.springs_parted;
        self.springs_of_sub_tets += c.springs_of_sub_tets;
    }
}

/// Every node's mass and every spring's stiffness are what the uncut mesh gives them through
/// the tets holding them now; the total mass and `sum k l^2` are the uncut mesh's less what
/// carving removed (each carved tet's, from the uncut mesh).
fn check(cutter: &Cutter, uncut: &Uncut, carved: Carved, what: &str) -> Checked {
    let mesh = cutter.mesh();
    let model = cutter.model();
    let mut checked = Checked::default();
    let mut expected: HashMap<_, f64> = HashMap::new();
    // Per spring: the tets holding it, how many of them are sub-tets, and what they give it.
    let mut edge_from: HashMap<[lancet::mesh::NodeKey; 2], (usize, usize, f64)> = HashMap::new();
    for (tk, t) in mesh.tets() {
        let p = mesh.tet_points(t);
        let b = p.map(|x| bits(&x));
        let mut edges = Vec::new();
        for i in 0..4 {
            for j in i + 1..4 {
                let (a, c) = (t.nodes[i].min(t.nodes[j]), t.nodes[i].max(t.nodes[j]));
                let l2 = (p[i] - p[j]).norm_squared();
                edges.push(([a, c], sorted([b[i], b[j]]), l2));
            }
        }
        if uncut.is_uncut(b) {
            for (n, c) in t.nodes.iter().zip(&b) {
                *expected.entry(*n).or_insert(0.0) += M / uncut.at_node[c] as f64;
            }
            for (key, rest, _) in edges {
                let e = edge_from.entry(key).or_insert((0, 0, 0.0));
                e.0 += 1;
                e.2 += K / uncut.at_edge[&rest] as f64;
            }
        } else {
            checked.sub_tets += 1;
            let centroid =
                Point3::from((p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0);
            let (rho, kappa) = uncut.density_at(&centroid);
            let v = mesh.tet_volume(tk);
            for n in t.nodes {
                *expected.entry(n).or_insert(0.0) += rho * v / 4.0;
            }
            for (key, _, l2) in edges {
                let e = edge_from.entry(key).or_insert((0, 0, 0.0));
                e.0 += 1;
                e.1 += 1;
                e.2 += kappa * v / l2;
            }
        }
    }
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
    let mut total = 0.0;
    for (n, &want) in &expected {
        let got = model.mass(*n).expect("a node a tet holds has a mass");
        assert!(
            close(got, want),
            "{what}: a node has mass {got}, expected {want}"
        );
        checked.nodes_not_m += !close(got, M) as usize;
        total += got;
    }
    let uncut_total = M * uncut.at_node.len() as f64;
    assert!(
        close(total, uncut_total - carved.mass),
        "{what}: total mass {total} kg, expected {} kg",
        uncut_total - carved.mass
    );
    let mut kl2 = 0.0;
    for (key, (_, of_sub_tets, want)) in edge_from {
        let s = model
            .spring_between(key[0], key[1])
            .expect("every tet edge has a spring");
        let got = s.stiffness;
        assert!(
            close(got, want),
            "{what}: a spring has stiffness {got}, expected {want}"
        );
        // Damping given per spring is shared as stiffness given per spring is.
        assert!(
            close(s.damping, got * C / K),
            "{what}: a spring has damping {}, expected {}",
            s.damping,
            got * C / K
        );
        kl2 += got * s.rest_length * s.rest_length;
        if of_sub_tets > 0 {
            checked.springs_of_sub_tets += 1;
        } else {
            checked.springs += 1;
            checked.springs_parted += (got < K * (1.0 - 1e-9)) as usize;
        }
    }
    let want = uncut.total_kl2() - carved.kl2;
    assert!(
        (kl2 - want).abs() <= 1e-9 * want,
        "{what}: the springs' sum k l^2 is {kl2}, expected {want}"
    );
    checked
}

/// What carving removed, from the uncut mesh's shares.
#[derive(Debug, Default, Clone, Copy)]
struct Carved {
    mass: f64,
    kl2: f64,
}

/// Three random strokes into a per-node box with `method`, at rest; after each cut every
/// invariant holds and every node and spring holds what the uncut mesh gives it.
fn run(seed: u64, method: CutMethod) -> Checked {
    let mut rng = Rng(seed * 7919);
    let (mesh, model) = per_node_box(&mut rng);
    let uncut = Uncut::of(&mesh);
    let volume = mesh.volume();
    let mut cutter = Cutter::new(mesh, model, method).unwrap();
    let mut carved = Carved::default();
    let mut total = Checked::default();
    for k in 0..3 {
        let rest: Vec<[f64; 3]> = cutter
            .mesh()
            .nodes()
            .map(|(_, n)| n.rest.coords.into())
            .collect();
        // The carved tets' mass and springs, from the uncut mesh's shares (carving removes
        // uncut tets only).
        let before: Vec<_> = cutter.mesh().tets().map(|(tk, t)| (tk, *t)).collect();
        let outcome = cutter.cut(&stroke(&mut rng), &rest).unwrap();
        for (tk, t) in before {
            if cutter.mesh().tet(tk).is_none() {
                let q = t.nodes.map(|n| cutter.mesh().rest(n));
                let b = q.map(|x| bits(&x));
                carved.mass += b.iter().map(|c| M / uncut.at_node[c] as f64).sum::<f64>();
                carved.kl2 += uncut.kl2(&b, &q);
            }
        }
        let what = format!("seed {seed} {method} cut {k}");
        if outcome.is_empty() {
            continue;
        }
        let report = cutter.check_invariants(volume, 0.0);
        assert!(report.passed(), "{what}: {:?}", report.violations);
        total.add(&check(&cutter, &uncut, carved, &what));
    }
    total
}

#[rstest]
fn cuts_of_a_per_node_spring_model_conserve_mass_and_keep_each_share(
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
) {
    let mut total = Checked::default();
    for seed in 1..=12 {
        total.add(&run(seed, method));
    }
    eprintln!("{method}: {total:?}");
    // Not vacuous: shares moved (copies hold part of a node's mass and part of an edge's
    // stiffness, carving leaves nodes with part of theirs), and subdividing made sub-tets.
    assert!(
        total.nodes_not_m > 0 && total.springs > 0,
        "{method}: {total:?}"
    );
    match method {
        CutMethod::Subdivide => assert!(
            total.sub_tets > 0 && total.springs_of_sub_tets > 0,
            "{total:?}"
        ),
        _ => assert!(total.sub_tets == 0 && total.springs_parted > 0, "{total:?}"),
    }
}

/// The defect this file was written for: a subdividing cut gave each node it made a whole
/// node's mass and more (each new tet at it gave `m / n`, `n` counting the tets added so far:
/// `m (1 + 1/2 + ...)`), so this box of 64 nodes of 10 g, 0.64 kg, weighed 0.94 kg after one
/// cut. The springs the cut made were given the same way.
#[test]
fn subdividing_a_box_of_per_node_mass_keeps_its_mass() {
    let mesh = BoxGrid {
        cells: [3, 3, 3],
        size: [0.03; 3],
        origin: [0.0; 3],
        split: TetSplit::Six,
    }
    .build()
    .unwrap();
    let nodes = mesh.node_count();
    let model = SpringModel::build(&mesh, &ModelConfig::new(Material::springs(K, M))).unwrap();
    let kl2 = |m: &SpringModel| -> f64 {
        m.springs()
            .map(|(_, s)| s.stiffness * s.rest_length * s.rest_length)
            .sum()
    };
    let kl2_before = kl2(&model);
    eprintln!(
        "dt before {}",
        lancet::model::stable_time_step(&model.pack(&mesh).unwrap()).dt
    );
    let mut cutter = Cutter::new(mesh, model, CutMethod::Subdivide).unwrap();
    let blade = ToolShape::Blade {
        width: 0.1,
        length: 0.1,
        thickness: 1e-4,
    };
    // Upright through the middle, off the grid planes: every tet it meets is split.
    let at = |z: f64| Isometry3::new(Vector3::new(0.015, 0.0137, z), Vector3::new(0.0, 0.0, 0.3));
    let rest: Vec<[f64; 3]> = cutter
        .mesh()
        .nodes()
        .map(|(_, n)| n.rest.coords.into())
        .collect();
    let outcome = cutter
        .cut(
            &Sweep::of_blade(&blade, &at(0.08), &at(-0.02)).unwrap(),
            &rest,
        )
        .unwrap();
    assert!(outcome.nodes_added > 0, "{outcome:?}");
    let total = cutter.model().total_mass();
    let want = M * nodes as f64;
    assert!(
        (total - want).abs() <= 1e-12 * want,
        "{} nodes of {M} kg weigh {total} kg after the cut",
        nodes
    );
    // The same for the springs: what a uniform stretch stores in them, `sum k l^2`, is kept
    // (each sub-tet edge `k / n`, as before, gave 1.41 times it).
    let model = cutter.model();
    let after = kl2(model);
    let stiffer = model.springs().filter(|(_, s)| s.stiffness > K).count();
    let stiffest = model
        .springs()
        .map(|(_, s)| s.stiffness)
        .fold(0.0, f64::max);
    let mut pm = cutter.mesh().clone();
    pm.remove_unused_nodes();
    let dt = lancet::model::stable_time_step(&model.pack(&pm).unwrap()).dt;
    eprintln!(
        "sum k l^2 {kl2_before} -> {after}; {stiffer} of {} springs stiffer than {K} N/m, the \
         stiffest {stiffest} N/m; stable dt {dt}",
        model.spring_count()
    );
    assert!(
        (after - kl2_before).abs() <= 1e-12 * kl2_before,
        "sum k l^2 went from {kl2_before} to {after}"
    );
}

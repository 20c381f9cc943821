//! Subdividing with a quality floor: a sweep close to an existing face layer or edge puts it on
//! the cut instead of making new nodes beside it, and planar cuts through a box make no tet
//! below the floor while still parting it into two pieces, each on its side of the plane.
//! Every expectation comes from the grid's geometry or from clipping the uncut mesh by the
//! plane, not from the cutter.

use crate::splitmix;
use std::collections::{BTreeMap, BTreeSet};

use lancet::cut::subdivide::{EDGE_SNAP, NODE_SNAP};
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::mesh::topology::components;
use lancet::mesh::{TET_EDGES, TET_FACES};
use lancet::model::{Material, ModelConfig, SpringModel};
use lancet::TetMesh;
use nalgebra::{Point3, Vector3};
use splitmix::Rng;

type P = Point3<f64>;
type V = Vector3<f64>;

const H: f64 = 0.01;
const FLOOR: f64 = 0.2;
/// A floor no split in these grids comes near: with it only the distance rule snaps beyond the
/// parameter rule.
const ANY_FLOOR: f64 = 1e-6;

fn grid(split: TetSplit) -> TetMesh {
    BoxGrid {
        cells: [4, 4, 4],
        size: [4.0 * H; 3],
        origin: [0.0; 3],
        split,
    }
    .build()
    .unwrap()
}

fn cutter(mesh: &TetMesh, floor: f64) -> Cutter {
    let config = ModelConfig::new(Material::elastic(3e3, 0.3, 1000.0));
    let model = SpringModel::build(mesh, &config).unwrap();
    Cutter::new(mesh.clone(), model, CutMethod::Subdivide)
        .unwrap()
        .with_quality_floor(floor)
}

/// The plane `n . x = c` (`n` unit) as a sweep: a square a metre wide, far larger than the box.
fn plane(n: V, c: f64) -> Sweep {
    let centre = P::new(2.0 * H, 2.0 * H, 2.0 * H);
    let o = centre - n * (n.dot(&centre.coords) - c);
    let u = n
        .cross(&if n.x.abs() < 0.9 { V::x() } else { V::y() })
        .normalize();
    let v = n.cross(&u);
    let q = [u + v, v - u, -u - v, u - v].map(|d| o + d * 0.5);
    Sweep::from_triangles(vec![[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
}

/// Cut once at rest (the classification positions are the rest positions).
fn cut_at_rest(cutter: &mut Cutter, sweep: &Sweep) {
    let rest: Vec<[f64; 3]> = cutter
        .mesh()
        .nodes()
        .map(|(_, n)| n.rest.coords.into())
        .collect();
    cutter.cut(sweep, &rest).unwrap();
}

fn key(p: &P) -> [u64; 3] {
    [p.x, p.y, p.z].map(f64::to_bits)
}

/// Nodes of the cut mesh at rest positions the uncut mesh has no node at (the nodes splitting
/// made; copies sit where their originals do), once each.
fn made_nodes(uncut: &TetMesh, cutter: &Cutter) -> Vec<P> {
    let old: BTreeSet<[u64; 3]> = uncut.nodes().map(|(_, n)| key(&n.rest)).collect();
    let mut seen = BTreeSet::new();
    cutter
        .mesh()
        .nodes()
        .map(|(_, n)| n.rest)
        .filter(|p| !old.contains(&key(p)) && seen.insert(key(p)))
        .collect()
}

/// How many nodes of the cut mesh sit at `p`.
fn nodes_at(cutter: &Cutter, p: &P) -> usize {
    cutter
        .mesh()
        .nodes()
        .filter(|(_, n)| key(&n.rest) == key(p))
        .count()
}

/// The other ends of the edges of `mesh` at the node at `p`.
fn neighbours(mesh: &TetMesh, p: &P) -> Vec<P> {
    let mut out: BTreeMap<[u64; 3], P> = BTreeMap::new();
    for (_, t) in mesh.tets() {
        let x = mesh.tet_points(t);
        for [a, b] in TET_EDGES {
            if key(&x[a]) == key(p) {
                out.insert(key(&x[b]), x[b]);
            } else if key(&x[b]) == key(p) {
                out.insert(key(&x[a]), x[a]);
            }
        }
    }
    out.into_values().collect()
}

fn distance_to_segment(x: &P, a: &P, b: &P) -> f64 {
    let ab = b - a;
    let s = ((x - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
    (x - (a + ab * s)).norm()
}

/// The longest rest edge of `mesh`.
fn longest_edge(mesh: &TetMesh) -> f64 {
    mesh.tets()
        .flat_map(|(_, t)| {
            let x = mesh.tet_points(t);
            TET_EDGES.map(|[a, b]| (x[a] - x[b]).norm())
        })
        .fold(0.0, f64::max)
}

fn centroid(p: &[P; 4]) -> P {
    P::from(p.iter().map(|q| q.coords).sum::<V>() / 4.0)
}

/// The volume of `mesh` on the positive side of `n . x = c`, by clipping each tet.
fn clipped_volume(mesh: &TetMesh, n: &V, c: f64) -> f64 {
    let vol = |a: &P, b: &P, c: &P, d: &P| (b - a).dot(&(c - a).cross(&(d - a))).abs() / 6.0;
    let mut total = 0.0;
    for (_, t) in mesh.tets() {
        let p = mesh.tet_points(t);
        let s = p.map(|q| n.dot(&q.coords) - c);
        let v = vol(&p[0], &p[1], &p[2], &p[3]);
        let (pos, neg): (Vec<usize>, Vec<usize>) = (0..4).partition(|&i| s[i] > 0.0);
        let cross = |i: usize, j: usize| p[i] + (p[j] - p[i]) * (s[i] / (s[i] - s[j]));
        total += match pos.len() {
            0 => 0.0,
            4 => v,
            // The corner tet cut off at one vertex scales the tet by the three edge fractions.
            1 => {
                let a = pos[0];
                v * neg.iter().map(|&j| s[a] / (s[a] - s[j])).product::<f64>()
            }
            3 => {
                let a = neg[0];
                v - v * pos.iter().map(|&j| s[a] / (s[a] - s[j])).product::<f64>()
            }
            // A wedge: the cones from p1 over its faces away from p1.
            _ => {
                let (p1, p2) = (pos[0], pos[1]);
                let (c11, c12) = (cross(p1, neg[0]), cross(p1, neg[1]));
                let (c21, c22) = (cross(p2, neg[0]), cross(p2, neg[1]));
                let a = p[p1];
                vol(&a, &c11, &c12, &c22) + vol(&a, &c11, &c22, &c21) + vol(&a, &p[p2], &c21, &c22)
            }
        };
    }
    total
}

/// The pieces of the cut mesh, each with its rest volume and on which side of `n . x = c` its
/// volume mostly lies.
fn pieces(cutter: &Cutter, n: &V, c: f64) -> Vec<(f64, f64)> {
    let mesh = cutter.mesh();
    let (of, count) = components(mesh);
    let mut v = vec![(0.0, 0.0); count];
    for (tk, t) in mesh.tets() {
        let w = mesh.tet_volume(tk);
        let x = centroid(&mesh.tet_points(t));
        let piece = &mut v[of[tk] as usize];
        piece.0 += w;
        piece.1 += w * (n.dot(&x.coords) - c);
    }
    v
}

fn assert_invariants(cutter: &Cutter, volume: f64, floor: f64, what: &str) {
    let report = cutter.check_invariants(volume, floor);
    assert!(report.passed(), "{what}: {report:#?}");
    assert_eq!(report.springs_differing_from_rebuild, Some(0), "{what}");
}

#[test]
fn a_sweep_near_a_face_layer_opens_that_layer_and_makes_no_node() {
    // The six-tet split puts the faces of every tet on its cell's faces and on the planes
    // x = y, y = z, x = z through the cell's main diagonal; all cells are split alike, so the
    // planes y = 2h and x = y through the box are layers of faces, each through 25 nodes. Every
    // edge not in a layer spans it: by h for y = 2h, by h / sqrt 2 (perpendicular) for x = y.
    // A plane parallel to a layer at distance d crosses those edges at d / span from the layer
    // node, and is d from the layer nodes, whose shortest edge is h.
    let mesh = grid(TetSplit::Six);
    let volume = mesh.volume();
    let diagonal = V::new(1.0, -1.0, 0.0).normalize();
    let cases = [
        // (normal, the layer's offset, the span of the edges across it, distance)
        (V::y(), 2.0 * H, H, 0.15 * H),
        (diagonal, 0.0, H / 2f64.sqrt(), 0.15 * H),
        (diagonal, 0.0, H / 2f64.sqrt(), 0.17 * H),
        (diagonal, 0.0, H / 2f64.sqrt(), 0.19 * H),
    ];
    for (n, layer, span, d) in cases {
        for side in [-1.0, 1.0] {
            let what = format!("normal {n:?}, distance {:.2} h on side {side}", d / H);
            let t = d / span;
            assert!(d < NODE_SNAP * H, "{what}: the sweep is not near the layer");
            let c = layer + side * d;
            let sweep = plane(n, c);

            for floor in [ANY_FLOOR, FLOOR] {
                let what = format!("{what}, floor {floor}");
                let mut with = cutter(&mesh, floor);
                cut_at_rest(&mut with, &sweep);
                assert_invariants(&with, volume, floor, &what);
                assert!(made_nodes(&mesh, &with).is_empty(), "{what}");
                assert_eq!(with.mesh().tet_count(), 384, "{what}: a tet was split");
                // Each of the 25 layer nodes is copied once.
                assert_eq!(with.mesh().node_count(), 125 + 25, "{what}");
                assert_eq!(with.crack_front(), 0, "{what}");
                // The pieces are the tets on either side of the layer, half the box each.
                let (of, count) = components(with.mesh());
                assert_eq!(count, 2, "{what}");
                let mut piece_of_side = [None; 2];
                for (tk, tet) in with.mesh().tets() {
                    let s = n.dot(&centroid(&with.mesh().tet_points(tet)).coords) - layer;
                    assert!(s.abs() > 0.1 * H, "{what}: a tet on the layer");
                    let piece = piece_of_side[usize::from(s > 0.0)].get_or_insert(of[tk]);
                    assert_eq!(*piece, of[tk], "{what}: a piece on both sides");
                }
                for (v, _) in pieces(&with, &n, layer) {
                    assert!((v - 0.5 * volume).abs() < 1e-12 * volume, "{what}: {v}");
                }
            }

            // The parameter rule alone snaps only crossings within EDGE_SNAP of a node.
            let mut without = cutter(&mesh, 0.0);
            cut_at_rest(&mut without, &sweep);
            assert_invariants(&without, volume, 0.0, &what);
            let made = made_nodes(&mesh, &without).len();
            if t < EDGE_SNAP {
                assert_eq!(made, 0, "{what}");
            } else {
                assert!(made > 0, "{what}: crossings at {t} of an edge were snapped");
            }
            eprintln!(
                "{what}: crossings at {t:.3} of their edges; nodes made 0 with a floor, \
                 {made} without"
            );
        }
    }
}

#[test]
fn a_sweep_near_an_edge_puts_the_edge_on_the_cut() {
    // The z edge from P = (2, 2, 1) h to Q = (2, 2, 2) h, and a plane through its middle nearly
    // along it (a normal found by searching for one that keeps every other crossing at the two
    // ends off the parameter rule): P and Q are 0.18 h from it, on either side.
    let mesh = grid(TetSplit::Six);
    let volume = mesh.volume();
    let n = V::new(-0.8147, 0.4553, 0.3591).normalize();
    let (p, q) = (
        P::new(2.0 * H, 2.0 * H, H),
        P::new(2.0 * H, 2.0 * H, 2.0 * H),
    );
    let c = n.dot(&nalgebra::center(&p, &q).coords);
    let sweep = plane(n, c);
    // From the geometry: both ends are within NODE_SNAP of their shortest edge (h) of the
    // plane, and every edge at them the plane crosses, crosses it between EDGE_SNAP and
    // 1 - EDGE_SNAP: the parameter rule snaps neither end.
    let mut crossings = Vec::new();
    for end in [p, q] {
        let de = n.dot(&end.coords) - c;
        assert!(de.abs() < NODE_SNAP * H, "{}", de / H);
        for other in neighbours(&mesh, &end) {
            assert!((other - end).norm() >= H * (1.0 - 1e-12));
            let dn = n.dot(&other.coords) - c;
            if de * dn < 0.0 {
                let t = de / (de - dn);
                assert!(t > EDGE_SNAP && t < 1.0 - EDGE_SNAP, "{t}");
                crossings.push(t);
            }
        }
    }
    let lowest = crossings.iter().copied().fold(1.0, f64::min);
    // The edges at P or Q, to check nothing is made on them.
    let edges: Vec<(P, P)> = [p, q]
        .iter()
        .flat_map(|e| neighbours(&mesh, e).into_iter().map(move |o| (*e, o)))
        .collect();
    let on_an_edge = |x: &P| {
        edges
            .iter()
            .any(|(a, b)| distance_to_segment(x, a, b) < 1e-9 * H)
    };

    // Without the floor the edge is split where the plane crosses it.
    let mut without = cutter(&mesh, 0.0);
    cut_at_rest(&mut without, &sweep);
    assert_invariants(&without, volume, 0.0, "without");
    let made = made_nodes(&mesh, &without);
    assert!(made
        .iter()
        .any(|x| distance_to_segment(x, &p, &q) < 1e-9 * H));

    let mut made_with = Vec::new();
    for floor in [ANY_FLOOR, FLOOR] {
        let mut with = cutter(&mesh, floor);
        cut_at_rest(&mut with, &sweep);
        assert_invariants(&with, volume, floor, "with");
        made_with = made_nodes(&mesh, &with);
        assert!(
            !made_with.is_empty(),
            "the rest of the cut still follows the plane"
        );
        for x in &made_with {
            assert!(
                !on_an_edge(x),
                "floor {floor}: a node made on an edge at P or Q: {x:?}"
            );
        }
        // Both ends joined the cut, and the cut opened there: each has one copy.
        assert_eq!(nodes_at(&with, &p), 2, "floor {floor}");
        assert_eq!(nodes_at(&with, &q), 2, "floor {floor}");
        assert_eq!(with.mesh().component_count(), 2, "floor {floor}");
        assert_eq!(with.crack_front(), 0, "floor {floor}");
    }
    eprintln!(
        "crossings at P and Q from {lowest:.3} of their edges; nodes made: {} without the \
         floor ({} on edges at P or Q), {} with the floor {FLOOR}",
        made.len(),
        made.iter().filter(|x| on_an_edge(x)).count(),
        made_with.len()
    );
}

#[test]
fn planar_cuts_with_a_floor_make_no_tet_below_it_and_still_part_the_box() {
    let mut lowest_without = f64::INFINITY;
    for split in [TetSplit::Six, TetSplit::Five] {
        let mesh = grid(split);
        let volume = mesh.volume();
        let longest = longest_edge(&mesh);
        let mut rng = Rng(17 + split as u64);
        let (mut made, mut made_with) = (0, 0);
        let (mut worst_volume, mut worst_volume_without) = (0.0f64, 0.0f64);
        let mut lowest_with = f64::INFINITY;
        let cases = 16;
        for case in 0..cases {
            let n = rng.unit();
            // Through the middle third of the box.
            let c = n.dot(&V::from_fn(|_, _| rng.range(H * 4.0 / 3.0, H * 8.0 / 3.0)));
            let what = format!("{split:?} case {case}");
            let sweep = plane(n, c);
            let above = clipped_volume(&mesh, &n, c);

            let mut without = cutter(&mesh, 0.0);
            cut_at_rest(&mut without, &sweep);
            let report = without.check_invariants(volume, 0.0);
            assert!(report.passed(), "{what}: {report:#?}");
            lowest_without = lowest_without.min(report.min_quality);
            made += made_nodes(&mesh, &without).len();
            let p = pieces(&without, &n, c);
            let high = p.iter().find(|p| p.1 > 0.0).map_or(0.0, |p| p.0);
            worst_volume_without = worst_volume_without.max((high - above).abs() / volume);

            let mut with = cutter(&mesh, FLOOR);
            cut_at_rest(&mut with, &sweep);
            let report = with.check_invariants(volume, FLOOR);
            assert!(report.passed(), "{what}: {report:#?}");
            assert_eq!(report.springs_differing_from_rebuild, Some(0));
            lowest_with = lowest_with.min(report.min_quality);
            made_with += made_nodes(&mesh, &with).len();
            // Two pieces, every face on the cut opened, one piece on each side.
            assert_eq!(report.fragments, 2, "{what}");
            assert_eq!(with.crack_front(), 0, "{what}");
            let pieces = pieces(&with, &n, c);
            let (lo, hi) = if pieces[0].1 > 0.0 {
                (pieces[1], pieces[0])
            } else {
                (pieces[0], pieces[1])
            };
            assert!(lo.1 < 0.0 && hi.1 > 0.0, "{what}: {pieces:?}");
            worst_volume = worst_volume.max((hi.0 - above).abs() / volume);
            // Each tet lies on its piece's side: it has a corner off the cut there (nodes made
            // on the plane are within rounding of it), and no corner further on the other side
            // than a snap can move the cut: half of the crossed edge (the quality rule; the
            // parameter and distance rules move it less).
            let (of, _) = components(with.mesh());
            let high = if pieces[0].1 > 0.0 { 0 } else { 1 };
            for (tk, t) in with.mesh().tets() {
                let side = if of[tk] == high { 1.0 } else { -1.0 };
                let s = with
                    .mesh()
                    .tet_points(t)
                    .map(|x| side * (n.dot(&x.coords) - c));
                assert!(
                    s.iter().any(|&s| s > 1e-9 * H),
                    "{what}: a tet with no corner on its side: {s:?}"
                );
                assert!(
                    s.iter().all(|&s| s > -0.5 * longest),
                    "{what}: a corner far on the wrong side: {s:?}"
                );
            }
            // Every boundary face of a piece is on the box's surface or has a copy of each of
            // its corners in the other piece.
            for (tk, local) in with.faces().boundary() {
                let t = with.mesh().tet(tk).unwrap();
                let f = TET_FACES[local as usize].map(|i| with.mesh().rest(t.nodes[i]));
                let outside = (0..3).any(|axis| {
                    f.iter().all(|x| x[axis] == 0.0) || f.iter().all(|x| x[axis] == 4.0 * H)
                });
                assert!(
                    outside || f.iter().all(|x| nodes_at(&with, x) >= 2),
                    "{what}"
                );
            }
        }
        assert!(lowest_with >= FLOOR);
        assert!(
            worst_volume < 0.05,
            "{split:?}: a piece {worst_volume} of the box off the plane's"
        );
        eprintln!(
            "{split:?}, {cases} planes: nodes made per cut {:.1} without the floor, {:.1} with \
             {FLOOR}; lowest quality {lowest_with:.3} with it; largest piece volume error \
             {worst_volume_without:.2e} of the box without it, {worst_volume:.2e} with it",
            made as f64 / cases as f64,
            made_with as f64 / cases as f64,
        );
    }
    // The floor is not vacuous: without it, the same cuts make tets below it.
    assert!(
        lowest_without < FLOOR,
        "lowest quality without the floor {lowest_without}"
    );
    eprintln!("lowest quality without the floor: {lowest_without:.3}");
}

/// Cut the box at rest by the planes `n . x = c` in turn, with a quality floor, and check that
/// the pieces fill the four quadrants the planes make (they cross inside the box). Every tet
/// lies in its piece's quadrant up to a whole edge: a node an earlier cut left on its surface
/// stays on the cut when a later crossing snaps to it, wherever the crossing is along the edge.
/// Pieces besides the largest of each quadrant may only lie within an edge of both planes:
/// where two snapped surfaces cross near the crossing line they can pinch off a few tets.
/// Returns the nodes made and how many such extra pieces there were.
fn assert_quadrants(
    mesh: &TetMesh,
    planes: [(V, f64); 2],
    floor: f64,
    what: &str,
) -> (usize, usize) {
    let volume = mesh.volume();
    let longest = longest_edge(mesh);
    let mut cutter = cutter(mesh, floor);
    for (n, c) in planes {
        cut_at_rest(&mut cutter, &plane(n, c));
        assert_invariants(&cutter, volume, floor, what);
    }
    assert_eq!(cutter.crack_front(), 0, "{what}");
    let m = cutter.mesh();
    let (of, count) = components(m);
    // Each piece's quadrant: the signs of its volume-weighted distances to the planes.
    let mut weighted = vec![([0.0; 2], 0.0); count];
    for (tk, t) in m.tets() {
        let x = centroid(&m.tet_points(t));
        let piece = &mut weighted[of[tk] as usize];
        for (w, (n, c)) in piece.0.iter_mut().zip(&planes) {
            *w += m.tet_volume(tk) * (n.dot(&x.coords) - c);
        }
        piece.1 += m.tet_volume(tk);
    }
    let quadrant: Vec<[bool; 2]> = weighted.iter().map(|w| w.0.map(|w| w > 0.0)).collect();
    let mut largest: BTreeMap<[bool; 2], usize> = BTreeMap::new();
    for (i, q) in quadrant.iter().enumerate() {
        let l = largest.entry(*q).or_insert(i);
        if weighted[i].1 > weighted[*l].1 {
            *l = i;
        }
    }
    assert_eq!(largest.len(), 4, "{what}: {weighted:?}");
    for (tk, t) in m.tets() {
        let piece = of[tk] as usize;
        let extra = largest[&quadrant[piece]] != piece;
        for x in m.tet_points(t) {
            for ((n, c), positive) in planes.iter().zip(quadrant[piece]) {
                let s = (n.dot(&x.coords) - c) * if positive { 1.0 } else { -1.0 };
                assert!(s > -longest, "{what}: a corner {s:e} m on the wrong side");
                if extra {
                    assert!(s < longest, "{what}: an extra piece away from the crossing");
                }
            }
        }
    }
    (made_nodes(mesh, &cutter).len(), count - 4)
}

#[test]
fn crossing_cuts_with_a_floor_leave_one_piece_per_quadrant() {
    // The planes of fixtures/scenes/cut_two_crossing.ron: y = 1.7 h, then x = 2.3 h. The
    // crossings at 0.3 of an edge from a node split into tets below 0.3, so with that floor
    // the first cut snaps to y = 2 h over much of the box, and the second cut meets tets
    // whose corners are all on the cut.
    let mesh = grid(TetSplit::Six);
    let fixture = [(V::y(), 1.7 * H), (V::x(), 2.3 * H)];
    for floor in [ANY_FLOOR, FLOOR, 0.3] {
        let what = format!("fixture planes, floor {floor}");
        assert_eq!(
            assert_quadrants(&mesh, fixture, floor, &what).1,
            0,
            "{what}"
        );
    }
    // Random pairs of planes through the middle third of the box, at least 45 degrees apart.
    let mut extra_pieces = 0;
    for split in [TetSplit::Six, TetSplit::Five] {
        let mesh = grid(split);
        let mut rng = Rng(41 + split as u64);
        let (mut made, mut made_with, mut extra_without) = (0, 0, 0);
        let mut cases = 0;
        while cases < 12 {
            let planes = [(); 2].map(|_| {
                let n = rng.unit();
                let c = n.dot(&V::from_fn(|_, _| rng.range(H * 4.0 / 3.0, H * 8.0 / 3.0)));
                (n, c)
            });
            if planes[0].0.dot(&planes[1].0).abs() > 0.5f64.sqrt() {
                continue;
            }
            let what = format!("{split:?} case {cases}");
            let (m, extra) = assert_quadrants(&mesh, planes, FLOOR, &what);
            made_with += m;
            extra_pieces += extra;
            let mut without = cutter(&mesh, 0.0);
            for (n, c) in planes {
                cut_at_rest(&mut without, &plane(n, c));
            }
            made += made_nodes(&mesh, &without).len();
            extra_without += without.mesh().component_count() - 4;
            cases += 1;
        }
        eprintln!(
            "{split:?}, {cases} pairs of crossing cuts: nodes made per pair {:.1} without the \
             floor, {:.1} with {FLOOR}; pieces beyond the four quadrants {extra_without} \
             without the floor",
            made as f64 / cases as f64,
            made_with as f64 / cases as f64,
        );
    }
    eprintln!("pieces beyond the four quadrants with the floor: {extra_pieces}");
    assert!(
        extra_pieces <= 4,
        "{extra_pieces} extra pieces in 24 pairs of cuts"
    );
}

#[test]
fn a_scene_quality_floor_reaches_the_cutter() {
    // Subdividing the two crossing cuts of this fixture without a floor makes tets below 0.3;
    // with the scene's floor at 0.3 the cuts keep to it and the checks (against the same floor)
    // find nothing, and the box still ends in its four quadrants.
    use lancet::scene::{run_scene, RunOptions, Scene};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/scenes/cut_two_crossing.ron");
    let mut scene = Scene::read(&path).unwrap();
    scene.cut.as_mut().unwrap().quality_floor = 0.3;
    let opts = RunOptions {
        cut_method: Some(CutMethod::Subdivide),
        check: true,
        no_output: true,
        ..Default::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    assert!(summary.expectations_passed, "{:#?}", summary.expectations);
    let cuts = summary.cuts.unwrap();
    assert!(cuts.checks > 0);
    assert!(cuts.violations.is_empty(), "{:#?}", cuts.violations);
    assert_eq!(cuts.fragments, 4);
}

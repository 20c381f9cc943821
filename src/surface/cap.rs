//! Keeping a render surface closed and outward through cuts: the triangles a cut crosses are
//! split at the blade's swept surface, and each side of the opening gets a cap.
//!
//! **Construction.** The cut is taken where the blade swept, the surface a user saw it cut,
//! not where the simulation mesh opened (carving removes whole tets, separating opens tet
//! faces up to a cell from the blade): splitting at the swept surface needs only
//! segment-triangle tests on the render surface, whatever the method, and the two sides of the
//! cut are then told apart by the side of the sweep each point lies on, which every method
//! agrees with away from the blade. For each render triangle whose corners lie on different
//! sides of the sweep:
//!
//! - where both of its crossed edges meet the sweep, it is split at the two crossing points,
//!   each of which becomes two vertices, one per side (the opening);
//! - where only one does, the blade stops inside it (a partial cut): the slit runs from that
//!   edge's crossing to the point where the sweep's boundary (the blade's edge at the end of its
//!   stroke) pierces the triangle, one vertex both sides share (or, failing that, the corner
//!   opposite the crossed edge);
//! - where neither does (the corners differ in side beyond the blade's reach), it stays.
//!
//! The new edges on each side form that side's rim: closed loops for a cut right through,
//! paths from one slit end to the other for a partial cut, closed along the blade's edge
//! between them. Each side's loops are projected on the sweep's best-fit plane and
//! triangulated with `spade`'s constrained Delaunay triangulation (the loops as constraints,
//! the triangles inside them by the even-odd rule, so a cross-section with holes is capped
//! right), the triangles ordered so that each rim edge is used once by the split surface and
//! once, the other way round, by the cap: the drawn surface stays closed and consistently
//! oriented, and as the source was outward, so is it. A constrained triangulation of the rim
//! itself, rather than clipping the sweep against the surface, needs no inside test in 3D and
//! makes no vertex the rim does not have.
//!
//! **Following the deformation.** Every new vertex (crossings, slit ends) is bound like the
//! surface's own vertices ([`super::embed`]), to the nearest tet whose centroid lies on its
//! side of the sweep (inside it when one holds it, else by the extended coordinates of that
//! tet beyond its nearest face), so that each cap moves with its own side; a vertex of a split
//! triangle that its rebinding left in a tet on the other side is bound the same way.
//!
//! **Several cuts.** A blade's successive strokes in one plane extend one cut: their sweeps are
//! kept together, and after each cut the surface is split again from the surface as read, so
//! that a slit grows rather than being capped at every step. A stroke in another plane starts a
//! new cut, applied after the earlier ones to their result. The vertices of the surface as read
//! keep their indices; the new ones are appended after them, made again at each cut.
//!
//! **Limits.** A cut is capped on its sweep's best-fit plane: a blade turned during a stroke
//! gets caps that are flat where its sweep is not. A rim the triangulation cannot take (two
//! crossing points at the same place, loops crossing in the plane) is left open and counted in
//! [`Capped::open`]. Vertices a carving dropped take their triangles out, which opens the
//! surface there.

use std::time::Instant;

use nalgebra::{Point3, Vector3};
use rustc_hash::FxHashMap;
use spade::handles::FixedVertexHandle;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use super::embed::{barycentric, bounds, closest_on_triangle, INSIDE_TOLERANCE};
use super::grid::Grid;
use super::rebind::side_of;
use super::{Binding, Embedding};
use crate::cut::Sweep;
use crate::mesh::{TetKey, TetMesh, TET_FACES};

/// One cut: the triangles of the strokes in one plane.
#[derive(Debug, Clone)]
struct CutPlane {
    triangles: Vec<[Point3<f64>; 3]>,
    normal: Vector3<f64>,
    origin: Point3<f64>,
}

/// What the last cut left drawn.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Capped {
    /// The triangles to draw (indices into the embedding's vertices, the appended ones
    /// included).
    pub triangles: Vec<[u32; 3]>,
    /// Vertices appended after the surface's own (crossings and slit ends).
    pub added: usize,
    /// Render triangles split.
    pub split: usize,
    /// Cap triangles made.
    pub cap_triangles: usize,
    /// Rims left open (their triangulation failed).
    pub open: usize,
    /// Seconds taken.
    pub seconds: f64,
}

/// The cuts a render surface has followed, and what it needs to split and cap them again.
#[derive(Debug, Clone)]
pub struct Capper {
    /// Vertices of the surface as read: the embedding's first ones.
    original: usize,
    /// The surface's own triangles.
    triangles: Vec<[u32; 3]>,
    cuts: Vec<CutPlane>,
}

/// How far from coplanar (sine of the angle between normals, and offset relative to the
/// stroke's size) a stroke may be and still extend the last cut.
const COPLANAR: f64 = 1e-6;

impl Capper {
    /// For a surface of `vertices` vertices (those of `embedding` when made) and `triangles`.
    pub fn new(vertices: usize, triangles: &[[u32; 3]]) -> Self {
        Capper {
            original: vertices,
            triangles: triangles.to_vec(),
            cuts: Vec::new(),
        }
    }

    /// Take the sweep of a cut, then split and cap the surface for every cut so far, rebinding
    /// the appended vertices in `mesh` (the mesh as cut). `embedding` has been rebound for the
    /// cut ([`super::Rebinder`]); its appended vertices are replaced.
    pub fn cut(&mut self, embedding: &mut Embedding, mesh: &TetMesh, sweep: &Sweep) -> Capped {
        let start = Instant::now();
        self.take(sweep);
        embedding.truncate(self.original);
        let binder = SideBinder::new(mesh);
        let mut out = Capped {
            triangles: embedding.drawn_triangles(&self.triangles),
            ..Capped::default()
        };
        for plane in &self.cuts {
            let tris = std::mem::take(&mut out.triangles);
            out.triangles = split_and_cap(embedding, tris, plane, &binder, &mut out);
        }
        out.added = embedding.len() - self.original;
        out.seconds = start.elapsed().as_secs_f64();
        out
    }

    /// Add `sweep` to the last cut if it lies in that cut's plane, else start a new cut.
    fn take(&mut self, sweep: &Sweep) {
        let tris = &sweep.triangles;
        if tris.is_empty() {
            return;
        }
        let (normal, origin, size) = fit(tris);
        if let Some(last) = self.cuts.last_mut() {
            let sine = last.normal.cross(&normal).norm();
            let offset = tris
                .iter()
                .flatten()
                .map(|p| last.normal.dot(&(p - last.origin)).abs())
                .fold(0.0, f64::max);
            if sine < COPLANAR && offset <= COPLANAR * size {
                last.triangles.extend_from_slice(tris);
                return;
            }
        }
        self.cuts.push(CutPlane {
            triangles: tris.clone(),
            normal,
            origin,
        });
    }
}

/// The unit area-weighted normal, centroid and largest extent of `tris`.
fn fit(tris: &[[Point3<f64>; 3]]) -> (Vector3<f64>, Point3<f64>, f64) {
    let mut n = Vector3::zeros();
    let mut c = Vector3::zeros();
    let mut area = 0.0;
    for t in tris {
        let a = (t[1] - t[0]).cross(&(t[2] - t[0]));
        n += a;
        let w = a.norm();
        c += w * (t[0].coords + t[1].coords + t[2].coords) / 3.0;
        area += w;
    }
    let (lo, hi) = bounds(&tris.iter().flatten().copied().collect::<Vec<_>>());
    let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    let normal = n.try_normalize(0.0).unwrap_or_else(Vector3::y);
    (normal, Point3::from(c / area.max(f64::MIN_POSITIVE)), size)
}

/// Where a segment `a b` crosses triangle `t` (its plane between the ends, inside it up to a
/// rounding tolerance), as the parameter along the segment.
fn segment_hits(a: &Point3<f64>, b: &Point3<f64>, t: &[Point3<f64>; 3]) -> Option<f64> {
    let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let (da, db) = (n.dot(&(a - t[0])), n.dot(&(b - t[0])));
    if (da > 0.0 && db > 0.0) || (da < 0.0 && db < 0.0) || da == db {
        return None;
    }
    let s = da / (da - db);
    let x = a + (b - a) * s;
    // Inside by the signs of the sub-triangles' areas along the normal, with a tolerance
    // relative to the triangle's size (a crossing on a shared edge of two sweep triangles).
    let tol = -1e-9 * n.norm_squared();
    let inside = (0..3).all(|k| {
        let (p, q) = (t[k], t[(k + 1) % 3]);
        (q - p).cross(&(x - p)).dot(&n) >= tol
    });
    inside.then_some(s)
}

/// The sweep's triangles, their bounds, and its boundary edges (used by one triangle).
struct SweepIndex<'a> {
    plane: &'a CutPlane,
    lo: [f64; 3],
    hi: [f64; 3],
    edges: Vec<[Point3<f64>; 2]>,
}

impl<'a> SweepIndex<'a> {
    fn new(plane: &'a CutPlane) -> Self {
        let key = |p: &Point3<f64>| [p.x, p.y, p.z].map(f64::to_bits);
        let mut count: FxHashMap<_, (usize, [Point3<f64>; 2])> = FxHashMap::default();
        for t in &plane.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let (ka, kb) = (key(&a), key(&b));
                let k = if ka < kb { (ka, kb) } else { (kb, ka) };
                count.entry(k).or_insert((0, [a, b])).0 += 1;
            }
        }
        let mut edges: Vec<_> = count
            .into_iter()
            .filter(|(_, (n, _))| *n == 1)
            .map(|(k, (_, e))| (k, e))
            .collect();
        // The same order every run.
        edges.sort_by_key(|a| a.0);
        let (mut lo, mut hi) = bounds(
            &plane
                .triangles
                .iter()
                .flatten()
                .copied()
                .collect::<Vec<_>>(),
        );
        let pad = 1e-9 * (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        for k in 0..3 {
            lo[k] -= pad;
            hi[k] += pad;
        }
        SweepIndex {
            plane,
            lo,
            hi,
            edges: edges.into_iter().map(|(_, e)| e).collect(),
        }
    }

    /// Whether a box meets the sweep's bounds.
    fn near(&self, (lo, hi): ([f64; 3], [f64; 3])) -> bool {
        (0..3).all(|k| lo[k] <= self.hi[k] && hi[k] >= self.lo[k])
    }

    /// Where the segment `a b` crosses the sweep.
    fn crossing(&self, a: &Point3<f64>, b: &Point3<f64>) -> Option<Point3<f64>> {
        self.plane
            .triangles
            .iter()
            .find_map(|t| segment_hits(a, b, t))
            .map(|s| a + (b - a) * s)
    }

    /// Where the sweep's boundary pierces the triangle `t`.
    fn boundary_through(&self, t: &[Point3<f64>; 3]) -> Option<Point3<f64>> {
        self.edges
            .iter()
            .find_map(|[a, b]| segment_hits(a, b, t).map(|s| a + (b - a) * s))
    }
}

/// Appends vertices to an embedding, each bound to a tet on its side of the sweep.
struct SideBinder<'a> {
    mesh: &'a TetMesh,
    tets: Vec<(TetKey, [Point3<f64>; 4])>,
    grid: Grid,
    dense: crate::mesh::DenseNodes,
}

impl<'a> SideBinder<'a> {
    fn new(mesh: &'a TetMesh) -> Self {
        let tets: Vec<(TetKey, [Point3<f64>; 4])> =
            mesh.tets().map(|(k, t)| (k, mesh.tet_points(t))).collect();
        let grid = Grid::new(&tets.iter().map(|(_, p)| bounds(p)).collect::<Vec<_>>());
        SideBinder {
            mesh,
            tets,
            grid,
            dense: mesh.dense_nodes(),
        }
    }

    /// Bind vertex `v` of `e` (at its rest position) to the nearest tet whose centroid lies on
    /// `side` of `sweep` (any tet for `None`); dropped when there is none.
    fn bind(&self, e: &mut Embedding, v: usize, side: Option<bool>, sweep: &Sweep) {
        let p = Point3::from(e.rest[v]);
        let found = self.grid.nearest(e.rest[v], |i| {
            let (_, t) = &self.tets[i as usize];
            if let Some(s) = side {
                let c = Point3::from((t[0].coords + t[1].coords + t[2].coords + t[3].coords) / 4.0);
                if side_of(sweep, &c) != s {
                    return f64::INFINITY;
                }
            }
            let w = barycentric(t, &p);
            if w.iter().all(|&w| w >= -INSIDE_TOLERANCE) {
                return 0.0;
            }
            TET_FACES
                .iter()
                .map(|f| (closest_on_triangle(&p, &t[f[0]], &t[f[1]], &t[f[2]]) - p).norm())
                .fold(f64::INFINITY, f64::min)
        });
        let Some((i, d)) = found.filter(|(_, d)| d.is_finite()) else {
            e.dropped[v] = true;
            e.weights[v] = [0.0; 4];
            return;
        };
        let (key, points) = &self.tets[i as usize];
        let w = barycentric(points, &p);
        let tet = self.mesh.tet(*key).expect("a tet of the mesh");
        e.nodes[v] = tet.nodes.map(|k| self.dense.index[k]);
        e.weights[v] = w;
        e.dropped[v] = false;
        e.bindings[v] = if d == 0.0 {
            Binding::Inside(*key)
        } else {
            // The face beyond which it lies: the corner opposite it has the lowest weight.
            let face = (0..4).min_by(|&a, &b| w[a].total_cmp(&w[b])).unwrap_or(0) as u8;
            Binding::Outside {
                tet: *key,
                face,
                distance: d,
            }
        };
    }

    /// Whether vertex `v` is bound to a tet of the mesh by its nodes now, on `side` of `sweep`
    /// (a vertex bound here at an earlier cut is not in the rebinder's index, and its tet may
    /// have been given new corners since).
    fn holds(&self, e: &Embedding, v: usize, side: bool, sweep: &Sweep) -> bool {
        let Some(t) = self.mesh.tet(e.bindings[v].tet()) else {
            return false;
        };
        let p = self.mesh.tet_points(t);
        let c = Point3::from((p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0);
        t.nodes.map(|k| self.dense.index[k]) == e.nodes[v] && side_of(sweep, &c) == side
    }
}

/// A crossing of a render edge: its two vertices, on the `+` and `-` side.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    plus: u32,
    minus: u32,
}

impl Crossing {
    fn on(&self, side: bool) -> u32 {
        if side {
            self.plus
        } else {
            self.minus
        }
    }
}

/// Split the triangles `tris` of `e` at `plane`'s sweep and cap the openings; returns the
/// triangles to draw.
fn split_and_cap(
    e: &mut Embedding,
    tris: Vec<[u32; 3]>,
    plane: &CutPlane,
    binder: &SideBinder,
    out: &mut Capped,
) -> Vec<[u32; 3]> {
    let index = SweepIndex::new(plane);
    let sweep = Sweep::from_triangles(plane.triangles.clone());
    let at = |e: &Embedding, v: u32| Point3::from(e.rest[v as usize]);
    let mut sides: FxHashMap<u32, bool> = FxHashMap::default();
    let mut crossings: FxHashMap<(u32, u32), Option<Crossing>> = FxHashMap::default();
    // Vertices to bind once all are made, with their side (`None`: shared by both).
    let mut new: Vec<(u32, Option<bool>)> = Vec::new();
    // Vertices of the surface that split triangles use, with their side.
    let mut kept: Vec<(u32, bool)> = Vec::new();
    // Each side's rim, as the cap must run along it.
    let mut rim: [Vec<(u32, u32)>; 2] = [Vec::new(), Vec::new()];
    let mut drawn = Vec::with_capacity(tris.len());
    for t in tris {
        let p = t.map(|v| at(e, v));
        if !index.near(bounds(&p)) {
            drawn.push(t);
            continue;
        }
        let s = t.map(|v| *sides.entry(v).or_insert_with(|| side_of(&sweep, &at(e, v))));
        if s[0] == s[1] && s[1] == s[2] {
            drawn.push(t);
            continue;
        }
        // The crossing of each edge whose ends differ in side.
        let mut cross = [None; 3];
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if s[k] == s[(k + 1) % 3] {
                continue;
            }
            let key = (a.min(b), a.max(b));
            cross[k] = *crossings.entry(key).or_insert_with(|| {
                let x = index.crossing(&at(e, a), &at(e, b))?;
                let plus = e.push(x);
                let minus = e.push(x);
                new.push((plus, Some(true)));
                new.push((minus, Some(false)));
                Some(Crossing { plus, minus })
            });
        }
        let cut: Vec<usize> = (0..3).filter(|&k| cross[k].is_some()).collect();
        match cut.len() {
            2 => {
                // The lone corner is the one both crossed edges meet at: rotate it first.
                let l = if cut == [0, 2] { 0 } else { cut[1] };
                let (a, b, c) = (t[l], t[(l + 1) % 3], t[(l + 2) % 3]);
                let (sl, so) = (s[l], !s[l]);
                let p = cross[l].expect("crossed");
                let q = cross[(l + 2) % 3].expect("crossed");
                drawn.push([a, p.on(sl), q.on(sl)]);
                drawn.push([p.on(so), b, c]);
                drawn.push([p.on(so), c, q.on(so)]);
                rim[sl as usize].push((q.on(sl), p.on(sl)));
                rim[so as usize].push((p.on(so), q.on(so)));
                kept.extend([(a, sl), (b, so), (c, so)]);
                out.split += 1;
            }
            1 => {
                // The blade stops inside: the slit runs from the crossing to where the sweep's
                // boundary pierces the triangle (or its far corner).
                let k = cut[0];
                let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                let (sa, sb) = (s[k], s[(k + 1) % 3]);
                let p = cross[k].expect("crossed");
                match index.boundary_through(&[at(e, a), at(e, b), at(e, c)]) {
                    Some(x) => {
                        let tip = e.push(x);
                        new.push((tip, None));
                        drawn.push([a, p.on(sa), tip]);
                        drawn.push([p.on(sb), b, tip]);
                        drawn.push([b, c, tip]);
                        drawn.push([c, a, tip]);
                        rim[sa as usize].push((tip, p.on(sa)));
                        rim[sb as usize].push((p.on(sb), tip));
                    }
                    None => {
                        drawn.push([a, p.on(sa), c]);
                        drawn.push([p.on(sb), b, c]);
                        rim[sa as usize].push((c, p.on(sa)));
                        rim[sb as usize].push((p.on(sb), c));
                    }
                }
                kept.extend([(a, sa), (b, sb)]);
                out.split += 1;
            }
            _ => drawn.push(t),
        }
    }
    for &(v, side) in &new {
        binder.bind(e, v as usize, side, &sweep);
    }
    // A vertex next to the opening that its rebinding left in a tet of the other side would
    // stretch its triangle across the opening.
    kept.sort_unstable();
    kept.dedup_by_key(|k| k.0);
    for (v, side) in kept {
        let v = v as usize;
        if v < e.len() && !e.dropped[v] && !binder.holds(e, v, side, &sweep) {
            binder.bind(e, v, Some(side), &sweep);
        }
    }
    for side in [true, false] {
        match cap(e, &rim[side as usize], plane) {
            Some(caps) => {
                out.cap_triangles += caps.len();
                drawn.extend(caps);
            }
            None => out.open += 1,
        }
    }
    drawn.retain(|t| t.iter().all(|&v| !e.dropped[v as usize]));
    drawn
}

/// The cap of one side: its rim edges (as the cap runs along them) chained into loops, open
/// paths closed from end to start, triangulated in the sweep's plane. `None` when the rim is
/// not a set of simple loops the triangulation can take.
fn cap(e: &Embedding, rim: &[(u32, u32)], plane: &CutPlane) -> Option<Vec<[u32; 3]>> {
    if rim.is_empty() {
        return Some(Vec::new());
    }
    let mut next: FxHashMap<u32, u32> = FxHashMap::default();
    let mut ends: FxHashMap<u32, usize> = FxHashMap::default();
    for &(a, b) in rim {
        if next.insert(a, b).is_some() {
            return None;
        }
        *ends.entry(b).or_default() += 1;
    }
    if ends.values().any(|&n| n > 1) {
        return None;
    }
    // Paths first (from a vertex nothing leads to), then loops, in a fixed order.
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable_by_key(|v| (ends.contains_key(v), *v));
    let mut seen: FxHashMap<u32, ()> = FxHashMap::default();
    let mut loops: Vec<Vec<u32>> = Vec::new();
    for s in starts {
        if seen.contains_key(&s) {
            continue;
        }
        let mut l = vec![s];
        seen.insert(s, ());
        let mut v = s;
        while let Some(&w) = next.get(&v) {
            if w == s || seen.contains_key(&w) {
                break;
            }
            seen.insert(w, ());
            l.push(w);
            v = w;
        }
        if l.len() >= 3 {
            loops.push(l);
        }
    }
    // Coordinates in the plane.
    let n = plane.normal;
    let u = n
        .cross(
            &(if n.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            }),
        )
        .normalize();
    let w = n.cross(&u);
    let flat = |v: u32| {
        let d = Point3::from(e.rest[v as usize]) - plane.origin;
        Point2::new(d.dot(&u), d.dot(&w))
    };
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> = Default::default();
    let mut vertex_of: FxHashMap<FixedVertexHandle, u32> = FxHashMap::default();
    let mut polys: Vec<Vec<Point2<f64>>> = Vec::new();
    for l in &loops {
        let mut handles = Vec::with_capacity(l.len());
        for &v in l {
            let h = cdt.insert(flat(v)).ok()?;
            if *vertex_of.entry(h).or_insert(v) != v {
                // Two rim vertices at one place in the plane.
                return None;
            }
            handles.push(h);
        }
        for k in 0..handles.len() {
            let (a, b) = (handles[k], handles[(k + 1) % handles.len()]);
            if !cdt.can_add_constraint(a, b) {
                return None;
            }
            cdt.add_constraint(a, b);
        }
        polys.push(l.iter().map(|&v| flat(v)).collect());
    }
    // The cap runs along its rim: the loop with the largest area says which way round the
    // plane's counter-clockwise triangles must be taken.
    let area = |p: &[Point2<f64>]| {
        (0..p.len())
            .map(|k| {
                let (a, b) = (p[k], p[(k + 1) % p.len()]);
                a.x * b.y - b.x * a.y
            })
            .sum::<f64>()
    };
    let outer = polys
        .iter()
        .map(|p| area(p))
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))?;
    let mut out = Vec::new();
    for f in cdt.inner_faces() {
        let pos = f.positions();
        let c = Point2::new(
            (pos[0].x + pos[1].x + pos[2].x) / 3.0,
            (pos[0].y + pos[1].y + pos[2].y) / 3.0,
        );
        if !polys
            .iter()
            .fold(false, |inside, p| inside ^ contains(p, c))
        {
            continue;
        }
        let v = f.vertices().map(|h| vertex_of[&h.fix()]);
        out.push(if outer > 0.0 { v } else { [v[0], v[2], v[1]] });
    }
    Some(out)
}

/// Whether `c` lies inside the polygon `p` (crossing number).
fn contains(p: &[Point2<f64>], c: Point2<f64>) -> bool {
    let mut inside = false;
    for k in 0..p.len() {
        let (a, b) = (p[k], p[(k + 1) % p.len()]);
        if (a.y > c.y) != (b.y > c.y) && c.x < a.x + (c.y - a.y) * (b.x - a.x) / (b.y - a.y) {
            inside = !inside;
        }
    }
    inside
}

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
//! A crossing on the sweep's boundary (the blade's edge at the end of a stroke lying along a
//! row of render vertices, so that the slit ends on a render edge) is one vertex both sides
//! share, the slit's end, and the triangle beyond that edge is split at it but not opened.
//!
//! A corner **on the sweep** (within [`ON_SWEEP`] of its size: a blade along a row of render
//! vertices, or along render edges) is split like a crossing, into a copy per side; each of its
//! triangles takes the copy of the side its other corners lie on, or is split from it to the
//! crossing of its opposite edge when they lie on either side. Where a slit ends along a render
//! edge lying in the sweep, that edge is split at the sweep's boundary, one vertex both sides
//! share. Each side's rim is then the edges between new vertices that only one of that side's
//! triangles uses, so that a rim running along render edges is found like one across them.
//!
//! The new edges on each side form that side's rim: closed loops for a cut right through,
//! paths from one slit end to the other for a partial cut, closed along the blade's edge
//! between them. Each side's loops are projected on the sweep's best-fit plane and
//! triangulated with `spade`'s constrained Delaunay triangulation (the loops as constraints,
//! the triangles inside them by the even-odd rule, told by crossing the constraints from the
//! triangulation's outside, so a cross-section with holes is capped right and rim vertices
//! collinear in the plane do not leave faces sided by rounding), the triangles ordered so that each rim edge is used once by the split surface and
//! once, the other way round, by the cap: the drawn surface stays closed and consistently
//! oriented, and as the source was outward, so is it. A constrained triangulation of the rim
//! itself, rather than clipping the sweep against the surface, needs no inside test in 3D and
//! makes no vertex the rim does not have.
//!
//! **Following the deformation.** Every new vertex (crossings, slit ends) is bound like the
//! surface's own vertices ([`super::embed`]), to the nearest tet whose centroid lies on its
//! side of the sweep (inside it when one holds it, else by the extended coordinates of that
//! tet beyond its nearest face), so that each cap moves with its own side; a vertex of a split
//! triangle that its rebinding left in a tet on the other side is bound the same way, and so is
//! any vertex of the surface over the sweep and within a tet's reach of it (separating opens
//! the faces between tets whose centroids the sweep parts, up to a cell from it: a vertex
//! between the sweep and those faces lies in a tet of the other piece).
//!
//! On a **curved sweep** (a blade turned during its stroke) the loops are still triangulated in
//! the best-fit plane's coordinates, but with points of the sweep inside them (on a grid of half
//! the rim's mean edge, each lifted onto the sweep along the plane's normal) and its folds (the
//! edges where its flat triangles meet at an angle) as constraints through points on them, so
//! that each cap triangle lies in one of the sweep's triangles; a render triangle whose slit
//! crosses a fold is split there too (a vertex per side at the fold's piercing), so that the
//! slit, and the rim, follow the sweep across it.
//!
//! **Several cuts.** A blade's successive strokes in one plane, or each starting where the last
//! ended (the blade's edge at the last step, turned or not), extend one cut: their sweeps are
//! kept together, and after each cut the surface is split again from the surface as read, so
//! that a slit grows rather than being capped at every step. A stroke going on from the last
//! along the same lines (a blade moving straight without turning) is merged with it into one
//! quad, so that a cut's sweep stays a few triangles over any number of steps. Strokes that
//! changed no tet are taken too ([`Capper::follow`], given by the world with the blade's next
//! cut, or when it leaves the tissue or stops, or when the run ends:
//! [`crate::world::World::finish_cuts`]): the surface is split along every stroke, but
//! only when the mesh changed. A stroke in another plane starts a
//! new cut, applied after the earlier ones to their result. The vertices of the surface as read
//! keep their indices; the new ones are appended after them, made again at each cut.
//!
//! **Limits.** A curved sweep must project one to one on its best-fit plane (a blade turned by
//! less than a right angle). Each render edge is taken to cross the sweep once at most: where
//! a turning blade's sweep folds back across a render edge (two crossings, corners on one side)
//! the slit runs straight past the fold, and the cap triangles on that stretch of rim leave the
//! sweep by as much as the fold reaches past it (0.61 mm in `tests/surface/surface_turning.rs`,
//! at the box's back face; the caps off the rim lie on the sweep to rounding).
//! A rim the triangulation cannot take (two crossing
//! points at the same place, loops crossing in the plane) is left open and counted in
//! [`Capped::open`]. Vertices a carving dropped take their triangles out, which opens the
//! surface there.

use std::time::Instant;

use nalgebra::{Point3, Vector3};
use rustc_hash::{FxHashMap, FxHashSet};

use super::cap_bind::{rebind_band, SideBinder};
use super::cap_fill::cap;
use super::cap_sweep::SweepIndex;
pub use super::cap_sweep::ON_SWEEP;
use super::embed::bounds;
use super::rebind::side_of;
use super::Embedding;
use crate::cut::Sweep;
use crate::mesh::TetMesh;

/// One cut: the triangles of the strokes in one plane.
#[derive(Debug, Clone)]
pub(super) struct CutPlane {
    pub(super) triangles: Vec<[Point3<f64>; 3]>,
    /// The unit normal and a point of the best-fit plane of `triangles`.
    pub(super) normal: Vector3<f64>,
    pub(super) origin: Point3<f64>,
    /// The corners of the last stroke's triangles: where the next stroke of the same blade
    /// starts.
    last_stroke: Vec<Point3<f64>>,
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
        let mut out = self.recap(embedding, mesh);
        out.seconds = start.elapsed().as_secs_f64();
        out
    }

    /// Take the sweep of a stroke without splitting the surface yet: a stroke that changed
    /// no tet, split and capped with the next [`Capper::cut`] or [`Capper::recap`] (so that
    /// the surface is split again only when the mesh changed).
    pub fn follow(&mut self, sweep: &Sweep) {
        self.take(sweep);
    }

    /// Split and cap the surface for every cut taken so far, rebinding the appended vertices in
    /// `mesh` (the mesh as cut); `embedding`'s appended vertices are replaced.
    pub fn recap(&mut self, embedding: &mut Embedding, mesh: &TetMesh) -> Capped {
        let start = Instant::now();
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
            // A stroke starting where the last one ended (the blade's edge at the last step,
            // whether or not it turned since) extends the same cut, fitted again as a whole.
            let bits = |p: &Point3<f64>| [p.x, p.y, p.z].map(f64::to_bits);
            let ends: FxHashSet<[u64; 3]> = last.last_stroke.iter().map(bits).collect();
            if tris.iter().flatten().any(|p| ends.contains(&bits(p))) {
                extend_strip(&mut last.triangles, tris);
                (last.normal, last.origin, _) = fit(&last.triangles);
                last.last_stroke = tris.iter().flatten().copied().collect();
                return;
            }
            let sine = last.normal.cross(&normal).norm();
            let offset = tris
                .iter()
                .flatten()
                .map(|p| last.normal.dot(&(p - last.origin)).abs())
                .fold(0.0, f64::max);
            if sine < COPLANAR && offset <= COPLANAR * size {
                extend_strip(&mut last.triangles, tris);
                last.last_stroke = tris.iter().flatten().copied().collect();
                return;
            }
        }
        self.cuts.push(CutPlane {
            triangles: tris.clone(),
            normal,
            origin,
            last_stroke: tris.iter().flatten().copied().collect(),
        });
    }
}

/// Add a stroke's triangles `tris` to a cut's, `cut`: each pair of them sweeping one side of
/// the blade (`[a0, b0, b1], [a0, b1, a1]`, as [`Sweep::of_blade`] makes them) that goes on
/// from a pair of the cut in its plane and along the same lines (a blade moving straight
/// without turning) is merged with it into one quad. A blade's sweep then stays a few
/// triangles however many steps it took, so that splitting the surface at it, and telling
/// sides by it, costs the same after a thousand strokes as after one.
fn extend_strip(cut: &mut Vec<[Point3<f64>; 3]>, tris: &[[Point3<f64>; 3]]) {
    let same =
        |p: &Point3<f64>, q: &Point3<f64>| p.coords.map(f64::to_bits) == q.coords.map(f64::to_bits);
    let pair =
        |t: &[Point3<f64>; 3], u: &[Point3<f64>; 3]| same(&t[0], &u[0]) && same(&t[2], &u[1]);
    // `b` goes on from `a` along the line from `p` (to rounding), forwards.
    let straight = |p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>| {
        let (u, v) = (a - p, b - a);
        u.cross(&v).norm() <= STRAIGHT * u.norm() * v.norm() && u.dot(&v) > 0.0
    };
    let mut k = 0;
    while k < tris.len() {
        if k + 1 < tris.len() && pair(&tris[k], &tris[k + 1]) {
            let (a0, b0, b1, a1) = (tris[k][0], tris[k][1], tris[k][2], tris[k + 1][2]);
            let before = (0..cut.len().saturating_sub(1)).rev().find(|&i| {
                pair(&cut[i], &cut[i + 1]) && same(&cut[i][2], &b0) && same(&cut[i + 1][2], &a0)
            });
            if let Some(i) = before {
                let (p0, q0) = (cut[i][0], cut[i][1]);
                // In one plane: the old quad's, which the new one's corners then lie in.
                let n = (q0 - p0).cross(&(b0 - p0));
                let flat = n.dot(&(a0 - p0)).abs() <= STRAIGHT * n.norm() * (a0 - p0).norm();
                if flat && straight(&p0, &a0, &a1) && straight(&q0, &b0, &b1) {
                    cut[i] = [p0, q0, b1];
                    cut[i + 1] = [p0, b1, a1];
                    k += 2;
                    continue;
                }
            }
        }
        cut.push(tris[k]);
        k += 1;
    }
}

/// How far from a straight line or a plane (sine of the angle) a stroke's corners may be for
/// [`extend_strip`] to merge it with the last: rounding only.
const STRAIGHT: f64 = 1e-12;

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

/// A crossing of a render edge: its two vertices, on the `+` and `-` side.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    plus: u32,
    minus: u32,
}

impl Crossing {
    /// Whether both sides share it (a slit's end).
    fn shared(&self) -> bool {
        self.plus == self.minus
    }

    fn on(&self, side: bool) -> u32 {
        if side {
            self.plus
        } else {
            self.minus
        }
    }
}

/// The two copies of a point on the sweep, one bound on each side (appended to `e`, bound once
/// all are made).
fn pair(e: &mut Embedding, new: &mut Vec<(u32, Option<bool>)>, x: Point3<f64>) -> Crossing {
    let plus = e.push(x);
    let minus = e.push(x);
    new.push((plus, Some(true)));
    new.push((minus, Some(false)));
    Crossing { plus, minus }
}

/// The crossing of a render edge at `x`: two copies, one per side, or, where `x` lies on the
/// sweep's boundary (a slit ending on a render edge: the blade's edge at the end of a stroke
/// along a row of render vertices), one vertex both sides share, the slit's end. Copies there
/// would be two rim vertices at one place, which no cap can take, and the triangle beyond the
/// edge is not cut.
fn crossing_at(
    e: &mut Embedding,
    new: &mut Vec<(u32, Option<bool>)>,
    index: &SweepIndex,
    x: Point3<f64>,
) -> Crossing {
    if index.on_boundary(&x) {
        let tip = e.push(x);
        new.push((tip, None));
        Crossing {
            plus: tip,
            minus: tip,
        }
    } else {
        pair(e, new, x)
    }
}

/// Split the triangles `tris` of `e` at `plane`'s sweep and cap the openings; returns the
/// triangles to draw.
///
/// A corner on the sweep (within [`ON_SWEEP`] of its size: a blade along a row of render
/// vertices or edges) is split like a crossing, one copy per side; a triangle it belongs to
/// takes the copy of the side its other corners lie on, or is split from it to the crossing of
/// its opposite edge when they lie on either side. Each side's rim is then the edges between
/// new vertices that only one of that side's triangles uses, so that a cut along render edges
/// (whose rim runs along them) is found like one across them.
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
    let first_new = e.len() as u32;
    // Each vertex's side of the sweep, `None` on it.
    let mut class: FxHashMap<u32, (Option<bool>, bool)> = FxHashMap::default();
    // The shared vertex where the sweep's boundary crosses a render edge lying in the sweep
    // from a corner on it to one beyond the blade's reach (a slit ending along render edges).
    let mut tips: FxHashMap<(u32, u32), Option<u32>> = FxHashMap::default();
    let mut crossings: FxHashMap<(u32, u32), Option<Crossing>> = FxHashMap::default();
    // The two copies of each vertex on the sweep.
    let mut copies: FxHashMap<u32, Crossing> = FxHashMap::default();
    // Vertices to bind once all are made, with their side (`None`: shared by both).
    let mut new: Vec<(u32, Option<bool>)> = Vec::new();
    // Vertices of the surface that split triangles use, with their side.
    let mut kept: Vec<(u32, bool)> = Vec::new();
    // The triangles made on one side of the opening, with that side: their edges between new
    // vertices that the side uses once are its rim.
    let mut sided: Vec<([u32; 3], bool)> = Vec::new();
    // Rim edges through a corner of the surface (a slit ending at a corner), as the cap runs
    // along them.
    let mut extra: [Vec<(u32, u32)>; 2] = [Vec::new(), Vec::new()];
    let mut drawn = Vec::with_capacity(tris.len());
    for t in tris {
        let p = t.map(|v| at(e, v));
        if !index.near(bounds(&p)) {
            drawn.push(t);
            continue;
        }
        let cp = t.map(|v| *class.entry(v).or_insert_with(|| index.classify(&at(e, v))));
        let c = cp.map(|c| c.0);
        // A corner on the sweep and one in its plane beyond it, the third off the plane: the
        // slit ends on their edge, where the sweep's boundary crosses it.
        let slit_end = (c.iter().filter(|c| c.is_none()).count() == 1)
            .then(|| {
                let o = (0..3).find(|&k| c[k].is_none())?;
                let (b, d) = ((o + 1) % 3, (o + 2) % 3);
                match (cp[b].1, cp[d].1) {
                    (true, false) => Some((o, b, d)),
                    (false, true) => Some((o, d, b)),
                    _ => None,
                }
            })
            .flatten();
        if let Some((o, q, m)) = slit_end {
            let key = (t[o].min(t[q]), t[o].max(t[q]));
            let tip = *tips.entry(key).or_insert_with(|| {
                let x = index.boundary_through(&p)?;
                let tip = e.push(x);
                new.push((tip, None));
                Some(tip)
            });
            if let Some(tip) = tip {
                let side = c[m].expect("off the plane");
                let oc = *copies
                    .entry(t[o])
                    .or_insert_with(|| pair(e, &mut new, p[o]));
                let os = oc.on(side);
                // The edge from the corner on the sweep to the one beyond it is split at the
                // tip, the triangle in two, both on the side of its third corner.
                let halves = if q == (o + 1) % 3 {
                    [[os, tip, t[m]], [tip, t[q], t[m]]]
                } else {
                    [[os, t[m], tip], [tip, t[m], t[q]]]
                };
                for tri in halves {
                    drawn.push(tri);
                    sided.push((tri, side));
                }
                kept.push((t[m], side));
                out.split += 1;
                continue;
            }
        }
        if c.contains(&None) {
            let copy = |copies: &mut FxHashMap<u32, Crossing>,
                        e: &mut Embedding,
                        new: &mut Vec<(u32, Option<bool>)>,
                        v: u32| {
                *copies.entry(v).or_insert_with(|| pair(e, new, at(e, v)))
            };
            let (plus, minus) = (c.contains(&Some(true)), c.contains(&Some(false)));
            let o = (0..3)
                .find(|&k| c[k].is_none())
                .expect("a corner on the sweep");
            let (b, d) = ((o + 1) % 3, (o + 2) % 3);
            let x = if plus && minus {
                // One corner on the sweep, the others on either side: split from it to the
                // crossing of the opposite edge.
                let key = (t[b].min(t[d]), t[b].max(t[d]));
                let (pb, pd) = (p[b], p[d]);
                *crossings.entry(key).or_insert_with(|| {
                    index
                        .crossing(&pb, &pd)
                        .map(|x| crossing_at(e, &mut new, &index, x))
                })
            } else {
                None
            };
            if let Some(x) = x {
                let (sb, sd) = (c[b].expect("off"), c[d].expect("off"));
                let q = copy(&mut copies, e, &mut new, t[o]);
                for (tri, side) in [
                    ([q.on(sb), t[b], x.on(sb)], sb),
                    ([q.on(sd), x.on(sd), t[d]], sd),
                ] {
                    drawn.push(tri);
                    sided.push((tri, side));
                }
                kept.extend([(t[b], sb), (t[d], sd)]);
                out.split += 1;
                continue;
            }
            // On one side, touching the sweep (or lying in it: then with the piece it bounds,
            // the side its outward normal points away from; or crossing it beyond the blade's
            // reach: with the side of its centroid).
            let centre = Point3::from((p[0].coords + p[1].coords + p[2].coords) / 3.0);
            let side = match (plus, minus) {
                (true, false) => true,
                (false, true) => false,
                (false, false) => {
                    let n = (p[1] - p[0])
                        .cross(&(p[2] - p[0]))
                        .try_normalize(0.0)
                        .unwrap_or_else(Vector3::zeros);
                    side_of(&sweep, &(centre - n * (16.0 * index.tolerance)))
                }
                (true, true) => side_of(&sweep, &centre),
            };
            let mut tri = t;
            for k in 0..3 {
                match c[k] {
                    None => tri[k] = copy(&mut copies, e, &mut new, t[k]).on(side),
                    Some(_) => kept.push((t[k], side)),
                }
            }
            drawn.push(tri);
            sided.push((tri, side));
            continue;
        }
        let s = c.map(|c| c.expect("off the sweep"));
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
            let (pa, pb) = (p[k], p[(k + 1) % 3]);
            cross[k] = *crossings.entry(key).or_insert_with(|| {
                index
                    .crossing(&pa, &pb)
                    .map(|x| crossing_at(e, &mut new, &index, x))
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
                // The slit runs from `p` to `q` through the points where the sweep's folds
                // pierce the triangle, so that it lies on the sweep, and so does the cap on it.
                let folds: Vec<Crossing> = index
                    .folds_through(
                        &[at(e, a), at(e, b), at(e, c)],
                        &at(e, p.plus),
                        &at(e, q.plus),
                    )
                    .into_iter()
                    .map(|x| pair(e, &mut new, x))
                    .collect();
                // The lone corner's side: fanned from it over the slit, `p` to `q`.
                let lone: Vec<u32> = std::iter::once(p.on(sl))
                    .chain(folds.iter().map(|m| m.on(sl)))
                    .chain([q.on(sl)])
                    .collect();
                // The other side: `p b c`, then fanned from `c` over the slit, `q` to `p`.
                let other: Vec<u32> = std::iter::once(q.on(so))
                    .chain(folds.iter().rev().map(|m| m.on(so)))
                    .chain([p.on(so)])
                    .collect();
                let fans = lone
                    .windows(2)
                    .map(|w| ([a, w[0], w[1]], sl))
                    .chain([([p.on(so), b, c], so)])
                    .chain(other.windows(2).map(|w| ([c, w[0], w[1]], so)));
                for (tri, side) in fans.collect::<Vec<_>>() {
                    drawn.push(tri);
                    sided.push((tri, side));
                }
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
                if p.shared() {
                    // The slit ends on this edge: the triangle is only split at its end.
                    drawn.push([a, p.plus, c]);
                    drawn.push([p.plus, b, c]);
                    continue;
                }
                match index.boundary_through(&[at(e, a), at(e, b), at(e, c)]) {
                    Some(x) => {
                        let tip = e.push(x);
                        new.push((tip, None));
                        for (tri, side) in [([a, p.on(sa), tip], sa), ([p.on(sb), b, tip], sb)] {
                            drawn.push(tri);
                            sided.push((tri, side));
                        }
                        drawn.push([b, c, tip]);
                        drawn.push([c, a, tip]);
                    }
                    None => {
                        drawn.push([a, p.on(sa), c]);
                        drawn.push([p.on(sb), b, c]);
                        extra[sa as usize].push((c, p.on(sa)));
                        extra[sb as usize].push((p.on(sb), c));
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
    rebind_band(e, binder, &index, &sweep, first_new);
    for side in [true, false] {
        let edges: FxHashSet<(u32, u32)> = sided
            .iter()
            .filter(|(_, s)| *s == side)
            .flat_map(|(t, _)| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
            .collect();
        let mut rim: Vec<(u32, u32)> = edges
            .iter()
            .filter(|&&(a, b)| a >= first_new && b >= first_new && !edges.contains(&(b, a)))
            .map(|&(a, b)| (b, a))
            .chain(extra[side as usize].iter().copied())
            .collect();
        // The same loops every run.
        rim.sort_unstable();
        match cap(e, &rim, &index) {
            Some((caps, inner)) => {
                // Points of a curved sweep inside the rim: bound on this side like the rim's.
                for v in inner {
                    binder.bind(e, v as usize, Some(side), &sweep);
                }
                out.cap_triangles += caps.len();
                drawn.extend(caps);
            }
            None => out.open += 1,
        }
    }
    drawn.retain(|t| t.iter().all(|&v| !e.dropped[v as usize]));
    drawn
}

//! Filling the rim of one side of a cut ([`super::cap`]): the rim's edges chained into loops,
//! open paths closed from end to start, projected on the sweep's best-fit plane and
//! triangulated with `spade`'s constrained Delaunay triangulation, points of a curved sweep
//! and its folds added inside the rim.

use nalgebra::{Point3, Vector3};
use rustc_hash::{FxHashMap, FxHashSet};
use spade::handles::FixedVertexHandle;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use super::cap_sweep::SweepIndex;
use super::Embedding;

/// The cap of one side: its rim edges (as the cap runs along them) chained into loops, open
/// paths closed from end to start, triangulated in the sweep's plane. `None` when the rim is
/// not a set of simple loops the triangulation can take.
pub(super) fn cap(
    e: &mut Embedding,
    rim: &[(u32, u32)],
    index: &SweepIndex,
) -> Option<(Vec<[u32; 3]>, Vec<u32>)> {
    let plane = index.plane;
    if rim.is_empty() {
        return Some((Vec::new(), Vec::new()));
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
    let flat_point = |p: &Point3<f64>| {
        let d = p - plane.origin;
        Point2::new(d.dot(&u), d.dot(&w))
    };
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> = Default::default();
    // The rim's constraints: the only ones the even-odd rule counts.
    let mut rim_edges: FxHashSet<(FixedVertexHandle, FixedVertexHandle)> = FxHashSet::default();
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
            rim_edges.insert((a, b));
            rim_edges.insert((b, a));
        }
        polys.push(l.iter().map(|&v| flat(v)).collect());
    }
    // On a curved sweep (a blade turned during its strokes) the cap follows it: points of the
    // sweep inside the rim, about a rim edge apart, split the triangulation so that its
    // triangles lie on the sweep up to its curvature over that distance, not on the plane.
    let mut inner = Vec::new();
    if index.curved {
        let edges = poly_edges(&polys);
        let h = spacing(&edges);
        // The sweep's folds, chained through the rim's vertices on them (where the slit
        // crosses a fold) and points on them inside the rim (a third of the grid's margin from
        // it), so that no cap triangle spans a fold.
        let rim_vertices: Vec<(u32, FixedVertexHandle)> =
            vertex_of.iter().map(|(&h, &v)| (v, h)).collect();
        let mut folds = Vec::with_capacity(index.kinks.len());
        for [a, b] in &index.kinks {
            let (fa, fb) = (flat_point(a), flat_point(b));
            folds.push((fa, fb));
            let ab = b - a;
            let mut chain: Vec<(f64, FixedVertexHandle)> = rim_vertices
                .iter()
                .filter_map(|&(v, h)| {
                    let p = Point3::from(e.rest[v as usize]);
                    let t = (ab.dot(&(p - a)) / ab.norm_squared()).clamp(0.0, 1.0);
                    ((a + ab * t - p).norm() <= index.tolerance).then_some((t, h))
                })
                .collect();
            let steps = ((fb.x - fa.x).hypot(fb.y - fa.y) / h).ceil().max(1.0) as usize;
            for i in 0..=steps {
                let t = i as f64 / steps as f64;
                let x = Point2::new(fa.x + (fb.x - fa.x) * t, fa.y + (fb.y - fa.y) * t);
                if !inside(&polys, x) || to_edges(&edges, x) <= h / 9.0 {
                    continue;
                }
                let handle = cdt.insert(x).ok()?;
                if let std::collections::hash_map::Entry::Vacant(slot) = vertex_of.entry(handle) {
                    let v = e.push(a + ab * t);
                    slot.insert(v);
                    inner.push(v);
                }
                chain.push((t, handle));
            }
            chain.sort_by(|x, y| x.0.total_cmp(&y.0));
            for pair in chain.windows(2) {
                let (p, q) = (pair[0].1, pair[1].1);
                let (x, y) = (cdt.vertex(p).position(), cdt.vertex(q).position());
                let mid = Point2::new(0.5 * (x.x + y.x), 0.5 * (x.y + y.y));
                if p != q && inside(&polys, mid) && cdt.can_add_constraint(p, q) {
                    cdt.add_constraint(p, q);
                }
            }
        }
        for x in inner_points(&polys, &edges, h) {
            // Off the folds, whose own points stand there.
            if folds.iter().any(|&(a, b)| to_segment(x, a, b) <= h / 3.0) {
                continue;
            }
            let q = plane.origin + u * x.x + w * x.y;
            let reach = n * (2.0 * index.size);
            let Some(on) = index.crossing(&(q - reach), &(q + reach)) else {
                continue;
            };
            let handle = cdt.insert(x).ok()?;
            if vertex_of.contains_key(&handle) {
                continue;
            }
            let v = e.push(on);
            vertex_of.insert(handle, v);
            inner.push(v);
        }
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
    let inside_face = even_odd(&cdt, &rim_edges);
    let mut out = Vec::new();
    for f in cdt.inner_faces() {
        if !inside_face[f.index()] {
            continue;
        }
        let v = f.vertices().map(|h| vertex_of[&h.fix()]);
        out.push(if outer > 0.0 { v } else { [v[0], v[2], v[1]] });
    }
    Some((out, inner))
}

/// Which faces of `cdt` (by index) lie inside its constraint loops by the even-odd rule: the
/// outer face is outside, and crossing a constraint edge from a face to its neighbour changes
/// side. Told from the triangulation's connectivity, not by testing a point of each face
/// against the loops: where rim vertices are collinear in the plane (a cut's crossings along a
/// straight line of the sweep, up to rounding) the triangulation has faces of no area along
/// the rim, whose centroids lie on it, and a point test sides them by rounding, which capped
/// stretches of rim the wrong way round.
fn even_odd(
    cdt: &ConstrainedDelaunayTriangulation<Point2<f64>>,
    rim: &FxHashSet<(FixedVertexHandle, FixedVertexHandle)>,
) -> Vec<bool> {
    let mut next: Vec<Vec<(usize, bool)>> = vec![Vec::new(); cdt.num_all_faces()];
    for edge in cdt.undirected_edges() {
        let d = edge.as_directed();
        let (a, b) = (d.face().index(), d.rev().face().index());
        let constraint = rim.contains(&(d.from().fix(), d.to().fix()));
        next[a].push((b, constraint));
        next[b].push((a, constraint));
    }
    let mut side: Vec<Option<bool>> = vec![None; next.len()];
    let outer = cdt.outer_face().index();
    side[outer] = Some(false);
    let mut queue = std::collections::VecDeque::from([outer]);
    while let Some(f) = queue.pop_front() {
        let s = side[f].expect("sided when queued");
        for &(g, constraint) in &next[f] {
            if side[g].is_none() {
                side[g] = Some(s ^ constraint);
                queue.push_back(g);
            }
        }
    }
    side.into_iter().map(|s| s.unwrap_or(false)).collect()
}

/// The edges of the polygons `polys`.
fn poly_edges(polys: &[Vec<Point2<f64>>]) -> Vec<(Point2<f64>, Point2<f64>)> {
    polys
        .iter()
        .flat_map(|p| (0..p.len()).map(move |k| (p[k], p[(k + 1) % p.len()])))
        .collect()
}

/// The spacing of a cap's inner points: half the mean rim edge, so that its triangles are
/// about as large as the rim's own spacing.
fn spacing(edges: &[(Point2<f64>, Point2<f64>)]) -> f64 {
    0.5 * edges
        .iter()
        .map(|(a, b)| (b.x - a.x).hypot(b.y - a.y))
        .sum::<f64>()
        / edges.len().max(1) as f64
}

/// Distance from `c` to the segment `a b`.
fn to_segment(c: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> f64 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let l2 = dx * dx + dy * dy;
    let s = if l2 > 0.0 {
        (((c.x - a.x) * dx + (c.y - a.y) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (c.x - a.x - s * dx).hypot(c.y - a.y - s * dy)
}

/// Distance from `c` to the nearest of `edges`.
fn to_edges(edges: &[(Point2<f64>, Point2<f64>)], c: Point2<f64>) -> f64 {
    edges
        .iter()
        .map(|&(a, b)| to_segment(c, a, b))
        .fold(f64::INFINITY, f64::min)
}

/// Whether `c` lies inside the polygons `polys` by the even-odd rule.
fn inside(polys: &[Vec<Point2<f64>>], c: Point2<f64>) -> bool {
    polys
        .iter()
        .fold(false, |inside, p| inside ^ contains(p, c))
}

/// Points inside the polygons `polys` (edges `edges`, by the even-odd rule) on a square grid
/// of spacing `h`, none closer than a third of that to an edge (no sliver triangles, no point
/// on a constraint).
fn inner_points(
    polys: &[Vec<Point2<f64>>],
    edges: &[(Point2<f64>, Point2<f64>)],
    h: f64,
) -> Vec<Point2<f64>> {
    if h <= 0.0 {
        return Vec::new();
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in polys.iter().flatten() {
        lo = [lo[0].min(p.x), lo[1].min(p.y)];
        hi = [hi[0].max(p.x), hi[1].max(p.y)];
    }
    let count = |k: usize| ((hi[k] - lo[k]) / h).floor() as usize;
    let mut out = Vec::new();
    for i in 0..=count(0) {
        for j in 0..=count(1) {
            // Centred in the bounds.
            let c = Point2::new(
                lo[0] + 0.5 * (hi[0] - lo[0] - count(0) as f64 * h) + i as f64 * h,
                lo[1] + 0.5 * (hi[1] - lo[1] - count(1) as f64 * h) + j as f64 * h,
            );
            if inside(polys, c) && to_edges(edges, c) > h / 3.0 {
                out.push(c);
            }
        }
    }
    out
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

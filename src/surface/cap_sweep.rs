//! The sweep of one cut as [`super::cap`] reads it: its triangles' bounds, its boundary (where
//! a slit ends), its folds (where a turning blade's triangles meet at an angle), and the side of
//! it a point lies on.

use nalgebra::{Point3, Vector3};
use rustc_hash::FxHashMap;

use super::cap::CutPlane;
use super::embed::{bounds, closest_on_triangle};

/// Where a segment `a b` crosses triangle `t` (its plane between the ends, inside it up to a
/// rounding tolerance), as the parameter along the segment.
pub(super) fn segment_hits(a: &Point3<f64>, b: &Point3<f64>, t: &[Point3<f64>; 3]) -> Option<f64> {
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

/// The sine of the angle between two of the sweep's triangles above which their common edge
/// is a fold ([`SweepIndex::kinks`]): anything above rounding.
const KINK: f64 = 1e-9;

/// How close to the sweep, relative to its largest extent, a render vertex counts as on it
/// (a blade along a row of render vertices, up to rounding): it is then split like a crossing.
pub const ON_SWEEP: f64 = 1e-8;

/// The sweep's triangles, their bounds, and its boundary edges (used by one triangle).
pub(super) struct SweepIndex<'a> {
    pub(super) plane: &'a CutPlane,
    /// The sweep's bounds, m.
    pub(super) lo: [f64; 3],
    pub(super) hi: [f64; 3],
    edges: Vec<[Point3<f64>; 2]>,
    /// Its inner edges where its two triangles meet at an angle (a turning blade's sweep
    /// folds there): a cap on it is split along them, so that each of its flat triangles
    /// lies in one of the sweep's.
    pub(super) kinks: Vec<[Point3<f64>; 2]>,
    /// How close to the sweep a point counts as on it, m.
    pub(super) tolerance: f64,
    /// Its largest extent, m.
    pub(super) size: f64,
    /// Whether it leaves its plane by more than the tolerance (a blade that turned).
    pub(super) curved: bool,
}

impl<'a> SweepIndex<'a> {
    pub(super) fn new(plane: &'a CutPlane) -> Self {
        let key = |p: &Point3<f64>| [p.x, p.y, p.z].map(f64::to_bits);
        // Each edge: how many triangles use it, its ends, the first one's unit normal, and
        // whether another meets it there at an angle.
        type Use = (usize, [Point3<f64>; 2], Vector3<f64>, bool);
        let mut count: FxHashMap<_, Use> = FxHashMap::default();
        for t in &plane.triangles {
            let normal = (t[1] - t[0])
                .cross(&(t[2] - t[0]))
                .try_normalize(0.0)
                .unwrap_or_else(Vector3::zeros);
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let (ka, kb) = (key(&a), key(&b));
                let k = if ka < kb { (ka, kb) } else { (kb, ka) };
                let e = count.entry(k).or_insert((0, [a, b], normal, false));
                if e.0 > 0 && e.2.cross(&normal).norm() > KINK {
                    e.3 = true;
                }
                e.0 += 1;
            }
        }
        let mut count: Vec<_> = count.into_iter().collect();
        // The same order every run.
        count.sort_by_key(|a| a.0);
        let edges = count
            .iter()
            .filter(|(_, (n, ..))| *n == 1)
            .map(|(_, (_, e, ..))| *e)
            .collect();
        let kinks = count
            .iter()
            .filter(|(_, (n, _, _, kinked))| *n == 2 && *kinked)
            .map(|(_, (_, e, ..))| *e)
            .collect();
        let (mut lo, mut hi) = bounds(
            &plane
                .triangles
                .iter()
                .flatten()
                .copied()
                .collect::<Vec<_>>(),
        );
        let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        let tolerance = ON_SWEEP * size;
        // A triangle with a corner on the sweep is near it.
        let pad = 2.0 * tolerance;
        for k in 0..3 {
            lo[k] -= pad;
            hi[k] += pad;
        }
        SweepIndex {
            plane,
            lo,
            hi,
            edges,
            kinks,
            tolerance,
            size,
            curved: plane
                .triangles
                .iter()
                .flatten()
                .any(|p| plane.normal.dot(&(p - plane.origin)).abs() > tolerance),
        }
    }

    /// The side of the sweep `p` lies on (that of its nearest triangle's plane, as
    /// [`side_of`] says), `None` when it lies on the sweep (within the tolerance); and whether
    /// it lies in that triangle's plane (on the sweep or beyond its boundary).
    pub(super) fn classify(&self, p: &Point3<f64>) -> (Option<bool>, bool) {
        let Some((t, d)) = self.nearest(p) else {
            return (Some(true), false);
        };
        let d2 = d * d;
        let normal = (t[1] - t[0]).cross(&(t[2] - t[0]));
        let height = normal.dot(&(p - t[0]));
        let in_plane = height.abs() <= self.tolerance * normal.norm();
        if d2 <= self.tolerance * self.tolerance {
            return (None, true);
        }
        (Some(height >= 0.0), in_plane)
    }

    /// The sweep's triangle nearest `p`, and the distance to it.
    pub(super) fn nearest(&self, p: &Point3<f64>) -> Option<(&[Point3<f64>; 3], f64)> {
        self.plane
            .triangles
            .iter()
            .map(|t| {
                let d = closest_on_triangle(p, &t[0], &t[1], &t[2]) - p;
                (t, d.norm())
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Whether a box meets the sweep's bounds.
    pub(super) fn near(&self, (lo, hi): ([f64; 3], [f64; 3])) -> bool {
        (0..3).all(|k| lo[k] <= self.hi[k] && hi[k] >= self.lo[k])
    }

    /// Where the segment `a b` crosses the sweep.
    pub(super) fn crossing(&self, a: &Point3<f64>, b: &Point3<f64>) -> Option<Point3<f64>> {
        self.plane
            .triangles
            .iter()
            .find_map(|t| segment_hits(a, b, t))
            .map(|s| a + (b - a) * s)
    }

    /// Whether `x` lies on the sweep's boundary (within the tolerance).
    pub(super) fn on_boundary(&self, x: &Point3<f64>) -> bool {
        self.edges.iter().any(|[a, b]| {
            let ab = b - a;
            let s = (ab.dot(&(x - a)) / ab.norm_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
            (a + ab * s - x).norm() <= self.tolerance
        })
    }

    /// Where the sweep's folds pierce the render triangle `t` inside it (farther than the
    /// tolerance from its edges), ordered from `from` to `to`: the corners of the line the
    /// sweep cuts across it between those two crossings of its edges.
    pub(super) fn folds_through(
        &self,
        t: &[Point3<f64>; 3],
        from: &Point3<f64>,
        to: &Point3<f64>,
    ) -> Vec<Point3<f64>> {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        let area = n.norm();
        if area == 0.0 || self.kinks.is_empty() {
            return Vec::new();
        }
        let inside = |x: &Point3<f64>| {
            (0..3).all(|k| {
                let (p, q) = (t[k], t[(k + 1) % 3]);
                (q - p).cross(&(x - p)).dot(&n) > self.tolerance * area * (q - p).norm()
            })
        };
        let mut out: Vec<(f64, Point3<f64>)> = self
            .kinks
            .iter()
            .filter_map(|[a, b]| segment_hits(a, b, t).map(|s| a + (b - a) * s))
            .filter(inside)
            .map(|x| ((x - from).dot(&(to - from)), x))
            .collect();
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        out.dedup_by(|a, b| (a.1 - b.1).norm() <= self.tolerance);
        out.into_iter().map(|(_, x)| x).collect()
    }

    /// Where the sweep's boundary pierces the triangle `t`.
    pub(super) fn boundary_through(&self, t: &[Point3<f64>; 3]) -> Option<Point3<f64>> {
        self.edges
            .iter()
            .find_map(|[a, b]| segment_hits(a, b, t).map(|s| a + (b - a) * s))
    }
}

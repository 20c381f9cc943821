//! Re-sweeps along a cut that splitting along faces ([`super::CutMethod::Separate`]) made. A
//! blade drawn again through a cut that opened under load meets the lips where the load carried
//! them: a lip tet whose centroid crossed the blade's plane is, to the face test alone,
//! separated from the tissue behind it, and cutting there would cut a one-tet slab off the lip.
//! Splitting follows faces, so it cannot cut parallel to an old cut within half a tet of it
//! anyway: such a crossing belongs to the old cut, and the blade makes nothing new.
//!
//! "Along the old cut" is decided in the tet's rest frame: each cut records, for both tets of
//! every face it separates, the blade's plane pulled back through that tet's deformation; a
//! later sweep is pulled back the same way and compared. Rigid motion and strain of the tissue
//! in between cancel, so a cut across a turned flap is still a new cut.

use nalgebra::{Matrix3, Point3, Vector3};
use rustc_hash::FxHashMap;

use super::exact::{segment_crosses_triangle, side};
use super::sweep::Sweep;
use crate::mesh::TetKey;

/// A plane in a tet's rest frame: the rest points `y` with `n . y = c` (`n` a unit vector).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestPlane {
    n: Vector3<f64>,
    c: f64,
}

/// Planes whose normals make more than this angle's cosine (30 degrees) count as one direction.
const ALONG_COS: f64 = 0.866;

impl RestPlane {
    /// The plane of triangle `t` (current frame) pulled back into the rest frame of a tet with
    /// corners `now` (current) and `rest`: the rest points its affine deformation puts on the
    /// plane. `None` for a tet flat at rest or crushed flat.
    pub fn pulled_back(
        t: &[Point3<f64>; 3],
        now: &[Point3<f64>; 4],
        rest: &[Point3<f64>; 4],
    ) -> Option<Self> {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0])).try_normalize(0.0)?;
        let edges =
            |p: &[Point3<f64>; 4]| Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        // x(y) = now[0] + F (y - rest[0]), F = Ds Dm^-1; the signed distance of x(y) to the
        // plane, n . (x(y) - t[0]), is affine in y with gradient F^T n.
        let f = edges(now) * edges(rest).try_inverse()?;
        let g = f.transpose() * n;
        let len = g.norm();
        if !(len > 0.0 && len.is_finite()) {
            return None;
        }
        let c = g.dot(&rest[0].coords) - n.dot(&(now[0] - t[0]));
        Some(RestPlane {
            n: g / len,
            c: c / len,
        })
    }

    /// Whether `other` runs along this plane near `at` (a rest point): normals within 30
    /// degrees (either way round) and the two planes within `tolerance` of each other there.
    pub fn along(&self, other: &RestPlane, at: &Point3<f64>, tolerance: f64) -> bool {
        let cos = self.n.dot(&other.n);
        if cos.abs() < ALONG_COS {
            return false;
        }
        let mine = self.n.dot(&at.coords) - self.c;
        let theirs = cos.signum() * (other.n.dot(&at.coords) - other.c);
        (mine - theirs).abs() <= tolerance
    }
}

/// For each tet, the tets a cut separated from it (across a face it opened or left on the crack
/// front), each with the blade's plane pulled back into the tet's rest frame at that cut.
///
/// A hash map, not a secondary map: few tets are ever cut, and a secondary map sized to the
/// largest key cut so far grows to the whole mesh at the first cut near its last tets (a
/// pause of milliseconds on a large mesh, most of it the kernel's first touch of the pages).
#[derive(Debug, Clone, Default)]
pub struct CutPartners(FxHashMap<TetKey, Vec<(TetKey, Option<RestPlane>)>>);

impl CutPartners {
    /// Record that a cut separated `a` (with the blade's plane in its rest frame) from `b`.
    pub fn record(&mut self, a: TetKey, b: TetKey, plane: Option<RestPlane>) {
        match self.0.get_mut(&a) {
            Some(list) => match list.iter_mut().find(|(t, _)| *t == b) {
                Some(entry) => entry.1 = plane,
                None => list.push((b, plane)),
            },
            None => {
                self.0.insert(a, vec![(b, plane)]);
            }
        }
    }

    /// The tets a cut separated from `t`, with the plane of that cut in `t`'s rest frame.
    pub fn of(&self, t: TetKey) -> &[(TetKey, Option<RestPlane>)] {
        self.0.get(&t).map_or(&[], Vec::as_slice)
    }
}

/// What the rule needs to know of a tet.
pub struct TetGeometry<C, R> {
    /// Corners at the classification (current) positions.
    pub now: C,
    /// Corners at rest.
    pub rest: R,
}

impl<C, R> TetGeometry<C, R>
where
    C: Fn(TetKey) -> [Point3<f64>; 4],
    R: Fn(TetKey) -> [Point3<f64>; 4],
{
    /// The plane of `t` in the rest frame of tet `k`.
    pub fn pulled_back(&self, k: TetKey, t: &[Point3<f64>; 3]) -> Option<RestPlane> {
        RestPlane::pulled_back(t, &(self.now)(k), &(self.rest)(k))
    }

    /// The sweep triangle that separates the centroids of `pair`, if any.
    pub fn separating<'s>(
        &self,
        pair: (TetKey, TetKey),
        sweep: &'s Sweep,
    ) -> Option<&'s [Point3<f64>; 3]> {
        let (c0, c1) = (centroid((self.now)(pair.0)), centroid((self.now)(pair.1)));
        sweep
            .triangles
            .iter()
            .find(|s| segment_crosses_triangle(&c0, &c1, s))
    }
}

/// Whether the sweep's separating `pair` (face neighbours) would cut along an old cut: one tet
/// of the pair, `x`, has a cut partner on the same side of the blade's plane as `x` now (the
/// plane does not separate what the old cut separated), and the blade's plane, pulled back into
/// `x`'s rest frame, runs along the old cut's (within 30 degrees, and within half of `x`'s
/// shortest rest edge at its rest centroid). The deformation has carried `x` across the plane
/// since it was cut from its partner: the blade runs in the old cut. A cut deepening the old
/// one separates the partners again, and a cut across it runs another way; neither is held.
pub fn along_old_cut<C, R>(
    pair: (TetKey, TetKey),
    partners: &CutPartners,
    sweep: &Sweep,
    tets: &TetGeometry<C, R>,
) -> bool
where
    C: Fn(TetKey) -> [Point3<f64>; 4],
    R: Fn(TetKey) -> [Point3<f64>; 4],
{
    let Some(t) = tets.separating(pair, sweep) else {
        return false;
    };
    [pair.0, pair.1].into_iter().any(|x| {
        let list = partners.of(x);
        if list.is_empty() {
            return false;
        }
        let (now, rest) = ((tets.now)(x), (tets.rest)(x));
        let cx = centroid(now);
        let Some(new) = RestPlane::pulled_back(t, &now, &rest) else {
            return false;
        };
        let tolerance = 0.5 * shortest_edge(&rest);
        list.iter().any(|&(e, old)| {
            let ce = centroid((tets.now)(e));
            side(t, &cx) == side(t, &ce)
                && old.is_some_and(|old| old.along(&new, &centroid(rest), tolerance))
        })
    })
}

fn centroid(p: [Point3<f64>; 4]) -> Point3<f64> {
    Point3::from((p[0].coords + p[1].coords + p[2].coords + p[3].coords) * 0.25)
}

fn shortest_edge(p: &[Point3<f64>; 4]) -> f64 {
    crate::mesh::TET_EDGES
        .iter()
        .map(|&[i, j]| (p[i] - p[j]).norm())
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use slotmap::SlotMap;

    /// A regular-ish tet of 1 cm edges around `c` (rest).
    fn tet_at(c: [f64; 3]) -> [Point3<f64>; 4] {
        let c = Point3::from(c);
        [
            c + Vector3::new(0.005, 0.0, -0.0035),
            c + Vector3::new(-0.005, 0.0, -0.0035),
            c + Vector3::new(0.0, 0.005, 0.0035),
            c + Vector3::new(0.0, -0.005, 0.0035),
        ]
    }

    type CornersOf<'a> = Box<dyn Fn(TetKey) -> [Point3<f64>; 4] + 'a>;

    /// Tets at rest and now, keyed.
    struct Tets {
        keys: Vec<TetKey>,
        rest: Vec<[Point3<f64>; 4]>,
        now: Vec<[Point3<f64>; 4]>,
    }

    impl Tets {
        /// Tets with rest centres `centres`, all moved now by `motion`, and then each by its
        /// own offset.
        fn new(centres: &[[f64; 3]], motion: Isometry3<f64>, offsets: &[[f64; 3]]) -> Self {
            let mut map: SlotMap<TetKey, ()> = SlotMap::with_key();
            let rest: Vec<_> = centres.iter().map(|&c| tet_at(c)).collect();
            let now = rest
                .iter()
                .zip(offsets)
                .map(|(t, o)| t.map(|p| motion * p + Vector3::from(*o)))
                .collect();
            Tets {
                keys: centres.iter().map(|_| map.insert(())).collect(),
                rest,
                now,
            }
        }

        fn index(&self, k: TetKey) -> usize {
            self.keys.iter().position(|&q| q == k).unwrap()
        }

        fn geometry(&self) -> TetGeometry<CornersOf<'_>, CornersOf<'_>> {
            TetGeometry {
                now: Box::new(move |k| self.now[self.index(k)]),
                rest: Box::new(move |k| self.rest[self.index(k)]),
            }
        }
    }

    /// A blade's sweep in the plane with normal `n` through `p`, 10 cm across.
    fn plane_sweep(p: Point3<f64>, n: Vector3<f64>) -> Sweep {
        let a = n
            .cross(&Vector3::x())
            .try_normalize(1e-9)
            .unwrap_or(Vector3::y());
        let b = n.cross(&a).normalize();
        let q = |s: f64, t: f64| p + a * s * 0.1 + b * t * 0.1;
        Sweep {
            triangles: vec![
                [q(-1.0, -1.0), q(1.0, -1.0), q(1.0, 1.0)],
                [q(-1.0, -1.0), q(1.0, 1.0), q(-1.0, 1.0)],
            ],
        }
    }

    /// Cut tet 0 from tet 1 across y = 0 at rest (recorded for both), as the cutter does.
    fn old_cut(tets: &Tets) -> CutPartners {
        let at_rest = TetGeometry {
            now: |k| tets.rest[tets.index(k)],
            rest: |k| tets.rest[tets.index(k)],
        };
        let sweep = plane_sweep(Point3::origin(), Vector3::y());
        let (a, b) = (tets.keys[0], tets.keys[1]);
        let t = at_rest
            .separating((a, b), &sweep)
            .expect("the old cut separates them");
        let mut p = CutPartners::default();
        p.record(a, b, at_rest.pulled_back(a, t));
        p.record(b, a, at_rest.pulled_back(b, t));
        p
    }

    // Tet 0 just below y = 0 (a lip); tet 1, its partner across the old cut; tet 2 behind tet
    // 0; tet 3 across the plane a centimetre deeper; tet 4 beside tet 0 along x.
    const CENTRES: [[f64; 3]; 5] = [
        [0.0, -0.0015, 0.0],
        [0.0, 0.0025, 0.0],
        [0.0, -0.0045, 0.0],
        [0.0, 0.0025, -0.01],
        [0.004, -0.0015, 0.0],
    ];

    #[test]
    fn a_lip_carried_across_the_plane_belongs_to_the_old_cut() {
        // The load carries tets 0 and 1 up by 1.7 mm, tet 2 by 1.2 mm: the lip crosses y = 0.
        for motion in [
            Isometry3::identity(),
            // The same with the whole tissue turned and moved: the rule does not care.
            Isometry3::from_parts(
                Translation3::new(0.3, -0.2, 0.1),
                UnitQuaternion::from_euler_angles(0.4, 1.1, -0.7),
            ),
        ] {
            let up = |h: f64| (motion.rotation * Vector3::new(0.0, h, 0.0)).into();
            let offsets = [up(1.7e-3), up(1.7e-3), up(1.2e-3), [0.0; 3], [0.0; 3]];
            let tets = Tets::new(&CENTRES, motion, &offsets);
            let partners = old_cut(&tets);
            let sweep = plane_sweep(motion * Point3::origin(), motion.rotation * Vector3::y());
            let pair = (tets.keys[0], tets.keys[2]);
            assert!(tets.geometry().separating(pair, &sweep).is_some());
            assert!(along_old_cut(pair, &partners, &sweep, &tets.geometry()));
            // Without the old cut it is a new one.
            let none = CutPartners::default();
            assert!(!along_old_cut(pair, &none, &sweep, &tets.geometry()));
        }
    }

    #[test]
    fn deepening_an_old_cut_is_new() {
        // Nothing moved; the blade goes on in the old cut's plane and separates tet 0 from tet
        // 3, deeper across it: tet 0's partner lies across the plane, as it should.
        let tets = Tets::new(&CENTRES, Isometry3::identity(), &[[0.0; 3]; 5]);
        let partners = old_cut(&tets);
        let sweep = plane_sweep(Point3::origin(), Vector3::y());
        let pair = (tets.keys[0], tets.keys[3]);
        assert!(tets.geometry().separating(pair, &sweep).is_some());
        assert!(!along_old_cut(pair, &partners, &sweep, &tets.geometry()));
    }

    #[test]
    fn a_cut_across_a_turned_flap_is_new() {
        // The tissue turned a quarter about z since the old cut: the world plane y = 2 mm
        // separates tet 0 from tet 4 and leaves tet 0 with its partner, but it runs across the
        // old cut in the tissue's own frame. (Compared in the world frame, the old cut's
        // direction would look parallel to it.)
        let quarter = Isometry3::rotation(Vector3::z() * std::f64::consts::FRAC_PI_2);
        let tets = Tets::new(&CENTRES, quarter, &[[0.0; 3]; 5]);
        let partners = old_cut(&tets);
        let sweep = plane_sweep(Point3::new(0.0, 0.002, 0.0), Vector3::y());
        let pair = (tets.keys[0], tets.keys[4]);
        assert!(tets.geometry().separating(pair, &sweep).is_some());
        assert!(!along_old_cut(pair, &partners, &sweep, &tets.geometry()));
        // A plane turned with the tissue runs along the old cut, and the lip lifted across it
        // is held.
        let along = plane_sweep(quarter * Point3::origin(), quarter * Vector3::y());
        let lifted = Tets::new(
            &CENTRES,
            quarter,
            &[
                (quarter.rotation * Vector3::new(0.0, 1.7e-3, 0.0)).into(),
                [0.0; 3],
                [0.0; 3],
                [0.0; 3],
                [0.0; 3],
            ],
        );
        let partners = old_cut(&lifted);
        let pair = (lifted.keys[0], lifted.keys[2]);
        assert!(lifted.geometry().separating(pair, &along).is_some());
        assert!(along_old_cut(pair, &partners, &along, &lifted.geometry()));
    }

    #[test]
    fn planes_along_each_other_within_the_angle_and_distance() {
        let rest = tet_at([0.0; 3]);
        let at = centroid(rest);
        let plane = |n: Vector3<f64>, p: Point3<f64>| {
            let t = plane_sweep(p, n).triangles[0];
            RestPlane::pulled_back(&t, &rest, &rest).unwrap()
        };
        let y = plane(Vector3::y(), Point3::origin());
        let tilted = |deg: f64| {
            let r = UnitQuaternion::from_euler_angles(0.0, 0.0, deg.to_radians());
            plane(r * Vector3::y(), Point3::origin())
        };
        assert!(y.along(&tilted(25.0), &at, 1e-3));
        assert!(!y.along(&tilted(35.0), &at, 1e-3));
        // Facing the other way is the same plane.
        assert!(y.along(&plane(-Vector3::y(), Point3::origin()), &at, 1e-9));
        let off = plane(Vector3::y(), Point3::new(0.0, 0.004, 0.0));
        assert!(y.along(&off, &at, 0.0045) && !y.along(&off, &at, 0.0035));
    }
}

//! Re-sweeps along a cut that splitting along faces ([`super::CutMethod::Separate`]) made. A
//! blade drawn again through a cut that opened under load meets the lips where the load carried
//! them: a lip tet whose centroid crossed the blade's plane is, to the face test alone,
//! separated from the tissue behind it, and cutting there would cut a one-tet slab off the lip.
//! Splitting follows faces, so it cannot cut parallel to an old cut within one tet of it anyway:
//! such a crossing belongs to the old cut, and the blade makes nothing new.

use nalgebra::Point3;
use slotmap::SecondaryMap;

use super::exact::{segment_crosses_triangle, side};
use super::sweep::Sweep;
use crate::mesh::TetKey;

/// Tets that a cut separated, per tet: the two tets of each face it opened or left on the
/// crack front.
#[derive(Debug, Clone, Default)]
pub struct CutPartners(SecondaryMap<TetKey, Vec<TetKey>>);

impl CutPartners {
    /// Record that a cut separated `a` and `b`.
    pub fn record(&mut self, a: TetKey, b: TetKey) {
        for (x, y) in [(a, b), (b, a)] {
            match self.0.get_mut(x) {
                Some(list) if list.contains(&y) => {}
                Some(list) => list.push(y),
                None => {
                    self.0.insert(x, vec![y]);
                }
            }
        }
    }

    /// The tets a cut separated from `t`.
    pub fn of(&self, t: TetKey) -> &[TetKey] {
        self.0.get(t).map_or(&[], Vec::as_slice)
    }
}

/// A partner counts as lying across the blade's plane when the direction to it is within 60
/// degrees of the plane's normal.
const ACROSS_COS: f64 = 0.5;

/// Where a tet is: its centroid at the classification positions and at rest.
pub struct Centroids<C, R> {
    /// At the classification (current) positions.
    pub now: C,
    /// At rest.
    pub rest: R,
}

/// Whether the sweep's separating `pair` (face neighbours) would cut along an old cut: one tet
/// of the pair has a cut partner that lay across the blade's plane from it at rest (the plane of
/// the sweep triangle between the pair's centroids; the direction between them within 60
/// degrees of its normal) and now lies on the same side. The deformation has carried that tet
/// across the plane since it was cut from its partner: the blade runs in the old cut. At rest
/// this never holds (a sweep meets the tissue where its rest geometry says), nor for a cut
/// across an old one.
pub fn along_old_cut<C, R>(
    pair: (TetKey, TetKey),
    partners: &CutPartners,
    sweep: &Sweep,
    centroid: &Centroids<C, R>,
) -> bool
where
    C: Fn(TetKey) -> Point3<f64>,
    R: Fn(TetKey) -> Point3<f64>,
{
    let (c0, c1) = ((centroid.now)(pair.0), (centroid.now)(pair.1));
    let Some(t) = sweep
        .triangles
        .iter()
        .find(|s| segment_crosses_triangle(&c0, &c1, s))
    else {
        return false;
    };
    let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
    if n.norm_squared() == 0.0 {
        return false;
    }
    let rest_side = |p: &Point3<f64>| (p - t[0]).dot(&n) >= 0.0;
    [pair.0, pair.1].into_iter().any(|x| {
        let (cx, rx) = ((centroid.now)(x), (centroid.rest)(x));
        partners.of(x).iter().any(|&e| {
            let (ce, re) = ((centroid.now)(e), (centroid.rest)(e));
            let d = re - rx;
            side(t, &cx) == side(t, &ce)
                && rest_side(&rx) != rest_side(&re)
                && d.dot(&n).abs() >= ACROSS_COS * d.norm() * n.norm()
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use slotmap::SlotMap;

    /// Tets reduced to their centroids, now and at rest.
    struct Scene {
        keys: Vec<TetKey>,
        now: Vec<Point3<f64>>,
        rest: Vec<Point3<f64>>,
    }

    impl Scene {
        fn new(tets: &[([f64; 3], [f64; 3])]) -> Self {
            let mut map: SlotMap<TetKey, ()> = SlotMap::with_key();
            Scene {
                keys: tets.iter().map(|_| map.insert(())).collect(),
                now: tets.iter().map(|t| Point3::from(t.0)).collect(),
                rest: tets.iter().map(|t| Point3::from(t.1)).collect(),
            }
        }

        fn along(&self, pair: (usize, usize), partners: &[(usize, usize)], sweep: &Sweep) -> bool {
            let mut p = CutPartners::default();
            for &(a, b) in partners {
                p.record(self.keys[a], self.keys[b]);
            }
            let at = |v: &Vec<Point3<f64>>, t: TetKey| {
                v[self.keys.iter().position(|&k| k == t).unwrap()]
            };
            let c = Centroids {
                now: |t| at(&self.now, t),
                rest: |t| at(&self.rest, t),
            };
            along_old_cut((self.keys[pair.0], self.keys[pair.1]), &p, sweep, &c)
        }
    }

    /// A blade swept down through the plane y = 0 (normal +y), over x, z in [-1, 1].
    fn plane_y0() -> Sweep {
        let p = |x: f64, z: f64| Point3::new(x, 0.0, z);
        Sweep {
            triangles: vec![
                [p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0)],
                [p(-1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)],
            ],
        }
    }

    #[test]
    fn a_lip_carried_across_the_plane_belongs_to_the_old_cut() {
        // Tet 0 was cut from tet 1 across y = 0; the load carried it to y = +0.2 mm. Tet 2
        // behind it did not cross.
        let s = Scene::new(&[
            ([0.0, 2e-4, 0.0], [0.0, -1e-3, 0.0]),
            ([0.0, 2.5e-3, 0.0], [0.0, 1.5e-3, 0.0]),
            ([0.0, -3e-3, 0.0], [0.0, -4e-3, 0.0]),
        ]);
        assert!(s.along((0, 2), &[(0, 1)], &plane_y0()));
        // Without that old cut, it is a new one.
        assert!(!s.along((0, 2), &[], &plane_y0()));
    }

    #[test]
    fn deepening_or_crossing_an_old_cut_is_new() {
        let sweep = plane_y0();
        // Deepening: tet 0 still lies on its own side, across from its partner; the sweep
        // separates it from tet 2 beyond the old cut's end.
        let s = Scene::new(&[
            ([0.0, -1e-3, 0.0], [0.0, -1e-3, 0.0]),
            ([0.0, 1.5e-3, 0.0], [0.0, 1.5e-3, 0.0]),
            ([0.0, 2e-3, -3e-3], [0.0, 2e-3, -3e-3]),
        ]);
        assert!(!s.along((0, 2), &[(0, 1)], &sweep));
        // Across: the old cut separated tet 0 from tet 1 along x, in the blade's plane's
        // direction; the blade now separates tet 0 from tet 2.
        let s = Scene::new(&[
            ([-1e-3, -1e-3, 0.0], [-1e-3, -1e-3, 0.0]),
            ([1e-3, -1e-3, 0.0], [1e-3, -1e-3, 0.0]),
            ([-1e-3, 1e-3, 0.0], [-1e-3, 1e-3, 0.0]),
        ]);
        assert!(!s.along((0, 2), &[(0, 1)], &sweep));
        // At rest: a pair that the sweep separates whose tets have partners on their own
        // sides of the plane.
        let s = Scene::new(&[
            ([0.0, -1e-3, 0.0], [0.0, -1e-3, 0.0]),
            ([0.0, 1e-3, 0.0], [0.0, 1e-3, 0.0]),
            ([0.0, -2e-3, 0.0], [0.0, -2e-3, 0.0]),
            ([0.0, 3e-3, 0.0], [0.0, 3e-3, 0.0]),
        ]);
        assert!(!s.along((0, 1), &[(0, 2), (1, 3)], &sweep));
    }
}

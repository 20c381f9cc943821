//! Subdividing a tet by the crossings on its edges, the same whatever order they came in.
//!
//! A blade that crosses a tet in one step and one that crosses it over several steps mark the
//! same edges, but splitting edges one at a time as they come makes sub-tets that depend on
//! the order (a quad face's diagonal goes to the node made first). So the sub-tets of a tet are
//! always worked out from the tet as it was before any split (its *parent*) and the full set of
//! its marked edges: the edges are bisected in one global order ([`edge_order`]: longest first,
//! then by the rest positions of their ends), and when a later step marks another edge of the
//! parent, its sub-tets are replaced by those of the larger set. Two tets sharing a face bisect
//! that face's marked edges in the same relative order, so their triangulations of it agree and
//! the mesh stays conforming. So a blade moving in its own plane makes the same tets in one step
//! or many; a blade moving out of its plane sweeps a curved surface, whose steps can snap and
//! end families differently.
//!
//! A family (a parent and its current sub-tets) lasts while its sub-tets are exactly the
//! template's: a cut that renames their corners (opening faces), or a split along an edge that
//! is not one of the parent's, ends it, and its sub-tets become parents of their own (see
//! `Cutter::parents_of` for keeping faces conforming around them).

use std::cmp::Ordering;

use nalgebra::Point3;
use rustc_hash::{FxHashMap, FxHashSet};
use slotmap::{new_key_type, SlotMap};

use crate::mesh::{NodeKey, TetKey, TET_EDGES};

new_key_type! {
    /// A tet subdivided by a cut, kept while its sub-tets follow the template.
    pub(super) struct FamilyKey;
}

/// A parent tet, the edges marked on it and its current sub-tets.
#[derive(Debug, Clone)]
pub(super) struct Family {
    /// The parent's corners, positively oriented.
    pub corners: [NodeKey; 4],
    pub region: i32,
    /// The node on each marked edge (an index into [`TET_EDGES`]).
    pub marks: Vec<(usize, NodeKey)>,
    /// The sub-tets now in the mesh.
    pub children: Vec<TetKey>,
    /// Whether the parent is a tet no cut had split (not a sub-tet of an ended family, whose
    /// faces may be parts of another parent's face).
    pub whole: bool,
}

/// The families of subdivided tets, which one each sub-tet belongs to, and the sub-tets of
/// ended families (loose).
#[derive(Debug, Clone, Default)]
pub(super) struct Families {
    families: SlotMap<FamilyKey, Family>,
    /// Hash maps, not secondary maps, for the reason `CutPartners` gives: few tets are ever
    /// subdivided.
    of: FxHashMap<TetKey, FamilyKey>,
    loose: FxHashSet<TetKey>,
}

impl Families {
    /// The family holding `t`, if any.
    pub fn of(&self, t: TetKey) -> Option<(FamilyKey, &Family)> {
        let f = *self.of.get(&t)?;
        Some((f, &self.families[f]))
    }

    /// Whether `t` is a sub-tet of an ended family: its faces may be parts of a parent's face.
    pub fn is_loose(&self, t: TetKey) -> bool {
        self.loose.contains(&t)
    }

    pub fn get(&self, f: FamilyKey) -> &Family {
        &self.families[f]
    }

    /// Start a family whose parent is the tet `t`, with corners `corners`.
    pub fn adopt(&mut self, t: TetKey, corners: [NodeKey; 4], region: i32) -> FamilyKey {
        let f = self.families.insert(Family {
            corners,
            region,
            marks: Vec::new(),
            children: vec![t],
            whole: !self.is_loose(t),
        });
        self.of.insert(t, f);
        self.loose.remove(&t);
        f
    }

    /// Mark the parent edge `edge` of `f` with node `k`.
    pub fn mark(&mut self, f: FamilyKey, edge: usize, k: NodeKey) {
        let marks = &mut self.families[f].marks;
        if !marks.iter().any(|&(e, _)| e == edge) {
            marks.push((edge, k));
        }
    }

    /// Give `f` its new sub-tets.
    pub fn set_children(&mut self, f: FamilyKey, children: Vec<TetKey>) {
        for &t in &self.families[f].children {
            self.of.remove(&t);
        }
        for &t in &children {
            self.of.insert(t, f);
            self.loose.remove(&t);
        }
        self.families[f].children = children;
    }

    /// End the family holding `t`, if any: its sub-tets stand alone from now on.
    pub fn end_family_of(&mut self, t: TetKey) {
        if let Some(&f) = self.of.get(&t) {
            self.end(f);
        }
    }

    /// End family `f`.
    pub fn end(&mut self, f: FamilyKey) {
        if let Some(family) = self.families.remove(f) {
            for t in family.children {
                self.of.remove(&t);
                // A sub-tet that is its parent whole is no part of another's face.
                if family.marks.is_empty() && family.whole {
                    continue;
                }
                self.loose.insert(t);
            }
        }
    }
}

/// The parent's six edges (indices into [`TET_EDGES`]) in the order they are bisected: longest
/// at rest first (bisecting the longest edge first keeps sub-tets rounder), ties by the rest
/// positions of their ends. A property of the edge alone, so every tet around it agrees.
pub(super) fn edge_order(rest: &[Point3<f64>; 4]) -> [usize; 6] {
    let key = |e: usize| {
        let [i, j] = TET_EDGES[e];
        let (a, b) = (rest[i], rest[j]);
        let (lo, hi) = if lexical(&a, &b) == Ordering::Greater {
            (b, a)
        } else {
            (a, b)
        };
        ((b - a).norm_squared(), lo, hi)
    };
    let mut order = [0, 1, 2, 3, 4, 5];
    order.sort_by(|&x, &y| {
        let (kx, ky) = (key(x), key(y));
        ky.0.total_cmp(&kx.0)
            .then_with(|| lexical(&kx.1, &ky.1))
            .then_with(|| lexical(&kx.2, &ky.2))
    });
    order
}

fn lexical(a: &Point3<f64>, b: &Point3<f64>) -> Ordering {
    a.x.total_cmp(&b.x)
        .then_with(|| a.y.total_cmp(&b.y))
        .then_with(|| a.z.total_cmp(&b.z))
}

/// The sub-tets of the tet `corners` with node `k` on each marked edge `(edge, k)`: the marked
/// edges bisected in `order`, each splitting every sub-tet holding it in two (one keeps each
/// end; orientation kept). Depends only on the set of marks, not on their order in `marks`.
pub(super) fn subdivide<T: Copy + PartialEq>(
    corners: [T; 4],
    marks: &[(usize, T)],
    order: &[usize; 6],
) -> Vec<[T; 4]> {
    let mut tets = vec![corners];
    for &e in order {
        let Some(&(_, k)) = marks.iter().find(|&&(m, _)| m == e) else {
            continue;
        };
        let [i, j] = TET_EDGES[e];
        let (a, b) = (corners[i], corners[j]);
        let mut next = Vec::with_capacity(tets.len() * 2);
        for t in tets {
            if t.contains(&a) && t.contains(&b) {
                next.push(t.map(|n| if n == b { k } else { n }));
                next.push(t.map(|n| if n == a { k } else { n }));
            } else {
                next.push(t);
            }
        }
        tets = next;
    }
    tets
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::signed_volume6;

    fn corners() -> [Point3<f64>; 4] {
        [
            Point3::new(0.1, -0.2, 0.05),
            Point3::new(1.3, 0.1, -0.1),
            Point3::new(0.2, 1.1, 0.2),
            Point3::new(0.3, 0.2, 0.9),
        ]
    }

    /// Points 0..4 are the corners, 4 + e the crossing on edge e (at a parameter per edge).
    fn points() -> Vec<Point3<f64>> {
        let c = corners();
        let mut p = c.to_vec();
        for (e, [i, j]) in TET_EDGES.iter().enumerate() {
            let t = 0.25 + 0.08 * e as f64;
            p.push(c[*i] + (c[*j] - c[*i]) * t);
        }
        p
    }

    /// The sub-tets as sets of corners (each is checked positive, so orientation is known).
    fn sorted(mut v: Vec<[usize; 4]>) -> Vec<[usize; 4]> {
        for t in &mut v {
            t.sort();
        }
        v.sort();
        v
    }

    #[test]
    fn every_set_of_marks_fills_the_tet_with_positive_sub_tets_whatever_their_order() {
        let p = points();
        let order = edge_order(&corners());
        let volume = signed_volume6(&p[0], &p[1], &p[2], &p[3]);
        for set in 0u32..64 {
            let marks: Vec<(usize, usize)> = (0..6)
                .filter(|e| set & (1 << e) != 0)
                .map(|e| (e, 4 + e))
                .collect();
            let tets = subdivide([0, 1, 2, 3], &marks, &order);
            let sum: f64 = tets
                .iter()
                .map(|t| {
                    let v = signed_volume6(&p[t[0]], &p[t[1]], &p[t[2]], &p[t[3]]);
                    assert!(v > 0.0, "marks {set:06b}: sub-tet {t:?} not positive");
                    v
                })
                .sum();
            assert!((sum - volume).abs() < 1e-12 * volume, "marks {set:06b}");
            let mut reversed = marks.clone();
            reversed.reverse();
            assert_eq!(
                sorted(subdivide([0, 1, 2, 3], &reversed, &order)),
                sorted(tets),
                "marks {set:06b}"
            );
        }
    }

    /// Two tets sharing a face, each subdivided with its own marks: the triangles of the shared
    /// face agree.
    #[test]
    fn tets_sharing_a_face_triangulate_it_alike() {
        let c = corners();
        // The mirror of corner 3 through face (0, 1, 2): tet (1, 0, 2, 4) is positive.
        let n = (c[1] - c[0]).cross(&(c[2] - c[0])).normalize();
        let mirror = c[3] - n * 2.0 * n.dot(&(c[3] - c[0]));
        let all = [c[0], c[1], c[2], c[3], mirror];
        let one = [0, 1, 2, 3];
        let two = [1, 0, 2, 4];
        // Crossing nodes named by their edge's ends, shared by both tets.
        let node = |a: usize, b: usize| 10 + a.min(b) * 5 + a.max(b);
        let marks_of = |t: [usize; 4], set: u32| -> Vec<(usize, usize)> {
            TET_EDGES
                .iter()
                .enumerate()
                .filter(|(_, [i, j])| {
                    let (a, b) = (t[*i].min(t[*j]), t[*i].max(t[*j]));
                    set & (1 << (a * 5 + b)) != 0
                })
                .map(|(e, [i, j])| (e, node(t[*i], t[*j])))
                .collect()
        };
        let face = |tets: Vec<[usize; 4]>| {
            let on = |n: usize| n < 3 || [node(0, 1), node(0, 2), node(1, 2)].contains(&n);
            let mut f: Vec<[usize; 3]> = tets
                .iter()
                .flat_map(|t| crate::mesh::TET_FACES.map(|l| l.map(|i| t[i])))
                .filter(|f| f.iter().all(|&n| on(n)))
                .map(|mut f| {
                    f.sort();
                    f
                })
                .collect();
            f.sort();
            f
        };
        // Bits a * 5 + b name edge (a, b): the shared face's three, then the other tets'.
        let bits = [1, 2, 7, 3, 8, 13, 4, 9, 14];
        for pattern in 0u32..(1 << bits.len()) {
            let set: u32 = bits
                .iter()
                .enumerate()
                .filter(|(i, _)| pattern & (1 << i) != 0)
                .map(|(_, b)| 1u32 << b)
                .sum();
            let sub = |t: [usize; 4]| {
                let rest = t.map(|i| all[i]);
                subdivide(t, &marks_of(t, set), &edge_order(&rest))
            };
            assert_eq!(face(sub(one)), face(sub(two)), "marks {set:025b}");
        }
    }
}

//! Which surface triangles hold each node, so that a cut that moves a few nodes in the layout
//! finds the triangles to renumber among theirs instead of scanning the whole surface (on a
//! 100k-tet box, some 20,000 triangles at every cut of the valence layout, whose patches move
//! nodes between buckets).

/// Triangle slots at each model node (ascending is not kept: the lists are a handful long).
#[derive(Debug, Clone, Default)]
pub struct TrianglesAtNodes {
    at: Vec<Vec<u32>>,
}

impl TrianglesAtNodes {
    /// The index of `triangles` (model node indices) over `nodes` nodes.
    pub fn of(triangles: &[[u32; 3]], nodes: usize) -> Self {
        let mut index = TrianglesAtNodes {
            at: crate::model::room::with_room(vec![Vec::new(); nodes]),
        };
        for (i, t) in triangles.iter().enumerate() {
            index.add(i as u32, t);
        }
        index
    }

    /// Room for `nodes` nodes (added nodes hold no triangle until one is added).
    pub fn grow(&mut self, nodes: usize) {
        if nodes > self.at.len() {
            self.at.resize(nodes, Vec::new());
        }
    }

    /// Slot `i` now holds triangle `t`.
    pub fn add(&mut self, i: u32, t: &[u32; 3]) {
        for &k in t {
            if let Some(list) = self.at.get_mut(k as usize) {
                list.push(i);
            }
        }
    }

    /// Slot `i` no longer holds triangle `t`.
    pub fn remove(&mut self, i: u32, t: &[u32; 3]) {
        for &k in t {
            if let Some(list) = self.at.get_mut(k as usize) {
                if let Some(p) = list.iter().position(|&x| x == i) {
                    list.swap_remove(p);
                }
            }
        }
    }

    /// Whether both hold the same triangles at every node, in whatever order (for checks).
    pub fn same_as(&self, other: &Self) -> bool {
        let sorted = |l: &[u32]| {
            let mut v = l.to_vec();
            v.sort_unstable();
            v
        };
        let n = self.at.len().max(other.at.len());
        (0..n as u32).all(|k| sorted(self.at(k)) == sorted(other.at(k)))
    }

    /// The slots of the triangles at node `k`.
    pub fn at(&self, k: u32) -> &[u32] {
        self.at.get(k as usize).map_or(&[], Vec::as_slice)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sorted(s: &[u32]) -> Vec<u32> {
        let mut v = s.to_vec();
        v.sort_unstable();
        v
    }

    #[test]
    fn edits_keep_the_index_equal_to_one_built_from_the_new_list() {
        let mut tris = vec![[0, 1, 2], [1, 2, 3], [2, 3, 4], [0, 3, 4]];
        let mut index = TrianglesAtNodes::of(&tris, 5);
        assert_eq!(sorted(index.at(2)), vec![0, 1, 2]);
        assert_eq!(
            index.at(9),
            &[] as &[u32],
            "a node past the index holds nothing"
        );
        // Slot 1 swapped for a triangle at a new node; one appended.
        index.grow(6);
        index.remove(1, &tris[1]);
        tris[1] = [1, 5, 3];
        index.add(1, &tris[1]);
        tris.push([5, 4, 0]);
        index.add(4, &tris[4]);
        let rebuilt = TrianglesAtNodes::of(&tris, 6);
        for k in 0..6 {
            assert_eq!(sorted(index.at(k)), sorted(rebuilt.at(k)), "node {k}");
        }
        assert!(index.same_as(&rebuilt));
        index.remove(4, &tris[4]);
        assert!(!index.same_as(&rebuilt), "a slot left out shows");
    }
}

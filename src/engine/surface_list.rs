//! The simulation's surface list edited in place by a cut: removed triangles swapped out,
//! added ones appended, and the edit undone the same way when the engine refuses it (no copy
//! of the whole surface per cut to restore from).

use std::collections::HashMap;

use crate::collide::broad::SurfaceEdit;

/// A surface triangle's corners in ascending order: the same key whichever way it is oriented.
pub(super) fn surface_key(t: &[u32; 3]) -> [u32; 3] {
    let mut k = *t;
    k.sort_unstable();
    k
}

/// What [`apply`] did, for [`undo`]: the slots whose triangle changed, and where each removed
/// triangle was.
pub(super) struct Applied {
    pub changed: Vec<u32>,
    removed_at: Vec<(usize, [u32; 3])>,
}

/// Apply `edit` (validated: every removed triangle is in `slots`, no added one is left in it)
/// to `triangles` and their `slots`.
pub(super) fn apply(
    triangles: &mut Vec<[u32; 3]>,
    slots: &mut HashMap<[u32; 3], u32>,
    edit: &SurfaceEdit,
) -> Applied {
    let mut changed = Vec::with_capacity(edit.removed.len() + edit.added.len());
    let mut removed_at = Vec::with_capacity(edit.removed.len());
    for t in &edit.removed {
        let slot = slots.remove(&surface_key(t)).expect("validated") as usize;
        triangles.swap_remove(slot);
        removed_at.push((slot, *t));
        if let Some(moved) = triangles.get(slot) {
            slots.insert(surface_key(moved), slot as u32);
            changed.push(slot as u32);
        }
    }
    for t in &edit.added {
        slots.insert(surface_key(t), triangles.len() as u32);
        changed.push(triangles.len() as u32);
        triangles.push(*t);
    }
    Applied {
        changed,
        removed_at,
    }
}

/// Undo what [`apply`] did with `edit`: the additions popped, then each removal's swap
/// reversed, last first.
pub(super) fn undo(
    triangles: &mut Vec<[u32; 3]>,
    slots: &mut HashMap<[u32; 3], u32>,
    edit: &SurfaceEdit,
    applied: Applied,
) {
    for t in &edit.added {
        triangles.pop();
        slots.remove(&surface_key(t));
    }
    for &(slot, t) in applied.removed_at.iter().rev() {
        if slot < triangles.len() {
            let moved = std::mem::replace(&mut triangles[slot], t);
            slots.insert(surface_key(&moved), triangles.len() as u32);
            triangles.push(moved);
        } else {
            triangles.push(t);
        }
        slots.insert(surface_key(&t), slot as u32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_edit_undone_leaves_the_list_and_its_slots_as_they_were() {
        let triangles: Vec<[u32; 3]> = (0..12).map(|i| [i, i + 1, i + 2]).collect();
        let slots: HashMap<[u32; 3], u32> = triangles
            .iter()
            .enumerate()
            .map(|(i, t)| (surface_key(t), i as u32))
            .collect();
        // The last triangle removed, one from the middle, the first; one flipped (removed and
        // added back reversed), two new.
        let edit = SurfaceEdit {
            removed: vec![[11, 12, 13], [5, 6, 7], [0, 1, 2], [3, 4, 5]],
            added: vec![[40, 41, 42], [5, 4, 3], [50, 51, 52]],
        };
        let (mut t, mut s) = (triangles.clone(), slots.clone());
        let applied = apply(&mut t, &mut s, &edit);
        assert_eq!(t.len(), 12 - 4 + 3);
        assert!(t
            .iter()
            .enumerate()
            .all(|(i, x)| s[&surface_key(x)] == i as u32));
        assert!(!t.contains(&[3, 4, 5]) && t.contains(&[5, 4, 3]));
        undo(&mut t, &mut s, &edit, applied);
        assert_eq!(t, triangles);
        assert_eq!(s, slots);
    }
}

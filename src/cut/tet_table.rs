//! What a cut's candidate scan reads of each tet, in one array indexed by the tet key's slot:
//! its corners as dense node indices, and the last cut that looked at it.
//!
//! The scan visits every tet at every node near the blade (about 3,000 per event on a
//! 100k-tet box) and, for each tet it has not seen, tests its bounds. Through the mesh that is
//! a stamp in a secondary map, a slot-map lookup of the tet and four lookups of its corners'
//! dense indices: cache misses that made up about a third of the cutter. Here it is one entry,
//! touched by the stamp and read again by the bounds test while still cached.
//!
//! The cutter keeps the entries current: it sets a tet's entry whenever it adds a tet or gives
//! one new corners ([`TetTable::set`]). Debug builds check every read against the mesh.

use slotmap::Key;

use crate::mesh::TetKey;

/// One tet's entry.
#[derive(Debug, Clone, Copy)]
struct Entry {
    /// The key the entry was set for ([`KeyData::as_ffi`]), so that a slot reused by a later
    /// tet is not read as the earlier one; `u64::MAX` for none.
    key: u64,
    corners: [u32; 4],
    stamp: u32,
}

const EMPTY: Entry = Entry {
    key: u64::MAX,
    corners: [u32::MAX; 4],
    stamp: 0,
};

/// Corners and scan stamps of every tet, by slot.
#[derive(Debug, Clone, Default)]
pub struct TetTable {
    entries: Vec<Entry>,
}

/// The slot index of a key (the low half of its FFI form, `slotmap::KeyData::as_ffi`; the
/// high half is its version).
fn slot(tk: TetKey) -> usize {
    (tk.data().as_ffi() & 0xffff_ffff) as usize
}

impl TetTable {
    /// Record the dense corners of tet `tk` (added, or given new corners).
    pub fn set(&mut self, tk: TetKey, corners: [u32; 4]) {
        let i = slot(tk);
        if i >= self.entries.len() {
            // Room for a quarter more: a cut adds tets a few at a time.
            self.entries
                .resize((i + 1).max(self.entries.len() * 5 / 4), EMPTY);
        }
        let e = &mut self.entries[i];
        // A new tet in a reused slot must not inherit the last cut's stamp.
        let stamp = if e.key == tk.data().as_ffi() {
            e.stamp
        } else {
            0
        };
        *e = Entry {
            key: tk.data().as_ffi(),
            corners,
            stamp,
        };
    }

    /// Forget tet `tk` (removed).
    pub fn forget(&mut self, tk: TetKey) {
        if let Some(e) = self.entries.get_mut(slot(tk)) {
            if e.key == tk.data().as_ffi() {
                *e = EMPTY;
            }
        }
    }

    /// The dense corners of tet `tk`, which must have been [`TetTable::set`] and not removed.
    pub fn corners(&self, tk: TetKey) -> [u32; 4] {
        self.get(tk)
            .unwrap_or_else(|| panic!("tet {tk:?} is not in the cutter's tet table"))
    }

    /// The dense corners of tet `tk`, or `None` if the table has no entry for it (a tet since
    /// removed, or one whose slot a later tet took).
    pub fn get(&self, tk: TetKey) -> Option<[u32; 4]> {
        self.entries
            .get(slot(tk))
            .filter(|e| e.key == tk.data().as_ffi())
            .map(|e| e.corners)
    }

    /// Stamp tet `tk` with `epoch`; true if it was not stamped with it already (the first
    /// visit of this scan).
    pub fn first_visit(&mut self, tk: TetKey, epoch: u32) -> bool {
        let e = &mut self.entries[slot(tk)];
        // Checked in every build, as `corners` is: the key sits beside the stamp, so the
        // comparison costs no memory access of its own.
        assert!(
            e.key == tk.data().as_ffi(),
            "tet {tk:?} is not in the cutter's tet table"
        );
        let first = e.stamp != epoch;
        e.stamp = epoch;
        first
    }

    /// Clear every stamp (the epoch counter wrapped).
    pub fn clear_stamps(&mut self) {
        for e in &mut self.entries {
            e.stamp = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slotmap::DenseSlotMap;

    #[test]
    fn a_reused_slot_is_a_new_tet_with_no_stamp() {
        let mut keys: DenseSlotMap<TetKey, ()> = DenseSlotMap::with_key();
        let a = keys.insert(());
        let mut t = TetTable::default();
        t.set(a, [1, 2, 3, 4]);
        assert!(t.first_visit(a, 7));
        assert!(!t.first_visit(a, 7));
        keys.remove(a);
        t.forget(a);
        let b = keys.insert(());
        assert_eq!(slot(a), slot(b), "the slot is reused");
        assert_eq!(t.get(a), None, "a forgotten tet has no entry");
        t.set(b, [5, 6, 7, 8]);
        assert_eq!(t.corners(b), [5, 6, 7, 8]);
        assert_eq!(t.get(b), Some([5, 6, 7, 8]));
        assert_eq!(
            t.get(a),
            None,
            "the slot's earlier tet is not read as the new one"
        );
        assert!(t.first_visit(b, 7));
        // New corners keep the stamp of the same tet.
        t.set(b, [5, 6, 7, 9]);
        assert!(!t.first_visit(b, 7));
        t.clear_stamps();
        assert!(t.first_visit(b, 7));
    }

    #[test]
    #[should_panic(expected = "not in the cutter's tet table")]
    fn a_stale_key_is_refused() {
        let mut keys: DenseSlotMap<TetKey, ()> = DenseSlotMap::with_key();
        let a = keys.insert(());
        let mut t = TetTable::default();
        t.set(a, [1, 2, 3, 4]);
        keys.remove(a);
        let b = keys.insert(());
        t.set(b, [5, 6, 7, 8]);
        t.corners(a);
    }
}

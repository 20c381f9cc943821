//! Room kept in the host arrays that cuts grow (nodes, springs), made with them: growing a
//! vector of megabytes copies it into fresh pages, a pause of 6-35 ms at 100,000 tets in the
//! fast CPU engine's arrays and of a millisecond or more at the first cut in the stability
//! bound's and the GPU engine's host copies at 375,000, where a cut otherwise costs under one.

/// Room for what cuts add to an array of `n` entries. A quarter: 350 subdividing cut events
/// into a 104,544-tet box add 16% nodes and 17% springs.
pub fn spare(n: usize) -> usize {
    n / 4
}

/// Make room in `v` for [`spare`] more entries than it holds.
pub fn reserve_room<T>(v: &mut Vec<T>) {
    v.reserve(spare(v.len()));
}

/// `v` with room for [`spare`] more entries (moved once, at construction).
pub fn with_room<T>(mut v: Vec<T>) -> Vec<T> {
    reserve_room(&mut v);
    v
}

/// A copy of `s` with room for [`spare`] more entries.
pub fn copy_with_room<T: Clone>(s: &[T]) -> Vec<T> {
    let mut v = Vec::with_capacity(s.len() + spare(s.len()));
    v.extend_from_slice(s);
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn room_is_a_quarter_more_and_keeps_the_entries() {
        let want: Vec<u32> = (0..800).collect();
        let v = with_room(want.clone());
        assert!(v.capacity() >= 1000, "{}", v.capacity());
        assert_eq!(v, want);
        let c = copy_with_room(&want);
        assert!(c.capacity() >= 1000, "{}", c.capacity());
        assert_eq!(c, want);
    }
}

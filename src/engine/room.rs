//! Room in the host arrays that cuts grow, as the GPU engine's device buffers have it (an
//! eighth more, their first upload's headroom): made with the engine, so that the first cut that
//! adds nodes does not move a whole array (and touch its pages for the first time) to a larger
//! one. On a mesh of a few hundred thousand nodes each such move was a pause of a millisecond
//! at the first cut.

/// Make room in `v` for an eighth more entries than it holds, at least 64.
pub fn reserve_room<T>(v: &mut Vec<T>) {
    v.reserve((v.len() / 8).max(64));
}

/// `v` with room for an eighth more entries ([`reserve_room`]).
pub fn with_room<T>(mut v: Vec<T>) -> Vec<T> {
    reserve_room(&mut v);
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn room_is_an_eighth_more_and_keeps_the_entries() {
        let v = with_room((0..800u32).collect::<Vec<_>>());
        assert!(v.capacity() >= 900, "{}", v.capacity());
        assert_eq!(v, (0..800u32).collect::<Vec<_>>());
        assert!(with_room(Vec::<u8>::new()).capacity() >= 64);
    }
}

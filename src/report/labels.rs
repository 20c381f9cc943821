//! Where the accuracy plot puts its point labels: beside their markers, never over another
//! label or marker. Points of different series often fall close together (the same step on
//! engines of similar speed), and labels drawn at one fixed offset then print over each other.

/// A label's top-left corner relative to its point, in pixels, tried in this order: above
/// right, below right, above left, below left, then level right and level left.
const OFFSETS: [(i32, i32); 6] = [(5, -16), (5, 4), (-5, -16), (-5, 4), (9, -6), (-9, -6)];

/// Half the side of the square kept clear around every marker, px.
const MARKER: i32 = 5;

/// An axis-aligned box in pixels: left, top, right, bottom.
type Rect = (i32, i32, i32, i32);

fn overlaps(a: Rect, b: Rect) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// The box of a label of `size` (width, height) placed with `offset` from `anchor`; a label to
/// the left of its point ends at the offset instead of starting there.
fn label_box(anchor: (i32, i32), offset: (i32, i32), size: (i32, i32)) -> Rect {
    let left = if offset.0 < 0 {
        anchor.0 + offset.0 - size.0
    } else {
        anchor.0 + offset.0
    };
    let top = anchor.1 + offset.1;
    (left, top, left + size.0, top + size.1)
}

/// For each label (its point `anchors[i]` in pixels and its text's `sizes[i]`), the offset of
/// its top-left corner from the point, or `None` where every candidate position would cover a
/// label already placed or any marker: that label is left out (the table has every number).
/// Labels are placed in order, so earlier ones win.
pub fn place_labels(anchors: &[(i32, i32)], sizes: &[(i32, i32)]) -> Vec<Option<(i32, i32)>> {
    let markers: Vec<Rect> = anchors
        .iter()
        .map(|&(x, y)| (x - MARKER, y - MARKER, x + MARKER, y + MARKER))
        .collect();
    let mut placed: Vec<Rect> = Vec::new();
    anchors
        .iter()
        .zip(sizes)
        .map(|(&anchor, &size)| {
            let spot = OFFSETS.iter().find_map(|&offset| {
                let b = label_box(anchor, offset, size);
                let free = !placed.iter().chain(&markers).any(|&o| overlaps(b, o));
                free.then_some((offset, b))
            });
            spot.map(|(offset, b)| {
                placed.push(b);
                // Text is drawn from its top-left corner: a label to the left starts at its
                // box's left edge.
                (b.0 - anchor.0, offset.1)
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxes(anchors: &[(i32, i32)], sizes: &[(i32, i32)]) -> Vec<Rect> {
        place_labels(anchors, sizes)
            .iter()
            .zip(anchors.iter().zip(sizes))
            .filter_map(|(o, (&a, &s))| {
                o.map(|(dx, dy)| (a.0 + dx, a.1 + dy, a.0 + dx + s.0, a.1 + dy + s.1))
            })
            .collect()
    }

    #[test]
    fn labels_of_points_close_together_never_overlap_each_other_or_a_marker() {
        // Five series at nearly the same place, and a ladder of points 12 px apart.
        let mut anchors = vec![(100, 100), (103, 101), (98, 99), (101, 104), (100, 100)];
        anchors.extend((0..10).map(|i| (200 + 12 * i, 150 - 3 * i)));
        let sizes = vec![(24, 11); anchors.len()];
        let placed = boxes(&anchors, &sizes);
        assert!(placed.len() >= 6, "only {} labels placed", placed.len());
        for (i, a) in placed.iter().enumerate() {
            for b in &placed[i + 1..] {
                assert!(!overlaps(*a, *b), "{a:?} and {b:?} overlap");
            }
            for &(x, y) in &anchors {
                let m = (x - MARKER, y - MARKER, x + MARKER, y + MARKER);
                assert!(!overlaps(*a, m), "{a:?} covers the marker at ({x}, {y})");
            }
        }
    }

    #[test]
    fn labels_of_points_far_apart_all_go_above_right() {
        let anchors = [(50, 50), (150, 120), (300, 40)];
        let offsets = place_labels(&anchors, &[(20, 11); 3]);
        assert_eq!(offsets, vec![Some((5, -16)); 3]);
    }
}

//! Current node positions in a box, as an engine answers them. A cut only looks at the tissue
//! near the blade, so it asks its [`PositionSource`] for the nodes in a box around the sweep (on
//! the GPU, one pass over the nodes and a readback of just those) instead of every node's
//! position, then for the few nodes around its candidates that the box missed. The engines
//! answer through this module whether or not the cutter is built (`cut` feature); what a cut
//! keeps of what it read is `crate::cut::reading::ReadPositions`.

use crate::error::{Error, Result};

/// Where a cut reads current node positions (m, dense model indices).
pub trait PositionSource {
    /// Every node whose current position lies in the box `lo..=hi` (a few outside it may come
    /// too), with its position, in any order (a node given twice is taken once).
    fn near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>>;
    /// The current positions of `nodes`, in their order.
    fn of(&mut self, nodes: &[u32]) -> Result<Vec<[f64; 3]>>;
}

/// Every node's current position, already read (dense order).
pub struct AllPositions<'a>(pub &'a [[f64; 3]]);

impl PositionSource for AllPositions<'_> {
    fn near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        Ok(self
            .0
            .iter()
            .enumerate()
            .filter(|(_, p)| inside(p, &lo, &hi))
            .map(|(i, &p)| (i as u32, p))
            .collect())
    }

    fn of(&mut self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        nodes
            .iter()
            .map(|&i| {
                self.0
                    .get(i as usize)
                    .copied()
                    .ok_or_else(|| Error::NodeOutOfRange {
                        node: i as u64,
                        count: self.0.len(),
                        message: format!(
                            "node {i} asked of {} positions; give every node's position",
                            self.0.len()
                        ),
                    })
            })
            .collect()
    }
}

/// Whether `p` lies in the box `lo..=hi`.
pub fn inside(p: &[f64; 3], lo: &[f64; 3], hi: &[f64; 3]) -> bool {
    (0..3).all(|c| p[c] >= lo[c] && p[c] <= hi[c])
}

/// The box `lo..=hi` in float32, grown by the rounding of float32 positions (rest plus
/// displacement) and of the box itself: every point inside in float64 is inside this one when
/// formed in float32. For engines that test positions in float32 first.
pub fn float32_box(lo: [f64; 3], hi: [f64; 3]) -> ([f32; 3], [f32; 3]) {
    let scale = (0..3)
        .map(|c| lo[c].abs().max(hi[c].abs()) + (hi[c] - lo[c]).abs())
        .fold(0.0, f64::max);
    let pad = 1e-6 * scale;
    (lo.map(|v| (v - pad) as f32), hi.map(|v| (v + pad) as f32))
}

/// Put nodes found near a blade in ascending node order, as [`crate::engine::Engine::nodes_near`]
/// gives them. The entries are 32 bytes: sorting 8-byte keys (node, place) and gathering once
/// moves a quarter of the bytes a sort of the entries does (a cut reads about a thousand).
pub fn sort_by_node(found: &mut Vec<(u32, [f64; 3])>) {
    if found.windows(2).all(|w| w[0].0 <= w[1].0) {
        return;
    }
    let mut keys: Vec<u64> = found
        .iter()
        .enumerate()
        .map(|(i, e)| (u64::from(e.0) << 32) | i as u64)
        .collect();
    keys.sort_unstable();
    *found = keys
        .iter()
        .map(|k| found[(k & 0xffff_ffff) as usize])
        .collect();
}

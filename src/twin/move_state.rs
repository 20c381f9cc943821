//! Twin of `shaders/move_state.wgsl` (pass `engine::gpu::move_state`): a patch's state moves,
//! every destination written from the state as it was before the patch. The blend is also the
//! fast engine's own ([`mix_state`], `engine::fast::patch`).

use crate::layout::patch::StateMove;

/// `a * (1 - t) + b * t` per component, in the order `shaders/move_state.wgsl` computes it:
/// the state a blended move writes, wherever it is computed.
pub fn mix_state(a: [f32; 4], b: [f32; 4], t: f32) -> [f32; 4] {
    std::array::from_fn(|c| a[c] * (1.0 - t) + b[c] * t)
}

impl StateMove {
    /// The state this move writes, given the state before the patch (one `[f32; 4]` per
    /// layout index): what the device computes, up to fused multiply-adds.
    pub fn apply_to(&self, old: &[[f32; 4]]) -> [f32; 4] {
        let Some(f) = self.from else {
            return [0.0; 4];
        };
        let a = old[f as usize];
        match self.blend {
            None => a,
            Some(b) => mix_state(a, old[b.with as usize], b.t),
        }
    }
}

/// One state buffer (layout order before the patch) after all of a patch's moves,
/// `slots` entries long (the layout's slots after the patch): entries no move writes keep
/// their value, and slots past `slots` (a shrinking patch clears them) are dropped.
pub fn move_state_cpu(state: &[[f32; 4]], moves: &[StateMove], slots: usize) -> Vec<[f32; 4]> {
    let mut out = state.to_vec();
    let most = moves.iter().map(|m| m.to as usize + 1).max().unwrap_or(0);
    out.resize(slots.max(most), [0.0; 4]);
    for m in moves {
        out[m.to as usize] = m.apply_to(state);
    }
    out.truncate(slots);
    out
}

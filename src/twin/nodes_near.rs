//! Twin of `shaders/nodes_near.wgsl` (pass `engine::gpu::nodes_near`): the node slots whose
//! current float32 position (rest plus displacement) lies in a float32 box. The GPU engine
//! narrows a read made ahead of a cut with the same test ([`in_box`]).

/// A node's current position as the pass forms it: rest plus displacement, in float32.
pub fn position(rest: [f32; 4], disp: [f32; 4]) -> [f32; 3] {
    [rest[0] + disp[0], rest[1] + disp[1], rest[2] + disp[2]]
}

/// Whether `x` lies in `lo..=hi` (bounds included), as the pass tests it.
pub fn in_box(x: [f32; 3], lo: [f32; 3], hi: [f32; 3]) -> bool {
    (0..3).all(|c| lo[c] <= x[c] && x[c] <= hi[c])
}

/// The slots whose position lies in `lo..=hi`, ascending, with their displacements: the set
/// the pass appends in some order. `rest` and `disp` are in layout order, one entry per slot.
pub fn nodes_near_cpu(
    rest: &[[f32; 4]],
    disp: &[[f32; 4]],
    lo: [f32; 3],
    hi: [f32; 3],
) -> Vec<(u32, [f32; 3])> {
    rest.iter()
        .zip(disp)
        .enumerate()
        .filter(|(_, (r, u))| in_box(position(**r, **u), lo, hi))
        .map(|(i, (_, u))| (i as u32, [u[0], u[1], u[2]]))
        .collect()
}

//! Twin of `shaders/device_copy.wgsl` (`report::device_copy`, the bandwidth floor's copy
//! kernel): every entry copied once, none written twice or skipped, however the dispatch folds
//! into rows. The arithmetic is nothing; what the twin states is the pass's coverage, which
//! its test checks through `report::device_copy::copy_on_device`.

/// The destination the copy pass leaves: `src`, entry for entry.
pub fn device_copy_cpu(src: &[[f32; 4]]) -> Vec<[f32; 4]> {
    src.to_vec()
}

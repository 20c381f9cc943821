//! The colour map of displacement magnitude, shared by the pictures (`lancet render`) and the
//! vertex colours of the `.glb` frames: viridis (perceptually uniform, readable in grey and by
//! most colour-blind viewers), from dark blue-violet at zero to yellow at the top of the range.
//!
//! Values are mapped linearly from `[0, max]` onto the map and clamped at both ends; a range
//! whose top is zero or not finite maps everything to the bottom colour.

/// Viridis at eleven evenly spaced stops (matplotlib's table sampled at 0, 0.1, ..., 1), RGB
/// in `[0, 1]`; between stops the map is interpolated linearly.
const VIRIDIS: [[f32; 3]; 11] = [
    [0.267, 0.005, 0.329],
    [0.283, 0.141, 0.458],
    [0.254, 0.265, 0.530],
    [0.207, 0.372, 0.553],
    [0.164, 0.471, 0.558],
    [0.128, 0.567, 0.551],
    [0.135, 0.659, 0.518],
    [0.267, 0.749, 0.441],
    [0.477504, 0.821444, 0.318195],
    [0.741, 0.873, 0.150],
    [0.993, 0.906, 0.144],
];

/// The colour of `t` in `[0, 1]` (clamped; NaN reads as 0).
pub fn viridis(t: f64) -> [f32; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = (x - i as f64) as f32;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [0, 1, 2].map(|c| a[c] + f * (b[c] - a[c]))
}

/// The colour of a displacement `d` (m) on the range `[0, max]`.
pub fn displacement_colour(d: f64, max: f64) -> [f32; 3] {
    if max > 0.0 && max.is_finite() {
        viridis(d / max)
    } else {
        viridis(0.0)
    }
}

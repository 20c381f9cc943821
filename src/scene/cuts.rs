//! Cutting in a scene run: the scene's `cut` section ([`SceneCut`]) made into the world's
//! [`CutSettings`]. The cutting itself is [`crate::world::cutting`]; its reports are
//! re-exported here under their old paths.

pub use super::cut_settings::{SceneCut, TimeStepPolicy};
use crate::cut::CutMethod;
pub use crate::world::cutting::{CutEvent, CutReport, CutSettings, TimeStepChange};

impl SceneCut {
    /// The world's settings for this section, cut by `method` (the first of `methods`
    /// otherwise), checked when `check` or the section asks, stepping at `bound_fraction` of
    /// a lowered bound under `Substep`.
    pub fn settings(
        &self,
        method: Option<CutMethod>,
        check: bool,
        bound_fraction: f64,
    ) -> CutSettings {
        CutSettings {
            method: method
                .or_else(|| self.methods.first().copied())
                .unwrap_or_default(),
            blades: self.blades.clone(),
            time_step: self.time_step,
            check: check || self.check,
            quality_floor: self.quality_floor,
            bound_fraction,
        }
    }
}

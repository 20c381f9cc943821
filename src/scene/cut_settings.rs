//! The `cut` section of a scene file: which methods and blades cut, what a cut that lowers the
//! stable bound does, whether the invariants are checked. Part of the schema that
//! [`super::cuts`] runs; it imports nothing of the scene, so the schema and the cut stage both
//! build on it.

use serde::{Deserialize, Serialize};

use crate::cut::CutMethod;

pub use crate::world::cutting::TimeStepPolicy;

/// Cutting settings of a scene.
///
/// ```ron
/// cut: Some((methods: [Separate, Remove], time_step: Substep, check: true)),
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneCut {
    /// The methods the scene runs with; the first unless the command line picks one. `lancet
    /// run` runs a scene once per method.
    pub methods: Vec<CutMethod>,
    /// Names of the blades that cut; empty for every blade of the scene.
    #[serde(default)]
    pub blades: Vec<String>,
    /// What a cut that lowers the stable bound below `dt` does.
    #[serde(default)]
    pub time_step: TimeStepPolicy,
    /// Check the invariants after every cut, and the engine patched so far against one built
    /// from scratch, device buffers included (also turned on by `lancet run --check`).
    #[serde(default)]
    pub check: bool,
    /// The rest volume-length ratio below which subdividing makes no tet (it snaps instead; see
    /// [`crate::cut::Cutter::with_quality_floor`]); 0 turns the floor off. The invariant check flags any
    /// tet below it, or below the uncut mesh's worst tet where that is lower (cuts do not
    /// mend the tets a mesh came with).
    #[serde(default = "default_quality_floor")]
    pub quality_floor: f64,
}

fn default_quality_floor() -> f64 {
    crate::cut::subdivide::DEFAULT_QUALITY_FLOOR
}

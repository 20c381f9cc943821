//! How a simulation runs: the time step, the integrator, the force model, the node order the
//! engines pack in, and how often divergence is checked ([`SimConfig`]); and, apart from it, how the GPU engine
//! lays out the springs ([`GpuOptions`]), given where the GPU engine is chosen.

use super::*;

/// How a simulation runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimConfig {
    /// Time step, s.
    pub dt: f64,
    /// Integration scheme.
    #[serde(default)]
    pub integrator: Integrator,
    /// How [`Integrator::BackwardEuler`] solves each step (ignored by the explicit schemes).
    #[serde(default)]
    pub solver: crate::physics::SolverSettings,
    /// Run even when `dt` is above the stable bound (divergence is still detected).
    #[serde(default)]
    pub allow_unstable: bool,
    /// Run on when watched tets turn inside out ([`crate::engine::Simulation::watch_mesh`]);
    /// by default the checks report them as [`crate::Error::Inverted`], like a divergence.
    #[serde(default)]
    pub allow_inverted: bool,
    /// Steps between divergence checks; divergence is reported at most this many steps after
    /// the energy crosses the limit.
    #[serde(default = "default_check_every")]
    pub check_every: u32,
    /// How the fast CPU engine and the GPU engine number the nodes when they pack the model
    /// (default: reverse Cuthill–McKee). Internal: results are the same physics in any order,
    /// only memory locality, hence speed, changes.
    #[serde(default)]
    pub node_order: NodeOrdering,
    /// The force model the elements exert (default: springs). The finite-element models run
    /// on the float64 reference engine and, with an explicit scheme, the fast float32 engine;
    /// the GPU engine refuses them (and `Auto` runs the fast engine, saying why).
    #[serde(default)]
    pub force_model: ForceModelKind,
}

/// How the GPU engine lays out and sums the springs: what only the GPU engine reads, given
/// where it is chosen ([`Simulation::with_gpu`], [`crate::engine::gpu::GpuEngine::new`]) rather
/// than in every simulation's [`SimConfig`]. The default is the connectivity layout; a
/// [`crate::layout::LayoutKind`] converts into these options with the default accumulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct GpuOptions {
    /// Spring layout of the GPU engine.
    #[serde(default)]
    pub layout: crate::layout::LayoutKind,
    /// How the edge layout brings spring forces to the nodes (default: the deterministic
    /// gather, the fastest on lavapipe); ignored by the other layouts.
    #[serde(default)]
    pub accumulation: crate::layout::edges::Accumulation,
}

impl From<crate::layout::LayoutKind> for GpuOptions {
    fn from(layout: crate::layout::LayoutKind) -> Self {
        GpuOptions {
            layout,
            ..GpuOptions::default()
        }
    }
}

/// The node numbering an engine packs its arrays in.
///
/// Engines renumber nodes so that a node's neighbours sit close in memory; the other orders
/// exist to measure what that buys (`lancet bench --order`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum NodeOrdering {
    /// Reverse Cuthill–McKee order of the spring graph: neighbours get nearby indices.
    #[default]
    Locality,
    /// The model's own order (as the mesh file or generator numbered the nodes).
    Identity,
    /// A random permutation drawn from this seed (the same seed gives the same order): the
    /// worst case for locality.
    Random(u64),
}

impl NodeOrdering {
    /// The renumbering of `model`'s nodes this ordering gives.
    pub fn order(self, model: &PackedModel) -> crate::layout::NodeOrder {
        use crate::layout::NodeOrder;
        match self {
            NodeOrdering::Locality => NodeOrder::locality(model),
            NodeOrdering::Identity => NodeOrder::identity(model.node_count()),
            NodeOrdering::Random(seed) => {
                NodeOrder::from_order(random_permutation(model.node_count(), seed))
            }
        }
    }
}

impl std::fmt::Display for NodeOrdering {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NodeOrdering::Locality => f.write_str("rcm"),
            NodeOrdering::Identity => f.write_str("identity"),
            NodeOrdering::Random(seed) => write!(f, "random({seed})"),
        }
    }
}

/// A Fisher–Yates shuffle of `0..n` driven by SplitMix64: deterministic for a seed and
/// identical on every platform, with no dependency on a random-number crate.
fn random_permutation(n: usize, seed: u64) -> Vec<u32> {
    let mut state = seed;
    let mut next = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut order: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        // Modulo bias is below 2^-40 for any mesh that fits in memory: irrelevant here.
        let j = (next() % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    order
}

fn default_check_every() -> u32 {
    10
}

impl SimConfig {
    /// Verlet at step `dt`, refusing unstable steps, checking every 10 steps.
    pub fn new(dt: f64) -> Self {
        SimConfig {
            dt,
            integrator: Integrator::Verlet,
            solver: crate::physics::SolverSettings::default(),
            allow_unstable: false,
            allow_inverted: false,
            check_every: default_check_every(),
            node_order: NodeOrdering::Locality,
            force_model: ForceModelKind::Springs,
        }
    }
}

//! The scene file format (RON): what to simulate, how, what to write and what to check.
//!
//! ```ron
//! Scene(
//!     name: "hanging beam",
//!     mesh: Beam(length: 0.1, width: 0.02, height: 0.02, cells_along: 20, cells_across: 4),
//!     material: (
//!         stiffness: Material(youngs_modulus: 5e4, poisson_ratio: 0.25),
//!         mass: Density(1000.0),
//!         damping: StiffnessProportional(1e-3),
//!     ),
//!     gravity: (0.0, 0.0, -9.81),
//!     fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: 1e-9)],
//!     dt: BoundFraction(0.9),
//!     steps: 2000,
//!     expect: [MaxDisplacement(min: Some(1e-3), max: Some(2e-2))],
//! )
//! ```

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::collide::{ToolShape, Trajectory};
use crate::engine::{EngineKind, Integrator};
use crate::error::{Error, Result};
use crate::mesh::generate::{BoxGrid, TetSplit};
use crate::model::{FixedSelector, Material};

/// Where the mesh comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum MeshSource {
    /// A mesh file. A relative path is taken from the scene file's folder; a path starting with
    /// `$LANCET_MESH_DIR/` from that environment variable's folder.
    File(String),
    /// A generated box of cells.
    Box(BoxGrid),
    /// Several generated boxes in one mesh (separate pieces, e.g. a block dropped on another).
    Boxes(Vec<BoxGrid>),
    /// A generated beam along x.
    Beam {
        /// Length along x, m.
        length: f64,
        /// Width along y, m.
        width: f64,
        /// Height along z, m.
        height: f64,
        /// Cells along x.
        cells_along: usize,
        /// Cells across y and z.
        cells_across: usize,
        /// How cells are split.
        #[serde(default)]
        split: TetSplit,
    },
}

/// A box of space whose tets (by centroid) get a region tag.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionBox {
    /// The tag to give.
    pub tag: i32,
    /// Smallest corner.
    pub min: [f64; 3],
    /// Largest corner.
    pub max: [f64; 3],
}

/// The fraction of the new stable bound a cut lowers the step to under `Substep` when the
/// scene gives its step in seconds (a scene with a `BoundFraction` step uses that fraction).
pub const DEFAULT_BOUND_FRACTION: f64 = crate::world::cutting::DEFAULT_BOUND_FRACTION;

/// The time step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum TimeStep {
    /// A fixed step, s.
    Seconds(f64),
    /// This fraction of the model's stable bound.
    BoundFraction(f64),
}

/// Writing results.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Folder for the frames and the `.pvd` (relative to the scene file's folder).
    pub dir: String,
    /// Write a VTU frame every this many steps (the first and last states are always written).
    pub every: u64,
}

/// Something the run must satisfy; checked after the last step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Expectation {
    /// Bounds on the largest nodal displacement, m.
    MaxDisplacement {
        /// Lower bound.
        #[serde(default)]
        min: Option<f64>,
        /// Upper bound.
        #[serde(default)]
        max: Option<f64>,
    },
    /// Bounds on the displacement of the node nearest `point` (rest position): one component
    /// (0 = x, 1 = y, 2 = z) or, without `component`, its magnitude.
    DisplacementAt {
        /// Rest position to look up the nearest node.
        point: [f64; 3],
        /// Which component; `None` for the magnitude.
        #[serde(default)]
        component: Option<usize>,
        /// Lower bound.
        #[serde(default)]
        min: Option<f64>,
        /// Upper bound.
        #[serde(default)]
        max: Option<f64>,
    },
    /// Bounds on deformed volume / rest volume.
    VolumeRatio {
        /// Lower bound.
        #[serde(default)]
        min: Option<f64>,
        /// Upper bound.
        #[serde(default)]
        max: Option<f64>,
    },
    /// Bounds on an energy at the end, J.
    Energy {
        /// Which energy.
        part: EnergyPart,
        /// Lower bound.
        #[serde(default)]
        min: Option<f64>,
        /// Upper bound.
        #[serde(default)]
        max: Option<f64>,
    },
    /// Bounds on the largest force a tool felt during the run (magnitude), N.
    ToolForce {
        /// The tool's name.
        tool: String,
        /// Lower bound.
        #[serde(default)]
        min: Option<f64>,
        /// Upper bound.
        #[serde(default)]
        max: Option<f64>,
    },
    /// Bounds on the number of connected pieces at the end (cut scenes count fragments).
    Fragments {
        /// Lower bound.
        #[serde(default)]
        min: Option<usize>,
        /// Upper bound.
        #[serde(default)]
        max: Option<usize>,
    },
    /// Bounds on the number of steps at which a cut changed the mesh.
    Cuts {
        /// Lower bound.
        #[serde(default)]
        min: Option<usize>,
        /// Upper bound.
        #[serde(default)]
        max: Option<usize>,
    },
    /// Bounds on the nodes cuts created.
    NodesAdded {
        /// Lower bound.
        #[serde(default)]
        min: Option<usize>,
        /// Upper bound.
        #[serde(default)]
        max: Option<usize>,
    },
    /// Bounds on the rest volume carving removed, as a fraction of the volume before.
    VolumeRemoved {
        /// Lower bound.
        #[serde(default)]
        min: Option<f64>,
        /// Upper bound.
        #[serde(default)]
        max: Option<f64>,
    },
    /// Bounds on how far a grasper carried the tissue it held: the largest, over the steps it
    /// held nodes, of their mean distance from their rest positions, m. Zero (so a positive
    /// `min` fails) when it never held anything.
    GraspCarried {
        /// The grasper's name.
        tool: String,
        /// Lower bound.
        #[serde(default)]
        min: Option<f64>,
        /// Upper bound.
        #[serde(default)]
        max: Option<f64>,
    },
    /// Bounds on how far the incision opened at the end: the largest distance between a node
    /// and a copy of it, m (splitting methods).
    Opening {
        /// Lower bound.
        #[serde(default)]
        min: Option<f64>,
        /// Upper bound.
        #[serde(default)]
        max: Option<f64>,
    },
    /// Upper bound on the fraction of the layout any one cut uploaded (an engine rebuilt at a
    /// lowered time step under `Substep` counts whole, so such a cut uploads more than 1).
    UploadFraction {
        /// Upper bound.
        max: f64,
    },
    /// Every cut kept the invariants (`cut.check` is turned on by this expectation).
    InvariantsHold,
    /// An expectation that applies only when the scene runs with this cut method.
    Method(crate::cut::CutMethod, Box<Expectation>),
    /// The run must be refused because dt is above the stable bound.
    RefusesTimeStep,
    /// The run must diverge and be reported (for scenes forced past the bound).
    Diverges,
}

/// Which energy an [`Expectation::Energy`] bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum EnergyPart {
    /// Kinetic energy (near zero once the body has settled).
    Kinetic,
    /// Energy stored in the springs.
    Elastic,
    /// Gravitational potential, zero at rest positions.
    Gravity,
    /// The sum.
    Total,
}

/// A scene: mesh, model, run settings, outputs and expectations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Name shown in summaries.
    pub name: String,
    /// The mesh.
    pub mesh: MeshSource,
    /// Scale, rotation and translation of the mesh as read or generated (a file without units
    /// or in millimetres brought to metres); everything else in the scene is in the placed
    /// mesh's coordinates.
    #[serde(default)]
    pub mesh_transform: super::placement::MeshTransform,
    /// A detailed surface drawn in place of the tets (`surface: File("organ.obj")`: OBJ, STL or
    /// PLY), placed by `mesh_transform` like the mesh and embedded in it at rest; with output
    /// on, its deformed shape is written per frame (see [`super::surface`]).
    #[serde(
        default,
        deserialize_with = "super::surface::deserialize",
        serialize_with = "super::surface::serialize",
        skip_serializing_if = "Option::is_none"
    )]
    pub surface: Option<super::surface::SurfaceSource>,
    /// Region tags to assign to generated (or file) meshes, applied in order.
    #[serde(default)]
    pub region_boxes: Vec<RegionBox>,
    /// Default material.
    pub material: Material,
    /// Materials by region tag.
    #[serde(default)]
    pub regions: BTreeMap<i32, Material>,
    /// Gravity, m/s^2.
    #[serde(default)]
    pub gravity: [f64; 3],
    /// Mass-proportional damping, 1/s.
    #[serde(default)]
    pub mass_damping: f64,
    /// Fixed nodes.
    #[serde(default)]
    pub fixed: Vec<FixedSelector>,
    /// Time step.
    pub dt: TimeStep,
    /// Number of steps.
    pub steps: u64,
    /// Engine.
    #[serde(default)]
    pub engine: EngineKind,
    /// GPU memory layout (for `engine: Gpu` or `Auto`).
    #[serde(default)]
    pub layout: crate::layout::LayoutKind,
    /// How the GPU edge layout brings spring forces to the nodes (`Gather`, `AtomicFixed`,
    /// `AtomicFloat`); ignored by the other layouts and engines.
    #[serde(default)]
    pub accumulation: crate::layout::edges::Accumulation,
    /// Integration scheme.
    #[serde(default)]
    pub integrator: Integrator,
    /// How `integrator: BackwardEuler` solves each step: `solver: (tolerance: 1e-5,
    /// max_iterations: 100)` (the defaults; `newton_iterations: 1`, `linearization: Definite`
    /// may be given too). Ignored by the explicit schemes.
    #[serde(default)]
    pub solver: crate::physics::SolverSettings,
    /// Force model: `Springs` (the default), `TensorMass` or `Corotational` (finite elements
    /// from each region's Young's modulus and Poisson ratio, on every engine and GPU layout,
    /// explicit or `BackwardEuler`; the GPU edge layout's atomic variants refuse tensor-mass
    /// and backward Euler; cuts update them tet by tet).
    #[serde(default)]
    pub force_model: crate::physics::ForceModelKind,
    /// Run even if dt is above the stable bound.
    #[serde(default)]
    pub allow_unstable: bool,
    /// Run on when tets turn inside out ([`crate::engine::SimConfig::allow_inverted`]). By
    /// default the simulation checks for inverted tets every
    /// [`crate::engine::INVERSION_CHECK_EVERY`] steps and stops, reported like a divergence,
    /// at the first step with one.
    #[serde(default)]
    pub allow_inverted: bool,
    /// VTU output.
    #[serde(default)]
    pub output: Option<Output>,
    /// What the run must satisfy.
    #[serde(default)]
    pub expect: Vec<Expectation>,
    /// Surgical tools and how they move: each step the runner poses them from their
    /// trajectories, culls the surface against them, pushes penetrating tissue out and records
    /// the force on each (`RunSummary::tools`).
    #[serde(default)]
    pub tools: Vec<SceneTool>,
    /// Cutting: the blades among `tools` cut the mesh as they sweep through it.
    #[serde(default)]
    pub cut: Option<super::cut_settings::SceneCut>,
    /// Tissue against itself: each step its surfaces that come closer than `thickness` are
    /// pushed apart symmetrically (`contact::self_response`).
    #[serde(default)]
    pub self_contact: Option<SceneSelfContact>,
}

/// Self-contact settings of a scene.
///
/// ```ron
/// self_contact: Some((thickness: 1e-4, max_depth: 1e-3)),
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSelfContact {
    /// Surfaces are kept this far apart, m.
    pub thickness: f64,
    /// How far behind the other surface a node may be and still be pushed back out, m (keep it
    /// below the size of a surface element).
    pub max_depth: f64,
    /// Sweeps over the contacts per step.
    #[serde(default = "default_self_contact_iterations")]
    pub iterations: usize,
}

fn default_self_contact_iterations() -> usize {
    8
}

/// A tool in a scene: a name for reports, a rigid shape, and how it moves.
///
/// ```ron
/// tools: [
///     (
///         name: "probe",
///         shape: Probe(radius: 0.002, length: 0.05),
///         trajectory: Keyframes([
///             (time: 0.0, translation: (0.05, 0.01, 0.03)),
///             (time: 0.5, translation: (0.05, 0.01, 0.018), rotation: (0.0, 0.2, 0.0)),
///         ]),
///     ),
///     (
///         name: "needle",
///         shape: Probe(radius: 0.0004, length: 0.04),
///         trajectory: Velocity(translation: (0.02, 0.01, 0.03), linear: (0.0, 0.0, -0.01)),
///     ),
///     (
///         name: "grasper",
///         shape: Grasper(jaw: (0.001, 0.006, 0.003), opening: 0.002),
///         trajectory: Keyframes([(time: 0.0, translation: (0.022, 0.005, 0.001))]),
///         // Closed (holding what lies between the jaws) from 0.02 s to 0.3 s.
///         grasp: [(close: 0.02, open: 0.3)],
///     ),
/// ]
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneTool {
    /// Name shown in summaries and force reports; unique within the scene.
    pub name: String,
    /// The rigid shape (tool frame: axis along local z, working end at the origin).
    pub shape: ToolShape,
    /// Keyframed poses or a scripted velocity.
    pub trajectory: Trajectory,
    /// When a grasper holds the tissue: at each window's `close` time it captures the surface
    /// nodes between its jaws ([`crate::contact::grasp::Grasp::close`]), carries them with it
    /// every step, and lets them go at `open`. Only for a `Grasper`; windows in increasing
    /// time, not overlapping.
    #[serde(default)]
    pub grasp: Vec<GraspWindow>,
}

/// A time window during which a grasper holds what lies between its jaws.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraspWindow {
    /// Time the grasper closes, s.
    pub close: f64,
    /// Time it opens again, s (after `close`).
    pub open: f64,
    /// How far outside the space between the jaws' inner faces a node may lie and still be
    /// captured, m; by default the jaw's half-thickness (`jaw.0`).
    #[serde(default)]
    pub reach: Option<f64>,
}

impl SceneTool {
    /// The grasp window holding time `t` (closed on `close <= t < open`), if any.
    pub fn grasp_at(&self, t: f64) -> Option<&GraspWindow> {
        self.grasp.iter().find(|w| w.close <= t && t < w.open)
    }

    /// Check the grasp windows against the shape: only a grasper grasps, times are finite and
    /// increasing, a reach is positive.
    fn validate_grasp(&self) -> std::result::Result<(), String> {
        if self.grasp.is_empty() {
            return Ok(());
        }
        let ToolShape::Grasper { .. } = self.shape else {
            return Err(
                "only a grasper can grasp: remove `grasp` or make the shape a Grasper".into(),
            );
        };
        for (k, w) in self.grasp.iter().enumerate() {
            if !(w.close.is_finite() && w.open.is_finite()) {
                return Err(format!(
                    "grasp window {k}: close ({}) and open ({}) must be finite times in seconds",
                    w.close, w.open
                ));
            }
            if w.open <= w.close {
                return Err(format!(
                    "grasp window {k}: opens at {} s, not after it closes at {} s; give open > \
                     close",
                    w.open, w.close
                ));
            }
            if let Some(prev) = k.checked_sub(1).map(|j| self.grasp[j]) {
                if w.close < prev.open {
                    return Err(format!(
                        "grasp window {k} closes at {} s, before window {} opens at {} s; list \
                         windows in increasing time without overlap",
                        w.close,
                        k - 1,
                        prev.open
                    ));
                }
            }
            if let Some(r) = w.reach {
                if !(r.is_finite() && r >= 0.0) {
                    return Err(format!(
                        "grasp window {k}: reach must be zero or positive and finite, got {r} m"
                    ));
                }
            }
        }
        Ok(())
    }
}

/// A scene error placed at the line of the first field `field` in `text` (a line that starts,
/// after white space, with `field:`), where there is one: the checks run on the parsed scene,
/// which keeps no lines.
fn at_field_line(e: Error, text: &str, field: &str) -> Error {
    let line = text.lines().position(|l| {
        l.trim_start()
            .strip_prefix(field)
            .is_some_and(|rest| rest.trim_start().starts_with(':'))
    });
    match (e, line) {
        (Error::Scene { path, message }, Some(i)) => {
            Error::parse(path, crate::error::Location::Line(i + 1), None, message, "")
        }
        (e, _) => e,
    }
}

/// The scene lancet runs when given none: a soft beam, clamped at one end, sagging under
/// gravity. Embedded so that `lancet run` works with no files.
pub const DEFAULT_SCENE: &str = include_str!("../../fixtures/scenes/default.ron");

impl Scene {
    /// Parse a scene from RON text; `path` is used in messages.
    /// Tools, cut settings, fixed-node selectors and expectations are validated here (see
    /// [`Scene::validate_expectations`]), so a mistake is reported before any mesh is read.
    /// Unknown fields are refused, naming the nearest valid one.
    pub fn from_ron(text: &str, path: &Path) -> Result<Scene> {
        // A UTF-8 byte-order mark (editors on Windows write one) is not RON.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let scene: Scene = ron::from_str(text).map_err(|e| {
            let (message, hint) = describe_ron_error(&e.code);
            Error::parse(
                path,
                crate::error::Location::Line(e.span.start.line),
                None,
                format!("scene is not valid: {message}"),
                hint,
            )
        })?;
        scene.validate_tools(path)?;
        scene.validate_cut(path)?;
        scene
            .validate_time_step(path)
            .map_err(|e| at_field_line(e, text, "dt"))?;
        scene.mesh_transform.validate().map_err(|m| Error::Scene {
            path: path.to_path_buf(),
            message: format!("mesh_transform: {m}"),
        })?;
        scene.validate_fixed(path)?;
        scene.validate_expectations(path)?;
        Ok(scene)
    }

    /// Check every tool's shape and trajectory and that names are unique; the message names
    /// the tool by index and name.
    pub fn validate_tools(&self, path: &Path) -> Result<()> {
        for (i, tool) in self.tools.iter().enumerate() {
            let fail = |message: String| Error::Scene {
                path: path.to_path_buf(),
                message: format!("tool {i} ({:?}): {message}", tool.name),
            };
            let detail = |e: Error| match e {
                Error::Options(m) => m,
                other => other.to_string(),
            };
            tool.shape.validate().map_err(|e| fail(detail(e)))?;
            tool.trajectory.validate().map_err(|e| fail(detail(e)))?;
            tool.validate_grasp().map_err(fail)?;
            if self.tools[..i].iter().any(|t| t.name == tool.name) {
                return Err(fail(
                    "another tool has this name; give each tool its own".into(),
                ));
            }
        }
        Ok(())
    }

    /// Check the cutting settings: at least one method, and blade names that name blades.
    pub fn validate_cut(&self, path: &Path) -> Result<()> {
        let Some(cut) = &self.cut else {
            return Ok(());
        };
        let fail = |message: String| Error::Scene {
            path: path.to_path_buf(),
            message: format!("cut: {message}"),
        };
        if cut.methods.is_empty() {
            return Err(fail(
                "give at least one method, e.g. methods: [Separate] or [Separate, Remove]".into(),
            ));
        }
        for name in &cut.blades {
            match self.tools.iter().find(|t| &t.name == name) {
                None => {
                    return Err(fail(format!(
                        "blade {name:?} is not one of the scene's tools; name a tool from \
                         `tools`"
                    )))
                }
                Some(t) if !matches!(t.shape, ToolShape::Blade { .. }) => {
                    return Err(fail(format!(
                        "tool {name:?} is not a blade; only blades cut"
                    )))
                }
                Some(_) => {}
            }
        }
        // The cutter reads a negative floor as none; refused here, so that "none" is only ever
        // written as 0.
        if !(0.0..1.0).contains(&cut.quality_floor) {
            return Err(fail(format!(
                "quality_floor {} must be a volume-length ratio in [0, 1) (0 turns the floor off)",
                cut.quality_floor
            )));
        }
        Ok(())
    }

    /// What in a valid scene is likely a mistake, one line each, for the command line to print
    /// as warnings. A `cut` section with no blade among the tools cuts nothing; it is allowed
    /// (a scene may check that other tools do not cut), but is more often a forgotten or
    /// misshaped blade.
    pub fn warnings(&self) -> Vec<String> {
        let mut warnings = Vec::new();
        let has_blade = self
            .tools
            .iter()
            .any(|t| matches!(t.shape, ToolShape::Blade { .. }));
        if self.cut.is_some() && !has_blade {
            warnings.push(
                "the scene has a `cut` section but no blade, so nothing will cut (only tools \
                 of shape Blade cut); add a blade to `tools`, or remove `cut`"
                    .into(),
            );
        }
        warnings
    }

    /// Whether a run must check the cut invariants (asked by the scene or an expectation).
    pub fn checks_cuts(&self) -> bool {
        fn wants(e: &Expectation) -> bool {
            match e {
                Expectation::InvariantsHold => true,
                Expectation::Method(_, inner) => wants(inner),
                _ => false,
            }
        }
        self.cut.as_ref().is_some_and(|c| c.check) || self.expect.iter().any(wants)
    }

    /// Read a scene file.
    pub fn read(path: &Path) -> Result<Scene> {
        // A mesh given where a scene goes would fail as RON ("expected opening `(`") or as
        // UTF-8: say what it is and what to do with it instead.
        const MESH_EXTENSIONS: [&str; 8] =
            ["msh", "mesh", "vtu", "vtk", "node", "ele", "veg", "face"];
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if let Some(ext) = extension.filter(|e| MESH_EXTENSIONS.contains(&e.as_str())) {
            return Err(Error::Scene {
                path: path.to_path_buf(),
                message: format!(
                    "this is a mesh (.{ext}), not a scene (.ron): `lancet info` reads a mesh, and \
                     a scene runs one with `mesh: File(\"...\")`"
                ),
            });
        }
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Scene::from_ron(&text, path)
    }

    /// The embedded default scene.
    pub fn default_scene() -> Scene {
        // The embedded text is a fixture checked by the test suite, so it always parses.
        Scene::from_ron(DEFAULT_SCENE, Path::new("<embedded default scene>"))
            .expect("the embedded default scene parses")
    }
}

/// Resolve a mesh path from a scene: relative to the scene's folder, or under
/// `$LANCET_MESH_DIR`.
pub fn resolve_mesh_path(file: &str, scene_dir: &Path, scene_path: &Path) -> Result<PathBuf> {
    if let Some(rest) = file.strip_prefix("$LANCET_MESH_DIR/") {
        let dir = std::env::var_os("LANCET_MESH_DIR").ok_or_else(|| Error::Scene {
            path: scene_path.to_path_buf(),
            message: format!(
                "mesh {file:?} needs the environment variable LANCET_MESH_DIR; set it to the \
                 folder of real meshes"
            ),
        })?;
        return Ok(PathBuf::from(dir).join(rest));
    }
    let p = PathBuf::from(file);
    Ok(if p.is_absolute() {
        p
    } else {
        scene_dir.join(p)
    })
}

/// A RON error in words, and what to do about it. An unknown field or variant (a misspelling
/// would otherwise be refused with only the list of valid names, or, before fields were
/// checked, silently ignored) names the nearest valid one.
fn describe_ron_error(code: &ron::Error) -> (String, String) {
    let (kind, expected, found, outer) = match code {
        ron::Error::NoSuchStructField {
            expected,
            found,
            outer,
        } => ("field", *expected, found, outer),
        ron::Error::NoSuchEnumVariant {
            expected,
            found,
            outer,
        } => ("variant", *expected, found, outer),
        other => {
            return (
                other.to_string().to_lowercase(),
                "see the scene format in the README".into(),
            )
        }
    };
    let within = outer
        .as_ref()
        .map_or(String::new(), |o| format!(" in `{o}`"));
    let message = format!("unknown {kind} `{found}`{within}");
    let valid = expected
        .iter()
        .map(|n| format!("`{n}`"))
        .collect::<Vec<_>>()
        .join(", ");
    let hint = match nearest_name(found, expected) {
        Some(near) => format!("did you mean `{near}`? (valid: {valid})"),
        None if expected.is_empty() => format!("remove `{found}`"),
        None => format!("use one of {valid}"),
    };
    (message, hint)
}

/// The name in `valid` nearest to `name` (by edit distance, case ignored), if it is near
/// enough to be a misspelling: at most a third of the longer name's letters differ.
pub(crate) fn nearest_name<'n>(name: &str, valid: &[&'n str]) -> Option<&'n str> {
    let lower = name.to_lowercase();
    valid
        .iter()
        .map(|v| (strsim::levenshtein(&lower, &v.to_lowercase()), *v))
        .min_by_key(|&(d, _)| d)
        .filter(|&(d, v)| d * 3 <= name.chars().count().max(v.chars().count()))
        .map(|(_, v)| v)
}

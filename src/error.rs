//! The one error type of lancet.
//!
//! Every message is lowercase, says what went wrong and what to do about it, and names the file,
//! line (or byte offset) and element when the input was a file.

use std::fmt;
use std::path::PathBuf;

/// Result alias used throughout the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Where in an input file something was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// 1-based line number in a text file.
    Line(usize),
    /// 0-based byte offset in a binary file or binary section.
    Byte(u64),
    /// The position is not known (for example the end of the file).
    Unknown,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(l) => write!(f, "line {l}"),
            Location::Byte(b) => write!(f, "byte {b}"),
            Location::Unknown => write!(f, "end of file"),
        }
    }
}

/// What the id in a [`ParseError`] numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IdKind {
    /// An element (a tet, a cell, a face), by its id in the file.
    #[default]
    Element,
    /// A node (a point, a vertex), by its id in the file.
    Node,
}

/// A problem in an input file: where, which element, what, and how to fix it.
#[derive(Debug, Clone, PartialEq)]
pub struct ParseError {
    /// The file that was being read.
    pub path: PathBuf,
    /// Where in the file.
    pub location: Location,
    /// The element (tet, cell) or node concerned, by the id written in the file, if any
    /// ([`ParseError::id_kind`] says which).
    pub element: Option<i64>,
    /// Whether `element` numbers an element or a node.
    pub id_kind: IdKind,
    /// What is wrong, lowercase.
    pub message: String,
    /// What the user can do about it, lowercase; may be empty.
    pub hint: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}: ", self.path.display(), self.location)?;
        if let Some(e) = self.element {
            let kind = match self.id_kind {
                IdKind::Element => "element",
                IdKind::Node => "node",
            };
            write!(f, "{kind} {e}: ")?;
        }
        write!(f, "{}", self.message)?;
        if !self.hint.is_empty() {
            write!(f, " ({})", self.hint)?;
        }
        Ok(())
    }
}

/// Where periodic checks place a failure: the check that found it, the last check that found
/// the state good, and whether the reported step was pinned down by replaying the steps between.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadStep {
    /// The step at which the check that found the failure ran.
    pub found_at: u64,
    /// The step of the last check that found the state good (0: the start).
    pub last_good: u64,
    /// Whether the reported step is the first bad one, found by replaying one step at a time
    /// from the state kept at `last_good`. False where the run was changed in between (contact
    /// corrections, cuts, a new state or time step), so that a replay would not be the same
    /// run: the failure then happened after `last_good`, by `found_at`.
    pub replayed: bool,
}

/// The part of a divergence or inversion message that says how its step was found.
fn found_text(found: &Option<BadStep>) -> String {
    match found {
        Some(f) if f.replayed => format!(
            " (the first bad step: the check at step {} found it, a replay from the good state \
             of step {} placed it)",
            f.found_at, f.last_good
        ),
        Some(f) => format!(
            " (found by the check at step {}; last seen good at step {}, and the run was \
             changed in between, so it was not replayed)",
            f.found_at, f.last_good
        ),
        None => String::new(),
    }
}

/// Everything that can go wrong in lancet.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be opened, read or written.
    #[error("{}: {source} ({})", path.display(), io_hint(source))]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },

    /// A mesh, scene or other input file is malformed.
    #[error("{0}")]
    Parse(Box<ParseError>),

    /// A mesh built in code (not read from a file) is invalid.
    #[error("invalid mesh: {0}")]
    Mesh(String),

    /// The model or a call on it is invalid in a way no variant below names (a fixed selector
    /// that selects nothing, a spring given twice, a surface edit that does not match the
    /// surface, ...).
    #[error("invalid model: {0}")]
    Model(String),

    /// A material, model or simulation parameter is out of its range: `name` is what a user
    /// calls it (`young's modulus`, `time step`, `region 2: poisson ratio`), `value` what was
    /// given.
    #[error("{name} is {value}; it must {requirement}")]
    InvalidParameter {
        /// The parameter.
        name: String,
        /// The value given.
        value: f64,
        /// What it must be, lowercase (`be finite and positive`).
        requirement: String,
    },

    /// A node index past the nodes there are (in the model, a change to it, a surface or the
    /// positions given for it).
    #[error("{message}")]
    NodeOutOfRange {
        /// The index given.
        node: u64,
        /// How many nodes there are where it was checked.
        count: usize,
        /// What named the node and what to do, lowercase.
        message: String,
    },

    /// Arguments that must have one entry each for the same things do not (nodes and the
    /// positions to move them to, masses and nodes, positions and velocities).
    #[error("{message}")]
    LengthMismatch {
        /// How many entries were given.
        given: usize,
        /// How many were needed.
        expected: usize,
        /// What was given for what, lowercase.
        message: String,
    },

    /// A model change ([`crate::model::ModelDiff`]) does not match the model or the layout it
    /// was applied to (a spring removed that does not exist, a layout out of step with its
    /// model). Nothing was changed: make the change against the current model, or rebuild.
    #[error("the change does not match the model: {0}")]
    DiffMismatch(String),

    /// A GPU layout cannot hold the model as asked (too few slots per node, more entries than
    /// 32-bit indices reach, an arrangement that leaves nodes out): choose another layout or
    /// capacity.
    #[error("the layout cannot hold the model: {0}")]
    LayoutCapacity(String),

    /// A call that reads the surface came before one was given: call `set_surface` with the
    /// boundary triangles first.
    #[error("{0}")]
    NoSurface(String),

    /// The time step is above the stable bound of explicit integration.
    #[error(
        "time step {dt:e} s exceeds the stable bound {bound:e} s (limited by node {node}); \
         lower dt below the bound, or set `allow_unstable: true` to run anyway"
    )]
    UnstableTimeStep {
        /// The requested step, seconds.
        dt: f64,
        /// The stable bound, seconds.
        bound: f64,
        /// The node (index in the mesh's node order) with the smallest per-node bound.
        node: usize,
    },

    /// A cut in a scene lowered the stable bound below the time step, and the scene's cut
    /// policy is `Stop`. Unlike [`Error::UnstableTimeStep`], `allow_unstable` does not apply:
    /// the fix is the policy in the scene's `cut` section.
    #[error(
        "the cut at step {step} lowered the stable bound to {bound:e} s (limited by node {node}), \
         below the time step {dt:e} s; set `time_step: Substep` in the scene's `cut` section to \
         go on at a smaller step, or `time_step: Warn` to go on at this one"
    )]
    CutLoweredTimeStep {
        /// The step after which the cut was made (steps taken so far).
        step: u64,
        /// The time step in use, seconds.
        dt: f64,
        /// The stable bound after the cut, seconds.
        bound: f64,
        /// The node (index in the model's node order) with the smallest per-node bound.
        node: usize,
    },

    /// The simulation blew up: NaN, infinity or exploding energy.
    #[error(
        "simulation diverged at step {step}{}, node {node}: {reason} (lower dt or raise damping)",
        found_text(.found)
    )]
    Diverged {
        /// The first bad step (1-based count of steps taken) where a replay from the last good
        /// check placed it (see `found`), else the step of the check that saw it.
        step: u64,
        /// The node (index in the mesh's node order) that showed it first or worst.
        node: usize,
        /// What was seen.
        reason: String,
        /// Which periodic check found it and when the state was last seen good; `None` where
        /// it was seen at the step itself.
        found: Option<BadStep>,
    },

    /// Tets turned inside out during a run (a material far too soft for its load, or a step
    /// too large): reported like a divergence, unless the run allows it
    /// ([`crate::engine::SimConfig::allow_inverted`], a scene's `allow_inverted`).
    #[error(
        "{count} tets inverted at step {step}{}; tet {tet} first, at {ratio:.3} of its rest \
         volume (stiffen the material, lower dt, or set `allow_inverted: true` to run on)",
        found_text(.found)
    )]
    Inverted {
        /// The first step with an inverted tet where a replay from the last good check placed
        /// it (see `found`), else the step of the check that found them.
        step: u64,
        /// The first inverted tet (index in the order of the tets watched: a mesh's tet order,
        /// the order of a written VTU's cells).
        tet: usize,
        /// How many tets are inverted.
        count: usize,
        /// The first inverted tet's signed volume over its rest volume (negative).
        ratio: f64,
        /// Which periodic check found them and when the tets were last seen upright.
        found: Option<BadStep>,
    },

    /// A face shared by more than two tets (a non-manifold mesh, or a tet listed twice), which
    /// a cut cannot split consistently. Nodes and tets are numbered from 0 in the mesh's order,
    /// as a written VTU numbers its points and cells.
    #[error(
        "the face of nodes {face:?} is shared by tets {tets:?}, and a face can have at most two; \
         a non-manifold mesh cannot be cut (remove duplicated tets, or repair the mesh, e.g. \
         with TetGen -d; nodes and tets are numbered from 0 as in a written VTU)"
    )]
    NonManifold {
        /// The face's corners (node indices in the mesh's dense order).
        face: [usize; 3],
        /// The tets that hold it (indices in the mesh's tet order), the one added last included.
        tets: Vec<usize>,
    },

    /// A scene file is inconsistent (unknown region, missing mesh, ...).
    #[error("{}: {message}", path.display())]
    Scene {
        /// The scene file.
        path: PathBuf,
        /// What is wrong and what to do.
        message: String,
    },

    /// The GPU device refused something (validation, limits, device loss).
    #[error("gpu: {0}")]
    Gpu(String),

    /// A feature or format that this build or this file needs is not available.
    #[error("unsupported: {0}")]
    Unsupported(String),

    /// A request to a report or tool is inconsistent (an empty list, a time step fraction above
    /// the stable bound, sample times that no common step divides).
    #[error("invalid options: {0}")]
    Options(String),
}

impl Error {
    /// Build a parse error.
    pub fn parse(
        path: impl Into<PathBuf>,
        location: Location,
        element: Option<i64>,
        message: impl Into<String>,
        hint: impl Into<String>,
    ) -> Self {
        Error::Parse(Box::new(ParseError {
            path: path.into(),
            location,
            element,
            id_kind: IdKind::Element,
            message: message.into(),
            hint: hint.into(),
        }))
    }

    /// This error, where it is a parse error, about the node its id numbers rather than an
    /// element (readers share their number parsing between node and element rows).
    pub fn about_node(self) -> Self {
        match self {
            Error::Parse(mut p) => {
                p.id_kind = IdKind::Node;
                Error::Parse(p)
            }
            other => other,
        }
    }

    /// Build an I/O error for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// The parse details, if this is a parse error.
    pub fn as_parse(&self) -> Option<&ParseError> {
        match self {
            Error::Parse(p) => Some(p),
            _ => None,
        }
    }
}

/// What to do about an I/O error: about the path where the path is likely the cause, about
/// memory where memory ran out (a reader's allocation failing is not a missing file).
fn io_hint(e: &std::io::Error) -> &'static str {
    match e.kind() {
        std::io::ErrorKind::OutOfMemory => {
            "not enough memory: free memory, or use a smaller mesh or fewer frames"
        }
        std::io::ErrorKind::InvalidInput | std::io::ErrorKind::InvalidData => {
            "check the value or the file's contents"
        }
        _ => "check that the path exists and is readable/writable",
    }
}

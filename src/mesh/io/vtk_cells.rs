//! The VTK cell types, as both VTK readers (legacy `.vtk` and XML `.vtu`) treat them.
//!
//! The two formats share VTK's cell type codes, so one table here keeps them reading the same
//! file content the same way and saying the same things about what they skipped.

/// What lancet does with a VTK cell type code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CellKind {
    /// `VTK_TETRA` (10): kept.
    Tet,
    /// `VTK_QUADRATIC_TETRA` (24): kept as a linear tet on its 4 corners.
    QuadraticTet,
    /// `VTK_TRIANGLE` (5): kept as a surface triangle.
    Triangle,
    /// `VTK_QUADRATIC_TRIANGLE` (22): kept as a surface triangle on its 3 corners.
    QuadraticTriangle,
    /// Vertices, lines and curves: skipped, they carry no volume.
    VertexOrLine,
    /// Surface cells other than triangles: skipped, lancet keeps triangles only.
    OtherSurface,
    /// A volume cell lancet cannot simulate, with its name for the message.
    Volume(&'static str),
    /// A code not in this table.
    Unknown,
}

impl CellKind {
    /// The kind of VTK cell type code `ty`.
    pub(crate) fn of(ty: i64) -> Self {
        match ty {
            10 => CellKind::Tet,
            24 => CellKind::QuadraticTet,
            5 => CellKind::Triangle,
            22 => CellKind::QuadraticTriangle,
            1..=4 | 21 | 35 => CellKind::VertexOrLine,
            6..=9 | 23 | 28 | 30 | 34 | 36 | 69 | 70 => CellKind::OtherSurface,
            11 => CellKind::Volume("voxel"),
            12 => CellKind::Volume("hexahedron"),
            13 => CellKind::Volume("wedge"),
            14 => CellKind::Volume("pyramid"),
            15 => CellKind::Volume("pentagonal prism"),
            16 => CellKind::Volume("hexagonal prism"),
            25 => CellKind::Volume("quadratic hexahedron"),
            26 => CellKind::Volume("quadratic wedge"),
            27 => CellKind::Volume("quadratic pyramid"),
            29 => CellKind::Volume("triquadratic hexahedron"),
            31 => CellKind::Volume("quadratic linear wedge"),
            32 => CellKind::Volume("biquadratic quadratic wedge"),
            33 => CellKind::Volume("biquadratic quadratic hexahedron"),
            37 => CellKind::Volume("triquadratic pyramid"),
            42 => CellKind::Volume("polyhedron"),
            _ => CellKind::Unknown,
        }
    }

    /// The number of points a kept cell lists; `None` for kinds that are skipped or refused.
    pub(crate) fn points(self) -> Option<usize> {
        match self {
            CellKind::Tet => Some(4),
            CellKind::QuadraticTet => Some(10),
            CellKind::Triangle => Some(3),
            CellKind::QuadraticTriangle => Some(6),
            _ => None,
        }
    }

    /// How many of a kept cell's points to take: VTK lists the corners first, so the leading 4
    /// (tets) or 3 (triangles) make the linear element.
    pub(crate) fn corners(self) -> usize {
        match self {
            CellKind::Tet | CellKind::QuadraticTet => 4,
            CellKind::Triangle | CellKind::QuadraticTriangle => 3,
            _ => 0,
        }
    }

    /// The message when a cell of type `ty` (this kind) lists `got` points instead of the
    /// number its type needs; `None` when the count is right or the kind is not kept.
    pub(crate) fn wrong_points(self, ty: i64, got: usize) -> Option<String> {
        let want = self.points()?;
        (got != want).then(|| format!("cell of type {ty} has {got} points, expected {want}"))
    }
}

/// The hint that goes with [`unsupported_message`].
pub(crate) const UNSUPPORTED_HINT: &str = "convert the mesh to tetrahedra (for example with \
     paraview's tetrahedralize filter) and export again";

/// The message for a cell of type `ty` that is neither kept nor skipped: a volume cell lancet
/// does not simulate, or a code not in the table.
pub(crate) fn unsupported_message(ty: i64) -> String {
    match CellKind::of(ty) {
        CellKind::Volume(name) => {
            format!("unsupported cell type {ty} ({name}); lancet simulates tetrahedra only")
        }
        _ => format!("unknown vtk cell type {ty}; lancet simulates tetrahedra only"),
    }
}

/// Cells skipped or simplified while reading, counted so that the notes give one line per
/// kind instead of one per cell.
#[derive(Debug, Default)]
pub(crate) struct CellTally {
    vertex_line: usize,
    other_surface: usize,
    quadratic_tets: usize,
    quadratic_triangles: usize,
    /// Region tags that were not integers and were rounded (legacy files store them as floats).
    pub(crate) fractional_tags: usize,
}

impl CellTally {
    /// Count a cell of kind `kind` if it is skipped or simplified.
    pub(crate) fn record(&mut self, kind: CellKind) {
        match kind {
            CellKind::VertexOrLine => self.vertex_line += 1,
            CellKind::OtherSurface => self.other_surface += 1,
            CellKind::QuadraticTet => self.quadratic_tets += 1,
            CellKind::QuadraticTriangle => self.quadratic_triangles += 1,
            _ => {}
        }
    }

    /// Append one note per non-zero count.
    pub(crate) fn notes(&self, notes: &mut Vec<String>) {
        let counts = [
            (self.vertex_line, "ignored", "vertex or line cell(s)"),
            (
                self.other_surface,
                "ignored",
                "surface cell(s) that are not triangles (quads, polygons, strips)",
            ),
            (
                self.quadratic_tets,
                "read",
                "quadratic (10-node) tet(s) as linear tets on their 4 corners",
            ),
            (
                self.quadratic_triangles,
                "read",
                "quadratic triangle(s) on their 3 corners",
            ),
            (
                self.fractional_tags,
                "rounded",
                "non-integer region tag(s) to the nearest integer",
            ),
        ];
        for (n, verb, what) in counts {
            if n > 0 {
                notes.push(format!("{verb} {n} {what}"));
            }
        }
    }
}

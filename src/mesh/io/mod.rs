//! Reading the mesh formats users have, and writing VTU for ParaView.
//!
//! Every reader parses its format into a [`RawMesh`] (points, tets as indices, surface
//! triangles, notes), checking syntax, counts, numbers and node references as it goes so that an
//! error can name the line. [`RawMesh::finish`] then does the checks common to all formats
//! (repeated nodes in a tet, zero volume, orientation) and builds the [`TetMesh`].
//!
//! Readers are hand-written: the crates that exist either cover one format version (mshio: Gmsh
//! 4.1 only) or pull dependencies that newer compilers reject (vtkio 0.6), and none reports the
//! line and element of a problem, which users need to fix their files.

pub mod gmsh;
pub mod medit;
#[cfg(feature = "vtu")]
pub mod pvd;
pub mod tetgen;
pub(crate) mod text;
pub mod vega;
pub(crate) mod vtk_cells;
pub mod vtk_legacy;
#[cfg(feature = "vtu")]
pub mod vtu;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Point3;

use super::{NodeKey, TetMesh};
use crate::error::{Error, Location, Result};

/// The file formats lancet reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Format {
    /// Gmsh 1 (`$NOD` / `$ELM`).
    Gmsh1,
    /// Gmsh 2.2, ASCII or binary.
    Gmsh22 {
        /// Whether the data sections are binary.
        binary: bool,
    },
    /// Gmsh 4.1, ASCII or binary.
    Gmsh41 {
        /// Whether the data sections are binary.
        binary: bool,
    },
    /// TetGen `.node` + `.ele` pair.
    TetGen,
    /// Medit `.mesh` (ASCII).
    Medit,
    /// Vega `.veg` (VegaFEM, iMSTK).
    Vega,
    /// VTK legacy `.vtk`, ASCII or binary.
    VtkLegacy {
        /// Whether the data sections are binary.
        binary: bool,
    },
    /// VTK XML unstructured grid `.vtu`.
    Vtu,
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let enc = |b: bool| if b { "binary" } else { "ascii" };
        match self {
            Format::Gmsh1 => write!(f, "gmsh 1"),
            Format::Gmsh22 { binary } => write!(f, "gmsh 2.2 {}", enc(*binary)),
            Format::Gmsh41 { binary } => write!(f, "gmsh 4.1 {}", enc(*binary)),
            Format::TetGen => write!(f, "tetgen"),
            Format::Medit => write!(f, "medit"),
            Format::Vega => write!(f, "vega"),
            Format::VtkLegacy { binary } => write!(f, "vtk legacy {}", enc(*binary)),
            Format::Vtu => write!(f, "vtu"),
        }
    }
}

/// A tet as read from a file, before validation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawTet {
    /// Indices into [`RawMesh::points`] (already mapped from the file's node ids).
    pub nodes: [u32; 4],
    /// Region tag (physical group, material id, cell attribute); 0 when the file has none.
    pub region: i32,
    /// The element's id as written in the file (or its 1-based position when the file has
    /// no ids), for error messages.
    pub id: i64,
    /// Where the element was read.
    pub location: Location,
}

/// A surface triangle read from a file: kept as a tagged surface element, never as a tet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawTriangle {
    /// Indices into [`RawMesh::points`].
    pub nodes: [u32; 3],
    /// Its tag in the file; 0 when none.
    pub tag: i32,
}

/// A material given in the mesh file itself (Vega files carry one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FileMaterial {
    /// Density, kg/m^3 (in the file's units).
    pub density: f64,
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson ratio.
    pub poisson_ratio: f64,
}

/// What a reader produced: points and elements with file ids mapped to indices.
#[derive(Debug, Clone, PartialEq)]
pub struct RawMesh {
    /// The format actually read.
    pub format: Format,
    /// Node positions, finite.
    pub points: Vec<[f64; 3]>,
    /// The id of each point as written in the file, for messages.
    pub point_ids: Vec<i64>,
    /// Tetrahedra.
    pub tets: Vec<RawTet>,
    /// Surface triangles, if the file lists any.
    pub triangles: Vec<RawTriangle>,
    /// A material carried by the file.
    pub material: Option<FileMaterial>,
    /// Things the reader skipped or assumed, one sentence each (for example
    /// "ignored 71 line elements").
    pub notes: Vec<String>,
}

impl RawMesh {
    /// An empty raw mesh of the given format.
    pub fn new(format: Format) -> Self {
        RawMesh {
            format,
            points: Vec::new(),
            point_ids: Vec::new(),
            tets: Vec::new(),
            triangles: Vec::new(),
            material: None,
            notes: Vec::new(),
        }
    }
}

/// A surface triangle of a loaded mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SurfaceTriangle {
    /// Its corners.
    pub nodes: [NodeKey; 3],
    /// Its tag in the file.
    pub tag: i32,
}

/// What loading a file did besides producing the mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadReport {
    /// The file read (for TetGen, the `.ele` file).
    pub path: PathBuf,
    /// The format read.
    pub format: Format,
    /// How many inverted tets were reoriented.
    pub reoriented: usize,
    /// How many nodes no tet used, and were dropped.
    pub dropped_nodes: usize,
    /// Material carried by the file.
    pub material: Option<FileMaterial>,
    /// Notes from the reader and the checks (ignored elements, reoriented tets, ...).
    pub notes: Vec<String>,
}

/// A mesh read from a file.
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// The tetrahedral mesh.
    pub mesh: TetMesh,
    /// Tagged surface triangles listed in the file.
    pub surface: Vec<SurfaceTriangle>,
    /// What happened while loading.
    pub report: LoadReport,
}

impl RawMesh {
    /// Validate the elements and build the mesh. Nodes that no tet uses are dropped (a node
    /// without mass cannot be simulated) and counted; inverted tets are reoriented and counted.
    pub fn finish(self, path: &Path) -> Result<LoadedMesh> {
        let err = |t: &RawTet, msg: String, hint: &str| {
            Error::parse(path, t.location, Some(t.id), msg, hint)
        };
        if self.tets.is_empty() {
            // Say what the file held instead: a surface, or elements of types skipped.
            let mut held = Vec::new();
            if !self.triangles.is_empty() {
                held.push(format!("{} surface triangles", self.triangles.len()));
            }
            held.extend(self.notes.iter().cloned());
            let held = if held.is_empty() {
                String::new()
            } else {
                format!(" (it holds: {})", held.join("; "))
            };
            return Err(Error::parse(
                path,
                Location::Unknown,
                None,
                format!("the file contains no tetrahedra{held}"),
                "lancet simulates volumes: export the volume mesh, not only its surface",
            ));
        }
        let mut used = vec![false; self.points.len()];
        for t in &self.tets {
            for &n in &t.nodes {
                match used.get_mut(n as usize) {
                    Some(u) => *u = true,
                    None => {
                        return Err(err(
                            t,
                            format!("references node index {n} beyond the {} nodes", used.len()),
                            "check the node numbering",
                        ))
                    }
                }
            }
        }
        let mut mesh = TetMesh::new();
        let mut keys: Vec<Option<NodeKey>> = vec![None; self.points.len()];
        let mut dropped = 0;
        for (i, p) in self.points.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(Error::parse(
                    path,
                    Location::Unknown,
                    self.point_ids.get(i).copied(),
                    format!("node has a non-finite coordinate {p:?}"),
                    "fix or remove the node",
                ));
            }
            if used[i] {
                keys[i] = Some(mesh.add_node(Point3::new(p[0], p[1], p[2])));
            } else {
                dropped += 1;
            }
        }
        let mut reoriented = 0;
        // A tet listed twice (Gmsh 2.2 repeats an element for each physical group it is in)
        // would double its mass and stiffness: it is kept once, with its first region.
        let mut first_listing: HashMap<[u32; 4], &RawTet> = HashMap::new();
        let mut duplicates: Vec<(&RawTet, &RawTet)> = Vec::new();
        for t in &self.tets {
            let mut sorted = t.nodes;
            sorted.sort_unstable();
            match first_listing.entry(sorted) {
                std::collections::hash_map::Entry::Occupied(first) => {
                    duplicates.push((first.get(), t));
                    continue;
                }
                std::collections::hash_map::Entry::Vacant(slot) => {
                    slot.insert(t);
                }
            }
            let mut k = [NodeKey::default(); 4];
            for (slot, &n) in k.iter_mut().zip(&t.nodes) {
                // Every node of a tet is used, so its key exists.
                *slot = keys[n as usize].ok_or_else(|| err(t, "internal".into(), ""))?;
            }
            let file_id = |n: u32| self.point_ids.get(n as usize).copied().unwrap_or(n as i64);
            for a in 0..4 {
                for b in a + 1..4 {
                    if t.nodes[a] == t.nodes[b] {
                        return Err(err(
                            t,
                            format!(
                                "tet uses node {} twice; a tet needs four distinct nodes",
                                file_id(t.nodes[a])
                            ),
                            "remove the element or fix its node list",
                        ));
                    }
                }
            }
            match mesh.add_tet_reorienting(k, t.region) {
                Ok((_, flipped)) => reoriented += flipped as usize,
                Err(_) => {
                    let ids = t.nodes.map(file_id);
                    return Err(err(
                        t,
                        format!("tet with nodes {ids:?} has zero volume"),
                        "remove the degenerate element or move its nodes apart",
                    ));
                }
            }
        }
        let mut notes = self.notes;
        if let Some((first, again)) = duplicates.first() {
            let other_regions = duplicates
                .iter()
                .filter(|(f, d)| f.region != d.region)
                .count();
            notes.push(format!(
                "merged {} duplicated tet(s) (the same four nodes listed again; element {} \
                 repeats element {}): each is kept once, with the region of its first listing \
                 ({} of them were listed again under another region)",
                duplicates.len(),
                again.id,
                first.id,
                other_regions
            ));
        }
        if reoriented > 0 {
            notes.push(format!(
                "reoriented {reoriented} inverted tet(s) (negative signed volume)"
            ));
        }
        if dropped > 0 {
            notes.push(format!("dropped {dropped} node(s) that no tet uses"));
        }
        let mut surface = Vec::with_capacity(self.triangles.len());
        let mut bad_tris = 0;
        for tri in &self.triangles {
            let k = tri.nodes.map(|n| keys.get(n as usize).copied().flatten());
            match k {
                [Some(a), Some(b), Some(c)] => surface.push(SurfaceTriangle {
                    nodes: [a, b, c],
                    tag: tri.tag,
                }),
                _ => bad_tris += 1,
            }
        }
        if !self.triangles.is_empty() {
            notes.push(format!(
                "kept {} surface triangle(s) as tagged surface elements",
                surface.len()
            ));
        }
        if bad_tris > 0 {
            notes.push(format!(
                "ignored {bad_tris} surface triangle(s) on nodes that no tet uses"
            ));
        }
        Ok(LoadedMesh {
            mesh,
            surface,
            report: LoadReport {
                path: path.to_path_buf(),
                format: self.format,
                reoriented,
                dropped_nodes: dropped,
                material: self.material,
                notes,
            },
        })
    }
}

/// Maps the node ids written in a file (sparse, any start) to dense point indices.
#[derive(Debug, Default)]
pub(crate) struct IdMap {
    map: HashMap<i64, u32>,
}

impl IdMap {
    /// Record that file id `id` is point `index`; a repeated id is an error.
    pub(crate) fn insert(&mut self, id: i64, index: u32, path: &Path, loc: Location) -> Result<()> {
        if self.map.insert(id, index).is_some() {
            return Err(Error::parse(
                path,
                loc,
                Some(id),
                format!("node id {id} is defined twice"),
                "give every node a unique id",
            )
            .about_node());
        }
        Ok(())
    }

    /// The point index of file id `id`, or an error naming the element that referenced it.
    pub(crate) fn get(&self, id: i64, path: &Path, loc: Location, element: i64) -> Result<u32> {
        self.map.get(&id).copied().ok_or_else(|| {
            Error::parse(
                path,
                loc,
                Some(element),
                format!("references node {id}, which is not defined"),
                "check the element's node list against the node section",
            )
        })
    }
}

/// Read a mesh file, choosing the reader from the extension (and, for `.msh`, the header).
///
/// For TetGen give either file of the `.node`/`.ele` pair.
pub fn read(path: impl AsRef<Path>) -> Result<LoadedMesh> {
    let path = path.as_ref();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    if ext == "node" || ext == "ele" {
        return tetgen::read_pair(path);
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    read_bytes(&bytes, &ext, path)
}

/// Parse a single-file format from memory; `ext` is the lowercase extension that names the
/// format (`msh`, `mesh`, `veg`, `vtk`, `vtu`). `path` is used in messages only.
pub fn read_bytes(bytes: &[u8], ext: &str, path: &Path) -> Result<LoadedMesh> {
    let raw = match ext {
        "msh" => gmsh::parse(bytes, path)?,
        // `.meshb` goes to the Medit reader so that it can say binary Medit is unsupported.
        "mesh" | "meshb" => medit::parse(bytes, path)?,
        "veg" => vega::parse(bytes, path)?,
        "vtk" => vtk_legacy::parse(bytes, path)?,
        #[cfg(feature = "vtu")]
        // The XML reader counts appended-data offsets from the first byte: a byte-order mark
        // is cut off first (byte offsets in its messages then count from after it).
        "vtu" => vtu::parse(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes), path)?,
        _ => {
            return Err(Error::Unsupported(format!(
                "{}: unknown mesh extension {ext:?}; lancet reads .msh (gmsh 1, 2.2, 4.1), \
                 .node/.ele (tetgen), .mesh (medit), .veg (vega), .vtk and .vtu",
                path.display()
            )))
        }
    };
    raw.finish(path)
}

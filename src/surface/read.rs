//! Render surfaces from files: Wavefront OBJ (through `tobj`), STL, ASCII or binary (through
//! `stl_io`), and PLY, ASCII or binary (through `ply-rs-bw`), chosen by the file's extension.
//! Polygons are triangulated, every object of an OBJ file joins one surface, and STL's
//! repeated corners are merged into shared vertices (bit-identical positions). Errors name the
//! file and what is wrong; no input makes a reader panic.

use std::io::{BufReader, Cursor};
use std::path::Path;

use ply_rs_bw::ply::Property;

use super::RenderSurface;
use crate::error::{Error, IdKind, Location, ParseError, Result};

/// The file formats a render surface is read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SurfaceFormat {
    /// Wavefront OBJ (`.obj`): `v` and `f` lines; materials, normals and texture coordinates
    /// are ignored.
    Obj,
    /// STL (`.stl`), ASCII or binary.
    Stl,
    /// PLY (`.ply`), ASCII or binary: a `vertex` element with `x y z` and a `face` element
    /// with a `vertex_indices` (or `vertex_index`) list.
    Ply,
}

impl SurfaceFormat {
    /// The format a file's extension names (case ignored), `None` for any other.
    pub fn of(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Self::Obj),
            "stl" => Some(Self::Stl),
            "ply" => Some(Self::Ply),
            _ => None,
        }
    }
}

/// Read the render surface in `path`, its format chosen by the extension.
pub fn read_surface(path: impl AsRef<Path>) -> Result<RenderSurface> {
    let path = path.as_ref();
    let format = SurfaceFormat::of(path).ok_or_else(|| {
        Error::Unsupported(format!(
            "{}: not a render surface format lancet reads; give a .obj, .stl or .ply file",
            path.display()
        ))
    })?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    read_surface_bytes(&bytes, format, path)
}

/// Read a render surface of `format` from `bytes`; `path` names the source in messages.
pub fn read_surface_bytes(
    bytes: &[u8],
    format: SurfaceFormat,
    path: &Path,
) -> Result<RenderSurface> {
    let (positions, triangles) = match format {
        SurfaceFormat::Obj => obj(bytes, path)?,
        SurfaceFormat::Stl => stl(bytes, path)?,
        SurfaceFormat::Ply => ply(bytes, path)?,
    };
    if triangles.is_empty() {
        return Err(bad(
            path,
            Location::Unknown,
            None,
            "the file holds no triangles",
            "export the surface as triangles or polygons, not points or lines",
        ));
    }
    RenderSurface::new(positions, triangles, &path.display().to_string()).map_err(|e| match e {
        Error::Mesh(m) => bad(
            path,
            Location::Unknown,
            None,
            m.split_once(": ").map_or(m.as_str(), |(_, rest)| rest),
            "",
        ),
        other => other,
    })
}

type Arrays = (Vec<[f64; 3]>, Vec<[u32; 3]>);

/// A parse error about `path`.
fn bad(path: &Path, location: Location, element: Option<i64>, message: &str, hint: &str) -> Error {
    Error::parse(path, location, element, message, hint)
}

fn obj(bytes: &[u8], path: &Path) -> Result<Arrays> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    // Materials are not read: a render surface here is geometry only.
    let (models, _) = tobj::load_obj_buf(&mut BufReader::new(bytes), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| {
        let (line, hint) = obj_error_line(bytes, &e);
        bad(
            path,
            line.map_or(Location::Unknown, Location::Line),
            None,
            &format!("not a valid wavefront obj surface: {e}"),
            hint,
        )
    })?;
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let base = positions.len() as u32;
        positions.extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        let count = (m.positions.len() / 3) as u32;
        for t in m.indices.chunks_exact(3) {
            if t.iter().any(|&i| i >= count) {
                return Err(bad(
                    path,
                    Location::Unknown,
                    None,
                    &format!(
                        "object `{}`: a face uses vertex {t:?} of {count}",
                        model.name
                    ),
                    "fix the face indices",
                ));
            }
            triangles.push([base + t[0], base + t[1], base + t[2]]);
        }
    }
    Ok((positions, triangles))
}

/// The line of the first `v` or `f` statement that `tobj`'s error is likely about (it reports
/// none), with what to do; `None` where no line is to blame.
fn obj_error_line(bytes: &[u8], e: &tobj::LoadError) -> (Option<usize>, &'static str) {
    let text = String::from_utf8_lossy(bytes);
    let mut vertices = 0i64;
    let bad_line = |pred: &mut dyn FnMut(&str, &[&str]) -> bool| {
        text.lines().enumerate().find_map(|(i, l)| {
            let words: Vec<&str> = l.split_whitespace().collect();
            let (head, rest) = words.split_first()?;
            pred(head, rest).then_some(i + 1)
        })
    };
    match e {
        tobj::LoadError::PositionParseError => (
            bad_line(&mut |head, rest| {
                head == "v"
                    && (rest.len() < 3 || rest[..3].iter().any(|w| w.parse::<f64>().is_err()))
            }),
            "a `v` line needs three numbers",
        ),
        tobj::LoadError::FaceParseError
        | tobj::LoadError::FaceVertexOutOfBounds
        | tobj::LoadError::InvalidPolygon => (
            bad_line(&mut |head, rest| {
                if head == "v" {
                    vertices += 1;
                }
                head == "f"
                    && (rest.len() < 3
                        || rest.iter().any(|w| {
                            w.split('/')
                                .next()
                                .and_then(|i| i.parse::<i64>().ok())
                                .is_none_or(|i| i == 0 || i > vertices || i < -vertices)
                        }))
            }),
            "a face needs three or more indices of vertices defined above it",
        ),
        _ => (None, ""),
    }
}

fn stl(bytes: &[u8], path: &Path) -> Result<Arrays> {
    let mesh = stl_io::read_stl(&mut Cursor::new(bytes)).map_err(|e| {
        bad(
            path,
            Location::Unknown,
            None,
            &format!("not a valid stl surface: {e}"),
            "a binary stl needs an 80-byte header, a triangle count and 50 bytes per triangle",
        )
    })?;
    let positions = mesh
        .vertices
        .iter()
        .map(|v| v.0.map(|c| c as f64))
        .collect();
    let triangles = mesh
        .faces
        .iter()
        .map(|f| f.vertices.map(|i| i as u32))
        .collect();
    Ok((positions, triangles))
}

fn ply(bytes: &[u8], path: &Path) -> Result<Arrays> {
    let parser = ply_rs_bw::parser::Parser::<ply_rs_bw::ply::DefaultElement>::new();
    let file = parser.read_ply(&mut Cursor::new(bytes)).map_err(|e| {
        bad(
            path,
            Location::Unknown,
            None,
            &format!("not a valid ply file: {e}"),
            "",
        )
    })?;
    let missing = |what: &str| {
        bad(
            path,
            Location::Unknown,
            None,
            &format!("the file has no {what}"),
            "a ply surface needs a `vertex` element with x, y, z and a `face` element with a \
             `vertex_indices` list",
        )
    };
    let vertices = file
        .payload
        .get("vertex")
        .ok_or_else(|| missing("`vertex` element"))?;
    let mut positions = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let mut p = [0.0; 3];
        for (c, name) in ["x", "y", "z"].iter().enumerate() {
            p[c] = v.get(*name).and_then(scalar).ok_or_else(|| {
                node_error(
                    path,
                    i,
                    &format!("vertex has no number `{name}`"),
                    "give every vertex x, y and z",
                )
            })?;
        }
        positions.push(p);
    }
    let faces = file
        .payload
        .get("face")
        .ok_or_else(|| missing("`face` element"))?;
    let mut triangles = Vec::with_capacity(faces.len());
    for (f, face) in faces.iter().enumerate() {
        let list = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .and_then(list)
            .ok_or_else(|| missing(&format!("`vertex_indices` list in face {f}")))?;
        let n = positions.len() as i64;
        if list.len() < 3 || list.iter().any(|&i| i < 0 || i >= n) {
            return Err(bad(
                path,
                Location::Unknown,
                Some(f as i64),
                &format!("face {list:?} needs three or more indices below {n}"),
                "fix the face's vertex indices",
            ));
        }
        // A fan: the polygons of a PLY surface are convex in practice.
        for k in 1..list.len() - 1 {
            triangles.push([list[0], list[k], list[k + 1]].map(|i| i as u32));
        }
    }
    Ok((positions, triangles))
}

/// A parse error about vertex `i`.
fn node_error(path: &Path, i: usize, message: &str, hint: &str) -> Error {
    Error::Parse(Box::new(ParseError {
        path: path.into(),
        location: Location::Unknown,
        element: Some(i as i64),
        id_kind: IdKind::Node,
        message: message.into(),
        hint: hint.into(),
    }))
}

/// A scalar PLY property as a float64.
fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

/// An integer PLY list as int64s.
fn list(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUChar(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListShort(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUShort(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListInt(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUInt(v) => v.iter().map(|&i| i as i64).collect(),
        _ => return None,
    })
}

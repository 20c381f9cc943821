//! Triangle meshes per frame as binary glTF 2.0 (`.glb`), which Blender, three.js and ParaView
//! open: one node per mesh (the tissue's surface, each tool), each with its own mesh, so that
//! a viewer can hide or colour them separately.
//!
//! The document is built with `gltf-json`'s typed structures (so field names and enumerations
//! are the specification's) and packed by hand into the GLB container (a 12-byte header, the
//! JSON chunk padded with spaces, the binary chunk padded with zeros, each to 4 bytes;
//! `gltf-json` has no writer for the container, and the container is those three lines of the
//! specification). Positions are float32, as glTF requires; indices are u32; a mesh with vertex
//! colours has a `COLOR_0` attribute (float32 RGB) that its material multiplies.

use std::collections::BTreeMap;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use gltf_json as json;
use json::validation::{Checked::Valid, USize64};

use crate::error::{Error, Result};
use crate::mesh::io::vtu::replace_file;

/// The GLB header's magic, "glTF".
pub const MAGIC: u32 = 0x4654_6C67;
/// Chunk type of the JSON chunk, "JSON".
pub const CHUNK_JSON: u32 = 0x4E4F_534A;
/// Chunk type of the binary chunk, "BIN\0".
pub const CHUNK_BIN: u32 = 0x004E_4942;

/// One mesh of a frame.
#[derive(Debug, Clone, Copy)]
pub struct GlbMesh<'a> {
    /// The node's and mesh's name ("tissue", a tool's name).
    pub name: &'a str,
    /// Vertex positions, m (written as float32).
    pub positions: &'a [[f64; 3]],
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: &'a [[u32; 3]],
    /// Vertex colours, RGB in `[0, 1]`, one per vertex (the tissue's displacement colours), or
    /// `None` for the material's colour alone.
    pub colours: Option<&'a [[f32; 3]]>,
    /// The material's base colour, RGBA.
    pub base_colour: [f32; 4],
}

/// The `.glb` bytes of a frame holding `meshes` (those without triangles are left out, as glTF
/// allows no empty accessor). A mesh whose triangles name a missing vertex, or whose colours
/// do not match its vertices, is an error.
pub fn glb_bytes(meshes: &[GlbMesh]) -> Result<Vec<u8>> {
    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("lancet {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        ..Default::default()
    };
    let mut bin: Vec<u8> = Vec::new();
    let mut nodes = Vec::new();
    for m in meshes.iter().filter(|m| !m.triangles.is_empty()) {
        check(m)?;
        let positions: Vec<[f32; 3]> = m.positions.iter().map(|p| p.map(|c| c as f32)).collect();
        let (lo, hi) = positions.iter().fold(
            ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    [0, 1, 2].map(|c| lo[c].min(p[c])),
                    [0, 1, 2].map(|c| hi[c].max(p[c])),
                )
            },
        );
        let mut attributes = BTreeMap::new();
        let position = push_accessor(
            &mut root,
            &mut bin,
            bytemuck::cast_slice(&positions),
            positions.len(),
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
            json::buffer::Target::ArrayBuffer,
            Some((lo, hi)),
        );
        attributes.insert(Valid(json::mesh::Semantic::Positions), position);
        if let Some(colours) = m.colours {
            let colour = push_accessor(
                &mut root,
                &mut bin,
                bytemuck::cast_slice(colours),
                colours.len(),
                json::accessor::Type::Vec3,
                json::accessor::ComponentType::F32,
                json::buffer::Target::ArrayBuffer,
                None,
            );
            attributes.insert(Valid(json::mesh::Semantic::Colors(0)), colour);
        }
        let indices = push_accessor(
            &mut root,
            &mut bin,
            bytemuck::cast_slice(m.triangles),
            3 * m.triangles.len(),
            json::accessor::Type::Scalar,
            json::accessor::ComponentType::U32,
            json::buffer::Target::ElementArrayBuffer,
            None,
        );
        let material = root.push(json::Material {
            name: Some(m.name.to_string()),
            // Cut faces and thin tools are seen from both sides.
            double_sided: true,
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor(m.base_colour),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.8),
                ..Default::default()
            },
            ..Default::default()
        });
        let mesh = root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(m.name.to_string()),
            primitives: vec![json::mesh::Primitive {
                attributes,
                extensions: None,
                extras: Default::default(),
                indices: Some(indices),
                material: Some(material),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            }],
            weights: None,
        });
        nodes.push(root.push(json::Node {
            mesh: Some(mesh),
            name: Some(m.name.to_string()),
            ..Default::default()
        }));
    }
    if !bin.is_empty() {
        root.push(json::Buffer {
            byte_length: USize64::from(bin.len()),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
    }
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some("frame".into()),
        nodes,
    });
    root.scene = Some(scene);
    let text = root
        .to_vec()
        .map_err(|e| Error::Unsupported(format!("glTF document: {e}")))?;
    Ok(container(text, bin))
}

/// Pack the JSON and binary chunks into the GLB container.
fn container(mut text: Vec<u8>, mut bin: Vec<u8>) -> Vec<u8> {
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let bin_chunk = if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total = 12 + 8 + text.len() + bin_chunk;
    let mut out = Vec::with_capacity(total);
    for word in [MAGIC, 2, total as u32, text.len() as u32, CHUNK_JSON] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&text);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    out
}

/// Append `bytes` to the binary chunk as a buffer view of its own, and an accessor over it.
#[allow(clippy::too_many_arguments)]
fn push_accessor(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    bytes: &[u8],
    count: usize,
    type_: json::accessor::Type,
    component: json::accessor::ComponentType,
    target: json::buffer::Target,
    bounds: Option<([f32; 3], [f32; 3])>,
) -> json::Index<json::Accessor> {
    // Every component here is 4 bytes, so views stay 4-byte aligned.
    let offset = bin.len();
    bin.extend_from_slice(bytes);
    let view = root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(bytes.len()),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: Some(Valid(target)),
        extensions: None,
        extras: Default::default(),
    });
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(component)),
        extensions: None,
        extras: Default::default(),
        type_: Valid(type_),
        min: bounds.map(|(lo, _)| json::Value::from(lo.to_vec())),
        max: bounds.map(|(_, hi)| json::Value::from(hi.to_vec())),
        name: None,
        normalized: false,
        sparse: None,
    })
}

/// Indices within the vertices, colours one per vertex, positions finite.
fn check(m: &GlbMesh) -> Result<()> {
    let n = m.positions.len();
    let bad = |what: String| Err(Error::Mesh(format!("glTF mesh {:?}: {what}", m.name)));
    if let Some(t) = m
        .triangles
        .iter()
        .position(|t| t.iter().any(|&v| v as usize >= n))
    {
        return bad(format!(
            "triangle {t} uses vertex {:?} but there are {n} vertices",
            m.triangles[t]
        ));
    }
    if let Some(i) = m
        .positions
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        return bad(format!(
            "vertex {i} is at {:?}, not a finite position",
            m.positions[i]
        ));
    }
    match m.colours {
        Some(c) if c.len() != n => bad(format!("{} colours for {n} vertices", c.len())),
        _ => Ok(()),
    }
}

/// Write one frame to `path` (whole to a temporary file, then renamed over it).
pub fn write_glb(path: &Path, meshes: &[GlbMesh]) -> Result<()> {
    let bytes = glb_bytes(meshes)?;
    replace_file(path, false, |w| w.write_all(&bytes))
}

/// A series of `.glb` frames in a folder: `<stem>_<NNNNNN>.glb`, numbered from 0. glTF has no
/// collection file; the numbering orders the frames, and Blender and ParaView open numbered
/// files as a sequence.
pub struct GlbSeries {
    dir: PathBuf,
    stem: String,
    frames: usize,
}

impl GlbSeries {
    /// A series `<stem>_NNNNNN.glb` in `dir` (created when the first frame is written).
    pub fn new(dir: &Path, stem: &str) -> Self {
        GlbSeries {
            dir: dir.to_path_buf(),
            stem: stem.to_string(),
            frames: 0,
        }
    }

    /// The path of frame `k`.
    pub fn frame_path(&self, k: usize) -> PathBuf {
        self.dir.join(format!("{}_{k:06}.glb", self.stem))
    }

    /// Write the next frame.
    pub fn frame(&mut self, meshes: &[GlbMesh]) -> Result<()> {
        std::fs::create_dir_all(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        write_glb(&self.frame_path(self.frames), meshes)?;
        self.frames += 1;
        Ok(())
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.frames
    }
}

/// Read a `.glb` file's container: its JSON document and binary chunk, after checking the
/// header and chunk lengths against the file's. For tests and tools that read frames back.
pub fn read_glb(bytes: &[u8]) -> io::Result<(json::Root, Vec<u8>)> {
    let bad = |what: &str| io::Error::new(io::ErrorKind::InvalidData, what.to_string());
    let word = |at: usize| -> io::Result<u32> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
            .ok_or_else(|| bad("truncated"))
    };
    if word(0)? != MAGIC || word(4)? != 2 {
        return Err(bad("not a glTF 2.0 binary file"));
    }
    if word(8)? as usize != bytes.len() {
        return Err(bad("header length differs from the file's"));
    }
    let json_len = word(12)? as usize;
    if word(16)? != CHUNK_JSON || !json_len.is_multiple_of(4) {
        return Err(bad("first chunk is not a padded JSON chunk"));
    }
    let text = bytes
        .get(20..20 + json_len)
        .ok_or_else(|| bad("truncated"))?;
    let root = json::Root::from_slice(text).map_err(|e| bad(&e.to_string()))?;
    let at = 20 + json_len;
    let bin = if at == bytes.len() {
        Vec::new()
    } else {
        let len = word(at)? as usize;
        if word(at + 4)? != CHUNK_BIN || at + 8 + len != bytes.len() {
            return Err(bad("second chunk is not a binary chunk ending the file"));
        }
        bytes[at + 8..].to_vec()
    };
    Ok((root, bin))
}

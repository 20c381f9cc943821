//! The state of one parse of a Gmsh file: its sections read into a [`RawMesh`], with what
//! was skipped or reduced noted once per kind.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use super::super::text::Lines;
use super::super::{IdMap, RawMesh, RawTet, RawTriangle};
use super::source::{read_point, unknown_binary_type, Ascii, Binary, Source};
use super::{
    block_header_bytes, capacity, clip, element_type, end_marker, expect_end, expect_end_binary,
    read_block, read_count, skip_section, Endian, Header, Kind,
};
use crate::error::{Error, Location, Result};

/// The state of one parse: what was read so far and what was skipped.
pub(super) struct Reader<'a> {
    path: &'a Path,
    header: Header,
    raw: RawMesh,
    ids: IdMap,
    /// Elements ignored, per type, for one note each.
    ignored: BTreeMap<i32, usize>,
    /// Higher-order elements reduced to their corners, per type.
    corners_only: BTreeMap<i32, usize>,
    /// First physical tag of each Gmsh 4.1 entity, by (dimension, entity tag).
    physical: HashMap<(i32, i32), i32>,
    /// Node ids of the element being read (reused between elements).
    nodes: Vec<i64>,
}

impl<'a> Reader<'a> {
    /// An empty reader for a file with this header.
    pub(super) fn new(path: &'a Path, header: Header) -> Self {
        Reader {
            path,
            header,
            raw: RawMesh::new(header.format()),
            ids: IdMap::default(),
            ignored: BTreeMap::new(),
            corners_only: BTreeMap::new(),
            physical: HashMap::new(),
            nodes: Vec::new(),
        }
    }

    /// Read the section opened by the line `name`.
    pub(super) fn section(&mut self, lines: &mut Lines<'a>, name: &str) -> Result<()> {
        match (self.header, name) {
            (Header::V1, "$NOD") => self.nodes_v2(lines, "$NOD"),
            (Header::V1, "$ELM") => self.elements_ascii_v2(lines, "$ELM"),
            (Header::V2 { .. }, "$Nodes") => self.nodes_v2(lines, "$Nodes"),
            (Header::V2 { binary: None }, "$Elements") => {
                self.elements_ascii_v2(lines, "$Elements")
            }
            (Header::V2 { binary: Some(e) }, "$Elements") => self.elements_binary_v2(lines, e),
            (Header::V4 { .. }, "$Entities") => {
                self.with_source(lines, "$Entities", |r, src| r.entities_v4(src))
            }
            (Header::V4 { .. }, "$Nodes") => {
                self.with_source(lines, "$Nodes", |r, src| r.nodes_v4(src))
            }
            (Header::V4 { .. }, "$Elements") => {
                self.with_source(lines, "$Elements", |r, src| r.elements_v4(src))
            }
            // Names of physical groups: regions are numbered by tag, names are not needed.
            (_, "$PhysicalNames") => skip_section(lines, name),
            _ => {
                skip_section(lines, name)?;
                self.raw.notes.push(format!(
                    "skipped section {} (not needed for the mesh)",
                    clip(name)
                ));
                Ok(())
            }
        }
    }

    /// Run `read` over the data of section `name` (ASCII or binary as the header says), then
    /// check the section's closing line.
    fn with_source(
        &mut self,
        lines: &mut Lines<'a>,
        name: &'static str,
        read: impl FnOnce(&mut Self, &mut dyn Source) -> Result<()>,
    ) -> Result<()> {
        let binary = match self.header {
            Header::V2 { binary: Some(e) } => Some((e, 8)),
            Header::V4 { binary } => binary,
            _ => None,
        };
        let end = end_marker(name);
        match binary {
            Some((endian, size_t)) => {
                let mut src = Binary::new(lines, endian, size_t);
                read(self, &mut src)?;
                expect_end_binary(lines, src.pos(), &end)
            }
            None => {
                read(self, &mut Ascii::new(lines, name))?;
                expect_end(lines, &end, name)
            }
        }
    }

    /// Record point `p` with file id `id`.
    fn add_point(&mut self, id: i64, p: [f64; 3], loc: Location) -> Result<()> {
        let index = u32::try_from(self.raw.points.len()).map_err(|_| {
            Error::parse(
                self.path,
                loc,
                Some(id),
                "more nodes than lancet can index (2^32)",
                "split the mesh",
            )
        })?;
        self.ids.insert(id, index, self.path, loc)?;
        self.raw.points.push(p);
        self.raw.point_ids.push(id);
        Ok(())
    }

    /// Reserve room for `count` more points, at most what `bytes_left` could hold.
    fn reserve_points(&mut self, count: u64, bytes_left: usize) {
        // A node needs at least 8 bytes ("1 0 0 0\n" in ASCII, more in binary).
        let n = capacity(count, bytes_left, 8);
        self.raw.points.reserve(n);
        self.raw.point_ids.reserve(n);
    }

    /// Gmsh 1 `$NOD` and Gmsh 2 `$Nodes`: a count line, then `id x y z` rows (binary: int id
    /// and three doubles per node).
    fn nodes_v2(&mut self, lines: &mut Lines<'a>, name: &'static str) -> Result<()> {
        let count = read_count(lines, name)?;
        let binary = matches!(self.header, Header::V2 { binary: Some(_) });
        // A binary node is an int and three doubles.
        let each = binary.then_some(4 + 3 * 8);
        self.with_source(lines, name, |r, src| {
            let what = format_args!("{name} declares {count} nodes");
            read_block(src, what, count, each, |src| {
                r.reserve_points(count, src.bytes_left());
                for i in 0..count {
                    src.begin(format_args!("node {} of {count}", i + 1))?;
                    let id = src.int("node id", None)?;
                    let p = read_point(src, id)?;
                    src.end(Some(id))?;
                    r.add_point(id, p, src.loc())?;
                }
                Ok(())
            })
        })
    }

    /// Gmsh 1 `$ELM` (`id type reg-phys reg-elem n nodes...`) and Gmsh 2 ASCII `$Elements`
    /// (`id type ntags tags... nodes...`); the first tag is the physical group, the region.
    fn elements_ascii_v2(&mut self, lines: &mut Lines<'a>, name: &'static str) -> Result<()> {
        let count = read_count(lines, name)?;
        let v1 = self.header == Header::V1;
        let mut src = Ascii::new(lines, name);
        for i in 0..count {
            src.begin(format_args!("element {} of {count}", i + 1))?;
            let id = src.int("element id", None)?;
            let etype = src.int32("element type", Some(id))?;
            let region = if v1 {
                let region = src.int32("physical region", Some(id))?;
                src.int("elementary region", Some(id))?;
                let declared = src.size("number of nodes", Some(id))?;
                let listed = src.left().unwrap_or(0);
                if declared != listed as u64 {
                    return Err(src.error(
                        Some(id),
                        format!("element declares {declared} nodes but lists {listed}"),
                        "fix the node count or the node list",
                    ));
                }
                region
            } else {
                let ntags = src.size("number of tags", Some(id))?;
                let mut region = 0;
                for t in 0..ntags {
                    let tag = src.int32("tag", Some(id))?;
                    if t == 0 {
                        region = tag;
                    }
                }
                region
            };
            self.element_nodes(&mut src, etype, id, false)?;
            src.end(Some(id))?;
            self.push_element(etype, id, region, src.loc())?;
        }
        expect_end(lines, &end_marker(name), name)
    }

    /// Gmsh 2 binary `$Elements`: a count line, then blocks of one element type, each with a
    /// header `type count ntags` and per element `id tags... nodes...`, all ints.
    fn elements_binary_v2(&mut self, lines: &mut Lines<'a>, endian: Endian) -> Result<()> {
        let count = read_count(lines, "$Elements")?;
        let mut src = Binary::new(lines, endian, 8);
        let mut read: u64 = 0;
        while read < count {
            src.begin(format_args!("element block header"))?;
            let etype = src.int32("element type", None)?;
            let follow = src.int("number of elements in the block", None)?;
            let ntags = src.int("number of tags", None)?;
            let Some((nodes, _, name)) = element_type(etype) else {
                return Err(unknown_binary_type(&src, etype));
            };
            if follow <= 0 || ntags < 0 || follow as u64 > count - read {
                return Err(src.error(
                    None,
                    format!(
                        "element block declares {follow} elements with {ntags} tags, \
                         but {} of the {count} elements remain",
                        count - read
                    ),
                    "the block header is damaged; export the file again",
                ));
            }
            // An int id, the tags and the nodes, four bytes each.
            let each = 4 * (1 + ntags as u64 + nodes as u64);
            let what =
                format_args!("element block declares {follow} elements ({name}) with {ntags} tags");
            read_block(&mut src, what, follow as u64, Some(each), |src| {
                for _ in 0..follow {
                    src.begin(format_args!("element"))?;
                    let id = src.int("element id", None)?;
                    let mut region = 0;
                    for t in 0..ntags {
                        let tag = src.int32("tag", Some(id))?;
                        if t == 0 {
                            region = tag;
                        }
                    }
                    self.element_nodes(src, etype, id, false)?;
                    self.push_element(etype, id, region, src.loc())?;
                }
                Ok(())
            })?;
            read += follow as u64;
        }
        expect_end_binary(lines, src.pos(), "$EndElements")
    }

    /// Gmsh 4.1 `$Entities`: only the first physical tag of each entity is kept (it is the
    /// region of the elements of that entity).
    fn entities_v4(&mut self, src: &mut dyn Source) -> Result<()> {
        src.begin(format_args!("entity counts"))?;
        let mut counts = [0u64; 4];
        for c in &mut counts {
            *c = src.size("entity count", None)?;
        }
        src.end(None)?;
        for (dim, &n) in (0i32..).zip(&counts) {
            for i in 0..n {
                src.begin(format_args!("entity {} of {n} of dimension {dim}", i + 1))?;
                let tag = src.int32("entity tag", None)?;
                // Points give a position, other entities a bounding box.
                let floats = if dim == 0 { 3 } else { 6 };
                for _ in 0..floats {
                    src.float("bounding box coordinate", None)?;
                }
                let nphys = src.size("number of physical tags", None)?;
                for p in 0..nphys {
                    let phys = src.int32("physical tag", None)?;
                    if p == 0 {
                        self.physical.insert((dim, tag), phys);
                    }
                }
                if dim > 0 {
                    let nbound = src.size("number of bounding entities", None)?;
                    for _ in 0..nbound {
                        src.int("bounding entity tag", None)?;
                    }
                }
                src.end(None)?;
            }
        }
        Ok(())
    }

    /// Gmsh 4.1 `$Nodes`: a header, then per entity block a header, the block's node tags,
    /// then their coordinates (plus parametric coordinates when flagged).
    fn nodes_v4(&mut self, src: &mut dyn Source) -> Result<()> {
        src.begin(format_args!("header of $Nodes"))?;
        let blocks = src.size("number of entity blocks", None)?;
        let declared = src.size("number of nodes", None)?;
        src.size("minimum node tag", None)?;
        src.size("maximum node tag", None)?;
        src.end(None)?;
        self.reserve_points(declared, src.bytes_left());
        let what = format_args!("$Nodes declares {blocks} entity blocks");
        let header = block_header_bytes(src);
        let total = read_block(src, what, blocks, header, |src| {
            let mut total: u64 = 0;
            let mut tags = Vec::new();
            for b in 0..blocks {
                src.begin(format_args!("header of node block {} of {blocks}", b + 1))?;
                let dim = src.int32("entity dimension", None)?;
                src.int32("entity tag", None)?;
                let parametric = src.int32("parametric flag", None)?;
                let n = src.size("number of nodes in the block", None)?;
                src.end(None)?;
                if !(0..=3).contains(&dim) || !(0..=1).contains(&parametric) {
                    return Err(src.error(
                        None,
                        format!(
                            "node block has entity dimension {dim} and parametric flag \
                             {parametric}; expected 0..3 and 0 or 1"
                        ),
                        "the block header is damaged; export the file again",
                    ));
                }
                // Parametric coordinates follow x y z: one per dimension of the entity.
                let extra = if parametric == 1 { dim } else { 0 };
                // A tag, then the coordinates.
                let each = src
                    .size_width()
                    .map(|w| (w + 8 * (3 + extra as usize)) as u64);
                let what = format_args!("node block {} of {blocks} declares {n} nodes", b + 1);
                read_block(src, what, n, each, |src| {
                    tags.clear();
                    tags.reserve(capacity(n, src.bytes_left(), 2));
                    for i in 0..n {
                        src.begin(format_args!(
                            "tag of node {} of {n} in block {}",
                            i + 1,
                            b + 1
                        ))?;
                        tags.push(src.id("node tag", None)?);
                        src.end(None)?;
                    }
                    for &tag in &tags {
                        src.begin(format_args!("coordinates of node {tag}"))?;
                        let p = read_point(src, tag)?;
                        for _ in 0..extra {
                            src.float("parametric coordinate", Some(tag))?;
                        }
                        src.end(Some(tag))?;
                        self.add_point(tag, p, src.loc())?;
                    }
                    Ok(())
                })?;
                total = total.saturating_add(n);
            }
            Ok(total)
        })?;
        if total != declared {
            return Err(src.error(
                None,
                format!("the node blocks hold {total} nodes but the header declares {declared}"),
                "fix the count in the first line of $Nodes",
            ));
        }
        Ok(())
    }

    /// Gmsh 4.1 `$Elements`: a header, then per entity block a header (dimension, entity,
    /// type, count) and one `tag nodes...` record per element.
    fn elements_v4(&mut self, src: &mut dyn Source) -> Result<()> {
        src.begin(format_args!("header of $Elements"))?;
        let blocks = src.size("number of entity blocks", None)?;
        let declared = src.size("number of elements", None)?;
        src.size("minimum element tag", None)?;
        src.size("maximum element tag", None)?;
        src.end(None)?;
        let what = format_args!("$Elements declares {blocks} entity blocks");
        let header = block_header_bytes(src);
        let total = read_block(src, what, blocks, header, |src| {
            let mut total: u64 = 0;
            for b in 0..blocks {
                src.begin(format_args!(
                    "header of element block {} of {blocks}",
                    b + 1
                ))?;
                let dim = src.int32("entity dimension", None)?;
                let entity = src.int32("entity tag", None)?;
                let etype = src.int32("element type", None)?;
                let n = src.size("number of elements in the block", None)?;
                src.end(None)?;
                if src.left().is_none() && element_type(etype).is_none() {
                    return Err(unknown_binary_type(src, etype));
                }
                // A tag and the nodes, a `size_t` each.
                let each = src
                    .size_width()
                    .zip(element_type(etype))
                    .map(|(w, (nodes, _, _))| (w * (1 + nodes)) as u64);
                let what =
                    format_args!("element block {} of {blocks} declares {n} elements", b + 1);
                // The region is the entity's physical group; without one, the entity itself.
                let region = self.physical.get(&(dim, entity)).copied().unwrap_or(entity);
                read_block(src, what, n, each, |src| {
                    for i in 0..n {
                        src.begin(format_args!("element {} of {n} in block {}", i + 1, b + 1))?;
                        let id = src.id("element tag", None)?;
                        self.element_nodes(src, etype, id, true)?;
                        src.end(Some(id))?;
                        self.push_element(etype, id, region, src.loc())?;
                    }
                    Ok(())
                })?;
                total = total.saturating_add(n);
            }
            Ok(total)
        })?;
        if total != declared {
            return Err(src.error(
                None,
                format!(
                    "the element blocks hold {total} elements but the header declares {declared}"
                ),
                "fix the count in the first line of $Elements",
            ));
        }
        Ok(())
    }

    /// Read the node ids of element `id` of type `etype` into `self.nodes`: as many as the
    /// type has (ASCII lines must list exactly that many). `wide` ids are `size_t` (4.1).
    fn element_nodes(
        &mut self,
        src: &mut dyn Source,
        etype: i32,
        id: i64,
        wide: bool,
    ) -> Result<()> {
        let n = match (element_type(etype), src.left()) {
            (Some((n, _, name)), Some(listed)) if listed != n => {
                return Err(src.error(
                    Some(id),
                    format!("a {name} (type {etype}) has {n} nodes, but the line lists {listed}"),
                    "fix the node list or the element type",
                ))
            }
            (Some((n, _, _)), _) => n,
            // Unknown type in ASCII: take the rest of the line; the element is ignored.
            (None, Some(listed)) => listed,
            (None, None) => return Err(unknown_binary_type(src, etype)),
        };
        self.nodes.clear();
        for _ in 0..n {
            let node = if wide {
                src.id("node id", Some(id))?
            } else {
                src.int("node id", Some(id))?
            };
            self.nodes.push(node);
        }
        Ok(())
    }

    /// Keep, ignore or refuse the element whose nodes are in `self.nodes`.
    fn push_element(&mut self, etype: i32, id: i64, region: i32, loc: Location) -> Result<()> {
        let Some((n, kind, name)) = element_type(etype) else {
            *self.ignored.entry(etype).or_default() += 1;
            return Ok(());
        };
        match kind {
            Kind::Other => *self.ignored.entry(etype).or_default() += 1,
            Kind::Solid => {
                return Err(Error::parse(
                    self.path,
                    loc,
                    Some(id),
                    format!(
                        "unsupported element type {etype} ({name}); lancet simulates tetrahedra"
                    ),
                    "convert to tetrahedra, e.g. mesh the geometry again with \
                     `gmsh -3 model.geo -o model.msh` without recombination",
                ))
            }
            Kind::Tet => {
                let nodes = self.corners::<4>(id, loc)?;
                self.raw.tets.push(RawTet {
                    nodes,
                    region,
                    id,
                    location: loc,
                });
                if n > 4 {
                    *self.corners_only.entry(etype).or_default() += 1;
                }
            }
            Kind::Triangle => {
                let nodes = self.corners::<3>(id, loc)?;
                self.raw.triangles.push(RawTriangle { nodes, tag: region });
                if n > 3 {
                    *self.corners_only.entry(etype).or_default() += 1;
                }
            }
        }
        Ok(())
    }

    /// The point indices of the first `N` nodes of the current element (Gmsh lists the
    /// corners of every element first).
    fn corners<const N: usize>(&self, id: i64, loc: Location) -> Result<[u32; N]> {
        let mut out = [0u32; N];
        for (o, &node) in out.iter_mut().zip(&self.nodes) {
            *o = self.ids.get(node, self.path, loc, id)?;
        }
        Ok(out)
    }

    /// The raw mesh, with one note per kind of element ignored or simplified.
    pub(super) fn finish(mut self) -> RawMesh {
        for (&t, n) in &self.ignored {
            self.raw.notes.push(match element_type(t) {
                Some((_, _, name)) => format!("ignored {n} {name} elements (type {t})"),
                None => format!("ignored {n} elements of unknown type {t}"),
            });
        }
        for (&t, n) in &self.corners_only {
            let Some((_, kind, name)) = element_type(t) else {
                continue;
            };
            let corners = if kind == Kind::Tet { 4 } else { 3 };
            let extra = if t == 11 || t == 9 {
                "mid-edge"
            } else {
                "higher-order"
            };
            self.raw.notes.push(format!(
                "dropped the {extra} nodes of {n} {name} elements (type {t}), \
                 keeping their {corners} corners"
            ));
        }
        self.raw
    }
}

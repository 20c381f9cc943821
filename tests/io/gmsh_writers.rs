//! Test-only Gmsh writers (2.2 and 4.1, ASCII and binary of either byte order and `size_t`
//! width) of one sample mesh, for round trips through every encoding.
#![cfg(feature = "formats")]

use lancet::mesh::generate::BoxGrid;
use lancet::mesh::io::RawMesh;

/// A small mesh with sparse node ids, two regions, a few triangles and a line.
pub(crate) struct Sample {
    pub(crate) ids: Vec<u64>,
    pub(crate) points: Vec<[f64; 3]>,
    /// Tets grouped by region (10 then 20), as indices into `points`.
    pub(crate) tets: Vec<([usize; 4], i32)>,
    pub(crate) tris: Vec<[usize; 3]>,
    pub(crate) line: [usize; 2],
}

const TET_ID0: u64 = 100;
const TRI_ID0: u64 = 500;
const LINE_ID: u64 = 900;
pub(crate) const TRI_TAG: i32 = 7;

pub(crate) fn sample() -> Sample {
    let mesh = BoxGrid::cube_cells([2, 2, 2], 0.1).build().unwrap();
    let dense = mesh.dense_nodes();
    let points: Vec<[f64; 3]> = dense
        .keys
        .iter()
        .map(|&k| {
            let p = mesh.rest(k);
            [p.x, p.y, p.z]
        })
        .collect();
    let n = points.len();
    // A permutation of sparse ids: neither dense nor increasing.
    let ids = (0..n).map(|i| 10 + 3 * ((i * 7) % n) as u64).collect();
    let mut tets: Vec<([usize; 4], i32)> = mesh
        .tets()
        .enumerate()
        .map(|(i, (_, t))| {
            let nodes = t.nodes.map(|k| dense.index[k] as usize);
            (nodes, if i % 2 == 0 { 10 } else { 20 })
        })
        .collect();
    tets.sort_by_key(|t| t.1);
    let tris = mesh
        .topology()
        .boundary
        .iter()
        .take(4)
        .map(|f| f.nodes.map(|k| dense.index[k] as usize))
        .collect();
    Sample {
        ids,
        points,
        tets,
        tris,
        line: [0, 1],
    }
}

fn i32_bytes(v: i32, big: bool) -> [u8; 4] {
    if big {
        v.to_be_bytes()
    } else {
        v.to_le_bytes()
    }
}

fn f64_bytes(v: f64, big: bool) -> [u8; 8] {
    if big {
        v.to_be_bytes()
    } else {
        v.to_le_bytes()
    }
}

/// Gmsh 2.2, ascii or binary (little- or big-endian).
pub(crate) fn write_v22(s: &Sample, binary: Option<bool>) -> Vec<u8> {
    let mut o = Vec::new();
    let elements = s.tets.len() + s.tris.len() + 1;
    match binary {
        None => o.extend_from_slice(b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"),
        Some(big) => {
            o.extend_from_slice(b"$MeshFormat\n2.2 1 8\n");
            o.extend_from_slice(&i32_bytes(1, big));
            o.extend_from_slice(b"\n$EndMeshFormat\n");
        }
    }
    o.extend_from_slice(format!("$Nodes\n{}\n", s.points.len()).as_bytes());
    for (id, p) in s.ids.iter().zip(&s.points) {
        match binary {
            None => o.extend_from_slice(format!("{id} {} {} {}\n", p[0], p[1], p[2]).as_bytes()),
            Some(big) => {
                o.extend_from_slice(&i32_bytes(*id as i32, big));
                for c in p {
                    o.extend_from_slice(&f64_bytes(*c, big));
                }
            }
        }
    }
    let nl = if binary.is_some() { "\n" } else { "" };
    o.extend_from_slice(format!("{nl}$EndNodes\n$Elements\n{elements}\n").as_bytes());
    // Each element: id, type, tags (physical, elementary), node ids.
    let mut rows: Vec<(u64, i32, [i32; 2], Vec<u64>)> = Vec::new();
    for (j, (t, region)) in s.tets.iter().enumerate() {
        let nodes = t.iter().map(|&i| s.ids[i]).collect();
        rows.push((TET_ID0 + j as u64, 4, [*region, 1], nodes));
    }
    for (j, t) in s.tris.iter().enumerate() {
        let nodes = t.iter().map(|&i| s.ids[i]).collect();
        rows.push((TRI_ID0 + j as u64, 2, [TRI_TAG, 5], nodes));
    }
    let line = s.line.iter().map(|&i| s.ids[i]).collect();
    rows.push((LINE_ID, 1, [0, 3], line));
    match binary {
        None => {
            for (id, ty, tags, nodes) in &rows {
                let nodes: Vec<String> = nodes.iter().map(|n| n.to_string()).collect();
                let row = format!("{id} {ty} 2 {} {} {}\n", tags[0], tags[1], nodes.join(" "));
                o.extend_from_slice(row.as_bytes());
            }
        }
        Some(big) => {
            // One block per run of equal types (the rows are grouped by type).
            let mut start = 0;
            while start < rows.len() {
                let ty = rows[start].1;
                let len = rows[start..].iter().take_while(|r| r.1 == ty).count();
                for v in [ty, len as i32, 2] {
                    o.extend_from_slice(&i32_bytes(v, big));
                }
                for (id, _, tags, nodes) in &rows[start..start + len] {
                    o.extend_from_slice(&i32_bytes(*id as i32, big));
                    for t in tags {
                        o.extend_from_slice(&i32_bytes(*t, big));
                    }
                    for n in nodes {
                        o.extend_from_slice(&i32_bytes(*n as i32, big));
                    }
                }
                start += len;
            }
        }
    }
    o.extend_from_slice(format!("{nl}$EndElements\n").as_bytes());
    o
}

/// Where a Gmsh 4.1 writer puts values: space-separated lines, or binary with a given size_t.
struct Sink {
    out: Vec<u8>,
    /// `None` for ascii; the width of size_t for binary.
    size_t: Option<usize>,
    /// Whether values were written since the last marker or line end.
    open: bool,
}

impl Sink {
    pub(crate) fn new(size_t: Option<usize>) -> Self {
        Sink {
            out: Vec::new(),
            size_t,
            open: false,
        }
    }

    pub(crate) fn token(&mut self, t: String) {
        if self.open {
            self.out.push(b' ');
        }
        self.out.extend_from_slice(t.as_bytes());
        self.open = true;
    }

    pub(crate) fn int(&mut self, v: i32) {
        match self.size_t {
            None => self.token(v.to_string()),
            Some(_) => self.bytes(&v.to_le_bytes()),
        }
    }

    pub(crate) fn size(&mut self, v: u64) {
        match self.size_t {
            None => self.token(v.to_string()),
            Some(4) => self.bytes(&(v as u32).to_le_bytes()),
            Some(_) => self.bytes(&v.to_le_bytes()),
        }
    }

    pub(crate) fn float(&mut self, v: f64) {
        match self.size_t {
            None => self.token(v.to_string()),
            Some(_) => self.bytes(&v.to_le_bytes()),
        }
    }

    pub(crate) fn bytes(&mut self, b: &[u8]) {
        self.out.extend_from_slice(b);
        self.open = true;
    }

    /// End an ascii row (binary rows have no end).
    pub(crate) fn end(&mut self) {
        if self.size_t.is_none() {
            self.out.push(b'\n');
            self.open = false;
        }
    }

    /// A text line such as `$Nodes`, on a line of its own in either encoding.
    pub(crate) fn line(&mut self, text: &str) {
        if self.open {
            self.out.push(b'\n');
        }
        self.out.extend_from_slice(text.as_bytes());
        self.out.push(b'\n');
        self.open = false;
    }
}

/// Gmsh 4.1, ascii (`size_t` = `None`) or little-endian binary with the given size_t width.
/// Tets of region 10 and 20 go to volume entities 1 and 2 (physical groups 10 and 20); the
/// second node block carries parametric coordinates to be skipped.
pub(crate) fn write_v41(s: &Sample, size_t: Option<usize>) -> Vec<u8> {
    let mut o = Sink::new(size_t);
    o.line("$MeshFormat");
    match size_t {
        None => o.line("4.1 0 8"),
        Some(w) => {
            o.line(&format!("4.1 1 {w}"));
            o.int(1);
        }
    }
    o.line("$EndMeshFormat");
    o.line("$Entities");
    for c in [0, 1, 1, 2] {
        o.size(c);
    }
    o.end();
    // entity: tag, bounding box, physical tags, bounding entities
    let entities: [(i32, &[i32], &[i32]); 4] = [
        (3, &[], &[]),
        (5, &[TRI_TAG], &[]),
        (1, &[10], &[5]),
        (2, &[20], &[-5]),
    ];
    for (tag, phys, bound) in entities {
        o.int(tag);
        for c in [0.0, 0.0, 0.0, 0.2, 0.2, 0.2] {
            o.float(c);
        }
        o.size(phys.len() as u64);
        phys.iter().for_each(|&p| o.int(p));
        o.size(bound.len() as u64);
        bound.iter().for_each(|&b| o.int(b));
        o.end();
    }
    o.line("$EndEntities");
    o.line("$Nodes");
    let n = s.points.len();
    let half = n / 2;
    for v in [2, n as u64, 1, *s.ids.iter().max().unwrap()] {
        o.size(v);
    }
    o.end();
    for (block, range) in [(1, 0..half), (2, half..n)] {
        let parametric = block == 2;
        o.int(3);
        o.int(block);
        o.int(parametric as i32);
        o.size(range.len() as u64);
        o.end();
        for i in range.clone() {
            o.size(s.ids[i]);
            o.end();
        }
        for i in range {
            s.points[i].iter().for_each(|&c| o.float(c));
            if parametric {
                (0..3).for_each(|_| o.float(0.5));
            }
            o.end();
        }
    }
    o.line("$EndNodes");
    o.line("$Elements");
    let elements = s.tets.len() + s.tris.len() + 1;
    for v in [4, elements as u64, 1, LINE_ID] {
        o.size(v);
    }
    o.end();
    let block = |o: &mut Sink, dim: i32, entity: i32, ty: i32, rows: &[(u64, Vec<usize>)]| {
        o.int(dim);
        o.int(entity);
        o.int(ty);
        o.size(rows.len() as u64);
        o.end();
        for (id, nodes) in rows {
            o.size(*id);
            nodes.iter().for_each(|&i| o.size(s.ids[i]));
            o.end();
        }
    };
    for (entity, region) in [(1, 10), (2, 20)] {
        let rows: Vec<(u64, Vec<usize>)> = s
            .tets
            .iter()
            .enumerate()
            .filter(|(_, t)| t.1 == region)
            .map(|(j, t)| (TET_ID0 + j as u64, t.0.to_vec()))
            .collect();
        block(&mut o, 3, entity, 4, &rows);
    }
    let tris: Vec<(u64, Vec<usize>)> = (s.tris.iter().enumerate())
        .map(|(j, t)| (TRI_ID0 + j as u64, t.to_vec()))
        .collect();
    block(&mut o, 2, 5, 2, &tris);
    block(&mut o, 1, 3, 1, &[(LINE_ID, s.line.to_vec())]);
    o.line("$EndElements");
    o.out
}

/// The parts of a raw mesh that must not depend on the encoding.
pub(crate) fn content(r: &RawMesh) -> impl PartialEq + std::fmt::Debug {
    let tets: Vec<_> = r.tets.iter().map(|t| (t.nodes, t.region, t.id)).collect();
    (
        r.points.clone(),
        r.point_ids.clone(),
        tets,
        r.triangles.clone(),
        r.notes.clone(),
    )
}

//! A box cut right through by an upright blade at rest, with a render surface of random
//! vertices in and around it rebound after every sweep: the fixture of the tests of a render
//! surface through cuts.
#![allow(dead_code)] // each test binary uses a different subset

use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, CutOutcome, Cutter, Sweep};
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::TetMesh;
use lancet::model::{Material, ModelConfig, SpringModel};
use lancet::surface::{CutChange, Embedding, Rebinder, RenderSurface};
use nalgebra::Isometry3;

/// Cell size, m.
pub const H: f64 = 0.01;
/// The blade's plane, `y = Y0`: between node layers, away from the edges' snapping ends.
pub const Y0: f64 = 0.0253;
const BLADE: ToolShape = ToolShape::Blade {
    width: 0.1,
    length: 0.1,
    thickness: 1e-4,
};

/// The 5 x 4 x 3 cm box of 1 cm cells.
pub fn box_mesh() -> TetMesh {
    BoxGrid::cube_cells([5, 4, 3], H).build().unwrap()
}

/// `n` random vertices in the box grown by 3 mm on every side, some of them outside the mesh,
/// in arbitrary triangles (the binding does not look at them).
pub fn cloud(seed: u64, n: usize) -> RenderSurface {
    let mut s = seed;
    let mut next = move || {
        // SplitMix64.
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let positions: Vec<[f64; 3]> = (0..n)
        .map(|_| [0.05, 0.04, 0.03].map(|hi: f64| -3e-3 + (hi + 6e-3) * next()))
        .collect();
    let triangles = (0..n as u32 / 3)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    RenderSurface::new(positions, triangles, "cloud").unwrap()
}

/// The box, its spring model, and a cutter by `method` (subdividing without a quality floor,
/// so that the cut follows the blade by the parameter rule alone).
pub fn cutter(method: CutMethod) -> Cutter {
    let mesh = box_mesh();
    let model =
        SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(3e3, 0.3, 1e3))).unwrap();
    Cutter::new(mesh, model, method)
        .unwrap()
        .with_quality_floor(0.0)
}

/// The sweeps of the upright blade in the plane `y = Y0` moving down through the whole box
/// in `steps` steps.
pub fn sweeps(steps: usize) -> Vec<Sweep> {
    sweeps_down_to(steps, -0.015)
}

/// The sweeps of the same blade moving down from above the box to height `bottom` in `steps`
/// steps (a partial cut for a `bottom` inside the box).
pub fn sweeps_down_to(steps: usize, bottom: f64) -> Vec<Sweep> {
    let at = |z: f64| Isometry3::translation(0.02, Y0, z);
    let top = 0.045;
    (0..steps)
        .map(|k| {
            let z0 = top + (bottom - top) * k as f64 / steps as f64;
            let z1 = top + (bottom - top) * (k + 1) as f64 / steps as f64;
            Sweep::of_blade(&BLADE, &at(z0), &at(z1)).unwrap()
        })
        .collect()
}

/// The sweeps of the upright blade between consecutive `poses` (a stroke of several steps).
pub fn sweeps_between(poses: &[Isometry3<f64>]) -> Vec<Sweep> {
    poses
        .windows(2)
        .map(|p| Sweep::of_blade(&BLADE, &p[0], &p[1]).unwrap())
        .collect()
}

/// One sweep at rest; with `rebinder`, the embedding follows it.
pub fn cut_once(
    cutter: &mut Cutter,
    sweep: &Sweep,
    follow: Option<(&mut Rebinder, &mut Embedding)>,
) -> (CutOutcome, usize) {
    let rest: Vec<[f64; 3]> = cutter
        .mesh()
        .nodes()
        .map(|(_, n)| n.rest.coords.into())
        .collect();
    let outcome = cutter.cut(sweep, &rest).unwrap();
    let rebound = match follow {
        Some((rebinder, e)) => {
            let change = CutChange {
                mesh: cutter.mesh(),
                faces: cutter.faces(),
                tets: &outcome.tets_changed,
                sweep,
            };
            rebinder.rebind(e, &change).vertices.len()
        }
        None => 0,
    };
    (outcome, rebound)
}

/// The two pieces of a box cut right through, pulled apart: each moved as a whole, the piece on
/// the blade's -y side one way, the other the other; nodes without a tet stay at rest.
pub struct Pulled {
    /// Node positions, dense order.
    pub x: Vec<[f64; 3]>,
    /// The piece of each tet.
    pub piece: slotmap::SecondaryMap<lancet::TetKey, u32>,
    /// The piece on the blade's -y side.
    pub minus: u32,
}

impl Pulled {
    /// Pull the pieces of `mesh` (two) apart.
    pub fn apart(mesh: &TetMesh) -> Self {
        let (piece, n) = lancet::mesh::topology::components(mesh);
        assert_eq!(n, 2, "cut through");
        // Which piece is on the blade's -y side: the one whose tets' centroids lie there.
        let mut y = [0.0; 2];
        let mut count = [0.0; 2];
        for (tk, t) in mesh.tets() {
            let c = mesh.tet_points(t).iter().map(|p| p.y).sum::<f64>() / 4.0;
            y[piece[tk] as usize] += c;
            count[piece[tk] as usize] += 1.0;
        }
        let minus = if y[0] / count[0] < y[1] / count[1] {
            0
        } else {
            1
        };
        let mut p = Pulled {
            x: Vec::new(),
            piece,
            minus,
        };
        let dense = mesh.dense_nodes();
        let mut u: Vec<Option<nalgebra::Vector3<f64>>> = vec![None; dense.keys.len()];
        for (tk, t) in mesh.tets() {
            let d = p.of_tet(tk);
            for k in t.nodes {
                let slot = &mut u[dense.index[k] as usize];
                assert!(slot.is_none_or(|s| s == d), "a node in both pieces");
                *slot = Some(d);
            }
        }
        p.x = dense
            .keys
            .iter()
            .zip(&u)
            .map(|(&k, d)| (mesh.rest(k) + d.unwrap_or_default()).into())
            .collect();
        p
    }

    /// How the piece of tet `t` moved.
    pub fn of_tet(&self, t: lancet::TetKey) -> nalgebra::Vector3<f64> {
        self.of_side(self.piece[t] == self.minus)
    }

    /// How the piece on the blade's -y side (`minus`) or the other moved.
    pub fn of_side(&self, minus: bool) -> nalgebra::Vector3<f64> {
        if minus {
            nalgebra::Vector3::new(1e-3, -4e-3, 2e-3)
        } else {
            nalgebra::Vector3::new(-2e-3, 5e-3, -1e-3)
        }
    }
}

/// The closed surface of the box `lo..hi`, `n` segments along each axis, triangles
/// counter-clockwise seen from outside: a finer surface than the mesh's boundary.
pub fn closed_box(lo: [f64; 3], hi: [f64; 3], n: [usize; 3]) -> RenderSurface {
    let mut index = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let mut vertex = |i: [usize; 3]| -> u32 {
        *index.entry(i).or_insert_with(|| {
            positions.push([0, 1, 2].map(|c| lo[c] + (hi[c] - lo[c]) * i[c] as f64 / n[c] as f64));
            (positions.len() - 1) as u32
        })
    };
    let mut triangles = Vec::new();
    // Each face: the axis it is normal to, which end, and the two axes spanning it in an order
    // whose cross product points out of the box.
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for end in [0, n[axis]] {
            for a in 0..n[u] {
                for b in 0..n[v] {
                    let at = |du: usize, dv: usize| {
                        let mut i = [0; 3];
                        i[axis] = end;
                        i[u] = a + du;
                        i[v] = b + dv;
                        i
                    };
                    let q = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)].map(&mut vertex);
                    // u x v is +axis: counter-clockwise at the far end, reversed at the near.
                    if end == 0 {
                        triangles.push([q[0], q[2], q[1]]);
                        triangles.push([q[0], q[3], q[2]]);
                    } else {
                        triangles.push([q[0], q[1], q[2]]);
                        triangles.push([q[0], q[2], q[3]]);
                    }
                }
            }
        }
    }
    RenderSurface::new(positions, triangles, "closed box").unwrap()
}

/// Why `triangles` is not a closed, consistently oriented surface: an edge not used exactly
/// once each way round (a directed edge used twice is a flipped triangle; one never used the
/// other way is a hole). `None` when it is.
pub fn not_closed(triangles: &[[u32; 3]]) -> Option<String> {
    let mut directed = std::collections::HashMap::new();
    for t in triangles {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    let mut bad: Vec<_> = directed
        .iter()
        .filter(|(&(a, b), &n)| n != 1 || directed.get(&(b, a)) != Some(&1))
        .map(|(e, n)| (*e, *n))
        .collect();
    bad.sort_unstable();
    (!bad.is_empty()).then(|| {
        format!(
            "{} of {} directed edges are not matched once the other way, e.g. {:?}",
            bad.len(),
            directed.len(),
            &bad[..bad.len().min(6)]
        )
    })
}

/// The volume enclosed by `triangles` at `positions` (positive for an outward surface).
pub fn enclosed_volume(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| nalgebra::Vector3::from(positions[v as usize]));
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

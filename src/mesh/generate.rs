//! Mesh generators: a box of hexahedral cells split into tets, and a beam.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::{NodeKey, TetMesh};
use crate::error::{Error, Result};

/// How each hexahedral cell is split into tets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum TetSplit {
    /// Five tets per cell (four corners and a central one), alternating with cell parity so
    /// that faces of neighbouring cells match.
    Five,
    /// Six tets per cell around the main diagonal (Freudenthal/Kuhn); conforming everywhere.
    #[default]
    Six,
}

/// A box `size` wide, starting at `origin`, made of `cells` hexahedra split into tets.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxGrid {
    /// Number of cells along x, y, z (each at least 1).
    pub cells: [usize; 3],
    /// Extent along x, y, z.
    pub size: [f64; 3],
    /// The corner with the smallest coordinates.
    #[serde(default)]
    pub origin: [f64; 3],
    /// How cells are split.
    #[serde(default)]
    pub split: TetSplit,
}

impl BoxGrid {
    /// A unit-spaced grid of `nx * ny * nz` cells of edge `h`, at the origin, six tets per cell.
    pub fn cube_cells(n: [usize; 3], h: f64) -> Self {
        BoxGrid {
            cells: n,
            size: [n[0] as f64 * h, n[1] as f64 * h, n[2] as f64 * h],
            origin: [0.0; 3],
            split: TetSplit::Six,
        }
    }

    /// The number of tets the box is split into (`None` if it overflows).
    pub fn tet_count(&self) -> Option<u64> {
        let per_cell = match self.split {
            TetSplit::Five => 5,
            TetSplit::Six => 6,
        };
        self.cells
            .iter()
            .try_fold(per_cell, |n: u64, &c| n.checked_mul(c as u64))
    }

    /// About how many bytes of memory a run of this box takes: its mesh, spring model, packed
    /// model and an engine's state, [`RUN_BYTES_PER_TET`] a tet (saturating).
    pub fn estimated_bytes(&self) -> u64 {
        self.tet_count()
            .unwrap_or(u64::MAX)
            .saturating_mul(RUN_BYTES_PER_TET)
    }

    /// Refuse a box whose run would need more than `available` bytes, with the estimate, so
    /// that a mistyped cell count is an error rather than an allocation failure that aborts
    /// the process. [`BoxGrid::build`] checks this against the memory the system reports
    /// available (Linux), before allocating anything.
    pub fn check_memory(&self, available: u64) -> Result<()> {
        let need = self.estimated_bytes();
        if need <= available {
            return Ok(());
        }
        let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
        let tets = self
            .tet_count()
            .map_or("too many".to_string(), |t| t.to_string());
        Err(Error::Mesh(format!(
            "a box of {:?} cells makes {tets} tets, which would need about {:.1} GiB of memory \
             to run ({RUN_BYTES_PER_TET} bytes a tet), but {:.1} GiB is available; use fewer \
             cells",
            self.cells,
            gib(need),
            gib(available)
        )))
    }

    /// Build the mesh. Nodes are numbered x fastest, then y, then z. A box too large for the
    /// memory available is refused first ([`BoxGrid::check_memory`]).
    pub fn build(&self) -> Result<TetMesh> {
        let [nx, ny, nz] = self.cells;
        if nx == 0 || ny == 0 || nz == 0 {
            return Err(Error::Mesh(format!(
                "box grid needs at least one cell along each axis, got {:?}",
                self.cells
            )));
        }
        if self.size.iter().any(|s| !s.is_finite() || *s <= 0.0)
            || self.origin.iter().any(|o| !o.is_finite())
        {
            return Err(Error::Mesh(format!(
                "box grid needs a positive finite size and a finite origin, got size {:?}, origin {:?}",
                self.size, self.origin
            )));
        }
        let total = (nx + 1)
            .checked_mul(ny + 1)
            .and_then(|v| v.checked_mul(nz + 1))
            .filter(|&v| v < u32::MAX as usize)
            .ok_or_else(|| Error::Mesh("box grid is too large for u32 node indices".into()))?;
        if let Some(available) = available_memory() {
            self.check_memory(available)?;
        }
        let mut mesh = TetMesh::new();
        let mut keys: Vec<NodeKey> = Vec::with_capacity(total);
        let h = [
            self.size[0] / nx as f64,
            self.size[1] / ny as f64,
            self.size[2] / nz as f64,
        ];
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    keys.push(mesh.add_node(Point3::new(
                        self.origin[0] + i as f64 * h[0],
                        self.origin[1] + j as f64 * h[1],
                        self.origin[2] + k as f64 * h[2],
                    )));
                }
            }
        }
        let id = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    // Cell corner c (bits x, y, z) is node (i + x, j + y, k + z).
                    let c = |bits: usize| {
                        keys[id(i + (bits & 1), j + ((bits >> 1) & 1), k + ((bits >> 2) & 1))]
                    };
                    for t in cell_tets(self.split, (i + j + k) % 2 == 1) {
                        mesh.add_tet_reorienting(t.map(c), 0)?;
                    }
                }
            }
        }
        Ok(mesh)
    }
}

/// Bytes a run takes per tet of a generated box: the mesh, the spring model, the packed model
/// and the engine's state together. Measured as the peak resident memory of `lancet run` of a
/// box of 40^3 cells (384,000 tets) for one step, less that of a one-cell box: 853 bytes a tet
/// with the fast engine (656 with the reference engine); rounded up.
pub const RUN_BYTES_PER_TET: u64 = 1000;

/// The memory the system says is available to a new allocation, bytes: `MemAvailable` of
/// `/proc/meminfo`, lowered to the cgroup's limit where one is set (Linux; `None` elsewhere,
/// where nothing is checked).
fn available_memory() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib: u64 = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    let mut available = kib.saturating_mul(1024);
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max").ok();
    if let Some(limit) = cgroup.and_then(|t| t.trim().parse::<u64>().ok()) {
        let used = std::fs::read_to_string("/sys/fs/cgroup/memory.current")
            .ok()
            .and_then(|t| t.trim().parse::<u64>().ok())
            .unwrap_or(0);
        available = available.min(limit.saturating_sub(used));
    }
    Some(available)
}

/// Local corner indices (bit 0 = x, bit 1 = y, bit 2 = z) of the tets of one cell.
fn cell_tets(split: TetSplit, odd: bool) -> Vec<[usize; 4]> {
    match split {
        // Paths 0 -> 7 along the axes in each of the six orders.
        TetSplit::Six => [
            [1, 2, 4],
            [1, 4, 2],
            [2, 1, 4],
            [2, 4, 1],
            [4, 1, 2],
            [4, 2, 1],
        ]
        .iter()
        .map(|&[a, b, _]| [0, a, a | b, 7])
        .collect(),
        TetSplit::Five if !odd => vec![
            [0, 3, 5, 6],
            [1, 0, 3, 5],
            [2, 0, 3, 6],
            [4, 0, 5, 6],
            [7, 3, 5, 6],
        ],
        TetSplit::Five => vec![
            [1, 2, 4, 7],
            [0, 1, 2, 4],
            [3, 1, 2, 7],
            [5, 1, 4, 7],
            [6, 2, 4, 7],
        ],
    }
}

/// A beam along x: `length` long with a `width` (y) by `height` (z) cross-section, with
/// `cells_along` cells along x and `cells_across` across each side of the section.
pub fn beam(
    length: f64,
    width: f64,
    height: f64,
    cells_along: usize,
    cells_across: usize,
) -> Result<TetMesh> {
    BoxGrid {
        cells: [cells_along, cells_across, cells_across],
        size: [length, width, height],
        origin: [0.0; 3],
        split: TetSplit::Six,
    }
    .build()
}

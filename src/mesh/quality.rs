//! Element quality: signed volume, volume-length ratio and dihedral angles.
//!
//! Slivers (flat tets with tiny dihedral angles) raise spring stiffness relative to lumped mass
//! and so lower the stable time step; these measures let a user see them before a run.

use nalgebra::Point3;

use super::{signed_volume6, TetMesh, TET_EDGES, TET_FACES};

/// Quality measures of one tet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetQuality {
    /// Signed volume (positive when correctly oriented).
    pub volume: f64,
    /// `6 sqrt(2) V / l_rms^3`: 1 for a regular tet, 0 for a flat one, negative when inverted.
    pub volume_length_ratio: f64,
    /// Smallest dihedral angle, degrees.
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle, degrees.
    pub max_dihedral_deg: f64,
}

/// `6 sqrt(2) V / l_rms^3` of a tet given its four corners (what [`TetQuality`] reports), alone:
/// cheaper than [`tet_quality`], which also measures the dihedral angles.
pub fn volume_length_ratio(p: &[Point3<f64>; 4]) -> f64 {
    let volume = signed_volume6(&p[0], &p[1], &p[2], &p[3]) / 6.0;
    let l2: f64 = TET_EDGES
        .iter()
        .map(|&[a, b]| (p[a] - p[b]).norm_squared())
        .sum::<f64>()
        / 6.0;
    let l_rms = l2.sqrt();
    if l_rms > 0.0 {
        6.0 * std::f64::consts::SQRT_2 * volume / (l_rms * l_rms * l_rms)
    } else {
        0.0
    }
}

/// Quality of a tet given its four corners.
pub fn tet_quality(p: &[Point3<f64>; 4]) -> TetQuality {
    let volume = signed_volume6(&p[0], &p[1], &p[2], &p[3]) / 6.0;
    let volume_length_ratio = volume_length_ratio(p);
    // Outward face normals; face i is opposite node i.
    let normals = TET_FACES.map(|[a, b, c]| {
        let n = (p[b] - p[a]).cross(&(p[c] - p[a]));
        let len = n.norm();
        if len > 0.0 {
            n / len
        } else {
            n
        }
    });
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for [a, b] in TET_EDGES {
        // The two faces meeting at edge (a, b) are those opposite the other two nodes.
        let mut others = (0..4).filter(|&i| i != a && i != b);
        let (c, d) = (others.next().unwrap_or(0), others.next().unwrap_or(0));
        let cos = (-normals[c].dot(&normals[d])).clamp(-1.0, 1.0);
        let angle = cos.acos().to_degrees();
        lo = lo.min(angle);
        hi = hi.max(angle);
    }
    TetQuality {
        volume,
        volume_length_ratio,
        min_dihedral_deg: lo,
        max_dihedral_deg: hi,
    }
}

/// Extremes of tet quality over a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QualityStats {
    /// Smallest volume-length ratio.
    pub min_volume_length_ratio: f64,
    /// Mean volume-length ratio.
    pub mean_volume_length_ratio: f64,
    /// Smallest dihedral angle over all tets, degrees.
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle over all tets, degrees.
    pub max_dihedral_deg: f64,
    /// Smallest tet volume.
    pub min_volume: f64,
}

impl TetMesh {
    /// Quality of every tet, in tet storage order.
    pub fn tet_qualities(&self) -> Vec<TetQuality> {
        self.tets()
            .map(|(_, t)| tet_quality(&self.tet_points(t)))
            .collect()
    }

    /// The smallest volume-length ratio over the mesh (infinite without tets): what a quality
    /// floor is checked against, without the angles and the per-tet list [`TetMesh::quality`]
    /// builds.
    pub fn min_volume_length_ratio(&self) -> f64 {
        self.tets()
            .map(|(_, t)| volume_length_ratio(&self.tet_points(t)))
            .fold(f64::INFINITY, f64::min)
    }

    /// Quality extremes over the mesh; `None` for a mesh without tets.
    pub fn quality(&self) -> Option<QualityStats> {
        let q = self.tet_qualities();
        if q.is_empty() {
            return None;
        }
        let mut s = QualityStats {
            min_volume_length_ratio: f64::INFINITY,
            mean_volume_length_ratio: 0.0,
            min_dihedral_deg: f64::INFINITY,
            max_dihedral_deg: f64::NEG_INFINITY,
            min_volume: f64::INFINITY,
        };
        for t in &q {
            s.min_volume_length_ratio = s.min_volume_length_ratio.min(t.volume_length_ratio);
            s.mean_volume_length_ratio += t.volume_length_ratio;
            s.min_dihedral_deg = s.min_dihedral_deg.min(t.min_dihedral_deg);
            s.max_dihedral_deg = s.max_dihedral_deg.max(t.max_dihedral_deg);
            s.min_volume = s.min_volume.min(t.volume);
        }
        s.mean_volume_length_ratio /= q.len() as f64;
        Some(s)
    }
}

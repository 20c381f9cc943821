//! `lancet info`: what a mesh file holds.

use super::*;

/// Print what a mesh file holds.
pub(crate) fn info(path: &Path, json: bool) -> lancet::Result<ExitCode> {
    let loaded = lancet::mesh::io::read(path)?;
    let mesh = &loaded.mesh;
    let topo = mesh.topology();
    let quality = mesh.quality();
    let components = mesh.component_count();
    let regions: serde_json::Map<String, serde_json::Value> = mesh
        .regions()
        .into_iter()
        .map(|(r, n)| (r.to_string(), json!(n)))
        .collect();
    let edges = mesh.edges().len();
    // The bounding box says at a glance what unit the file is in (a liver 6.5 units across is
    // in millimetres, or has no unit, rather than metres).
    let bounds = mesh
        .bounds()
        .map(|(lo, hi)| ([lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]));
    if json {
        let v = json!({
            "path": path.display().to_string(),
            "format": loaded.report.format.to_string(),
            "nodes": mesh.node_count(),
            "tets": mesh.tet_count(),
            "edges": edges,
            "boundary_faces": topo.boundary.len(),
            "surface_triangles": loaded.surface.len(),
            "volume": mesh.volume(),
            "bounds": bounds.map(|(lo, hi)| {
                let size = [0, 1, 2].map(|c| hi[c] - lo[c]);
                json!({ "min": lo, "max": hi, "size": size })
            }),
            "inverted": loaded.report.reoriented,
            "dropped_nodes": loaded.report.dropped_nodes,
            "min_quality": quality.map(|q| q.min_volume_length_ratio),
            "mean_quality": quality.map(|q| q.mean_volume_length_ratio),
            "min_dihedral_deg": quality.map(|q| q.min_dihedral_deg),
            "max_dihedral_deg": quality.map(|q| q.max_dihedral_deg),
            "components": components,
            "regions": regions,
            "notes": loaded.report.notes,
        });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(ExitCode::SUCCESS);
    }
    println!("{} ({})", path.display(), loaded.report.format);
    println!(
        "{} nodes, {} tets, {} edges (springs), {} boundary faces",
        mesh.node_count(),
        mesh.tet_count(),
        edges,
        topo.boundary.len()
    );
    println!(
        "volume {:.6e}, {} component(s), {} inverted tet(s) reoriented",
        mesh.volume(),
        components,
        loaded.report.reoriented
    );
    if let Some((lo, hi)) = bounds {
        println!(
            "bounds: min ({:.6e}, {:.6e}, {:.6e}), max ({:.6e}, {:.6e}, {:.6e}), size ({:.6e}, \
             {:.6e}, {:.6e})",
            lo[0],
            lo[1],
            lo[2],
            hi[0],
            hi[1],
            hi[2],
            hi[0] - lo[0],
            hi[1] - lo[1],
            hi[2] - lo[2]
        );
    }
    if let Some(q) = quality {
        println!(
            "quality: volume-length ratio min {:.4} mean {:.4}; dihedral angles {:.2}..{:.2} deg",
            q.min_volume_length_ratio,
            q.mean_volume_length_ratio,
            q.min_dihedral_deg,
            q.max_dihedral_deg
        );
    }
    let regions: Vec<String> = mesh
        .regions()
        .iter()
        .map(|(r, n)| format!("{r}: {n} tets"))
        .collect();
    println!("regions: {}", regions.join(", "));
    for note in &loaded.report.notes {
        println!("note: {note}");
    }
    Ok(ExitCode::SUCCESS)
}

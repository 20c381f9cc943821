//! The self-contact broad phase on the device: on deformed surfaces (generated and real) the
//! GPU pair list equals its CPU twin, contains every pair the brute-force float64 test finds,
//! never pairs triangles that share a node and lists each pair once; a surface stretched past
//! the grid's cells and a pair buffer that is too small are handled by running again; the
//! culler follows surface edits (cuts) without being built again.

use crate::{common, models};
use lancet::collide::broad::Surface;
use lancet::collide::self_broad::self_pairs_exact;
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, SimConfig};
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::TetMesh;
use lancet::model::{Material, ModelConfig, PackedModel, SpringModel};
use lancet::twin::broad_self::self_pairs_cpu;
use models::Rng;

fn model_of(mesh: &TetMesh) -> PackedModel {
    SpringModel::build(mesh, &ModelConfig::new(Material::elastic(5e3, 0.3, 1000.0)))
        .unwrap()
        .pack(mesh)
        .unwrap()
}

/// Set a random displacement of up to `amplitude` (m) plus a fold: the upper half pressed down
/// by `fold` (m), so that surface triangles meet.
fn deform(engine: &mut GpuEngine, model: &PackedModel, seed: u64, amplitude: f64, fold: f64) {
    let mut rng = Rng(seed);
    let zmid = model.rest.iter().map(|p| p[2]).sum::<f64>() / model.rest.len() as f64;
    let x: Vec<[f64; 3]> = model
        .rest
        .iter()
        .map(|r| {
            let mut p = r.map(|c| c + (rng.next() - 0.5) * amplitude);
            if r[2] > zmid {
                p[2] -= fold;
            }
            p
        })
        .collect();
    engine.set_state(&x, &vec![[0.0; 3]; x.len()]);
}

/// Cull at `margin` and check against the twin and the exact answer; returns the pair count.
fn check(engine: &mut GpuEngine, surface: &Surface, margin: f64) -> (usize, u32) {
    let r = engine.cull_self(margin).unwrap();
    let (disp, _) = engine.raw_state().unwrap();
    let twin = self_pairs_cpu(
        &r.grid,
        &engine.rest_f32(),
        &disp,
        &engine.surface_layout_order().unwrap(),
    )
    .expect("the grid the device settled on fits the surface");
    assert_eq!(r.pairs, twin, "device and twin differ");
    assert!(
        r.pairs.windows(2).all(|w| w[0] < w[1]),
        "a pair listed twice"
    );
    for &[t, u] in &r.pairs {
        let (a, b) = (surface.triangles[t as usize], surface.triangles[u as usize]);
        assert!(
            t < u && !a.iter().any(|n| b.contains(n)),
            "pair {t}-{u} shares a node"
        );
    }
    let exact = self_pairs_exact(&engine.positions(), &surface.triangles, margin);
    for p in &exact {
        assert!(r.pairs.binary_search(p).is_ok(), "missed {p:?}");
    }
    (r.pairs.len(), r.reruns)
}

#[test]
fn folded_box_pairs_equal_the_twin_and_contain_every_exact_pair() {
    let Some(ctx) = common::gpu() else { return };
    let mesh = BoxGrid::cube_cells([8, 8, 6], 0.004).build().unwrap();
    let (model, surface) = (model_of(&mesh), Surface::of(&mesh));
    let mut engine =
        GpuEngine::with_context(ctx, &model, SimConfig::new(1e-5), LayoutKind::Valence).unwrap();
    engine.set_surface(&surface.triangles).unwrap();
    let mut total = 0;
    for seed in 0..6 {
        deform(&mut engine, &model, seed, 2e-3, 4e-3 * seed as f64);
        let (n, _) = check(&mut engine, &surface, 1e-3);
        total += n;
        let all = surface.triangles.len() * (surface.triangles.len() - 1) / 2;
        assert!(n < all / 20, "culled too little: {n} of {all}");
    }
    assert!(total > 0, "no deformation brought triangles together");
}

#[test]
fn real_mesh_pairs_equal_the_twin_and_contain_every_exact_pair() {
    let Some(dir) = std::env::var_os("LANCET_MESH_DIR") else {
        eprintln!("skipped: LANCET_MESH_DIR is not set");
        return;
    };
    let Some(ctx) = common::gpu() else { return };
    let mut mesh = lancet::mesh::io::read(std::path::Path::new(&dir).join("sofa/liver2.msh"))
        .unwrap()
        .mesh;
    // Into metres: about 6 cm across.
    let (lo, hi) = mesh.bounds().unwrap();
    let factor = 0.06 / (hi - lo).norm();
    let keys: Vec<_> = mesh.nodes().map(|(k, _)| k).collect();
    for k in keys {
        let p = mesh.rest(k);
        mesh.set_rest(k, p * factor).unwrap();
    }
    let (model, surface) = (model_of(&mesh), Surface::of(&mesh));
    let mut engine =
        GpuEngine::with_context(ctx, &model, SimConfig::new(1e-5), LayoutKind::Connectivity)
            .unwrap();
    engine.set_surface(&surface.triangles).unwrap();
    for seed in 0..4 {
        deform(&mut engine, &model, 10 + seed, 3e-3, 5e-3 * seed as f64);
        check(&mut engine, &surface, 5e-4);
    }
}

#[test]
fn a_stretched_surface_and_a_full_pair_buffer_run_again_and_lose_nothing() {
    let Some(ctx) = common::gpu() else { return };
    let mesh = BoxGrid::cube_cells([10, 10, 4], 0.004).build().unwrap();
    let (model, surface) = (model_of(&mesh), Surface::of(&mesh));
    let mut engine =
        GpuEngine::with_context(ctx, &model, SimConfig::new(1e-5), LayoutKind::Edges).unwrap();
    engine.set_surface(&surface.triangles).unwrap();
    // Stretch to three times the size: boxes outgrow the cells made for the rest shape.
    let x: Vec<[f64; 3]> = model.rest.iter().map(|r| r.map(|c| 3.0 * c)).collect();
    engine.set_state(&x, &vec![[0.0; 3]; x.len()]);
    let (_, reruns) = check(&mut engine, &surface, 1e-3);
    assert!(
        reruns >= 1,
        "the stretched surface should have grown the cell"
    );
    // A margin as large as the body: more pairs than the initial buffer holds.
    engine.set_state(&model.rest, &vec![[0.0; 3]; x.len()]);
    let (n, reruns) = check(&mut engine, &surface, 0.05);
    assert!(n > 1024 && reruns >= 1, "{n} pairs after {reruns} reruns");
}

/// The self-contact culler survives surface edits, as cuts make them: after slots are
/// replaced, the list grows past the culler's hash table (tet faces inside the box are
/// appended, as carving exposes them) and then shrinks, the device pairs still equal the twin's
/// on the edited surface and contain every exact pair, and the culler was built once (it used
/// to be dropped at every edit and built again, pipelines and all, at the next cull).
#[test]
fn the_self_culler_follows_surface_edits_without_being_built_again() {
    let Some(ctx) = common::gpu() else { return };
    let mesh = BoxGrid::cube_cells([8, 8, 6], 0.004).build().unwrap();
    let (model, surface) = (model_of(&mesh), Surface::of(&mesh));
    let mut engine =
        GpuEngine::with_context(ctx, &model, SimConfig::new(1e-5), LayoutKind::Valence).unwrap();
    engine.set_surface(&surface.triangles).unwrap();
    deform(&mut engine, &model, 3, 2e-3, 8e-3);
    let margin = 1e-3;
    check(&mut engine, &surface, margin);
    assert_eq!(engine.self_culler_builds(), 1);
    let table = engine.cull_self(margin).unwrap().grid.table as usize;
    // Faces of the tets in the box's lower half, none of them on the boundary: more than
    // the table has buckets for, with the surface.
    let dense = mesh.dense_nodes();
    let on_surface: std::collections::HashSet<[u32; 3]> = surface
        .triangles
        .iter()
        .map(|t| {
            let mut t = *t;
            t.sort_unstable();
            t
        })
        .collect();
    let mut inner: Vec<[u32; 3]> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for (_, tet) in mesh.tets() {
        let n = tet.nodes.map(|k| dense.index[k]);
        for skip in 0..4 {
            let mut f: Vec<u32> = (0..4).filter(|&i| i != skip).map(|i| n[i]).collect();
            f.sort_unstable();
            let f = [f[0], f[1], f[2]];
            if !on_surface.contains(&f) && seen.insert(f) {
                inner.push(f);
            }
        }
    }
    let grow = table - surface.triangles.len() / 2 + 64;
    assert!(inner.len() > grow, "{} inner faces", inner.len());
    let mut edited = Surface {
        triangles: surface.triangles.clone(),
    };
    // Three slots replaced by inner faces, then enough appended to outgrow the table.
    let replaced = [0u32, 17, 101];
    for (k, &slot) in replaced.iter().enumerate() {
        edited.triangles[slot as usize] = inner[k];
    }
    edited.triangles.extend_from_slice(&inner[3..3 + grow]);
    engine.edit_surface(&edited.triangles, &replaced).unwrap();
    assert!(2 * edited.triangles.len() > table);
    for seed in [4, 5] {
        deform(&mut engine, &model, seed, 2e-3, 8e-3);
        check(&mut engine, &edited, margin);
    }
    let grown = engine.cull_self(margin).unwrap().grid;
    assert!(
        grown.table as usize >= 2 * edited.triangles.len(),
        "{grown:?}"
    );
    // Shrunk back below the first list: slots past the end leave the surface.
    edited.triangles.truncate(surface.triangles.len() - 40);
    engine.edit_surface(&edited.triangles, &[]).unwrap();
    check(&mut engine, &edited, margin);
    // A new margin: a new grid for the same passes.
    check(&mut engine, &edited, 2e-3);
    assert_eq!(engine.self_culler_builds(), 1, "the culler was built again");
}

//! The `.glb` frames a run writes beside its VTU frames: a valid glTF 2.0 container (header and
//! chunk lengths, a document gltf-json parses and validates), a node for the tissue and one per
//! tool, the tissue's vertices where the VTU (no render surface) or VTP (render surface) frame
//! of the same step puts them, and the blade where its trajectory puts it.

use std::path::{Path, PathBuf};

use gltf_json::validation::Validate;
use lancet::cut::CutMethod;
use lancet::scene::{run_scene, RunOptions, Scene};
use lancet::surface::glb::{glb_bytes, read_glb, GlbMesh};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/scenes")
        .join(name)
}

/// A node's mesh's POSITION data and its accessor's min and max.
struct Positions {
    points: Vec<[f32; 3]>,
    min: [f32; 3],
    max: [f32; 3],
}

/// Read the `.glb` at `path`, check it is valid glTF, and return its nodes' names with their
/// positions.
fn read_frame(path: &Path) -> Vec<(String, Positions)> {
    let bytes = std::fs::read(path).unwrap();
    let (root, bin) = read_glb(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut errors = Vec::new();
    root.validate(&root, gltf_json::Path::new, &mut |p, e| {
        errors.push(format!("{}: {e}", p()))
    });
    assert!(errors.is_empty(), "{}: {errors:?}", path.display());
    assert_eq!(root.buffers.len(), 1);
    assert!(root.buffers[0].byte_length.0 as usize <= bin.len());
    let scene = &root.scenes[root.scene.unwrap().value()];
    scene
        .nodes
        .iter()
        .map(|&n| {
            let node = &root.nodes[n.value()];
            let mesh = &root.meshes[node.mesh.unwrap().value()];
            let prim = &mesh.primitives[0];
            let (_, &acc) = prim
                .attributes
                .iter()
                .find(|(k, _)| {
                    matches!(
                        k,
                        gltf_json::validation::Checked::Valid(gltf_json::mesh::Semantic::Positions)
                    )
                })
                .unwrap();
            let acc = &root.accessors[acc.value()];
            let view = &root.buffer_views[acc.buffer_view.unwrap().value()];
            let start = view.byte_offset.map_or(0, |o| o.0 as usize);
            let count = acc.count.0 as usize;
            assert_eq!(view.byte_length.0 as usize, 12 * count);
            let points: Vec<[f32; 3]> =
                bytemuck::pod_collect_to_vec(&bin[start..start + 12 * count]);
            let three = |v: &Option<gltf_json::Value>| -> [f32; 3] {
                let a = v.as_ref().unwrap().as_array().unwrap();
                [0, 1, 2].map(|i| a[i].as_f64().unwrap() as f32)
            };
            // Every index names a vertex.
            let idx = &root.accessors[prim.indices.unwrap().value()];
            let iview = &root.buffer_views[idx.buffer_view.unwrap().value()];
            let istart = iview.byte_offset.map_or(0, |o| o.0 as usize);
            let indices: Vec<u32> =
                bytemuck::pod_collect_to_vec(&bin[istart..istart + 4 * idx.count.0 as usize]);
            assert!(indices.iter().all(|&i| (i as usize) < count));
            assert_eq!(indices.len() % 3, 0);
            (
                node.name.clone().unwrap(),
                Positions {
                    min: three(&acc.min),
                    max: three(&acc.max),
                    points,
                },
            )
        })
        .collect()
}

/// The `timestep` of each `<DataSet>` in a `.pvd`.
fn pvd_times(path: &Path) -> Vec<f64> {
    std::fs::read_to_string(path)
        .unwrap()
        .split("timestep=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap().parse().unwrap())
        .collect()
}

fn sorted(mut v: Vec<[f32; 3]>) -> Vec<[f32; 3]> {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v
}

/// A box cut through by a blade (separate: the cut opens faces, duplicating nodes): at every
/// frame the tissue node holds exactly the boundary vertices of the VTU frame's mesh (the
/// faces the cut opened included) at the VTU's positions, and the scalpel node is the blade's
/// box where the keyframes put it at the frame's time.
#[test]
fn glb_frames_hold_the_cut_boundary_and_the_blade() {
    let out = tempfile::tempdir().unwrap();
    let path = fixture("cut_box_through.ron");
    let scene = Scene::read(&path).unwrap();
    let opts = RunOptions {
        output_dir: Some(out.path().to_path_buf()),
        steps: Some(200),
        frame_every: Some(50),
        cut_method: Some(CutMethod::Separate),
        ..Default::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    let files = summary.frame_files.clone().expect("the run writes output");
    assert_eq!(summary.frames_written, 5);
    assert_eq!(files.glb_frames, summary.frames_written);
    let stem = lancet::scene::runner::series_stem(&scene, Some(CutMethod::Separate));
    let times = pvd_times(&out.path().join(format!("{stem}.pvd")));
    assert_eq!(times, pvd_times(&files.tools_pvd.unwrap()));
    let mut boundary_sizes = Vec::new();
    for (k, &t) in times.iter().enumerate() {
        let nodes = read_frame(&out.path().join(format!("{stem}_{k:06}.glb")));
        let names: Vec<&str> = nodes.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["tissue", "scalpel"]);
        // The VTU frame's boundary, from its own mesh.
        let vtu = lancet::mesh::io::read(out.path().join(format!("{stem}_{k:06}.vtu")))
            .unwrap()
            .mesh;
        let dense = vtu.dense_nodes();
        let boundary = lancet::collide::broad::Surface::of(&vtu).triangles;
        let mut used: Vec<u32> = boundary.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        let expected: Vec<[f32; 3]> = used
            .iter()
            .map(|&n| {
                let p = vtu.node(dense.keys[n as usize]).unwrap().rest;
                [p.x as f32, p.y as f32, p.z as f32]
            })
            .collect();
        let tissue = &nodes[0].1;
        assert_eq!(sorted(tissue.points.clone()), sorted(expected), "frame {k}");
        boundary_sizes.push(tissue.points.len());
        // The blade: 10 cm wide along x, 0.2 mm thick along y, 10 cm long up z, its edge
        // going from z = 5 cm down at 2 m/s until 0.03 s.
        let blade = &nodes[1].1;
        let extent = [0, 1, 2].map(|c| (blade.max[c] - blade.min[c]) as f64);
        for (got, want) in extent.iter().zip([0.1, 2e-4, 0.1]) {
            assert!((got - want).abs() < 1e-6, "frame {k}: extent {extent:?}");
        }
        let edge = 0.05 - 2.0 * t.min(0.03);
        assert!(
            (blade.min[2] as f64 - edge).abs() < 1e-6,
            "frame {k} at {t} s: edge at {} not {edge}",
            blade.min[2]
        );
    }
    // The cut opened faces: the last frame's boundary has more vertices than the first's.
    assert!(boundary_sizes[4] > boundary_sizes[0], "{boundary_sizes:?}");
}

/// A scene with a render surface: the tissue node is that surface (42 vertices), at the
/// positions of the VTP frame of the same step.
#[test]
fn glb_frames_hold_the_render_surface_as_the_vtp_frames_do() {
    let out = tempfile::tempdir().unwrap();
    let path = fixture("surface_sphere.ron");
    let scene = Scene::read(&path).unwrap();
    let opts = RunOptions {
        output_dir: Some(out.path().to_path_buf()),
        steps: Some(100),
        ..Default::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();
    let stem = lancet::scene::runner::series_stem(&scene, None);
    let frames = summary.frame_files.unwrap().glb_frames;
    assert_eq!(frames, summary.surface.unwrap().frames_written);
    for k in 0..frames {
        let nodes = read_frame(&out.path().join(format!("{stem}_{k:06}.glb")));
        assert_eq!(nodes.len(), 1, "no tools");
        let (name, tissue) = &nodes[0];
        assert_eq!(name, "tissue");
        assert_eq!(tissue.points.len(), 42);
        let vtp =
            std::fs::read_to_string(out.path().join(format!("{stem}_surface_{k:06}.vtp"))).unwrap();
        let body = &vtp[vtp.find("Name=\"positions\"").unwrap()..];
        let body = &body[body.find('>').unwrap() + 1..body.find("</DataArray>").unwrap()];
        let v: Vec<f64> = body
            .split_whitespace()
            .map(|w| w.parse().unwrap())
            .collect();
        let expected: Vec<[f32; 3]> = v
            .chunks_exact(3)
            .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
            .collect();
        assert_eq!(tissue.points, expected, "frame {k}");
    }
}

/// Bad meshes are refused with the mesh and the element named, before anything is written.
#[test]
fn a_bad_mesh_is_refused_with_its_name() {
    let positions = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mesh = |triangles: &'static [[u32; 3]], colours| GlbMesh {
        name: "organ",
        positions: &positions,
        triangles,
        colours,
        base_colour: [1.0; 4],
    };
    let e = glb_bytes(&[mesh(&[[0, 1, 3]], None)])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("organ") && e.contains("triangle 0 uses vertex [0, 1, 3]"),
        "{e}"
    );
    let e = glb_bytes(&[mesh(&[[0, 1, 2]], Some(&[[0.0; 3]]))])
        .unwrap_err()
        .to_string();
    assert!(e.contains("1 colours for 3 vertices"), "{e}");
    // A good one reads back with its header length equal to its size.
    let bytes = glb_bytes(&[mesh(&[[0, 1, 2]], None)]).unwrap();
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
        bytes.len()
    );
    assert_eq!(bytes.len() % 4, 0);
    read_glb(&bytes).unwrap();
}

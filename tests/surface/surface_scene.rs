//! A scene's render surface: read from its file, placed by `mesh_transform` like the mesh,
//! and written per frame as VTK PolyData beside the mesh's frames, the first frame at rest and
//! every frame at the positions the embedding gives from that frame's nodes.

use std::path::{Path, PathBuf};

use lancet::scene::{run_scene, RunOptions, Scene};
use lancet::surface::read::read_surface;

fn scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/surface_sphere.ron")
}

/// The numbers of the `<DataArray>` named `name` in a `.vtp` file, in threes.
fn data_array(text: &str, name: &str) -> Vec<[f64; 3]> {
    let start = text.find(&format!("Name=\"{name}\"")).expect(name);
    let body = &text[start..];
    let body = &body[body.find('>').unwrap() + 1..body.find("</DataArray>").unwrap()];
    let v: Vec<f64> = body
        .split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect();
    v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

fn run(text: &str, out: &Path) -> lancet::scene::RunSummary {
    let scene = Scene::from_ron(text, &scene_path()).unwrap();
    let opts = RunOptions {
        output_dir: Some(out.to_path_buf()),
        ..Default::default()
    };
    run_scene(&scene, &scene_path(), &opts, |_, _| {}).unwrap()
}

#[test]
fn the_surface_is_written_per_frame_and_sags_with_the_beam() {
    let out = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scene_path()).unwrap();
    let summary = run(&text, out.path());
    assert!(summary.expectations_passed, "{:?}", summary.expectations);
    let s = summary.surface.expect("the scene has a surface");
    assert_eq!((s.vertices, s.triangles, s.outside), (42, 80, 0));
    assert_eq!(
        s.frames_written, summary.frames_written,
        "one surface frame per mesh frame"
    );
    let pvd = std::fs::read_to_string(s.pvd.unwrap()).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), s.frames_written);
    let rest =
        read_surface(Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/surfaces/sphere.obj"))
            .unwrap();
    let frame = |k: usize| {
        let stem = lancet::scene::runner::series_stem(
            &Scene::from_ron(&text, &scene_path()).unwrap(),
            None,
        );
        let path = out.path().join(format!("{stem}_surface_{k:06}.vtp"));
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    };
    let first = data_array(&frame(0), "positions");
    for (v, (f, r)) in first.iter().zip(&rest.positions).enumerate() {
        for c in 0..3 {
            // The weighted sum of the nodes' rest positions: the vertex, to rounding.
            assert!(
                (f[c] - r[c]).abs() < 1e-17,
                "vertex {v}: first frame {f:?}, rest {r:?}"
            );
        }
    }
    let last_text = frame(s.frames_written - 1);
    let last = data_array(&last_text, "positions");
    let u = data_array(&last_text, "displacement");
    for v in 0..42 {
        for c in 0..3 {
            assert_eq!(u[v][c], last[v][c] - rest.positions[v][c], "vertex {v}");
        }
        // Mid-beam under gravity: down, by less than the tip's few millimetres.
        assert!(
            u[v][2] < -1e-4 && u[v][2] > -5e-3,
            "vertex {v} moved {:?}",
            u[v]
        );
    }
}

#[test]
fn the_surface_is_placed_by_the_mesh_transform() {
    let out = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scene_path()).unwrap().replace(
        "    surface:",
        "    mesh_transform: (translation: (0.1, -0.3, 0.02), rotation: (0.0, 0.0, 90.0)),\n    surface:",
    );
    // The clamp and the expectation are where the beam was: dropped for this placement.
    let text = text
        .replace("steps: 400", "steps: 2")
        .lines()
        .filter(|l| !l.contains("Plane(") && !l.contains("DisplacementAt"))
        .collect::<Vec<_>>()
        .join("\n");
    let summary = run(&text, out.path());
    // Placed with the beam, the sphere is still inside it; left where the file has it, every
    // vertex would be centimetres outside.
    assert_eq!(summary.surface.unwrap().outside, 0);
}

/// The box of `surface_cut_box.ron` cut right through by `method`, its render surface (on the
/// box's boundary) following the cuts.
fn cut_box(method: lancet::cut::CutMethod) -> lancet::scene::RunSummary {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/surface_cut_box.ron");
    let scene = Scene::read(&path).unwrap();
    let opts = RunOptions {
        cut_method: Some(method),
        no_output: true,
        ..Default::default()
    };
    run_scene(&scene, &path, &opts, |_, _| {}).unwrap()
}

/// A surface on the simulation box's boundary stays near the boundary of the pieces through a
/// cut that separates them, while the free piece falls centimetres away from the one that
/// hangs (the scene's expectations): the vertices of the falling piece went with it. The
/// surface is split at the blade's sweep (y = 0.017) and separating opens the tet faces whose
/// centroids the sweep parts, up to a cell (1 cm) from it: a vertex between the two goes with
/// its side of the sweep, off the boundary of its piece by less than a cell, and every vertex
/// away from the opening stays on it (the mean gap a small fraction of that).
#[test]
fn the_surface_stays_on_the_boundary_of_the_pieces() {
    let method = lancet::cut::CutMethod::Separate;
    let summary = cut_box(method);
    assert!(summary.expectations_passed, "{:#?}", summary.expectations);
    let cuts = summary.cuts.as_ref().unwrap();
    let s = summary.surface.unwrap();
    assert_eq!(s.gap_rest.vertices, s.vertices);
    assert!(s.gap_rest.max < 1e-15, "{method}: {:?}", s.gap_rest);
    let cell = 0.01;
    assert!(
        s.gap_end.max < cell && s.gap_end.mean < cell / 20.0,
        "{method}: {:?}",
        s.gap_end
    );
    assert_eq!(s.rebinds, cuts.cuts, "{method}: one rebinding per cut");
    assert!(s.vertices_rebound > 100, "{method}: {}", s.vertices_rebound);
    assert_eq!(s.dropped, 0);
}

/// Carving takes a layer out: its surface vertices go to the nearest face left on their side
/// of the blade, within the layer's thickness (1 cm) of the boundary, and none is dropped (each
/// side keeps material).
#[test]
fn carved_surface_vertices_stay_within_the_layer_of_their_side() {
    let summary = cut_box(lancet::cut::CutMethod::Remove);
    assert!(summary.expectations_passed, "{:#?}", summary.expectations);
    let s = summary.surface.unwrap();
    assert!(s.gap_end.max < 0.01, "{:?}", s.gap_end);
    assert_eq!(s.dropped, 0);
    assert!(s.vertices_rebound > 100);
}

//! Nothing a run was asked to write is lost or silently replaced: each cut method of a scene
//! writes its own series, names differing only in punctuation write different files, and a
//! rerun leaves no frame its series does not list.

use std::path::Path;

use lancet::mesh::generate::BoxGrid;
use lancet::mesh::io::pvd::PvdWriter;
use lancet::scene::runner::series_stem;
use lancet::scene::{run_scene, RunOptions, Scene};

fn scene(name: &str, cut: &str) -> Scene {
    let text = format!(
        r#"Scene(
    name: "{name}",
    mesh: Box((cells: (1, 1, 1), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    dt: BoundFraction(0.5),
    steps: 4,
    output: Some((dir: "out", every: 2)),
    cut: {cut},
)"#
    );
    Scene::from_ron(&text, Path::new("x.ron")).unwrap()
}

fn vtu_files(dir: &Path, prefix: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.starts_with(prefix) && n.ends_with(".vtu"))
        .collect();
    v.sort();
    v
}

/// A scene run with each of its cut methods once wrote every method's frames over the same
/// series; each method now has its own, and both are on disk after both runs.
#[test]
fn each_cut_method_writes_its_own_series() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("incision", "Some((methods: [Separate, Remove]))");
    let mut pvds = Vec::new();
    for method in [
        lancet::cut::CutMethod::Separate,
        lancet::cut::CutMethod::Remove,
    ] {
        let opts = RunOptions {
            output_dir: Some(dir.path().to_path_buf()),
            cut_method: Some(method),
            ..Default::default()
        };
        let summary = run_scene(&s, Path::new("x.ron"), &opts, |_, _| {}).unwrap();
        pvds.push(summary.pvd.unwrap());
    }
    assert_ne!(pvds[0], pvds[1]);
    for p in &pvds {
        assert!(p.exists(), "{}", p.display());
    }
    // The scene's first method is the default, and names the series the same way.
    assert_eq!(
        dir.path().join(format!("{}.pvd", series_stem(&s, None))),
        pvds[0]
    );
}

/// Names differing only in punctuation gave the same file name; a plain name keeps its
/// readable form.
#[test]
fn names_differing_only_in_punctuation_give_different_series() {
    let stems: Vec<String> = ["a.b", "a:b", "a/b", "a_b", "a?b"]
        .iter()
        .map(|n| series_stem(&scene(n, "None"), None))
        .collect();
    for (i, a) in stems.iter().enumerate() {
        assert!(!a.contains(['/', '.', ':', '?']), "{a}");
        for b in &stems[i + 1..] {
            assert_ne!(a, b);
        }
    }
    assert_eq!(
        series_stem(&scene("hanging beam-2", "None"), None),
        "hanging_beam-2"
    );
}

/// A rerun with fewer frames once left the earlier run's later frames beside a series that did
/// not list them; they are removed, and another series in the folder is left alone.
#[test]
fn a_rerun_with_fewer_frames_leaves_no_stale_frames() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = BoxGrid::cube_cells([1; 3], 0.01).build().unwrap();
    let mut first = PvdWriter::new(dir.path(), "run", Default::default()).unwrap();
    let mut other = PvdWriter::new(dir.path(), "run_other", Default::default()).unwrap();
    for t in 0..4 {
        first.frame(t as f64, &mesh, None).unwrap();
        other.frame(t as f64, &mesh, None).unwrap();
    }
    assert_eq!(vtu_files(dir.path(), "run_0").len(), 4);
    let mut rerun = PvdWriter::new(dir.path(), "run", Default::default()).unwrap();
    rerun.frame(0.0, &mesh, None).unwrap();
    assert_eq!(vtu_files(dir.path(), "run_0"), ["run_000000.vtu"]);
    assert_eq!(vtu_files(dir.path(), "run_other_").len(), 4);
}

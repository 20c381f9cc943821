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

/// Names differing only in punctuation gave the same file name (`a b` and `a_b` both wrote
/// `a_b.pvd`); a plain name keeps its readable form.
#[test]
fn names_differing_only_in_punctuation_give_different_series() {
    let stems: Vec<String> = ["a.b", "a:b", "a/b", "a_b", "a?b", "a b", "a  b", "a__b"]
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

/// A scene's name and cut method once read like another scene's name: `a` cut by `Remove`
/// and a scene named `a remove` both wrote `a_remove.pvd`.
#[test]
fn a_name_and_method_never_read_as_another_name() {
    let cut = series_stem(
        &scene("a", "Some((methods: [Remove]))"),
        Some(lancet::cut::CutMethod::Remove),
    );
    for other in ["a remove", "a_remove", "a.remove", "a-remove"] {
        assert_ne!(series_stem(&scene(other, "None"), None), cut, "{other}");
    }
}

/// A folder run of two scenes that would write the same series (a scene file copied and its
/// name left as it was) ran both, the second replacing the first's frames without a word. It
/// is refused before anything runs, naming both files; two names differing only in
/// punctuation run side by side, each into its own series.
#[test]
fn a_folder_run_refuses_two_scenes_writing_one_series() {
    let dir = tempfile::tempdir().unwrap();
    let write = |file: &str, name: &str| {
        let text = format!(
            r#"Scene(
    name: "{name}",
    mesh: Box((cells: (1, 1, 1), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    dt: BoundFraction(0.5),
    steps: 4,
    output: Some((dir: "out", every: 2)),
)"#
        );
        std::fs::write(dir.path().join(file), text).unwrap();
    };
    let run = || {
        std::process::Command::new(env!("CARGO_BIN_EXE_lancet"))
            .args(["run", dir.path().to_str().unwrap()])
            .output()
            .unwrap()
    };
    write("first.ron", "beam");
    write("second.ron", "beam");
    let out = run();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("first.ron") && err.contains("second.ron") && err.contains("beam.pvd"),
        "{err}"
    );
    assert!(!dir.path().join("out").exists(), "nothing runs: {err}");

    // Names differing in letter case are one file on macOS and Windows: refused too.
    write("second.ron", "Beam");
    let out = run();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("letter case"), "{err}");

    write("first.ron", "a b");
    write("second.ron", "a_b");
    let out = run();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut pvds: Vec<String> = std::fs::read_dir(dir.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".pvd"))
        .collect();
    pvds.sort();
    assert_eq!(pvds.len(), 2, "{pvds:?}");
    for p in &pvds {
        let text = std::fs::read_to_string(dir.path().join("out").join(p)).unwrap();
        assert_eq!(text.matches("<DataSet").count(), 3, "{p}: {text}");
    }
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

/// A killed writer leaves its hidden temporary files (`.<file>.<pid>.tmp`, the pid differing
/// from run to run), which accumulated; a new series of the same name removes those of its
/// frames and collection, and leaves other series' and other files alone.
#[test]
fn a_new_series_removes_the_temporary_files_a_killed_run_left() {
    let dir = tempfile::tempdir().unwrap();
    let left = [".run_000003.vtu.4242.tmp", ".run.pvd.4242.tmp"];
    let kept = [
        ".run_other_000000.vtu.4242.tmp",
        ".run_other.pvd.7.tmp",
        ".run.pvd.tmp",
        "run_notes.txt",
    ];
    for f in left.iter().chain(&kept) {
        std::fs::write(dir.path().join(f), b"partial").unwrap();
    }
    PvdWriter::new(dir.path(), "run", Default::default()).unwrap();
    for f in left {
        assert!(!dir.path().join(f).exists(), "{f} left behind");
    }
    for f in kept {
        assert!(dir.path().join(f).exists(), "{f} removed");
    }
}

/// Frames are no longer synced to disk one by one, but the collection still lists, after each
/// frame, exactly the frames written, each whole: a run killed between frames (here: a writer
/// never finished nor dropped) leaves a series that reads back.
#[test]
fn a_series_never_finished_reads_back_whole() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = BoxGrid::cube_cells([2; 3], 0.01).build().unwrap();
    let mut w = PvdWriter::new(dir.path(), "killed", Default::default()).unwrap();
    for t in 0..3 {
        w.frame(t as f64, &mesh, None).unwrap();
    }
    std::mem::forget(w);
    let pvd = std::fs::read_to_string(dir.path().join("killed.pvd")).unwrap();
    let files: Vec<&str> = pvd
        .split("file=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap())
        .collect();
    assert_eq!(files.len(), 3, "{pvd}");
    for f in files {
        let back = lancet::mesh::io::read(dir.path().join(f)).unwrap();
        assert_eq!(back.mesh.tet_count(), mesh.tet_count());
    }
    let hidden: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(hidden.is_empty(), "{hidden:?}");
}

//! Scene mistakes are refused when the scene is read (or, for what needs the mesh, when the
//! model is built), with the file, the place and what to give instead: unknown fields, fixed
//! selectors that select nothing, expectations that cannot be checked, boxes too large for
//! memory.

use std::path::Path;

use lancet::error::Location;
use lancet::mesh::generate::{BoxGrid, TetSplit, RUN_BYTES_PER_TET};
use lancet::scene::{run_scene, RunOptions, Scene};

/// A small box scene with `extra` fields appended inside `Scene(...)`.
fn scene_with(extra: &str) -> String {
    format!(
        r#"Scene(
    name: "x",
    mesh: Box((cells: (2, 2, 2), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    dt: BoundFraction(0.5),
    steps: 10,
    {extra}
)"#
    )
}

fn refusal(text: &str) -> lancet::Error {
    Scene::from_ron(text, Path::new("dir/x.ron")).expect_err("the scene is refused")
}

/// The 1-based line of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

// Item 3: unknown fields.

/// A misspelled `mass_damping` once ran undamped with no word: it is refused with the file,
/// the line it is on and the field meant.
#[test]
fn a_misspelled_top_level_field_is_refused_with_its_line_and_the_nearest_name() {
    let text = scene_with("gravity: (0.0, 0.0, -9.81),\n    mass_dampng: 60.0,");
    let err = refusal(&text);
    let msg = err.to_string();
    assert!(msg.contains("dir/x.ron"), "{msg}");
    assert!(msg.contains("`mass_dampng`"), "{msg}");
    assert!(msg.contains("did you mean `mass_damping`?"), "{msg}");
    let p = err.as_parse().expect("a parse error with a place");
    assert_eq!(
        p.location,
        Location::Line(line_of(&text, "mass_dampng")),
        "{msg}"
    );
}

/// Fields of nested structs and of enum variants are checked too.
#[test]
fn misspelled_nested_fields_are_refused_with_the_nearest_name() {
    let material = scene_with("").replace("youngs_modulus", "youngs_modulos");
    let msg = refusal(&material).to_string();
    assert!(msg.contains("did you mean `youngs_modulus`?"), "{msg}");

    let output = scene_with(r#"output: Some((dir: "out", evry: 10)),"#);
    let msg = refusal(&output).to_string();
    assert!(msg.contains("did you mean `every`?"), "{msg}");

    let fixed = scene_with(
        "fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerence: 1e-9)],",
    );
    let msg = refusal(&fixed).to_string();
    assert!(msg.contains("did you mean `tolerance`?"), "{msg}");
}

/// A name far from every valid one gets the list instead of a guess.
#[test]
fn an_unknown_field_like_no_valid_one_lists_the_valid_names() {
    let msg = refusal(&scene_with("wobble: 3.0,")).to_string();
    assert!(msg.contains("unknown field `wobble`"), "{msg}");
    assert!(!msg.contains("did you mean"), "{msg}");
    assert!(msg.contains("`mass_damping`"), "{msg}");
}

/// Every fixture scene still reads: none relied on a field being ignored.
#[test]
fn every_fixture_scene_reads() {
    let dir = Path::new(crate::REPO).join("fixtures/scenes");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "ron") {
            Scene::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            n += 1;
        }
    }
    assert!(n > 10, "{n} fixtures");
}

// Item 4: fixed-node selectors.

/// Selectors whose numbers select nothing whatever the mesh are refused when the scene is read.
#[test]
fn selectors_that_cannot_select_are_refused_when_the_scene_is_read() {
    let cases = [
        (
            "Plane(point: (NaN, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: 1e-9)",
            "finite",
        ),
        (
            "Box(min: (0.0, 0.0, 0.02), max: (0.01, 0.01, 0.0))",
            "above max",
        ),
        (
            "Plane(point: (0.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: -1e-3)",
            "tolerance",
        ),
        (
            "HalfSpace(point: (0.0, 0.0, 0.0), normal: (0.0, 0.0, 0.0), tolerance: 0.0)",
            "no direction",
        ),
    ];
    for (selector, why) in cases {
        let msg = refusal(&scene_with(&format!("fixed: [{selector}],"))).to_string();
        assert!(msg.contains("fixed selector 0"), "{selector}: {msg}");
        assert!(msg.contains(why), "{selector}: {msg}");
    }
}

/// A selector valid in itself that selects no node of this mesh (a plane far away, a region
/// the mesh does not have) once ran the body free and passed; the run is refused, naming the
/// selector and the mesh's extent.
#[test]
fn a_selector_that_selects_no_node_of_the_mesh_fails_the_run() {
    for selector in [
        "Plane(point: (5.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: 1e-9)",
        "Region(7)",
        "Box(min: (1.0, 1.0, 1.0), max: (2.0, 2.0, 2.0))",
    ] {
        let text = scene_with(&format!(
            "gravity: (0.0, 0.0, -9.81),\n    fixed: [{selector}],"
        ));
        let scene = Scene::from_ron(&text, Path::new("x.ron")).unwrap();
        let err = run_scene(
            &scene,
            Path::new("x.ron"),
            &RunOptions {
                no_output: true,
                ..Default::default()
            },
            |_, _| {},
        )
        .expect_err("the run is refused");
        let msg = err.to_string();
        assert!(msg.contains("selects no node"), "{selector}: {msg}");
        assert!(msg.contains("0.01"), "the mesh's extent: {msg}");
    }
    // The same scene fixed on a face of the box runs.
    let text = scene_with(
        "fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: 1e-9)],",
    );
    let scene = Scene::from_ron(&text, Path::new("x.ron")).unwrap();
    let opts = RunOptions {
        no_output: true,
        ..Default::default()
    };
    assert!(run_scene(&scene, Path::new("x.ron"), &opts, |_, _| {}).is_ok());
}

// Item 8: expectations.

/// Expectations that can never be checked as written are refused when the scene is read,
/// naming the expectation by index.
#[test]
fn expectations_that_cannot_be_checked_are_refused_when_the_scene_is_read() {
    let cases = [
        (
            "DisplacementAt(point: (NaN, 0.0, 0.0), max: Some(1.0))",
            "finite coordinates",
        ),
        (
            "DisplacementAt(point: (0.0, 0.0, 0.0), component: Some(3), max: Some(1.0))",
            "component 3",
        ),
        ("MaxDisplacement(min: Some(2.0), max: Some(1.0))", "swap"),
        ("VolumeRatio(min: Some(NaN))", "finite"),
        ("ToolForce(tool: \"probe\", max: Some(1.0))", "no tool"),
        ("Fragments(min: Some(2))", "does not cut"),
        ("Method(Separate, Cuts(min: Some(1)))", "does not cut"),
        ("UploadFraction(max: -1.0)", "does not cut"),
    ];
    for (expectation, why) in cases {
        let text = scene_with(&format!(
            "expect: [MaxDisplacement(max: Some(1.0)), {expectation}],"
        ));
        let msg = refusal(&text).to_string();
        assert!(msg.contains("expectation 1"), "{expectation}: {msg}");
        assert!(msg.contains(why), "{expectation}: {msg}");
    }
}

/// A tool name close to the scene's is suggested.
#[test]
fn an_expectation_naming_a_misspelled_tool_suggests_the_tool() {
    let probe = r#"tools: [(name: "probe", shape: Probe(radius: 0.002, length: 0.05),
        trajectory: Keyframes([(time: 0.0, translation: (0.0, 0.0, 0.05))]))],"#;
    let text = scene_with(&format!(
        "{probe}\n    expect: [ToolForce(tool: \"prob\", max: Some(1.0))],"
    ));
    let msg = refusal(&text).to_string();
    assert!(msg.contains("did you mean \"probe\"?"), "{msg}");
    let grasp = scene_with(&format!(
        "{probe}\n    expect: [GraspCarried(tool: \"probe\", min: Some(0.0))],"
    ));
    let msg = refusal(&grasp).to_string();
    assert!(msg.contains("not a grasper"), "{msg}");
}

// Item 5: generated boxes too large for memory.

/// A box of 400^3 cells (384 million tets) once aborted the process on an allocation failure;
/// it is refused with the estimate where the memory is not there, and a small box is not.
#[test]
fn a_box_too_large_for_memory_is_refused_with_the_estimate() {
    let big = BoxGrid::cube_cells([400; 3], 1e-3);
    let tets = 400u64.pow(3) * 6;
    assert_eq!(big.tet_count(), Some(tets));
    let sixteen_gib = 16u64 << 30;
    let msg = big.check_memory(sixteen_gib).unwrap_err().to_string();
    assert!(msg.contains(&tets.to_string()), "{msg}");
    let gib = (tets * RUN_BYTES_PER_TET) as f64 / (1u64 << 30) as f64;
    assert!(msg.contains(&format!("{gib:.1} GiB")), "{msg}");
    assert!(msg.contains("16.0 GiB is available"), "{msg}");
    assert!(BoxGrid::cube_cells([10; 3], 1e-3)
        .check_memory(sixteen_gib)
        .is_ok());
    // Five tets a cell count as five.
    let five = BoxGrid {
        split: TetSplit::Five,
        ..BoxGrid::cube_cells([10; 3], 1e-3)
    };
    assert_eq!(five.tet_count(), Some(5000));
}

/// Building a box of 1000^3 cells (its nodes still fit 32-bit indices; six billion tets) is
/// refused before anything is allocated, on any machine with less than several terabytes.
#[test]
fn building_a_box_far_too_large_is_an_error_not_an_abort() {
    let err = BoxGrid::cube_cells([1000; 3], 1e-3).build().unwrap_err();
    assert!(err.to_string().contains("GiB of memory"), "{err}");
}

// Item 9: messages.

/// A zero time step was refused by the engine with a message naming no file: it is refused
/// when the scene is read, naming the file and the line of `dt`.
#[test]
fn a_zero_or_negative_time_step_is_refused_naming_the_scene_file_and_line() {
    for dt in ["Seconds(0.0)", "Seconds(-1e-4)", "BoundFraction(NaN)"] {
        let text = scene_with("").replace("BoundFraction(0.5)", dt);
        let err = refusal(&text);
        let msg = err.to_string();
        let line = line_of(&text, "dt:");
        assert!(
            msg.starts_with(&format!("dir/x.ron: line {line}: dt:")),
            "{dt}: {msg}"
        );
        assert!(msg.contains("finite and positive"), "{dt}: {msg}");
        let p = err.as_parse().expect("a parse error with a place");
        assert_eq!(p.location, lancet::Location::Line(line), "{dt}");
    }
}

/// Running out of memory while reading once said to check that the path exists.
#[test]
fn an_out_of_memory_error_does_not_blame_the_path() {
    let oom = lancet::Error::io(
        "big.msh",
        std::io::Error::from(std::io::ErrorKind::OutOfMemory),
    )
    .to_string();
    assert!(!oom.contains("path exists"), "{oom}");
    assert!(oom.contains("not enough memory"), "{oom}");
    let missing = lancet::Error::io(
        "gone.msh",
        std::io::Error::from(std::io::ErrorKind::NotFound),
    )
    .to_string();
    assert!(missing.contains("path exists"), "{missing}");
}

/// A scene saved with a UTF-8 byte-order mark was refused at line 1 ("expected opening `(`").
#[test]
fn a_scene_with_a_utf8_byte_order_mark_is_read() {
    let text = scene_with("");
    let plain = Scene::from_ron(&text, Path::new("dir/x.ron")).unwrap();
    let marked = Scene::from_ron(&format!("\u{feff}{text}"), Path::new("dir/x.ron"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((marked.name, marked.steps), (plain.name, plain.steps));
}

/// A mesh transform that would turn every tet inside out or move nodes to no place is refused
/// when the scene is read, naming the field.
#[test]
fn a_mesh_transform_without_a_positive_finite_scale_is_refused() {
    for bad in [
        "mesh_transform: (scale: 0.0),",
        "mesh_transform: (scale: -0.001),",
        "mesh_transform: (scale: NaN),",
        "mesh_transform: (rotation: (0.0, inf, 0.0)),",
    ] {
        let msg = refusal(&scene_with(bad)).to_string();
        assert!(
            msg.contains("mesh_transform") && msg.contains("x.ron"),
            "{bad}: {msg}"
        );
    }
    // Translated, rotated and scaled, a box keeps its volume times the cube of the scale.
    let path = Path::new("x.ron");
    let placed = Scene::from_ron(
        &scene_with(
            "mesh_transform: (scale: 2.0, rotation: (30.0, 45.0, 60.0), translation: (1.0, 0.0, 0.0)),",
        ),
        path,
    )
    .unwrap();
    let mesh = lancet::scene::runner::build_mesh(&placed, path).unwrap();
    let volume = mesh.volume();
    assert!((volume / 8e-6 - 1.0).abs() < 1e-9, "{volume}");
    assert!(mesh.tets().all(|(_, t)| {
        let [a, b, c, d] = mesh.tet_points(t);
        (b - a).cross(&(c - a)).dot(&(d - a)) > 0.0
    }));
}

/// Scale first, then rotate (about x, then y, then z), then translate: (1, 0, 0) scaled by 2,
/// turned 90 degrees about z and moved up by 1 is (0, 2, 1); (0, 1, 0) turned about x goes to
/// z, which the turn about z then leaves alone.
#[test]
fn a_mesh_transform_scales_then_rotates_then_translates() {
    use lancet::scene::placement::MeshTransform;
    use nalgebra::Point3;
    let t = MeshTransform {
        scale: 2.0,
        rotation: [0.0, 0.0, 90.0],
        translation: [0.0, 0.0, 1.0],
    };
    let p = t.apply(Point3::new(1.0, 0.0, 0.0));
    assert!((p - Point3::new(0.0, 2.0, 1.0)).norm() < 1e-12, "{p}");
    let t = MeshTransform {
        rotation: [90.0, 0.0, 90.0],
        ..Default::default()
    };
    let p = t.apply(Point3::new(0.0, 1.0, 0.0));
    assert!((p - Point3::new(0.0, 0.0, 1.0)).norm() < 1e-12, "{p}");
}

/// A mesh given where a scene goes is named as a mesh, with what to do instead; it failed as
/// RON ("expected opening `(`") or as UTF-8 before.
#[test]
fn a_mesh_given_as_a_scene_is_named_as_a_mesh() {
    for file in ["liver.msh", "box.VTU", "torus.veg", "tets.ele"] {
        let err = Scene::read(Path::new(file)).unwrap_err().to_string();
        assert!(
            err.contains(file) && err.contains("is a mesh") && err.contains("lancet info"),
            "{file}: {err}"
        );
    }
}

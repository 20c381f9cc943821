//! The C example compiled by the system C compiler against the generated header and the
//! shared library, run, and checked against the same run made through the Rust API: the
//! positions after 300 steps agree to the last bit, and the force on the probe is the Rust
//! run's.

use std::path::{Path, PathBuf};
use std::process::Command;

use lancet::collide::ToolShape;
use lancet::engine::{EngineKind, SimConfig};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{FixedSelector, Material, ModelConfig};
use lancet::world::WorldBuilder;
use nalgebra::Isometry3;

/// The folder holding the shared library: `target/<profile>/deps`, beside this test (where
/// `cargo test` builds it), or `target/<profile>` (where `cargo build` puts it).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test knows its path");
    let deps = exe.parent().expect("tests run from target/<profile>/deps");
    let name = library_name();
    let found = [Some(deps), deps.parent()]
        .into_iter()
        .flatten()
        .find(|d| d.join(&name).exists())
        .unwrap_or(deps)
        .to_path_buf();
    found
}

/// `liblancet_c.so` (or the platform's name for it).
fn library_name() -> String {
    format!(
        "{}lancet_c{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    )
}

/// The example's run through the Rust API: its final positions and the last force.
fn rust_run() -> (Vec<[f64; 3]>, [f64; 3]) {
    let mesh = BoxGrid {
        cells: [4, 4, 4],
        size: [0.02; 3],
        origin: [0.0; 3],
        split: Default::default(),
    }
    .build()
    .unwrap();
    let mut model = ModelConfig::new(Material::elastic(10e3, 0.3, 1000.0));
    model.gravity = [0.0, 0.0, -9.81];
    model.mass_damping = 20.0;
    model.fixed.push(FixedSelector::Box {
        min: [-1.0, -1.0, -1e-9],
        max: [1.0, 1.0, 1e-9],
    });
    let mut world = WorldBuilder::new(mesh, &model, SimConfig::new(1.0))
        .unwrap()
        .engine(EngineKind::Reference)
        .bound_fraction(0.5)
        .unwrap()
        .build()
        .unwrap();
    let probe = world
        .add_tool(
            "probe",
            ToolShape::Sphere { radius: 0.003 },
            Isometry3::translation(0.01, 0.01, 0.0235),
        )
        .unwrap();
    let steps = 300;
    let mut force = [0.0; 3];
    for k in 1..=steps {
        let z = 0.0235 - 2e-3 * f64::from(k) / f64::from(steps);
        world
            .set_tool_pose(probe, Isometry3::translation(0.01, 0.01, z))
            .unwrap();
        let report = world.step().unwrap();
        force = report.tools[probe.index()].force.into();
    }
    (world.positions(), force)
}

#[test]
fn the_c_example_runs_and_matches_the_rust_api() {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib = library_dir();
    let so = lib.join(library_name());
    assert!(so.exists(), "{} was not built", so.display());
    let work = tempfile::tempdir().unwrap();
    let exe = work.path().join("press");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let built = Command::new(&cc)
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(manifest.join("include"))
        .arg(manifest.join("examples/press.c"))
        .arg("-L")
        .arg(&lib)
        .arg("-llancet_c")
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("cannot run the C compiler `{cc}` (set CC): {e}"));
    assert!(
        built.status.success(),
        "the C example does not compile:\n{}",
        String::from_utf8_lossy(&built.stderr)
    );
    let positions = work.path().join("positions.txt");
    let ran = Command::new(&exe).arg(&positions).output().unwrap();
    let stdout = String::from_utf8_lossy(&ran.stdout);
    assert!(
        ran.status.success(),
        "the C example failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&ran.stderr)
    );
    let c_positions: Vec<[f64; 3]> = std::fs::read_to_string(&positions)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    let (expected, force) = rust_run();
    assert_eq!(c_positions.len(), expected.len(), "node counts");
    assert_eq!(c_positions, expected, "positions after 300 steps");
    // The probe pressed: the tissue pushes it up (a physical sign, not a copied number).
    assert!(force[2] > 0.0, "the probe felt {force:?}");
    let last = stdout
        .lines()
        .rfind(|l| l.starts_with("step 300"))
        .expect("the example reports step 300");
    assert!(
        last.contains(&format!("{:.4})", force[2])),
        "C reports `{last}`, the Rust run {force:?}"
    );
    assert!(
        stdout.contains("expected error: tool 7 does not exist"),
        "{stdout}"
    );
}

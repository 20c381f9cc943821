//! The run summary counts what was checked: an expectation for another cut method is shown as
//! skipped and counted neither way, and a count is printed as a whole number.

use std::process::Command;

/// A one-cell box cut with two methods by a blade held above it (so nothing is cut), that
/// expects, for the remove method only, no cut.
const SCENE: &str = r#"Scene(
    name: "two methods",
    mesh: Box((cells: (1, 1, 1), size: (0.01, 0.01, 0.01))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.25), mass: Density(1000.0)),
    dt: BoundFraction(0.5),
    steps: 4,
    tools: [(name: "b", shape: Blade(width: 0.02, length: 0.02, thickness: 2e-4),
             trajectory: Keyframes([(time: 0.0, translation: (0.0, 0.0, 0.05))]))],
    cut: Some((methods: [Separate, Remove])),
    expect: [Method(Remove, Cuts(max: Some(0))), MaxDisplacement(max: Some(1.0))],
)"#;

#[test]
fn an_expectation_for_another_method_is_skipped_and_counts_are_whole_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two.ron");
    std::fs::write(&path, SCENE).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lancet"))
        .args(["run", path.to_str().unwrap(), "--no-output"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The separate run skips the remove-only expectation ...
    assert!(text.contains("  skip  [remove] not this method"), "{text}");
    assert!(!text.contains("pass  [remove] not this method"), "{text}");
    // ... and the remove run checks it: zero cuts, printed as a count.
    assert!(
        text.contains("[remove] steps that cut <= 0e0 (measured 0)"),
        "{text}"
    );
    assert!(!text.contains("measured 0.0000e0"), "{text}");
}

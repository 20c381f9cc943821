//! `lancet report accuracy --model-error`: the cantilever fixture's static tip deflection under
//! each force model against Timoshenko beam theory, and its convergence over refinements.

use std::path::Path;

use lancet::physics::ForceModelKind;
use lancet::report::model_error::{model_error, richardson};
use lancet::scene::Scene;
use lancet::Error;

const ALL: [ForceModelKind; 3] = [
    ForceModelKind::Springs,
    ForceModelKind::TensorMass,
    ForceModelKind::Corotational,
];

fn cantilever() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/fem_cantilever.ron");
    Scene::read(&path).unwrap()
}

#[test]
fn the_cantilever_model_error_is_against_timoshenko_and_shrinks_with_refinement() {
    let report = model_error(&cantilever(), &ALL, 2, |_| {}).unwrap();
    // Timoshenko for the fixture's 10 x 2 x 2 cm beam, E = 1 MPa, nu = 0.3, 1000 kg/m^3, by
    // hand: q = 1000 * 9.81 * 4e-4 = 3.924 N/m, I = 0.02^4 / 12 = 1.3333e-8 m^4; bending
    // q L^4 / (8 E I) = 3.679e-3 m, shear q L^2 / (2 kappa G A) with G = E / 2.6 and kappa =
    // 13 / 15.3: 1.501e-4 m. Downward (gravity along -z).
    let theory = -(3.679e-3 + 1.501e-4);
    assert!(
        (report.analytic_tip_m - theory).abs() < 1e-3 * theory.abs(),
        "{} against {theory}",
        report.analytic_tip_m
    );
    assert_eq!(report.rows.len(), 6);
    // Two meshes give no order of convergence to extrapolate with.
    assert!(report.extrapolated.is_empty(), "{:?}", report.extrapolated);
    let row = |model: &str, along: usize| {
        report
            .rows
            .iter()
            .find(|r| r.force_model == model && r.cells_along == along)
            .unwrap()
    };
    for along in [10, 20] {
        let (linear, co) = (row("tensor-mass", along), row("corotational", along));
        // Constant-strain tets lock in bending: stiffer than the beam.
        assert!(linear.relative_error < 0.0, "{linear:?}");
        // A sag of a few per cent of the length: rotations barely matter.
        assert!(
            (co.tip_m - linear.tip_m).abs() < 0.02 * linear.tip_m.abs(),
            "{co:?} {linear:?}"
        );
        // The error is the tip's against the analytic one, as the table prints it.
        let e = (linear.tip_m - report.analytic_tip_m) / report.analytic_tip_m;
        assert!((e - linear.relative_error).abs() < 1e-12);
    }
    // On 10 x 2 x 2 cells the linear tets sag about half the beam (tests/physics/
    // fem_validation.rs); refined, the error at least halves (first-order convergence).
    let (coarse, fine) = (row("tensor-mass", 10), row("tensor-mass", 20));
    assert!(
        (-0.65..-0.35).contains(&coarse.relative_error),
        "{coarse:?}"
    );
    assert!(
        fine.relative_error.abs() < 0.5 * coarse.relative_error.abs(),
        "{fine:?} {coarse:?}"
    );
    // Springs are a different model: their answer is not the elements'.
    let springs = row("springs", 20);
    assert!(
        (springs.tip_m - fine.tip_m).abs() > 0.05 * fine.tip_m.abs(),
        "{springs:?} {fine:?}"
    );
}

#[test]
fn a_scene_without_an_analytic_answer_is_refused_with_the_reason() {
    let mut scene = cantilever();
    scene.mesh = lancet::scene::MeshSource::Box(lancet::mesh::generate::BoxGrid::cube_cells(
        [2, 2, 2],
        0.01,
    ));
    match model_error(&scene, &ALL, 1, |_| {}) {
        Err(Error::Unsupported(why)) => assert!(why.contains("Beam"), "{why}"),
        other => panic!("not refused: {other:?}"),
    }
}

#[test]
fn richardson_extrapolation_recovers_the_limit_and_order_of_a_power_law() {
    // t(h) = t0 + c h^p at h = 1, 1/2, 1/4, for orders between first and second.
    for (t0, c, p) in [(-3.8e-3, 2.0e-3, 2.0), (1.0, -0.5, 1.0), (0.25, 0.1, 1.58)] {
        let t = |h: f64| t0 + c * h.powf(p);
        let (limit, order) = richardson(t(1.0), t(0.5), t(0.25)).unwrap();
        assert!(
            (limit - t0).abs() < 1e-12 * t0.abs().max(1.0),
            "{limit} {t0}"
        );
        assert!((order - p).abs() < 1e-9, "{order} {p}");
    }
    // Values that do not converge monotonically have no order to read.
    assert!(richardson(1.0, 0.5, 0.75).is_none());
    assert!(richardson(1.0, 0.9, 0.5).is_none());
    assert!(richardson(1.0, 1.0, 1.0).is_none());
}

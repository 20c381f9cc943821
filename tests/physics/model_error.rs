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

/// The expectation: within 3% of Timoshenko on a refined mesh, converging over three
/// refinements. Five-tet cells (the six-tet split around one diagonal is stiffer in bending:
/// -3.5% on 80 x 16 x 16 cells against -2.6% with five) of 1.25 by 1.67 mm on the finest mesh,
/// 80 x 12 x 12 cells: the cheapest mesh found within 3% (`lancet report accuracy
/// fixtures/scenes/fem_cantilever.ron --model-error --model-error-only --force-models
/// tensor-mass --cells-along 20 --cells-across 3 --split five --refinements 3
/// --expect-within 0.03` prints this table). Tensor-mass, the linear elasticity Timoshenko's
/// beam is the theory of, in one Newton step; about a second and a quarter in all.
#[test]
fn the_cantilever_is_within_3_percent_of_timoshenko_on_a_refined_mesh() {
    use lancet::mesh::generate::TetSplit;
    use lancet::report::model_error::with_beam_cells;
    let scene = with_beam_cells(&cantilever(), Some(20), Some(3), Some(TetSplit::Five)).unwrap();
    let report = model_error(&scene, &[ForceModelKind::TensorMass], 3, |_| {}).unwrap();
    let cells: Vec<[usize; 3]> = report
        .rows
        .iter()
        .map(|r| [r.cells_along, r.cells_across, r.tets])
        .collect();
    assert_eq!(
        cells,
        [[20, 3, 900], [40, 6, 7200], [80, 12, 57600]],
        "20 x 3 x 3 cells, five tets each, refined twice"
    );
    let errors: Vec<f64> = report.rows.iter().map(|r| r.relative_error).collect();
    eprintln!("errors {errors:?}, extrapolated {:?}", report.extrapolated);
    // Converging: every mesh stiffer than the beam (locking), and each refinement cuts the
    // error by more than half (first order or better).
    assert!(errors.iter().all(|&e| e < 0.0), "{errors:?}");
    assert!(
        errors.windows(2).all(|w| w[1].abs() < 0.5 * w[0].abs()),
        "{errors:?}"
    );
    assert!(
        errors[2].abs() < 0.03,
        "{:.2}% on 80 x 12 x 12",
        100.0 * errors[2]
    );
    assert!(report.beyond(0.03).is_empty(), "{:?}", report.beyond(0.03));
    // The meshes converge to within 2% of the beam: what is left is the mesh's, not the
    // model's (a clamped 3D bar is not quite Timoshenko's beam at its root).
    let [limit] = &report.extrapolated[..] else {
        panic!("no extrapolation: {:?}", report.extrapolated)
    };
    assert!(
        limit.relative_error.abs() < 0.02 && (1.0..=2.5).contains(&limit.order),
        "{limit:?}"
    );
    // The check sees a model that is not within: the coarsest mesh alone.
    let coarse = model_error(&scene, &[ForceModelKind::TensorMass], 1, |_| {}).unwrap();
    let beyond = coarse.beyond(0.03);
    assert!(
        beyond.len() == 1 && beyond[0].contains("20 x 3 x 3"),
        "{beyond:?}"
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
    // Nor can its beam cells be set.
    let set = lancet::report::model_error::with_beam_cells(&scene, Some(4), None, None);
    assert!(matches!(set, Err(Error::Unsupported(_))), "{set:?}");
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

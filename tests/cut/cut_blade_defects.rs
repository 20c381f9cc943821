//! Two defects random cut sequences (`cut_properties.rs`) found, kept fixed on single
//! incisions: a blade pulled out along its axis carving with rounding-level sides, and
//! subdividing a repeated sweep at a floor pulling nodes onto the cut.

use crate::incisions::{blade_push, small_box};
use crate::models::Rng;
use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::model::{Material, ModelConfig, SpringModel};
use nalgebra::{Isometry3, Point3, Vector3};

/// A 3 cm box of 1 cm cells (a random tet split) cut by `method`, and a blade 2 cm wide pushed
/// along its own axis, from outside, to a random depth inside it: the poses before and after.
fn incision(seed: u64, method: CutMethod) -> (Cutter, ToolShape, Isometry3<f64>, Isometry3<f64>) {
    let mut rng = Rng(seed);
    let mesh = small_box(&mut rng);
    let (blade, from, to) = blade_push(&mut rng);
    let model =
        SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(3e3, 0.3, 1e3))).unwrap();
    (Cutter::new(mesh, model, method).unwrap(), blade, from, to)
}

fn rest_positions(cutter: &Cutter) -> Vec<[f64; 3]> {
    cutter
        .mesh()
        .nodes()
        .map(|(_, n)| n.rest.coords.into())
        .collect()
}

/// A blade moved along its own axis sweeps with its edge (pushed in) or its back (pulled out)
/// only: its sides move along themselves. Rounding keeps them as triangles of about 1e-18 m^2
/// that run the blade's whole length unless a side must move outwards by more than rounding
/// to lead (`Sweep::of_blade`), and carving would remove every tet their edges pass
/// (`triangle_meets_tet` tests the triangle's edges against the tet's faces): a blade pulled
/// straight back out of tissue that slid a little sideways carved along its sides. Random
/// sequences with trembling blades met it; with subdividing it split edges along a trembling
/// blade's side too.
#[test]
fn a_blade_pulled_straight_out_carves_nothing() {
    let mut carved = Vec::new();
    for seed in 1..=50 {
        let (mut cutter, blade, from, to) = incision(seed, CutMethod::Remove);
        let rest = rest_positions(&cutter);
        cutter
            .cut(&Sweep::of_blade(&blade, &from, &to).unwrap(), &rest)
            .unwrap();
        let out = Sweep::of_blade(&blade, &to, &from).unwrap();
        let slivers = out
            .triangles
            .iter()
            .filter(|t| (t[1] - t[0]).cross(&(t[2] - t[0])).norm() < 1e-12)
            .count();
        // The tissue slides 3 mm along the blade's width; then out.
        let shift = to.rotation * Vector3::x() * 0.003;
        let slid: Vec<[f64; 3]> = rest
            .iter()
            .map(|p| (Point3::from(*p) + shift).coords.into())
            .collect();
        let outcome = cutter.cut(&out, &slid).unwrap();
        if slivers > 0 || outcome.tets_removed > 0 {
            carved.push((seed, slivers, outcome.tets_removed));
        }
    }
    assert!(
        carved.is_empty(),
        "(seed, side triangles kept, tets carved pulling out): {carved:?}"
    );
}

/// Subdividing at the default floor, the same sweep again at once, at the same (rest)
/// positions, cuts nothing new. The nodes the first sweep made lie on the sweep, so edges
/// from them meet it (the tie rule); counted as crossed, they pulled a neighbour within
/// `NODE_SNAP` of the sweep onto the cut, one just beyond where the blade's edge stopped, and
/// faces opened or the crack front changed. An edge meeting the sweep at a node already on the
/// cut now crosses nothing new.
#[test]
fn subdividing_the_same_sweep_again_at_the_default_floor_cuts_nothing_new() {
    let mut again = Vec::new();
    for seed in 1..=100 {
        let (mut cutter, blade, from, to) = incision(seed, CutMethod::Subdivide);
        // The edge's band alone (no side triangles, see the test above).
        let (q0, q1) = (
            blade.blade_quad(&from).unwrap(),
            blade.blade_quad(&to).unwrap(),
        );
        let sweep = Sweep::from_triangles(vec![[q0[0], q0[1], q1[1]], [q0[0], q1[1], q1[0]]]);
        cutter.cut(&sweep, &rest_positions(&cutter)).unwrap();
        let front = cutter.crack_front();
        let outcome = cutter.cut(&sweep, &rest_positions(&cutter)).unwrap();
        if !outcome.is_empty() || cutter.crack_front() != front {
            again.push((seed, outcome.faces_cut, outcome.nodes_added));
        }
    }
    assert!(
        again.is_empty(),
        "(seed, faces cut, nodes added by the repeat): {again:?}"
    );
}

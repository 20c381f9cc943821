//! The tolerance that GPU tests allow between a device that rounds differently from the CPU
//! (an H100 fuses multiply-adds) and the CPU twin (`common::assert_twin`) still catches a
//! spring left out: dropping any one spring of a model that moves anything moves the twin's
//! state past it in all but a few cases. CPU only: both runs are the twin's.

use crate::{common, models};
use lancet::engine::gpu::step_params;
use lancet::engine::{Integrator, SimConfig};
use lancet::layout::{LayoutKind, NodeOrder, PackedLayout};
use models::{random_model, random_state};
use rstest::rstest;

type Raw = (Vec<[f32; 4]>, Vec<[f32; 4]>);

fn twin(
    layout: &PackedLayout,
    model: &lancet::model::PackedModel,
    config: SimConfig,
    raw: &Raw,
    steps: usize,
) -> Raw {
    let p = step_params(model, config);
    let gather = lancet::layout::edges::Accumulation::Gather;
    let unused = lancet::layout::edges::FixedPoint::new(1.0, 1);
    layout.steps_cpu(&p, gather, &unused, raw.clone(), steps)
}

#[rstest]
fn a_dropped_spring_moves_the_twin_past_the_tolerance(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let steps = 13;
    let model = random_model(41, true);
    let config = SimConfig {
        integrator,
        ..SimConfig::new(2e-5)
    };
    let layout = PackedLayout::pack(
        &model,
        LayoutKind::Connectivity,
        NodeOrder::locality(&model),
    )
    .unwrap();
    // A random state in layout order: displacements, and the last steps (Verlet)
    // or the velocities (symplectic Euler).
    let (x, v) = random_state(&model, 41);
    let rank = &layout.order().rank;
    let mut raw: Raw = (
        vec![[0.0; 4]; layout.node_slots()],
        vec![[0.0; 4]; layout.node_slots()],
    );
    for i in 0..model.node_count() {
        let (r, at) = (model.rest[i], rank[i] as usize);
        for c in 0..3 {
            let u = x[i][c] - r[c];
            raw.0[at][c] = u as f32;
            raw.1[at][c] = match integrator {
                Integrator::Verlet => (v[i][c] * config.dt) as f32,
                Integrator::SymplecticEuler | Integrator::BackwardEuler => v[i][c] as f32,
            };
        }
    }
    let base = twin(&layout, &model, config, &raw, steps);
    let tolerance = 1e-5 * steps as f64;
    let (mut passed, mut tried) = (0, 0);
    for k in 0..model.springs().len() {
        let mut less = model.clone();
        less.springs_mut().remove(k);
        let other = models::fresh(&less, &layout);
        let t = twin(&other, &less, config, &raw, steps);
        let d = common::relative_difference(&t.0, &base.0, &raw.0)
            .max(common::relative_difference(&t.1, &base.1, &raw.1));
        // A spring between two fixed nodes moves nothing: no test could see it go.
        if d > 0.0 {
            tried += 1;
            passed += usize::from(d <= tolerance);
        }
    }
    eprintln!("{integrator:?}: {passed} of {tried} dropped springs within the tolerance");
    assert!(tried > 100);
    assert!(
        passed * 100 <= tried,
        "{passed} of {tried} dropped springs pass the twin tolerance"
    );
}

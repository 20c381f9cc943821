//! The fast engine's AVX2/FMA kernels (used where the CPU has them) step like its baseline
//! kernels: the same physics, differing only by fused-multiply-add rounding.

use crate::models;
use lancet::engine::fast::FastEngine;
use lancet::engine::{Engine, Integrator, SimConfig};
use lancet::model::stable_time_step;
use lancet::report::bench::relative_l2;
use models::{random_model, random_state};
use rstest::rstest;

#[rstest]
fn wide_and_baseline_kernels_agree(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(false, true)] damped: bool,
) {
    let model = random_model(71, damped);
    let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    config.integrator = integrator;
    let (x, v) = random_state(&model, 71);
    let run = |wide: bool| {
        let mut e = FastEngine::new(&model, config);
        let used = e.set_wide_simd(wide);
        e.set_state(&x, &v);
        e.step(300);
        (used, e.positions())
    };
    let (wide_used, wide) = run(true);
    let (baseline_used, baseline) = run(false);
    assert!(!baseline_used);
    if !wide_used {
        eprintln!("skipped: this CPU has no AVX2/FMA, only the baseline kernels run");
        return;
    }
    let e = relative_l2(&model.rest, &wide, &baseline);
    // Rounding only (measured ~1e-7); a wrong lane or missed spring gives 1e-2 and more.
    assert!(e < 1e-5, "AVX2 kernels off the baseline by {e:.2e}");
}

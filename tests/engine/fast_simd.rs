//! The fast engine's AVX2/FMA kernels, and those with AVX-512 (used where the CPU has them),
//! step like its baseline kernels: the same physics, differing only by fused-multiply-add
//! rounding (and, with AVX-512, each spring's `1 / l` from an estimate and a Newton step), with
//! the springs' constants per end and with one material kept once.

use crate::models;
use lancet::engine::fast::FastEngine;
use lancet::engine::{Engine, Integrator, SimConfig};
use lancet::model::{stable_time_step, PackedModel};
use lancet::report::bench::relative_l2;
use models::{one_material, random_model, random_state};
use rstest::rstest;

/// The random model of `seed`, with one spring material where `one`.
fn model_of(seed: u64, damped: bool, one: bool) -> PackedModel {
    let model = random_model(seed, damped);
    if one {
        one_material(model)
    } else {
        model
    }
}

/// `steps` steps of a fast engine from `(x, v)` with the wide kernels (`wide`) and AVX-512
/// (`avx512`) asked for: whether each is in use, and the positions.
fn step_with(
    model: &PackedModel,
    config: SimConfig,
    (x, v): (&[[f64; 3]], &[[f64; 3]]),
    (wide, avx512): (bool, bool),
    steps: u32,
) -> (bool, bool, Vec<[f64; 3]>) {
    let mut e = FastEngine::new(model, config);
    let used = e.set_wide_simd(wide);
    let used_512 = e.set_avx512(avx512);
    e.set_state(x, v);
    e.step(steps);
    (used, used_512, e.positions())
}

#[rstest]
fn wide_and_baseline_kernels_agree(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(false, true)] damped: bool,
    #[values(false, true)] one: bool,
    #[values(false, true)] avx512: bool,
) {
    let model = model_of(71, damped, one);
    let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    config.integrator = integrator;
    assert_eq!(
        FastEngine::new(&model, config).uniform_springs().is_some(),
        one
    );
    let (x, v) = random_state(&model, 71);
    let run = |wide: bool| step_with(&model, config, (&x, &v), (wide, avx512), 300);
    let (wide_used, wide_512, wide) = run(true);
    let (baseline_used, baseline_512, baseline) = run(false);
    assert!(!baseline_used && !baseline_512);
    if !wide_used {
        eprintln!("skipped: this CPU has no AVX2/FMA, only the baseline kernels run");
        return;
    }
    assert!(avx512 || !wide_512);
    if avx512 && !wide_512 {
        eprintln!("skipped: this CPU has no AVX-512F/VL, the AVX2 kernels are checked alone");
        return;
    }
    let e = relative_l2(&model.rest, &wide, &baseline);
    // Rounding only (measured ~1e-7); a wrong lane or missed spring gives 1e-2 and more.
    assert!(
        e < 1e-5,
        "AVX2 kernels (AVX-512: {avx512}) off the baseline by {e:.2e}"
    );
}

/// Backward Euler's product, read lane by lane, is compiled a second time for AVX2 and FMA
/// like the explicit kernels: each lane sums its node's blocks in row order in both builds and
/// Rust fuses no multiply-add by itself, so the two give the same bits (a lane read from the
/// wrong component or a block left out would differ at the first step's product).
#[test]
fn backward_euler_wide_and_baseline_products_give_the_same_bits() {
    let model = random_model(72, true);
    let mut config = SimConfig::new(30.0 * stable_time_step(&model).dt);
    config.integrator = Integrator::BackwardEuler;
    let (x, v) = random_state(&model, 72);
    let run = |wide: bool| {
        let mut e = FastEngine::new(&model, config);
        let used = e.set_wide_simd(wide);
        e.set_state(&x, &v);
        e.step(5);
        (used, e.positions(), e.solver_stats().unwrap())
    };
    let (wide_used, wide, wide_stats) = run(true);
    let (_, baseline, baseline_stats) = run(false);
    if !wide_used {
        eprintln!("skipped: this CPU has no AVX2/FMA, only the baseline kernels run");
        return;
    }
    assert!(baseline_stats.iterations > 5, "{baseline_stats:?}");
    assert_eq!(wide_stats, baseline_stats);
    let bits =
        |x: &[[f64; 3]]| -> Vec<[u64; 3]> { x.iter().map(|p| p.map(f64::to_bits)).collect() };
    assert!(
        bits(&wide) == bits(&baseline),
        "the AVX2 product's steps differ"
    );
}

/// A spring whose two ends meet has no direction and pushes nothing, in every kernel: the
/// AVX-512 estimate of `1 / l` is infinite there and its NaN must be masked out, the division
/// of the others masked alike. Its ends' neighbours then step as in the baseline kernels.
#[rstest]
fn a_spring_of_zero_length_pushes_nothing_in_every_kernel(
    #[values(false, true)] damped: bool,
    #[values(false, true)] one: bool,
    #[values(false, true)] avx512: bool,
) {
    let model = model_of(73, damped, one);
    let config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    let (mut x, v) = random_state(&model, 73);
    let s = model
        .springs()
        .iter()
        .find(|s| s.nodes.iter().all(|&n| !model.fixed[n as usize]))
        .expect("a spring between free nodes");
    let [i, j] = s.nodes.map(|n| n as usize);
    x[j] = x[i];
    let run = |wide: bool| step_with(&model, config, (&x, &v), (wide, avx512), 1);
    let (_, _, baseline) = run(false);
    assert!(baseline.iter().flatten().all(|c| c.is_finite()));
    let (wide_used, wide_512, wide) = run(true);
    if !wide_used || (avx512 && !wide_512) {
        eprintln!("skipped: this CPU lacks the kernel asked for");
        return;
    }
    assert!(
        wide.iter().flatten().all(|c| c.is_finite()),
        "a zero-length spring made the wide kernels' step not finite (AVX-512: {avx512})"
    );
    let e = relative_l2(&model.rest, &wide, &baseline);
    assert!(e < 1e-5, "off the baseline by {e:.2e} (AVX-512: {avx512})");
}

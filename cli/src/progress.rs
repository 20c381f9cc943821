//! The progress bar of `lancet run`, shown by the run's expected duration.

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Runs expected to take longer than this show a progress bar.
pub(crate) const SHOW_FOR_RUNS_OVER: Duration = Duration::from_secs(2);

/// Wall time to measure before judging how long a run will take: the first steps of a run
/// (warming caches, the GPU's first submissions) are the slowest, and a single step of a fast
/// engine takes microseconds, too short to time alone.
pub(crate) const SAMPLE: Duration = Duration::from_millis(200);

/// Whether a run that has taken `elapsed` for `done` of its `total` steps is expected to take
/// longer than [`SHOW_FOR_RUNS_OVER`]; `None` while too little of it has run to tell.
pub(crate) fn expected_long(elapsed: Duration, done: u64, total: u64) -> Option<bool> {
    if elapsed >= SHOW_FOR_RUNS_OVER {
        return Some(done < total);
    }
    if elapsed < SAMPLE || done == 0 {
        return None;
    }
    let expected = elapsed.as_secs_f64() * total as f64 / done as f64;
    Some(expected > SHOW_FOR_RUNS_OVER.as_secs_f64())
}

/// A progress bar on stderr that appears once a run is expected to take longer than
/// [`SHOW_FOR_RUNS_OVER`], estimated from its first steps; never under `--json`, nor when
/// stderr is not a terminal (indicatif checks that).
pub(crate) struct RunProgress {
    bar: ProgressBar,
    start: Instant,
    /// Whether the bar may still appear: not yet shown, and not under `--json`.
    pending: bool,
}

impl RunProgress {
    /// A hidden bar for a run of `steps` steps named `name`.
    pub(crate) fn new(name: &str, steps: u64, json: bool) -> Self {
        let bar = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} steps, eta {eta}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        bar.set_message(name.to_string());
        RunProgress {
            bar,
            start: Instant::now(),
            pending: !json,
        }
    }

    /// `done` of `total` steps have run.
    pub(crate) fn update(&mut self, done: u64, total: u64) {
        // Judged short, or too early to tell, the run is judged again at the next update,
        // since a run can slow down (cuts add nodes); a clock reading costs far less than a
        // step.
        if self.pending && expected_long(self.start.elapsed(), done, total) == Some(true) {
            self.pending = false;
            self.bar.set_length(total);
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
        }
        self.bar.set_position(done);
    }

    /// Clear the bar, if it was shown.
    pub(crate) fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    /// The bar once showed for 2,000 steps or more, whatever they took: a 15 s scene of 500
    /// slow steps showed none, and a 0.1 s run of 100,000 fast steps showed one.
    #[test]
    fn the_bar_follows_the_expected_run_time_not_the_step_count() {
        // 10 of 500 steps in 0.3 s: about 15 s to go.
        assert_eq!(expected_long(ms(300), 10, 500), Some(true));
        // 50,000 of 100,000 steps in 0.3 s: 0.6 s in all.
        assert_eq!(expected_long(ms(300), 50_000, 100_000), Some(false));
        // Too early to tell: the first few milliseconds say little.
        assert_eq!(expected_long(ms(5), 1, 500), None);
        // Already past the threshold: shown while steps remain.
        assert_eq!(expected_long(ms(2500), 90, 100), Some(true));
    }
}

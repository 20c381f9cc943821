//! The command line, scene files (reading, validation, runs, output series) and reports.
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour, named as the file it was.

#[path = "../../../tests/common/mod.rs"]
mod common;

mod cli;
mod cli_bench;
mod cli_report_accuracy;
mod cli_summary;
mod cut_time_step;
mod inverted_tets;
mod output_series;
mod render_cli;
mod report_accuracy;
mod scene_validation;
mod scenes;

/// The repository root: the scene fixtures and the library's files live there, beside `cli/`.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

//! Benchmarks and accuracy reports from Python: what `lancet bench` and `lancet report
//! accuracy` measure, as the dicts their `--json` prints, so that a sweep can run layout
//! benchmarks and accuracy ladders as it runs scenes.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyDict;

use lancet::layout::LayoutKind;
use lancet::report::accuracy::{scene_accuracy, AccuracyOptions};
use lancet::report::bandwidth;
use lancet::report::bench::{run_bench, BenchMesh, BenchOptions, Preset};

use crate::world::{engine_kind, integrator as parse_integrator};
use crate::{apply_overrides, load_scene, py_err, to_python, value_err};

/// `"connectivity"`, `"valence"`, `"edges"`.
fn layout_kind(name: &str) -> PyResult<LayoutKind> {
    match name.to_ascii_lowercase().as_str() {
        "connectivity" => Ok(LayoutKind::Connectivity),
        "valence" => Ok(LayoutKind::Valence),
        "edges" => Ok(LayoutKind::Edges),
        _ => Err(value_err(format!(
            "layout `{name}`: choose connectivity, valence or edges"
        ))),
    }
}

fn parse_all<T>(names: &[String], parse: fn(&str) -> PyResult<T>) -> PyResult<Vec<T>> {
    names.iter().map(|n| parse(n)).collect()
}

/// Time the engines and GPU layouts on generated cubes (`cubes`: cells per side, 1 cm cells,
/// six tets each) or on the peers' `preset` (`"damped"` or `"undamped"`, its two boxes), as
/// `lancet bench --json` does: `{"bandwidth": ..., "rows": [...], "skipped": [...]}`, each row
/// with ms per step, bytes per step, the achieved bandwidth and its share of the STREAM floor,
/// and the error against the float64 engine. GPU rows without an adapter are in `skipped`.
#[pyfunction]
#[pyo3(signature = (cubes=None, engines=None, layouts=None, steps=200, integrator=None, preset=None))]
pub(crate) fn bench<'py>(
    py: Python<'py>,
    cubes: Option<Vec<usize>>,
    engines: Option<Vec<String>>,
    layouts: Option<Vec<String>>,
    steps: u64,
    integrator: Option<&str>,
    preset: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut opts = BenchOptions::default();
    if let Some(e) = engines {
        opts.engines = parse_all(&e, engine_kind)?;
    }
    if let Some(l) = layouts {
        opts.layouts = parse_all(&l, layout_kind)?;
    }
    if steps == 0 {
        return Err(value_err("steps must be at least 1"));
    }
    opts.steps = steps;
    opts.chunk = opts.chunk.min(steps);
    if let Some(i) = integrator {
        opts.integrator = parse_integrator(i)?;
    }
    opts.preset = match preset.map(str::to_ascii_lowercase).as_deref() {
        None => None,
        Some("damped") => Some(Preset::Damped),
        Some("undamped") => Some(Preset::Undamped),
        Some(p) => {
            return Err(value_err(format!(
                "preset `{p}`: choose damped or undamped"
            )))
        }
    };
    let meshes: Vec<BenchMesh> = match (&cubes, opts.preset) {
        (Some(c), _) => c.iter().map(|&n| BenchMesh::Cube(n)).collect(),
        (None, Some(_)) => Preset::meshes(Default::default()),
        (None, None) => vec![BenchMesh::Cube(8)],
    };
    if meshes.iter().any(|m| matches!(m, BenchMesh::Cube(0))) {
        return Err(value_err("a cube needs at least one cell per side"));
    }
    // The GIL is released while the engines run, as for scenes.
    let (bw, report) = py
        .detach(|| {
            // 2^24 doubles per array (128 MiB), as the CLI measures the floor.
            let bw = bandwidth::stream_triad(1 << 24, 5);
            run_bench(&meshes, &opts, &bw, || None).map(|r| (bw, r))
        })
        .map_err(py_err)?;
    let out = PyDict::new(py);
    out.set_item("bandwidth", to_python(py, &bw)?)?;
    out.set_item("rows", to_python(py, &report.rows)?)?;
    out.set_item("skipped", to_python(py, &report.skipped)?)?;
    Ok(out.into_any())
}

/// Error against run time on a scene, as `lancet report accuracy --json` gives it: each engine
/// and layout at each rung of `ladder` (fractions of the stable bound) and, with
/// `implicit_ladder` (multiples of it), backward Euler beside them, against a converged
/// reference. `path` None is the embedded default scene; `overrides` as for `run_scene` (the
/// run lasts the scene's `steps` at its step: `overrides={"steps": 400}` shortens it).
#[pyfunction]
#[pyo3(signature = (path=None, overrides=None, engines=None, layouts=None, ladder=None, implicit_ladder=None))]
pub(crate) fn accuracy<'py>(
    py: Python<'py>,
    path: Option<PathBuf>,
    overrides: Option<&Bound<'py, PyDict>>,
    engines: Option<Vec<String>>,
    layouts: Option<Vec<String>>,
    ladder: Option<Vec<f64>>,
    implicit_ladder: Option<Vec<f64>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (scene, scene_path) = load_scene(path)?;
    let scene = apply_overrides(py, &scene, &scene_path, overrides)?;
    let mut opts = AccuracyOptions::default();
    if let Some(e) = engines {
        opts.engines = parse_all(&e, engine_kind)?;
    }
    if let Some(l) = layouts {
        opts.layouts = parse_all(&l, layout_kind)?;
    }
    if let Some(l) = ladder {
        if l.iter().any(|&f| !(f > 0.0 && f <= 1.0)) {
            return Err(value_err(format!(
                "ladder {l:?}: each rung is a fraction of the stable bound in (0, 1]"
            )));
        }
        opts.ladder = l;
    }
    if let Some(l) = implicit_ladder {
        if l.iter().any(|&f| !(f.is_finite() && f > 0.0)) {
            return Err(value_err(format!(
                "implicit ladder {l:?}: each rung is a positive multiple of the stable bound"
            )));
        }
        opts.implicit_ladder = l;
    }
    let report = py
        .detach(|| scene_accuracy(&scene, &scene_path, &opts, |_| {}))
        .map_err(py_err)?;
    to_python(py, &report)
}

//! The `lancet._lancet` extension module: scenes, meshes and worlds for Python. The Python
//! package `lancet` (in `lancet/`) re-exports it and adds sweeps (`lancet.sweep`).
//!
//! Errors of the library are raised as `lancet.LancetError` with the library's message (file,
//! line and element, or step and node, and what to do); bad arguments as `ValueError`.

use std::path::{Path, PathBuf};

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use lancet::scene::{run_scene as run, RunOptions, Scene};

mod reports;
mod world;

create_exception!(
    _lancet,
    LancetError,
    PyException,
    "An error reported by lancet."
);

/// A library error as a Python exception.
pub(crate) fn py_err(e: lancet::Error) -> PyErr {
    LancetError::new_err(e.to_string())
}

/// A bad argument.
pub(crate) fn value_err(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// `json` (a serde value) as the Python object `json.loads` would give.
pub(crate) fn to_python<'py>(
    py: Python<'py>,
    value: &impl serde::Serialize,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| value_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// The scene at `path` (None: the embedded default scene) and the path naming it.
fn load_scene(path: Option<PathBuf>) -> PyResult<(Scene, PathBuf)> {
    match path {
        None => Ok((
            Scene::default_scene(),
            PathBuf::from("<embedded default scene>"),
        )),
        Some(p) => Ok((Scene::read(&p).map_err(py_err)?, p)),
    }
}

/// Apply `overrides` (dotted field paths to JSON-able values, e.g. `{"steps": 200,
/// "material.density": 1100.0, "dt": {"Seconds": 1e-4}}`) to `scene` through its serde form,
/// so that every scene field can be swept; a path that names no field is an error.
pub(crate) fn apply_overrides(
    py: Python<'_>,
    scene: &Scene,
    path: &Path,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<Scene> {
    let Some(overrides) = overrides.filter(|o| !o.is_empty()) else {
        return Ok(scene.clone());
    };
    let mut value = serde_json::to_value(scene).map_err(|e| value_err(e.to_string()))?;
    let dumps = py.import("json")?.getattr("dumps")?;
    for (key, v) in overrides.iter() {
        let key: String = key.extract()?;
        let text: String = dumps.call1((v,))?.extract()?;
        let new: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| value_err(e.to_string()))?;
        let mut at = &mut value;
        for part in key.split('.') {
            at = at
                .get_mut(part)
                .ok_or_else(|| value_err(format!("override `{key}`: the scene has no `{part}`")))?;
        }
        *at = new;
    }
    let scene: Scene = serde_json::from_value(value)
        .map_err(|e| value_err(format!("overrides {overrides}: {e}")))?;
    // The checks `Scene::read` makes, on the changed scene.
    scene.validate_tools(path).map_err(py_err)?;
    scene.validate_cut(path).map_err(py_err)?;
    scene.validate_time_step(path).map_err(py_err)?;
    scene.validate_fixed(path).map_err(py_err)?;
    scene.validate_expectations(path).map_err(py_err)?;
    Ok(scene)
}

/// Run a scene with its expectations, as `lancet run --json` does, and return its summary as
/// a dict (`expectations_passed`, `steps`, `max_displacement`, `energy`, `tools`, `cuts`, ...).
///
/// `path`: a scene file (None: the embedded default scene). `overrides`: scene fields to
/// change, by dotted path (see `lancet.sweep`). `engine` (`"auto"`, `"reference"`,
/// `"fast"`, `"gpu"`), `steps`, `cut_method`: as the CLI's options. Frames are written only to
/// `output_dir` when given.
#[pyfunction]
#[pyo3(signature = (path=None, overrides=None, engine=None, steps=None, cut_method=None, output_dir=None))]
fn run_scene<'py>(
    py: Python<'py>,
    path: Option<PathBuf>,
    overrides: Option<&Bound<'py, PyDict>>,
    engine: Option<&str>,
    steps: Option<u64>,
    cut_method: Option<&str>,
    output_dir: Option<PathBuf>,
) -> PyResult<Bound<'py, PyAny>> {
    let (scene, scene_path) = load_scene(path)?;
    let scene = apply_overrides(py, &scene, &scene_path, overrides)?;
    let opts = RunOptions {
        engine: engine.map(world::engine_kind).transpose()?,
        steps,
        cut_method: cut_method.map(world::cut_method).transpose()?,
        no_output: output_dir.is_none(),
        output_dir,
        ..RunOptions::default()
    };
    // The GIL is released while the scene runs, so that other Python threads go on.
    let summary = py
        .detach(|| run(&scene, &scene_path, &opts, |_, _| {}))
        .map_err(py_err)?;
    to_python(py, &summary)
}

/// A tetrahedral mesh read from a file (Gmsh 1/2.2/4.1, TetGen, Medit, Vega, VTK, VTU).
#[pyclass(module = "lancet")]
struct Mesh {
    mesh: lancet::TetMesh,
}

#[pymethods]
impl Mesh {
    /// Node coordinates, an (n, 3) float64 array in the mesh's node order.
    #[getter]
    fn nodes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat: Vec<f64> = self
            .mesh
            .nodes()
            .flat_map(|(_, node)| [node.rest.x, node.rest.y, node.rest.z])
            .collect();
        let n = flat.len() / 3;
        PyArray1::from_vec(py, flat).reshape([n, 3])
    }

    /// Tets, an (m, 4) uint32 array of node indices into `nodes`.
    #[getter]
    fn tets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let dense = self.mesh.dense_nodes();
        let flat: Vec<u32> = self
            .mesh
            .tets()
            .flat_map(|(_, t)| t.nodes.map(|k| dense.index[k]))
            .collect();
        let m = flat.len() / 4;
        PyArray1::from_vec(py, flat).reshape([m, 4])
    }

    /// Number of nodes.
    #[getter]
    fn node_count(&self) -> usize {
        self.mesh.node_count()
    }

    /// Number of tets.
    #[getter]
    fn tet_count(&self) -> usize {
        self.mesh.tet_count()
    }

    /// Volume of the mesh, m^3.
    #[getter]
    fn volume(&self) -> f64 {
        self.mesh.volume()
    }

    fn __repr__(&self) -> String {
        format!(
            "Mesh({} nodes, {} tets)",
            self.mesh.node_count(),
            self.mesh.tet_count()
        )
    }
}

/// Read a tetrahedral mesh file (by extension).
#[pyfunction]
fn read_mesh(path: PathBuf) -> PyResult<Mesh> {
    Ok(Mesh {
        mesh: lancet::mesh::io::read(&path).map_err(py_err)?.mesh,
    })
}

#[pymodule]
fn _lancet(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("LancetError", m.py().get_type::<LancetError>())?;
    m.add_function(wrap_pyfunction!(run_scene, m)?)?;
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(reports::bench, m)?)?;
    m.add_function(wrap_pyfunction!(reports::accuracy, m)?)?;
    m.add_class::<Mesh>()?;
    m.add_class::<world::World>()?;
    Ok(())
}

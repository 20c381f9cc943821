//! `lancet.World`: the tissue, its tools, cutting and contact, stepped together
//! (`lancet::world::World`). Each step: pose the tools (or a coupled device), `step()`, read
//! the forces and `positions`.

use std::path::PathBuf;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use lancet::collide::ToolShape;
use lancet::cut::CutMethod;
use lancet::engine::{EngineKind, Integrator, SimConfig};
use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::mesh::TetMesh;
use lancet::model::{FixedSelector, Material, ModelConfig};
use lancet::scene::RunOptions;
use lancet::world::{CutSettings, ToolHandle, VirtualCoupling, WorldBuilder};

use crate::{apply_overrides, load_scene, py_err, to_python, value_err};

/// `"auto"`, `"reference"`, `"fast"`, `"gpu"`.
pub(crate) fn engine_kind(name: &str) -> PyResult<EngineKind> {
    match name.to_ascii_lowercase().as_str() {
        "auto" => Ok(EngineKind::Auto),
        "reference" => Ok(EngineKind::Reference),
        "fast" | "cpu" => Ok(EngineKind::Fast),
        "gpu" => Ok(EngineKind::Gpu),
        _ => Err(value_err(format!(
            "engine `{name}`: choose auto, reference, fast or gpu"
        ))),
    }
}

/// `"remove"`, `"separate"`, `"subdivide"`.
pub(crate) fn cut_method(name: &str) -> PyResult<CutMethod> {
    match name.to_ascii_lowercase().as_str() {
        "remove" => Ok(CutMethod::Remove),
        "separate" => Ok(CutMethod::Separate),
        "subdivide" => Ok(CutMethod::Subdivide),
        _ => Err(value_err(format!(
            "cut method `{name}`: choose remove, separate or subdivide"
        ))),
    }
}

/// `"verlet"`, `"symplectic_euler"`, `"backward_euler"`.
pub(crate) fn integrator(name: &str) -> PyResult<Integrator> {
    match name.to_ascii_lowercase().replace(['_', '-'], "").as_str() {
        "verlet" => Ok(Integrator::Verlet),
        "symplecticeuler" => Ok(Integrator::SymplecticEuler),
        "backwardeuler" => Ok(Integrator::BackwardEuler),
        _ => Err(value_err(format!(
            "integrator `{name}`: choose verlet, symplectic_euler or backward_euler"
        ))),
    }
}

/// A pose from a position (m) and a quaternion `w, x, y, z`.
fn pose(position: [f64; 3], rotation: [f64; 4]) -> PyResult<Isometry3<f64>> {
    let [w, x, y, z] = rotation;
    let q = Quaternion::new(w, x, y, z);
    if !position.iter().chain(&rotation).all(|c| c.is_finite()) || q.norm() < 1e-12 {
        return Err(value_err(format!(
            "pose {position:?} / {rotation:?}: a finite position and a nonzero quaternion \
             (w, x, y, z) are needed"
        )));
    }
    Ok(Isometry3::from_parts(
        Translation3::from(Vector3::from(position)),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// The tissue, its tools, cutting and contact, stepped together. Make one with
/// `World.box(...)`, `World.from_mesh(...)` or `World.from_scene(...)`.
#[pyclass(module = "lancet", unsendable)]
pub(crate) struct World {
    world: lancet::world::World,
}

/// The material and time-stepping arguments shared by `box` and `from_mesh`.
struct Setup {
    youngs_modulus: f64,
    poisson_ratio: f64,
    density: f64,
    gravity: [f64; 3],
    mass_damping: f64,
    fixed_box: Option<([f64; 3], [f64; 3])>,
    engine: String,
    integrator: String,
    dt: Option<f64>,
    bound_fraction: f64,
}

impl Setup {
    fn build(self, mesh: TetMesh) -> PyResult<World> {
        let mut model = ModelConfig::new(Material::elastic(
            self.youngs_modulus,
            self.poisson_ratio,
            self.density,
        ));
        model.gravity = self.gravity;
        model.mass_damping = self.mass_damping;
        if let Some((min, max)) = self.fixed_box {
            model.fixed.push(FixedSelector::Box { min, max });
        }
        let mut config = SimConfig::new(self.dt.unwrap_or(1.0));
        config.integrator = integrator(&self.integrator)?;
        let mut builder = WorldBuilder::new(mesh, &model, config)
            .map_err(py_err)?
            .engine(engine_kind(&self.engine)?);
        if self.dt.is_none() {
            builder = builder
                .bound_fraction(self.bound_fraction)
                .map_err(py_err)?;
        }
        Ok(World {
            world: builder.build().map_err(py_err)?,
        })
    }
}

impl World {
    fn handle(&self, tool: usize) -> PyResult<ToolHandle> {
        self.world.tool_handle(tool).ok_or_else(|| {
            value_err(format!(
                "tool {tool} does not exist: the world has {} tools",
                self.world.tools().len()
            ))
        })
    }
}

#[pymethods]
impl World {
    /// A box of `size` (m) from the origin, `cells` cubes each split into five tets, of a
    /// linear-elastic material; nodes in `fixed_box` (`(min, max)` corners) held at rest.
    /// `dt` in seconds, or None for `bound_fraction` of the stable bound.
    #[staticmethod]
    #[pyo3(name = "box", signature = (size, cells, youngs_modulus=10e3, poisson_ratio=0.3, density=1000.0, gravity=[0.0, 0.0, -9.81], mass_damping=0.0, fixed_box=None, engine="auto", integrator="verlet", dt=None, bound_fraction=0.9))]
    #[allow(clippy::too_many_arguments)]
    fn new_box(
        size: [f64; 3],
        cells: [usize; 3],
        youngs_modulus: f64,
        poisson_ratio: f64,
        density: f64,
        gravity: [f64; 3],
        mass_damping: f64,
        fixed_box: Option<([f64; 3], [f64; 3])>,
        engine: &str,
        integrator: &str,
        dt: Option<f64>,
        bound_fraction: f64,
    ) -> PyResult<World> {
        let mesh = BoxGrid {
            cells,
            size,
            origin: [0.0; 3],
            split: Default::default(),
        }
        .build()
        .map_err(py_err)?;
        Setup {
            youngs_modulus,
            poisson_ratio,
            density,
            gravity,
            mass_damping,
            fixed_box,
            engine: engine.into(),
            integrator: integrator.into(),
            dt,
            bound_fraction,
        }
        .build(mesh)
    }

    /// The mass-spring benchmark of `lancet bench --preset` (the one `benches/peers/` runs in
    /// Taichi and Warp): a box of `cells` cells of 5 cm (`"small"`: 40x20x20, `"large"`:
    /// 72x36x36, or three counts) split into five tets (`split="six"`: six), springs of 5e4
    /// N/m on the tet edges with 5 N s/m along each (`preset="undamped"`: none), 0.125 kg a
    /// node, the face x = 0 fixed, gravity, 2e-4 s steps of symplectic Euler. `cells`
    /// defaults to `"large"`; `engine` is `"fast"` (the default), `"reference"`, `"gpu"` or
    /// `"auto"`. Names are read in any case.
    #[staticmethod]
    #[pyo3(signature = (preset="damped", cells=None, split="five", engine="fast"))]
    fn preset(
        preset: &str,
        cells: Option<&Bound<'_, PyAny>>,
        split: &str,
        engine: &str,
    ) -> PyResult<World> {
        use lancet::report::bench::Preset;
        let preset = match preset.to_ascii_lowercase().as_str() {
            "damped" => Preset::Damped,
            "undamped" => Preset::Undamped,
            _ => {
                return Err(value_err(format!(
                    "preset `{preset}`: choose damped or undamped"
                )))
            }
        };
        let cells: [usize; 3] = match cells {
            None => Preset::GRIDS[1],
            Some(c) => match c.extract::<String>() {
                Ok(name) => match name.to_ascii_lowercase().as_str() {
                    "small" => Preset::GRIDS[0],
                    "large" => Preset::GRIDS[1],
                    _ => {
                        return Err(value_err(format!(
                            "cells `{name}`: choose small, large or three cell counts"
                        )))
                    }
                },
                Err(_) => c.extract().map_err(|_| {
                    value_err("cells: \"small\", \"large\" or three cell counts, such as (8, 4, 4)")
                })?,
            },
        };
        let split = match split.to_ascii_lowercase().as_str() {
            "five" => TetSplit::Five,
            "six" => TetSplit::Six,
            _ => return Err(value_err(format!("split `{split}`: choose five or six"))),
        };
        let mesh = BoxGrid {
            split,
            ..BoxGrid::cube_cells(cells, Preset::CELL)
        }
        .build()
        .map_err(py_err)?;
        let model = preset.model_config(&mesh);
        let world = WorldBuilder::new(mesh, &model, Preset::sim_config())
            .map_err(py_err)?
            .engine(engine_kind(engine)?)
            .build()
            .map_err(py_err)?;
        Ok(World { world })
    }

    /// A world of a tetrahedral mesh file, with the arguments of `World.box`.
    #[staticmethod]
    #[pyo3(signature = (path, youngs_modulus=10e3, poisson_ratio=0.3, density=1000.0, gravity=[0.0, 0.0, -9.81], mass_damping=0.0, fixed_box=None, engine="auto", integrator="verlet", dt=None, bound_fraction=0.9))]
    #[allow(clippy::too_many_arguments)]
    fn from_mesh(
        path: PathBuf,
        youngs_modulus: f64,
        poisson_ratio: f64,
        density: f64,
        gravity: [f64; 3],
        mass_damping: f64,
        fixed_box: Option<([f64; 3], [f64; 3])>,
        engine: &str,
        integrator: &str,
        dt: Option<f64>,
        bound_fraction: f64,
    ) -> PyResult<World> {
        let mesh = lancet::mesh::io::read(&path).map_err(py_err)?.mesh;
        Setup {
            youngs_modulus,
            poisson_ratio,
            density,
            gravity,
            mass_damping,
            fixed_box,
            engine: engine.into(),
            integrator: integrator.into(),
            dt,
            bound_fraction,
        }
        .build(mesh)
    }

    /// The world of a scene file (None: the embedded default scene), with `overrides` as in
    /// `run_scene`: mesh, material, time step, tools at their first pose, cutting, contact.
    /// The scene's trajectories are not played: pose the tools yourself.
    #[staticmethod]
    #[pyo3(signature = (path=None, overrides=None, engine=None))]
    fn from_scene(
        py: Python<'_>,
        path: Option<PathBuf>,
        overrides: Option<&Bound<'_, PyDict>>,
        engine: Option<&str>,
    ) -> PyResult<World> {
        let (scene, scene_path) = load_scene(path)?;
        let scene = apply_overrides(py, &scene, &scene_path, overrides)?;
        let opts = RunOptions {
            engine: engine.map(engine_kind).transpose()?,
            no_output: true,
            ..RunOptions::default()
        };
        Ok(World {
            world: lancet::world::World::from_scene(&scene, &scene_path, &opts).map_err(py_err)?,
        })
    }

    /// Add a tool: `kind` is `"probe"` (radius, length), `"sphere"` (radius), `"blade"`
    /// (width, length, thickness) or `"grasper"` (jaw half-extents, opening); at `position`
    /// with `rotation` (w, x, y, z). Returns its index.
    #[pyo3(signature = (name, kind, position, rotation=[1.0, 0.0, 0.0, 0.0], radius=0.0, length=0.0, width=0.0, thickness=0.0, jaw=[0.0; 3], opening=0.0))]
    #[allow(clippy::too_many_arguments)]
    fn add_tool(
        &mut self,
        name: &str,
        kind: &str,
        position: [f64; 3],
        rotation: [f64; 4],
        radius: f64,
        length: f64,
        width: f64,
        thickness: f64,
        jaw: [f64; 3],
        opening: f64,
    ) -> PyResult<usize> {
        let shape = match kind.to_ascii_lowercase().as_str() {
            "probe" | "needle" => ToolShape::Probe { radius, length },
            "sphere" => ToolShape::Sphere { radius },
            "blade" => ToolShape::Blade {
                width,
                length,
                thickness,
            },
            "grasper" => ToolShape::Grasper { jaw, opening },
            _ => {
                return Err(value_err(format!(
                    "tool kind `{kind}`: choose probe, sphere, blade or grasper"
                )))
            }
        };
        let h = self
            .world
            .add_tool(name, shape, pose(position, rotation)?)
            .map_err(py_err)?;
        Ok(h.index())
    }

    /// Set tool `tool`'s pose for the end of the next step.
    #[pyo3(signature = (tool, position, rotation=[1.0, 0.0, 0.0, 0.0]))]
    fn set_tool_pose(
        &mut self,
        tool: usize,
        position: [f64; 3],
        rotation: [f64; 4],
    ) -> PyResult<()> {
        let h = self.handle(tool)?;
        self.world
            .set_tool_pose(h, pose(position, rotation)?)
            .map_err(py_err)
    }

    /// Couple tool `tool` to a haptic device by a spring-damper (N/m, N s/m, proxy kg); then
    /// set the device's pose with `set_device_pose` and render `step()["tools"][i]["rendered"]`.
    fn couple_tool(
        &mut self,
        tool: usize,
        stiffness: f64,
        damping: f64,
        proxy_mass: f64,
    ) -> PyResult<()> {
        let h = self.handle(tool)?;
        self.world
            .couple(
                h,
                VirtualCoupling {
                    stiffness,
                    damping,
                    proxy_mass,
                },
            )
            .map_err(py_err)
    }

    /// The haptic device's pose and velocity (m/s) for the coupled tool `tool`.
    #[pyo3(signature = (tool, position, rotation=[1.0, 0.0, 0.0, 0.0], velocity=[0.0; 3]))]
    fn set_device_pose(
        &mut self,
        tool: usize,
        position: [f64; 3],
        rotation: [f64; 4],
        velocity: [f64; 3],
    ) -> PyResult<()> {
        let h = self.handle(tool)?;
        self.world
            .set_device_pose(h, pose(position, rotation)?, Vector3::from(velocity))
            .map_err(py_err)
    }

    /// Cut with every blade from now on, by `method` (`"remove"`, `"separate"`,
    /// `"subdivide"`).
    #[pyo3(signature = (method="separate"))]
    fn enable_cutting(&mut self, method: &str) -> PyResult<()> {
        self.world
            .enable_cutting(CutSettings {
                method: cut_method(method)?,
                ..CutSettings::default()
            })
            .map_err(py_err)
    }

    /// Close grasper `tool` on the tissue within `reach` (m) of its jaws.
    fn grasp(&mut self, tool: usize, reach: f64) -> PyResult<()> {
        let h = self.handle(tool)?;
        self.world.grasp(h, reach).map_err(py_err)
    }

    /// Let go of what grasper `tool` holds.
    fn release(&mut self, tool: usize) -> PyResult<()> {
        let h = self.handle(tool)?;
        self.world.release(h).map_err(py_err)
    }

    /// Take one step (poses, step, cuts, grasps, contacts) and return what it did: a dict
    /// with `step`, `time`, `tools` (each `force`, `contacts`, `rendered`, ...), `cuts`,
    /// `contacts`, `deepest`.
    fn step<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let report = self.world.step().map_err(py_err)?;
        let out = PyDict::new(py);
        out.set_item("step", report.step)?;
        out.set_item("time", report.time)?;
        out.set_item("contacts", report.contacts)?;
        out.set_item("deepest", report.deepest)?;
        out.set_item("cuts", to_python(py, &report.cuts)?)?;
        let tools = report
            .tools
            .iter()
            .map(|t| {
                let d = PyDict::new(py);
                d.set_item("force", <[f64; 3]>::from(t.force))?;
                d.set_item("friction", <[f64; 3]>::from(t.friction))?;
                d.set_item("contacts", t.contacts)?;
                d.set_item("deepest", t.deepest)?;
                d.set_item("held", t.held)?;
                d.set_item("rendered", t.rendered.map(<[f64; 3]>::from))?;
                Ok(d)
            })
            .collect::<PyResult<Vec<_>>>()?;
        out.set_item("tools", tools)?;
        Ok(out.into_any())
    }

    /// Take `steps` steps with the tools where they are (the GIL released meanwhile).
    /// `check=False` leaves out the divergence and inversion checks, as `lancet bench` times
    /// the engines: for timing a world without tools or self-contact against other codes. A
    /// run that blew up meanwhile is then only reported by the next checked `run` or `step`.
    #[pyo3(signature = (steps, check=true))]
    fn run(&mut self, py: Python<'_>, steps: u64, check: bool) -> PyResult<()> {
        let world = &mut self.world;
        if check {
            return py.detach(|| world.run_with(steps, |_| {})).map_err(py_err);
        }
        if world.has_contacts() {
            return Err(value_err(
                "run(check=False) times the simulation alone, and this world has tools or \
                 self-contact: run it checked",
            ));
        }
        py.detach(|| {
            let mut left = steps;
            while left > 0 {
                let chunk = left.min(u32::MAX as u64) as u32;
                world.sim_mut().step_unchecked(chunk);
                left -= chunk as u64;
            }
        });
        Ok(())
    }

    /// Node positions now, an (n, 3) float64 array in the mesh's node order (cuts add nodes
    /// at the end). A new array each call, made without a further copy of lancet's read-back.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat = self.world.positions().into_flattened();
        let n = flat.len() / 3;
        PyArray1::from_vec(py, flat).reshape([n, 3])
    }

    /// Rest positions, an (n, 3) float64 array.
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat = self.world.model().rest.clone().into_flattened();
        let n = flat.len() / 3;
        PyArray1::from_vec(py, flat).reshape([n, 3])
    }

    /// Nodes now (cuts add nodes).
    #[getter]
    fn node_count(&self) -> usize {
        self.world.model().node_count()
    }

    /// Tets now.
    #[getter]
    fn tet_count(&self) -> usize {
        self.world.mesh().tet_count()
    }

    /// The time step, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.world.sim().config().dt
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self) -> f64 {
        self.world.sim().time()
    }

    /// The engine that runs (with its device for the GPU).
    #[getter]
    fn engine(&self) -> String {
        self.world.sim().engine_name()
    }

    /// Why the engine differs from the one asked for (no GPU for `"auto"`), or None.
    #[getter]
    fn engine_note(&self) -> Option<String> {
        self.world.sim().engine_note().map(str::to_string)
    }

    fn __repr__(&self) -> String {
        format!(
            "World({} nodes, {} tets, {} tools, dt {:e} s, {})",
            self.world.model().node_count(),
            self.world.mesh().tet_count(),
            self.world.tools().len(),
            self.world.sim().config().dt,
            self.world.sim().engine_name()
        )
    }
}

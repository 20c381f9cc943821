//! `LancetWorld`: the tissue, its tools, cutting and contact, stepped together
//! (`lancet::world::World`). Build one from a scene file, from a mesh file, or as a box; add
//! tools; then each step: set the tools' poses (or a coupled device's pose), step, read the
//! forces and the positions.

use std::ffi::c_char;

use lancet::collide::ToolShape;
use lancet::cut::CutMethod;
use lancet::engine::{EngineKind, Integrator, SimConfig};
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::TetMesh;
use lancet::model::{FixedSelector, Material, ModelConfig};
use lancet::scene::RunOptions;
use lancet::world::{CutSettings, StepReport, ToolHandle, VirtualCoupling, World, WorldBuilder};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::error::{guard, invalid, out, text, Failure, LancetStatus};

/// A world: opaque to the host.
pub struct LancetWorld {
    world: World,
    /// The last step's report, for the per-tool reads.
    last: Option<StepReport>,
}

/// Which engine steps the tissue.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LancetEngine {
    /// The GPU where one is usable, else the fast CPU engine (`lancet_world_engine_note` says
    /// why).
    Auto = 0,
    /// The float64 serial reference engine.
    Reference = 1,
    /// The fast float32 multi-threaded CPU engine.
    Fast = 2,
    /// The wgpu engine (an error without a usable adapter).
    Gpu = 3,
}

/// How time is integrated.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LancetIntegrator {
    /// Position Verlet (explicit; the default).
    Verlet = 0,
    /// Symplectic Euler (explicit).
    SymplecticEuler = 1,
    /// Linearised backward Euler with conjugate gradients (implicit: any step is stable).
    BackwardEuler = 2,
}

/// A linear-elastic material and the loads on it.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct LancetMaterial {
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson's ratio.
    pub poisson_ratio: f64,
    /// Density, kg/m^3.
    pub density: f64,
    /// Mass-proportional damping, 1/s (0: none).
    pub mass_damping: f64,
    /// Gravity, m/s^2.
    pub gravity: [f64; 3],
}

/// How the world steps and which nodes are held.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct LancetSettings {
    /// The engine.
    pub engine: LancetEngine,
    /// The integrator.
    pub integrator: LancetIntegrator,
    /// The time step, s; 0 to take `bound_fraction` of the stable bound instead.
    pub dt: f64,
    /// The fraction of the stable bound to step at when `dt` is 0 (e.g. 0.9).
    pub bound_fraction: f64,
    /// Nonzero: hold the nodes inside the box `fixed_min`..`fixed_max` (m) at rest.
    pub fix_box: u8,
    /// Smallest corner of the held box, m.
    pub fixed_min: [f64; 3],
    /// Largest corner of the held box, m.
    pub fixed_max: [f64; 3],
}

/// A pose: where a tool's frame is. The rotation is a unit quaternion `w, x, y, z`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct LancetPose {
    /// Position of the tool frame's origin, m.
    pub position: [f64; 3],
    /// Rotation, `w, x, y, z` (normalised on input).
    pub rotation: [f64; 4],
}

/// A tool's shape (see `lancet::collide::ToolShape` for each frame).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LancetToolKind {
    /// A capsule from the origin to `(0, 0, length)` of `radius`: a probe or needle.
    Probe = 0,
    /// A sphere of `radius` at the origin.
    Sphere = 1,
    /// A blade: the quad `|x| <= width/2`, `y = 0`, `0 <= z <= length`, `thickness` along y.
    Blade = 2,
    /// A grasper: two jaw boxes of half-extents `jaw`, `opening` apart along x.
    Grasper = 3,
}

/// A tool to add. Fields a kind does not use are ignored.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct LancetToolDesc {
    /// The shape.
    pub kind: LancetToolKind,
    /// Probe and sphere radius, m.
    pub radius: f64,
    /// Probe axis length; blade length, m.
    pub length: f64,
    /// Blade width, m.
    pub width: f64,
    /// Blade thickness, m.
    pub thickness: f64,
    /// Grasper jaw half-extents, m.
    pub jaw: [f64; 3],
    /// Grasper opening, m.
    pub opening: f64,
}

/// What one step did.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct LancetStepInfo {
    /// Steps taken so far.
    pub step: u64,
    /// Simulated time, s.
    pub time: f64,
    /// Cuts this step made.
    pub cuts: u32,
    /// Tissue nodes in contact with tools.
    pub contacts: u32,
    /// Deepest penetration resolved, m.
    pub deepest: f64,
    /// Nodes in the tissue now (cuts add nodes).
    pub nodes: u64,
}

/// How a blade cuts.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LancetCutMethod {
    /// Remove the tets the blade sweeps through.
    Remove = 0,
    /// Split along existing faces.
    Separate = 1,
    /// Subdivide the tets along the blade.
    Subdivide = 2,
}

fn engine_kind(e: LancetEngine) -> EngineKind {
    match e {
        LancetEngine::Auto => EngineKind::Auto,
        LancetEngine::Reference => EngineKind::Reference,
        LancetEngine::Fast => EngineKind::Fast,
        LancetEngine::Gpu => EngineKind::Gpu,
    }
}

fn pose_of(p: &LancetPose) -> Result<Isometry3<f64>, Failure> {
    let [w, x, y, z] = p.rotation;
    let q = Quaternion::new(w, x, y, z);
    let finite = p.position.iter().chain(&p.rotation).all(|c| c.is_finite());
    if !finite || q.norm() < 1e-12 {
        return Err(invalid(format!(
            "pose {:?} / {:?}: the position must be finite and the rotation a nonzero \
             quaternion w, x, y, z (identity: 1, 0, 0, 0)",
            p.position, p.rotation
        )));
    }
    Ok(Isometry3::from_parts(
        Translation3::from(Vector3::from(p.position)),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// Build a world of `mesh` with `material` and `settings`.
fn build(
    mesh: TetMesh,
    material: &LancetMaterial,
    settings: &LancetSettings,
) -> Result<World, Failure> {
    let mut config = ModelConfig::new(Material::elastic(
        material.youngs_modulus,
        material.poisson_ratio,
        material.density,
    ));
    config.gravity = material.gravity;
    config.mass_damping = material.mass_damping;
    if settings.fix_box != 0 {
        config.fixed.push(FixedSelector::Box {
            min: settings.fixed_min,
            max: settings.fixed_max,
        });
    }
    let mut sim = SimConfig::new(if settings.dt > 0.0 { settings.dt } else { 1.0 });
    sim.integrator = match settings.integrator {
        LancetIntegrator::Verlet => Integrator::Verlet,
        LancetIntegrator::SymplecticEuler => Integrator::SymplecticEuler,
        LancetIntegrator::BackwardEuler => Integrator::BackwardEuler,
    };
    let mut builder = WorldBuilder::new(mesh, &config, sim)?.engine(engine_kind(settings.engine));
    if settings.dt <= 0.0 {
        builder = builder.bound_fraction(settings.bound_fraction)?;
    }
    Ok(builder.build()?)
}

/// The material and settings arguments, refused when NULL.
///
/// # Safety
/// Each pointer is NULL or points to a valid value.
unsafe fn inputs<'a>(
    material: *const LancetMaterial,
    settings: *const LancetSettings,
) -> Result<(&'a LancetMaterial, &'a LancetSettings), Failure> {
    // SAFETY: the contract above.
    unsafe {
        Ok((
            material
                .as_ref()
                .ok_or_else(|| invalid("material is NULL"))?,
            settings
                .as_ref()
                .ok_or_else(|| invalid("settings is NULL"))?,
        ))
    }
}

fn finish(world: World, out_world: &mut *mut LancetWorld) {
    *out_world = Box::into_raw(Box::new(LancetWorld { world, last: None }));
}

/// A world from the scene file at `path` (NULL: the embedded default scene): its mesh,
/// material, engine, time step, fixed nodes, tools (named as in the scene, at their first
/// pose), cutting and contact. The scene's trajectories are not played: the host poses the
/// tools. Release with `lancet_world_free`.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string; `world` points to writable storage.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_from_scene(
    path: *const c_char,
    world: *mut *mut LancetWorld,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let slot = unsafe { out(world, "world") }?;
        *slot = std::ptr::null_mut();
        // SAFETY: the contract above.
        let (scene, scene_path) = unsafe { crate::scene::load_scene(path) }?;
        let w = World::from_scene(&scene, &scene_path, &RunOptions::default())?;
        finish(w, slot);
        Ok(())
    })
}

/// A world of the tetrahedral mesh file at `mesh_path` (Gmsh, TetGen, Medit, Vega, VTK, VTU:
/// by extension) with `material` and `settings`.
///
/// # Safety
/// `mesh_path` is a NUL-terminated string; `material`, `settings` point to valid values;
/// `world` points to writable storage.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_from_mesh_file(
    mesh_path: *const c_char,
    material: *const LancetMaterial,
    settings: *const LancetSettings,
    world: *mut *mut LancetWorld,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let (slot, path) = unsafe { (out(world, "world")?, text(mesh_path, "mesh_path")?) };
        *slot = std::ptr::null_mut();
        // SAFETY: the contract above.
        let (material, settings) = unsafe { inputs(material, settings) }?;
        let mesh = lancet::mesh::io::read(path)?.mesh;
        finish(build(mesh, material, settings)?, slot);
        Ok(())
    })
}

/// A world of a box `size` (m) with its smallest corner at the origin, of `cells` cubes each
/// split into five tets, with `material` and `settings`.
///
/// # Safety
/// `size` and `cells` point to three values each; `material`, `settings` to valid values;
/// `world` to writable storage.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_new_box(
    size: *const f64,
    cells: *const u32,
    material: *const LancetMaterial,
    settings: *const LancetSettings,
    world: *mut *mut LancetWorld,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let slot = unsafe { out(world, "world") }?;
        *slot = std::ptr::null_mut();
        if size.is_null() || cells.is_null() {
            return Err(invalid("size and cells must point to three values each"));
        }
        // SAFETY: the contract above: three values each.
        let (size, cells) = unsafe {
            (
                [*size, *size.add(1), *size.add(2)],
                [*cells, *cells.add(1), *cells.add(2)],
            )
        };
        // SAFETY: the contract above.
        let (material, settings) = unsafe { inputs(material, settings) }?;
        let mesh = BoxGrid {
            cells: cells.map(|c| c as usize),
            size,
            origin: [0.0; 3],
            split: Default::default(),
        }
        .build()?;
        finish(build(mesh, material, settings)?, slot);
        Ok(())
    })
}

/// Release a world; NULL is accepted.
///
/// # Safety
/// `world` is NULL or a world made by lancet and not yet released.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_free(world: *mut LancetWorld) {
    if !world.is_null() {
        // SAFETY: made by `Box::into_raw` in this library (the contract).
        drop(unsafe { Box::from_raw(world) });
    }
}

unsafe fn get<'a>(world: *mut LancetWorld) -> Result<&'a mut LancetWorld, Failure> {
    // SAFETY: a world made by lancet, used by one thread at a time (the contract).
    unsafe { world.as_mut() }.ok_or_else(|| invalid("world is NULL"))
}

fn handle(w: &LancetWorld, tool: u32) -> Result<ToolHandle, Failure> {
    w.world.tool_handle(tool as usize).ok_or_else(|| {
        invalid(format!(
            "tool {tool} does not exist: the world has {} tools",
            w.world.tools().len()
        ))
    })
}

/// Nodes of the tissue now (cuts add nodes); 0 for NULL.
///
/// # Safety
/// `world` is NULL or a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_node_count(world: *const LancetWorld) -> usize {
    // SAFETY: the contract above.
    unsafe { world.as_ref() }.map_or(0, |w| w.world.model().node_count())
}

/// Tets of the tissue now; 0 for NULL.
///
/// # Safety
/// `world` is NULL or a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_tet_count(world: *const LancetWorld) -> usize {
    // SAFETY: the contract above.
    unsafe { world.as_ref() }.map_or(0, |w| w.world.mesh().tet_count())
}

/// The time step, s (0 for NULL).
///
/// # Safety
/// `world` is NULL or a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_dt(world: *const LancetWorld) -> f64 {
    // SAFETY: the contract above.
    unsafe { world.as_ref() }.map_or(0.0, |w| w.world.sim().config().dt)
}

/// Copy the current node positions into `xyz` (`3 * node_count` doubles, x, y, z per node in
/// the mesh's node order). `len` is the number of doubles `xyz` holds.
///
/// # Safety
/// `world` is a live world; `xyz` points to `len` writable doubles.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_positions(
    world: *mut LancetWorld,
    xyz: *mut f64,
    len: usize,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        let x = w.world.positions();
        if xyz.is_null() || len < 3 * x.len() {
            return Err(invalid(format!(
                "positions need {} doubles (3 per node, {} nodes); got {len}{}",
                3 * x.len(),
                x.len(),
                if xyz.is_null() { " and NULL" } else { "" }
            )));
        }
        // SAFETY: `len` writable doubles (the contract), at least 3 * nodes.
        let dst = unsafe { std::slice::from_raw_parts_mut(xyz, 3 * x.len()) };
        for (d, p) in dst.chunks_exact_mut(3).zip(&x) {
            d.copy_from_slice(p);
        }
        Ok(())
    })
}

/// Add a tool named `name` of shape `desc` at `pose`; its index (0, 1, ... in the order
/// added) goes to `*tool`.
///
/// # Safety
/// `world` is a live world; `name` a NUL-terminated string; `desc`, `pose` valid; `tool`
/// writable.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_add_tool(
    world: *mut LancetWorld,
    name: *const c_char,
    desc: *const LancetToolDesc,
    pose: *const LancetPose,
    tool: *mut u32,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let (w, name, slot) = unsafe { (get(world)?, text(name, "name")?, out(tool, "tool")?) };
        // SAFETY: the contract above.
        let (desc, pose) = unsafe {
            (
                desc.as_ref().ok_or_else(|| invalid("desc is NULL"))?,
                pose.as_ref().ok_or_else(|| invalid("pose is NULL"))?,
            )
        };
        let shape = match desc.kind {
            LancetToolKind::Probe => ToolShape::Probe {
                radius: desc.radius,
                length: desc.length,
            },
            LancetToolKind::Sphere => ToolShape::Sphere {
                radius: desc.radius,
            },
            LancetToolKind::Blade => ToolShape::Blade {
                width: desc.width,
                length: desc.length,
                thickness: desc.thickness,
            },
            LancetToolKind::Grasper => ToolShape::Grasper {
                jaw: desc.jaw,
                opening: desc.opening,
            },
        };
        let h = w.world.add_tool(name, shape, pose_of(pose)?)?;
        *slot = h.index() as u32;
        Ok(())
    })
}

/// Set tool `tool`'s pose for the end of the next step.
///
/// # Safety
/// `world` is a live world; `pose` valid.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_set_tool_pose(
    world: *mut LancetWorld,
    tool: u32,
    pose: *const LancetPose,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        // SAFETY: the contract above.
        let pose = unsafe { pose.as_ref() }.ok_or_else(|| invalid("pose is NULL"))?;
        let h = handle(w, tool)?;
        w.world.set_tool_pose(h, pose_of(pose)?)?;
        Ok(())
    })
}

/// Couple tool `tool` to a haptic device by a spring-damper (`stiffness` N/m, `damping`
/// N s/m, proxy mass kg): from now on the host sets the device's pose with
/// `lancet_world_set_device_pose` and sends `lancet_world_tool_rendered_force` to the device.
///
/// # Safety
/// `world` is a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_couple_tool(
    world: *mut LancetWorld,
    tool: u32,
    stiffness: f64,
    damping: f64,
    proxy_mass: f64,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        let h = handle(w, tool)?;
        w.world.couple(
            h,
            VirtualCoupling {
                stiffness,
                damping,
                proxy_mass,
            },
        )?;
        Ok(())
    })
}

/// The haptic device's pose and linear velocity (m/s, three doubles; NULL for zero) for the
/// coupled tool `tool`.
///
/// # Safety
/// `world` is a live world; `pose` valid; `velocity` NULL or three doubles.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_set_device_pose(
    world: *mut LancetWorld,
    tool: u32,
    pose: *const LancetPose,
    velocity: *const f64,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        // SAFETY: the contract above.
        let pose = unsafe { pose.as_ref() }.ok_or_else(|| invalid("pose is NULL"))?;
        let v = if velocity.is_null() {
            Vector3::zeros()
        } else {
            // SAFETY: three doubles (the contract).
            unsafe { Vector3::new(*velocity, *velocity.add(1), *velocity.add(2)) }
        };
        let h = handle(w, tool)?;
        w.world.set_device_pose(h, pose_of(pose)?, v)?;
        Ok(())
    })
}

/// Cut with every blade tool from now on, by `method`.
///
/// # Safety
/// `world` is a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_enable_cutting(
    world: *mut LancetWorld,
    method: LancetCutMethod,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        let method = match method {
            LancetCutMethod::Remove => CutMethod::Remove,
            LancetCutMethod::Separate => CutMethod::Separate,
            LancetCutMethod::Subdivide => CutMethod::Subdivide,
        };
        w.world.enable_cutting(CutSettings {
            method,
            ..CutSettings::default()
        })?;
        Ok(())
    })
}

/// Close grasper `tool` on the tissue within `reach` (m) of its jaws; it carries what it
/// holds until `lancet_world_release`.
///
/// # Safety
/// `world` is a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_grasp(
    world: *mut LancetWorld,
    tool: u32,
    reach: f64,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        let h = handle(w, tool)?;
        w.world.grasp(h, reach)?;
        Ok(())
    })
}

/// Let go of what grasper `tool` holds.
///
/// # Safety
/// `world` is a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_release(world: *mut LancetWorld, tool: u32) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        let h = handle(w, tool)?;
        w.world.release(h)?;
        Ok(())
    })
}

/// Take one step in the library's order (poses, step, cuts, grasps, contacts); what it did
/// goes to `*info` (NULL: not wanted).
///
/// # Safety
/// `world` is a live world; `info` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_step(
    world: *mut LancetWorld,
    info: *mut LancetStepInfo,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        let report = w.world.step()?;
        // SAFETY: the contract above.
        if let Some(info) = unsafe { info.as_mut() } {
            *info = LancetStepInfo {
                step: report.step,
                time: report.time,
                cuts: report.cuts.len() as u32,
                contacts: report.contacts as u32,
                deepest: report.deepest,
                nodes: w.world.model().node_count() as u64,
            };
        }
        w.last = Some(report);
        Ok(())
    })
}

/// Take `steps` steps (no tool poses change between them).
///
/// # Safety
/// `world` is a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_run(world: *mut LancetWorld, steps: u64) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let w = unsafe { get(world) }?;
        for _ in 0..steps {
            w.last = Some(w.world.step()?);
        }
        Ok(())
    })
}

/// The reaction force on tool `tool` at the last step (N, three doubles into `force`): what
/// the tissue pushed back with; zero before the first step.
///
/// # Safety
/// `world` is a live world; `force` three writable doubles.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_tool_force(
    world: *mut LancetWorld,
    tool: u32,
    force: *mut f64,
) -> LancetStatus {
    tool_vector(world, tool, force, |t| Some(t.force))
}

/// The force to render on the haptic device coupled to tool `tool` at the last step (N, three
/// doubles): the coupling's spring-damper force, which has no step-to-step jump beyond the
/// coupling's stiffness. `LANCET_STATUS_INVALID_ARGUMENT` if the tool is not coupled.
///
/// # Safety
/// `world` is a live world; `force` three writable doubles.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_tool_rendered_force(
    world: *mut LancetWorld,
    tool: u32,
    force: *mut f64,
) -> LancetStatus {
    tool_vector(world, tool, force, |t| t.rendered)
}

fn tool_vector(
    world: *mut LancetWorld,
    tool: u32,
    force: *mut f64,
    pick: impl Fn(&lancet::world::ToolStep) -> Option<Vector3<f64>>,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the callers' contract.
        let w = unsafe { get(world) }?;
        if force.is_null() {
            return Err(invalid("force is NULL"));
        }
        let h = handle(w, tool)?;
        let v = match &w.last {
            Some(report) => {
                let t = report
                    .tools
                    .get(h.index())
                    .ok_or_else(|| invalid(format!("tool {tool} was added after the last step")))?;
                pick(t).ok_or_else(|| invalid(format!("tool {tool} is not coupled to a device")))?
            }
            None => Vector3::zeros(),
        };
        // SAFETY: three writable doubles (the callers' contract).
        unsafe { std::ptr::copy_nonoverlapping(v.as_ptr(), force, 3) };
        Ok(())
    })
}

/// Why the engine differs from the one asked for (no GPU for `LANCET_ENGINE_AUTO`), as a
/// string to release with `lancet_string_free`; NULL when it does not.
///
/// # Safety
/// `world` is NULL or a live world.
#[no_mangle]
pub unsafe extern "C" fn lancet_world_engine_note(world: *const LancetWorld) -> *mut c_char {
    // SAFETY: the contract above.
    let note = unsafe { world.as_ref() }.and_then(|w| w.world.sim().engine_note());
    note.map_or(std::ptr::null_mut(), |n| {
        std::ffi::CString::new(n.replace('\0', " "))
            .unwrap_or_default()
            .into_raw()
    })
}

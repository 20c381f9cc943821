/* lancet: soft-tissue simulation with cutting. C ABI, generated from capi/src by cbindgen: do not edit. */

#ifndef LANCET_H
#define LANCET_H

#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

// What a call did. Anything but `LANCET_STATUS_OK` leaves a message for
// [`lancet_last_error`].
typedef enum LancetStatus {
  // Success.
  LANCET_STATUS_OK = 0,
  // A NULL pointer, a string that is not UTF-8, a handle or index out of range, an array
  // too short.
  LANCET_STATUS_INVALID_ARGUMENT = 1,
  // A file could not be read or written.
  LANCET_STATUS_IO = 2,
  // A mesh or scene file is malformed (the message names the file, line and element).
  LANCET_STATUS_PARSE = 3,
  // The model cannot be built or changed as asked (a material, a node out of range, ...).
  LANCET_STATUS_MODEL = 4,
  // The time step is above the explicit integrator's stable bound (the message gives the
  // bound), or a cut lowered the bound below it.
  LANCET_STATUS_UNSTABLE_TIME_STEP = 5,
  // The simulation diverged or a tet inverted (the message names the step and node or tet).
  LANCET_STATUS_DIVERGED = 6,
  // The GPU failed (device lost, out of memory).
  LANCET_STATUS_GPU = 7,
  // Not supported by this build or this combination of options.
  LANCET_STATUS_UNSUPPORTED = 8,
  // A bug inside lancet: a panic was caught (please report the message).
  LANCET_STATUS_PANIC = 9,
} LancetStatus;

// Which engine steps the tissue.
typedef enum LancetEngine {
  // The GPU where one is usable, else the fast CPU engine (`lancet_world_engine_note` says
  // why).
  LANCET_ENGINE_AUTO = 0,
  // The float64 serial reference engine.
  LANCET_ENGINE_REFERENCE = 1,
  // The fast float32 multi-threaded CPU engine.
  LANCET_ENGINE_FAST = 2,
  // The wgpu engine (an error without a usable adapter).
  LANCET_ENGINE_GPU = 3,
} LancetEngine;

// How time is integrated.
typedef enum LancetIntegrator {
  // Position Verlet (explicit; the default).
  LANCET_INTEGRATOR_VERLET = 0,
  // Symplectic Euler (explicit).
  LANCET_INTEGRATOR_SYMPLECTIC_EULER = 1,
  // Linearised backward Euler with conjugate gradients (implicit: any step is stable).
  LANCET_INTEGRATOR_BACKWARD_EULER = 2,
} LancetIntegrator;

// A tool's shape (see `lancet::collide::ToolShape` for each frame).
typedef enum LancetToolKind {
  // A capsule from the origin to `(0, 0, length)` of `radius`: a probe or needle.
  LANCET_TOOL_KIND_PROBE = 0,
  // A sphere of `radius` at the origin.
  LANCET_TOOL_KIND_SPHERE = 1,
  // A blade: the quad `|x| <= width/2`, `y = 0`, `0 <= z <= length`, `thickness` along y.
  LANCET_TOOL_KIND_BLADE = 2,
  // A grasper: two jaw boxes of half-extents `jaw`, `opening` apart along x.
  LANCET_TOOL_KIND_GRASPER = 3,
} LancetToolKind;

// How a blade cuts.
typedef enum LancetCutMethod {
  // Remove the tets the blade sweeps through.
  LANCET_CUT_METHOD_REMOVE = 0,
  // Split along existing faces.
  LANCET_CUT_METHOD_SEPARATE = 1,
  // Subdivide the tets along the blade.
  LANCET_CUT_METHOD_SUBDIVIDE = 2,
} LancetCutMethod;

// A world: opaque to the host.
typedef struct LancetWorld LancetWorld;

// A linear-elastic material and the loads on it.
typedef struct LancetMaterial {
  // Young's modulus, Pa.
  double youngs_modulus;
  // Poisson's ratio.
  double poisson_ratio;
  // Density, kg/m^3.
  double density;
  // Mass-proportional damping, 1/s (0: none).
  double mass_damping;
  // Gravity, m/s^2.
  double gravity[3];
} LancetMaterial;

// How the world steps and which nodes are held.
typedef struct LancetSettings {
  // The engine.
  enum LancetEngine engine;
  // The integrator.
  enum LancetIntegrator integrator;
  // The time step, s; 0 to take `bound_fraction` of the stable bound instead.
  double dt;
  // The fraction of the stable bound to step at when `dt` is 0 (e.g. 0.9).
  double bound_fraction;
  // Nonzero: hold the nodes inside the box `fixed_min`..`fixed_max` (m) at rest.
  uint8_t fix_box;
  // Smallest corner of the held box, m.
  double fixed_min[3];
  // Largest corner of the held box, m.
  double fixed_max[3];
} LancetSettings;

// A tool to add. Fields a kind does not use are ignored.
typedef struct LancetToolDesc {
  // The shape.
  enum LancetToolKind kind;
  // Probe and sphere radius, m.
  double radius;
  // Probe axis length; blade length, m.
  double length;
  // Blade width, m.
  double width;
  // Blade thickness, m.
  double thickness;
  // Grasper jaw half-extents, m.
  double jaw[3];
  // Grasper opening, m.
  double opening;
} LancetToolDesc;

// A pose: where a tool's frame is. The rotation is a unit quaternion `w, x, y, z`.
typedef struct LancetPose {
  // Position of the tool frame's origin, m.
  double position[3];
  // Rotation, `w, x, y, z` (normalised on input).
  double rotation[4];
} LancetPose;

// What one step did.
typedef struct LancetStepInfo {
  // Steps taken so far.
  uint64_t step;
  // Simulated time, s.
  double time;
  // Cuts this step made.
  uint32_t cuts;
  // Tissue nodes in contact with tools.
  uint32_t contacts;
  // Deepest penetration resolved, m.
  double deepest;
  // Nodes in the tissue now (cuts add nodes).
  uint64_t nodes;
} LancetStepInfo;

#ifdef __cplusplus
extern "C" {
#endif // __cplusplus

// The message of this thread's last failed call (empty if none failed yet). The pointer is
// valid until this thread's next failing call; copy it to keep it.
const char *lancet_last_error(void);

// The library's version, e.g. `"0.1.0"` (static storage).
const char *lancet_version(void);

// Release a string lancet returned (e.g. by `lancet_run_scene`); NULL is accepted.
//
// # Safety
// `s` is NULL or a string returned by lancet and not yet released.
void lancet_string_free(char *s);

// Run the scene file at `path` (NULL: the embedded default scene) with its expectations, and
// return its summary as JSON in `*summary_json` (release it with `lancet_string_free`). The
// status is `LANCET_STATUS_OK` when the run completed, whether or not its expectations held:
// read `"expectations_passed"` in the summary. Frames are written where the scene says.
//
// # Safety
// `path` is NULL or a NUL-terminated string; `summary_json` points to writable storage.
enum LancetStatus lancet_run_scene(const char *path, char **summary_json);

// A world from the scene file at `path` (NULL: the embedded default scene): its mesh,
// material, engine, time step, fixed nodes, tools (named as in the scene, at their first
// pose), cutting and contact. The scene's trajectories are not played: the host poses the
// tools. Release with `lancet_world_free`.
//
// # Safety
// `path` is NULL or a NUL-terminated string; `world` points to writable storage.
enum LancetStatus lancet_world_from_scene(const char *path, struct LancetWorld **world);

// A world of the tetrahedral mesh file at `mesh_path` (Gmsh, TetGen, Medit, Vega, VTK, VTU:
// by extension) with `material` and `settings`.
//
// # Safety
// `mesh_path` is a NUL-terminated string; `material`, `settings` point to valid values;
// `world` points to writable storage.
enum LancetStatus lancet_world_from_mesh_file(const char *mesh_path,
                                              const struct LancetMaterial *material,
                                              const struct LancetSettings *settings,
                                              struct LancetWorld **world);

// A world of a box `size` (m) with its smallest corner at the origin, of `cells` cubes each
// split into five tets, with `material` and `settings`.
//
// # Safety
// `size` and `cells` point to three values each; `material`, `settings` to valid values;
// `world` to writable storage.
enum LancetStatus lancet_world_new_box(const double *size,
                                       const uint32_t *cells,
                                       const struct LancetMaterial *material,
                                       const struct LancetSettings *settings,
                                       struct LancetWorld **world);

// Release a world; NULL is accepted.
//
// # Safety
// `world` is NULL or a world made by lancet and not yet released.
void lancet_world_free(struct LancetWorld *world);

// Nodes of the tissue now (cuts add nodes); 0 for NULL.
//
// # Safety
// `world` is NULL or a live world.
size_t lancet_world_node_count(const struct LancetWorld *world);

// Tets of the tissue now; 0 for NULL.
//
// # Safety
// `world` is NULL or a live world.
size_t lancet_world_tet_count(const struct LancetWorld *world);

// The time step, s (0 for NULL).
//
// # Safety
// `world` is NULL or a live world.
double lancet_world_dt(const struct LancetWorld *world);

// Copy the current node positions into `xyz` (`3 * node_count` doubles, x, y, z per node in
// the mesh's node order). `len` is the number of doubles `xyz` holds.
//
// # Safety
// `world` is a live world; `xyz` points to `len` writable doubles.
enum LancetStatus lancet_world_positions(struct LancetWorld *world, double *xyz, size_t len);

// Add a tool named `name` of shape `desc` at `pose`; its index (0, 1, ... in the order
// added) goes to `*tool`.
//
// # Safety
// `world` is a live world; `name` a NUL-terminated string; `desc`, `pose` valid; `tool`
// writable.
enum LancetStatus lancet_world_add_tool(struct LancetWorld *world,
                                        const char *name,
                                        const struct LancetToolDesc *desc,
                                        const struct LancetPose *pose,
                                        uint32_t *tool);

// Set tool `tool`'s pose for the end of the next step.
//
// # Safety
// `world` is a live world; `pose` valid.
enum LancetStatus lancet_world_set_tool_pose(struct LancetWorld *world,
                                             uint32_t tool,
                                             const struct LancetPose *pose);

// Couple tool `tool` to a haptic device by a spring-damper (`stiffness` N/m, `damping`
// N s/m, proxy mass kg): from now on the host sets the device's pose with
// `lancet_world_set_device_pose` and sends `lancet_world_tool_rendered_force` to the device.
//
// # Safety
// `world` is a live world.
enum LancetStatus lancet_world_couple_tool(struct LancetWorld *world,
                                           uint32_t tool,
                                           double stiffness,
                                           double damping,
                                           double proxy_mass);

// The haptic device's pose and linear velocity (m/s, three doubles; NULL for zero) for the
// coupled tool `tool`.
//
// # Safety
// `world` is a live world; `pose` valid; `velocity` NULL or three doubles.
enum LancetStatus lancet_world_set_device_pose(struct LancetWorld *world,
                                               uint32_t tool,
                                               const struct LancetPose *pose,
                                               const double *velocity);

// Cut with every blade tool from now on, by `method`.
//
// # Safety
// `world` is a live world.
enum LancetStatus lancet_world_enable_cutting(struct LancetWorld *world,
                                              enum LancetCutMethod method);

// Close grasper `tool` on the tissue within `reach` (m) of its jaws; it carries what it
// holds until `lancet_world_release`.
//
// # Safety
// `world` is a live world.
enum LancetStatus lancet_world_grasp(struct LancetWorld *world, uint32_t tool, double reach);

// Let go of what grasper `tool` holds.
//
// # Safety
// `world` is a live world.
enum LancetStatus lancet_world_release(struct LancetWorld *world, uint32_t tool);

// Take one step in the library's order (poses, step, cuts, grasps, contacts); what it did
// goes to `*info` (NULL: not wanted).
//
// # Safety
// `world` is a live world; `info` NULL or writable.
enum LancetStatus lancet_world_step(struct LancetWorld *world, struct LancetStepInfo *info);

// Take `steps` steps (no tool poses change between them).
//
// # Safety
// `world` is a live world.
enum LancetStatus lancet_world_run(struct LancetWorld *world, uint64_t steps);

// The reaction force on tool `tool` at the last step (N, three doubles into `force`): what
// the tissue pushed back with; zero before the first step.
//
// # Safety
// `world` is a live world; `force` three writable doubles.
enum LancetStatus lancet_world_tool_force(struct LancetWorld *world, uint32_t tool, double *force);

// The force to render on the haptic device coupled to tool `tool` at the last step (N, three
// doubles): the coupling's spring-damper force, which has no step-to-step jump beyond the
// coupling's stiffness. `LANCET_STATUS_INVALID_ARGUMENT` if the tool is not coupled.
//
// # Safety
// `world` is a live world; `force` three writable doubles.
enum LancetStatus lancet_world_tool_rendered_force(struct LancetWorld *world,
                                                   uint32_t tool,
                                                   double *force);

// Why the engine differs from the one asked for (no GPU for `LANCET_ENGINE_AUTO`), as a
// string to release with `lancet_string_free`; NULL when it does not.
//
// # Safety
// `world` is NULL or a live world.
char *lancet_world_engine_note(const struct LancetWorld *world);

#ifdef __cplusplus
}  // extern "C"
#endif  // __cplusplus

#endif  /* LANCET_H */

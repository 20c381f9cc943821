//! A world from a scene file: its mesh, model, step, engine, tools, cutting and self-contact.

use std::path::Path;

use super::{World, WorldBuilder};
use crate::engine::SimConfig;
use crate::error::{Error, Result};
use crate::scene::runner::{build_mesh, model_config};
use crate::scene::schema::TimeStep;
use crate::scene::{RunOptions, Scene};

impl WorldBuilder {
    /// The builder of `scene` (read from `scene_path`, which locates its relative paths and
    /// names it in messages), with `opts` overriding its engine, layout and accumulation.
    pub fn from_scene(scene: &Scene, scene_path: &Path, opts: &RunOptions) -> Result<Self> {
        let scene_err = |message: String| Error::Scene {
            path: scene_path.to_path_buf(),
            message,
        };
        let mesh = build_mesh(scene, scene_path)?;
        let placeholder = SimConfig {
            integrator: scene.integrator,
            solver: scene.solver,
            allow_unstable: scene.allow_unstable,
            allow_inverted: scene.allow_inverted,
            force_model: scene.force_model,
            ..SimConfig::new(1.0)
        };
        let model = crate::model::SpringModel::build(&mesh, &model_config(scene))
            .map_err(|e| scene_err(e.to_string()))?;
        let packed = model.pack(&mesh)?;
        let builder = WorldBuilder {
            mesh,
            model,
            packed,
            config: placeholder,
            engine: opts.engine.unwrap_or(scene.engine),
            gpu: crate::engine::GpuOptions {
                layout: opts.layout.unwrap_or(scene.layout),
                accumulation: opts.accumulation.unwrap_or(scene.accumulation),
            },
        };
        let bound = builder.bound().map_err(|e| scene_err(e.to_string()))?;
        let dt = match scene.dt {
            TimeStep::Seconds(s) => s,
            TimeStep::BoundFraction(f) if f > 0.0 && f.is_finite() && bound.dt.is_finite() => {
                f * bound.dt
            }
            TimeStep::BoundFraction(f) => {
                return Err(scene_err(format!(
                    "dt: BoundFraction({f}) needs a positive fraction of a finite bound (bound \
                     is {:e} s); give dt: Seconds(...) instead",
                    bound.dt
                )))
            }
        };
        let mut builder = builder;
        builder.config = SimConfig {
            dt,
            ..builder.config
        };
        Ok(builder)
    }
}

impl World {
    /// The world of `scene`, ready to step: [`WorldBuilder::from_scene`], built, with
    /// [`World::set_up_scene`]. The scene's trajectories and grasp windows are not the
    /// world's: [`crate::scene::driver::SceneDriver`] poses the tools from them at every step.
    pub fn from_scene(scene: &Scene, scene_path: &Path, opts: &RunOptions) -> Result<World> {
        let mut world = WorldBuilder::from_scene(scene, scene_path, opts)?.build()?;
        world.set_up_scene(scene, opts)?;
        Ok(world)
    }

    /// Give the world `scene`'s tools (at their trajectories' poses at the current time), its
    /// cutting (by `opts.cut_method`, else its first method; checked if `opts.check` or the
    /// scene asks) and its self-contact.
    pub fn set_up_scene(&mut self, scene: &Scene, opts: &RunOptions) -> Result<()> {
        if scene.tools.is_empty() && scene.self_contact.is_none() {
            return Ok(());
        }
        if cfg!(not(feature = "collide")) {
            return Err(Error::Unsupported(
                "this scene has tools but this build has no collision handling (enable the \
                 `collide` cargo feature)"
                    .into(),
            ));
        }
        #[cfg(feature = "collide")]
        self.set_self_contact(scene.self_contact.map(|s| {
            crate::contact::self_response::SelfContactSettings {
                thickness: s.thickness,
                max_depth: s.max_depth,
                iterations: s.iterations,
            }
        }))?;
        if let Some(cut) = &scene.cut {
            let fraction = match scene.dt {
                TimeStep::BoundFraction(f) => f,
                TimeStep::Seconds(_) => super::cutting::DEFAULT_BOUND_FRACTION,
            };
            let check = opts.check || scene.checks_cuts();
            self.enable_cutting(cut.settings(opts.cut_method, check, fraction))?;
        }
        let t0 = self.sim.time();
        for t in &scene.tools {
            self.add_tool(&t.name, t.shape, t.trajectory.pose_at(t0))?;
        }
        Ok(())
    }
}

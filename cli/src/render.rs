//! `lancet render`: run a scene and write PNG pictures of it, drawn headless with wgpu.

use super::*;

use lancet::render::frames::{PictureOptions, PngFrames};

/// What `lancet render` was asked for.
pub(crate) struct RenderRequest {
    pub scene: PathBuf,
    pub output: PathBuf,
    pub frames: u64,
    pub pictures: PictureOptions,
    pub run: RunOptions,
    pub json: bool,
}

/// Run the scene (once, with its first cut method or `--method`), drawing `frames` pictures
/// evenly spaced through the run, the last at its end.
pub(crate) fn render(req: RenderRequest) -> lancet::Result<ExitCode> {
    let scene = Scene::read(&req.scene)?;
    for w in scene.warnings() {
        eprintln!("warning: {}: {w}", req.scene.display());
    }
    let ctx = lancet::engine::gpu::GpuContext::new().map_err(|e| {
        lancet::Error::Unsupported(format!(
            "rendering needs a GPU adapter (any wgpu opens; lavapipe, Vulkan on the CPU, \
             works): {e}"
        ))
    })?;
    let steps = req.run.steps.unwrap_or(scene.steps);
    let frames = req.frames.max(1);
    let run = RunOptions {
        frame_every: Some(steps.div_ceil(frames).max(1)),
        // Pictures only: no VTU or glTF frames (`lancet run --output` writes those).
        no_output: true,
        ..req.run
    };
    let stem = lancet::scene::runner::series_stem(&scene, run.cut_method);
    let mut sink = PngFrames::new(&ctx, &scene, &req.output, &stem, req.pictures)?;
    let mut bar = crate::progress::RunProgress::new(&scene.name, steps, req.json);
    let summary = lancet::scene::run_scene_with(
        &scene,
        &req.scene,
        &run,
        |done, total| bar.update(done, total),
        Some(&mut sink),
    );
    bar.finish();
    let summary = summary?;
    if req.json {
        let value = json!({
            "scene": summary.scene,
            "engine": summary.engine,
            "device": ctx.describe(),
            "camera": sink.camera().map(|c| json!({
                "eye": [c.eye.x, c.eye.y, c.eye.z],
                "target": [c.target.x, c.target.y, c.target.z],
                "up": [c.up.x, c.up.y, c.up.z],
                "fov_y_degrees": c.fov_y.to_degrees(),
            })),
            "pictures": sink.pictures,
            "message": summary.message,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&value).unwrap_or_default()
        );
    } else {
        println!(
            "{}: {} steps on {}, pictures drawn on {}",
            summary.scene,
            summary.steps,
            summary.engine,
            ctx.describe()
        );
        for p in &sink.pictures {
            println!(
                "  {}  t = {:.4} s, colour bar 0 to {:.3e} m, {:.1}% covered",
                p.path.display(),
                p.time,
                p.colour_max,
                100.0 * p.coverage
            );
        }
        if let Some(m) = &summary.message {
            println!("  note: {m}");
        }
    }
    Ok(if summary.diverged || summary.refused {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

//! Running a scene file (or the embedded default scene) whole, as `lancet run --json` does.

use std::ffi::{c_char, CString};
use std::path::{Path, PathBuf};

use lancet::scene::{run_scene, RunOptions, Scene};

use crate::error::{guard, out, text, Failure, LancetStatus};

/// The scene file at `path`, or the embedded default scene for NULL, and the path naming it.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string.
pub(crate) unsafe fn load_scene(path: *const c_char) -> Result<(Scene, PathBuf), Failure> {
    if path.is_null() {
        return Ok((
            Scene::default_scene(),
            PathBuf::from("<embedded default scene>"),
        ));
    }
    // SAFETY: the contract above.
    let p = Path::new(unsafe { text(path, "path") }?);
    Ok((Scene::read(p)?, p.to_path_buf()))
}

/// Run the scene file at `path` (NULL: the embedded default scene) with its expectations, and
/// return its summary as JSON in `*summary_json` (release it with `lancet_string_free`). The
/// status is `LANCET_STATUS_OK` when the run completed, whether or not its expectations held:
/// read `"expectations_passed"` in the summary. Frames are written where the scene says.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string; `summary_json` points to writable storage.
#[no_mangle]
pub unsafe extern "C" fn lancet_run_scene(
    path: *const c_char,
    summary_json: *mut *mut c_char,
) -> LancetStatus {
    guard(|| {
        // SAFETY: the contract above.
        let slot = unsafe { out(summary_json, "summary_json") }?;
        *slot = std::ptr::null_mut();
        // SAFETY: the contract above.
        let (scene, scene_path) = unsafe { load_scene(path) }?;
        let summary = run_scene(&scene, &scene_path, &RunOptions::default(), |_, _| {})?;
        let json = serde_json::to_string(&summary)
            .map_err(|e| Failure(LancetStatus::Model, format!("summary to JSON: {e}")))?;
        *slot = CString::new(json).unwrap_or_default().into_raw();
        Ok(())
    })
}

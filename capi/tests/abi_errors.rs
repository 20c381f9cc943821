//! The boundary's error handling: NULL and malformed arguments give a status and a message,
//! never a crash; a missing file names the file; statuses follow the library's errors.

use std::ffi::{CStr, CString};

use lancet_c::*;

fn last_error() -> String {
    // SAFETY: lancet_last_error returns a valid NUL-terminated string.
    unsafe { CStr::from_ptr(lancet_last_error()) }
        .to_string_lossy()
        .into_owned()
}

#[test]
fn null_and_bad_arguments_are_refused_with_a_message() {
    let mut world: *mut LancetWorld = std::ptr::null_mut();
    // SAFETY: testing the NULL contract.
    let s = unsafe {
        lancet_world_new_box(
            std::ptr::null(),
            std::ptr::null(),
            std::ptr::null(),
            std::ptr::null(),
            &mut world,
        )
    };
    assert_eq!(s, LancetStatus::InvalidArgument);
    assert!(last_error().contains("size and cells"), "{}", last_error());
    assert!(world.is_null());

    let path = CString::new("/nonexistent/organ.msh").unwrap();
    // SAFETY: valid arguments.
    let s = unsafe { lancet_world_from_scene(path.as_ptr(), &mut world) };
    assert_ne!(s, LancetStatus::Ok);
    assert!(
        last_error().contains("/nonexistent/organ.msh"),
        "{}",
        last_error()
    );

    // SAFETY: NULL world is accepted by the counters and by free.
    unsafe {
        assert_eq!(lancet_world_node_count(std::ptr::null()), 0);
        lancet_world_free(std::ptr::null_mut());
        lancet_string_free(std::ptr::null_mut());
    }
}

#[test]
fn a_positions_array_too_short_is_refused_and_an_unstable_step_is_named() {
    let size = [0.01; 3];
    let cells = [2u32; 3];
    let material = LancetMaterial {
        youngs_modulus: 1e4,
        poisson_ratio: 0.3,
        density: 1000.0,
        mass_damping: 0.0,
        gravity: [0.0, 0.0, -9.81],
    };
    let mut settings = LancetSettings {
        engine: LancetEngine::Reference,
        integrator: LancetIntegrator::Verlet,
        dt: 0.0,
        bound_fraction: 0.5,
        fix_box: 0,
        fixed_min: [0.0; 3],
        fixed_max: [0.0; 3],
    };
    let mut world: *mut LancetWorld = std::ptr::null_mut();
    // SAFETY: valid arguments.
    let s = unsafe {
        lancet_world_new_box(
            size.as_ptr(),
            cells.as_ptr(),
            &material,
            &settings,
            &mut world,
        )
    };
    assert_eq!(s, LancetStatus::Ok, "{}", last_error());
    // SAFETY: a live world.
    let n = unsafe { lancet_world_node_count(world) };
    assert_eq!(n, 27);
    let mut x = vec![0.0; 3 * n - 1];
    // SAFETY: a live world and a buffer of the given length.
    let s = unsafe { lancet_world_positions(world, x.as_mut_ptr(), x.len()) };
    assert_eq!(s, LancetStatus::InvalidArgument);
    assert!(last_error().contains("81 doubles"), "{}", last_error());
    // SAFETY: made above.
    unsafe { lancet_world_free(world) };

    // A step far above the explicit bound: refused, with the bound in the message.
    settings.dt = 1.0;
    // SAFETY: valid arguments.
    let s = unsafe {
        lancet_world_new_box(
            size.as_ptr(),
            cells.as_ptr(),
            &material,
            &settings,
            &mut world,
        )
    };
    assert_eq!(s, LancetStatus::UnstableTimeStep, "{}", last_error());
    assert!(last_error().contains("bound"), "{}", last_error());
    assert!(world.is_null());
}

#[test]
fn the_default_scene_runs_through_the_abi_and_passes() {
    let mut json: *mut std::ffi::c_char = std::ptr::null_mut();
    // SAFETY: NULL path = the embedded default scene.
    let s = unsafe { lancet_run_scene(std::ptr::null(), &mut json) };
    assert_eq!(s, LancetStatus::Ok, "{}", last_error());
    // SAFETY: a string made by lancet_run_scene.
    let text = unsafe { CStr::from_ptr(json) }
        .to_string_lossy()
        .into_owned();
    unsafe { lancet_string_free(json) };
    let summary: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(
        summary["expectations_passed"],
        serde_json::Value::Bool(true),
        "{text}"
    );
    assert!(summary["steps"].as_u64().unwrap() > 0);
}

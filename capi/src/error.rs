//! Status codes, the thread's last error message, and the guard every entry point runs in:
//! it turns a `lancet::Error` into a status and a message, and catches panics.

use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// What a call did. Anything but `LANCET_STATUS_OK` leaves a message for
/// [`lancet_last_error`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LancetStatus {
    /// Success.
    Ok = 0,
    /// A NULL pointer, a string that is not UTF-8, a handle or index out of range, an array
    /// too short.
    InvalidArgument = 1,
    /// A file could not be read or written.
    Io = 2,
    /// A mesh or scene file is malformed (the message names the file, line and element).
    Parse = 3,
    /// The model cannot be built or changed as asked (a material, a node out of range, ...).
    Model = 4,
    /// The time step is above the explicit integrator's stable bound (the message gives the
    /// bound), or a cut lowered the bound below it.
    UnstableTimeStep = 5,
    /// The simulation diverged or a tet inverted (the message names the step and node or tet).
    Diverged = 6,
    /// The GPU failed (device lost, out of memory).
    Gpu = 7,
    /// Not supported by this build or this combination of options.
    Unsupported = 8,
    /// A bug inside lancet: a panic was caught (please report the message).
    Panic = 9,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// Keep `message` as this thread's last error.
pub(crate) fn set_error(message: &str) {
    // Interior NULs cannot appear in a C string: shown as spaces.
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// The status of a library error.
pub(crate) fn status_of(e: &lancet::Error) -> LancetStatus {
    use lancet::Error as E;
    match e {
        E::Io { .. } => LancetStatus::Io,
        E::Parse(_) | E::Mesh(_) | E::NonManifold { .. } | E::Scene { .. } => LancetStatus::Parse,
        E::UnstableTimeStep { .. } | E::CutLoweredTimeStep { .. } => LancetStatus::UnstableTimeStep,
        E::Diverged { .. } | E::Inverted { .. } => LancetStatus::Diverged,
        E::Gpu(_) => LancetStatus::Gpu,
        E::Unsupported(_) | E::Options(_) => LancetStatus::Unsupported,
        _ => LancetStatus::Model,
    }
}

/// An error of the C boundary itself (a bad argument), with its message.
pub(crate) struct Failure(pub LancetStatus, pub String);

impl From<lancet::Error> for Failure {
    fn from(e: lancet::Error) -> Self {
        Failure(status_of(&e), e.to_string())
    }
}

/// A bad argument.
pub(crate) fn invalid(message: impl Into<String>) -> Failure {
    Failure(LancetStatus::InvalidArgument, message.into())
}

/// Run `f`, turning its error or panic into a status and this thread's last error.
pub(crate) fn guard(f: impl FnOnce() -> Result<(), Failure>) -> LancetStatus {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => LancetStatus::Ok,
        Ok(Err(Failure(status, message))) => {
            set_error(&message);
            status
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            set_error(&format!("internal error (please report): {what}"));
            LancetStatus::Panic
        }
    }
}

/// A `&str` from a C string argument named `what`.
pub(crate) unsafe fn text<'a>(ptr: *const c_char, what: &str) -> Result<&'a str, Failure> {
    if ptr.is_null() {
        return Err(invalid(format!("{what} is NULL")));
    }
    // SAFETY: the caller passes a NUL-terminated string (the function's contract).
    unsafe { CStr::from_ptr(ptr) }
        .to_str()
        .map_err(|e| invalid(format!("{what} is not UTF-8: {e}")))
}

/// A mutable reference from a non-NULL pointer argument named `what`.
pub(crate) unsafe fn out<'a, T>(ptr: *mut T, what: &str) -> Result<&'a mut T, Failure> {
    // SAFETY: non-NULL pointers are valid and exclusive (the function's contract).
    unsafe { ptr.as_mut() }.ok_or_else(|| invalid(format!("{what} is NULL")))
}

/// The message of this thread's last failed call (empty if none failed yet). The pointer is
/// valid until this thread's next failing call; copy it to keep it.
#[no_mangle]
pub extern "C" fn lancet_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// The library's version, e.g. `"0.1.0"` (static storage).
#[no_mangle]
pub extern "C" fn lancet_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// Release a string lancet returned (e.g. by `lancet_run_scene`); NULL is accepted.
///
/// # Safety
/// `s` is NULL or a string returned by lancet and not yet released.
#[no_mangle]
pub unsafe extern "C" fn lancet_string_free(s: *mut c_char) {
    if !s.is_null() {
        // SAFETY: made by `CString::into_raw` in this library (the contract).
        drop(unsafe { CString::from_raw(s) });
    }
}

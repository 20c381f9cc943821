//! Helpers shared by the GPU tests.

use lancet::engine::gpu::GpuContext;

/// The GPU to test on. Without one the test prints why and is skipped, except when
/// `LANCET_REQUIRE_GPU=1` (CI, with lavapipe installed), where a missing GPU fails the test.
pub fn gpu() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => Some(ctx),
        Err(e) if std::env::var("LANCET_REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("LANCET_REQUIRE_GPU=1 but no GPU is usable: {e}")
        }
        Err(e) => {
            eprintln!("skipped: no GPU adapter ({e})");
            None
        }
    }
}

//! The test binaries that need the GPU are built only with the `gpu` feature, which the
//! library's default features leave out: `cargo test` at the repository root turns it on (the
//! CLI crate asks for every feature), `cargo test -p lancet` alone does not. Where a GPU is
//! required (`LANCET_REQUIRE_GPU=1`, as in CI) leaving them out must not pass silently.

/// Whether this build has the GPU engine (and so the GPU test binaries).
const GPU_BUILT: bool = cfg!(feature = "gpu");

#[test]
fn the_gpu_tests_are_built_where_a_gpu_is_required() {
    let required = std::env::var("LANCET_REQUIRE_GPU").as_deref() == Ok("1");
    if required && !GPU_BUILT {
        panic!(
            "LANCET_REQUIRE_GPU=1, but this build has no `gpu` feature, so the GPU tests were \
             not built: run `cargo test` at the repository root, or `cargo test -p lancet \
             --all-features`"
        );
    }
}

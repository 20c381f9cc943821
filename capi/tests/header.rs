//! `include/lancet.h` is what cbindgen makes of the crate's source now (settings in
//! `cbindgen.toml`). When it is not, the test writes the new header and fails, so that the
//! change is seen and committed.

use std::path::Path;

#[test]
fn header_is_current() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(dir.join("cbindgen.toml")).unwrap();
    let bindings = cbindgen::generate_with_config(dir, config).expect("cbindgen reads capi/src");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let path = dir.join("include/lancet.h");
    let committed = std::fs::read(&path).unwrap_or_default();
    if committed != generated {
        std::fs::create_dir_all(dir.join("include")).unwrap();
        std::fs::write(&path, &generated).unwrap();
        panic!(
            "{} was out of date with capi/src and has been regenerated: review and commit it",
            path.display()
        );
    }
}

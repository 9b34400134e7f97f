//! Generates the fixture sensor (tests/fixtures/do-probe/spec, a made-up
//! probe that is in neither manual) through the public `yosemitech-codegen`
//! API, exactly as a downstream crate would; `src/lib.rs` includes it as
//! `yosemitech_tests::do_probe`. No Rust is written for that sensor.

use std::path::PathBuf;

fn main() -> Result<(), yosemitech_codegen::Error> {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default()).join("fixtures");
    // This package has no `std` feature: emit the device handles unconditionally.
    yosemitech_codegen::Config::new()
        .std_feature(None)
        .compile(manifest_dir.join("fixtures/do-probe/spec"), &out_dir)?;
    // The hostile-but-valid fixture (tests/fixtures/hostile-valid): text that
    // tries to escape doc comments and literals, names next to Rust's own,
    // counts at their maximum. `src/lib.rs` includes it as `yosemitech_tests::hostile`.
    yosemitech_codegen::Config::new()
        .std_feature(None)
        .compile(manifest_dir.join("fixtures/hostile-valid/spec"), out_dir.with_file_name("hostile"))?;
    Ok(())
}

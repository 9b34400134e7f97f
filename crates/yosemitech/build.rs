//! Generates one module per sensor from `spec/` (a symlink to the workspace's
//! spec directory, packaged as real files) into `OUT_DIR`; `src/lib.rs`
//! `include!`s them. Nothing is written outside `OUT_DIR`.

use std::path::PathBuf;

fn main() -> Result<(), yosemitech_codegen::Error> {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default());
    yosemitech_codegen::Config::new()
        .std_feature(Some("std"))
        .async_device_handles(Some("tokio"))
        .compile(manifest_dir.join("spec"), out_dir)?;
    Ok(())
}

//! `cargo xtask codegen [--check]`: writes the code generated from `spec/`
//! to `crates/yosemitech/generated/`, the sensor modules the `yosemitech`
//! crate compiles (it has no build script). `--check` fails when they are
//! stale (CI, and xtask's own test under `cargo test`).

use std::process::ExitCode;

const USAGE: &str = "usage: cargo xtask codegen [--check]";

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let Some(check) = crate::check_flag(args, USAGE)? else {
        return Ok(ExitCode::SUCCESS);
    };
    let root = crate::root();
    // `std` gates the blocking device handles, `tokio` the async ones: the
    // features of crates/yosemitech/Cargo.toml.
    let generated = yosemitech_codegen::Config::new()
        .std_feature(Some("std"))
        .async_device_handles(Some("tokio"))
        .generate(&[root.join("spec")])
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let files = generated.files().into_iter().map(|(name, contents)| (name, contents.to_owned())).collect();
    crate::generated_files::GeneratedFiles {
        what: "generated code",
        command: "cargo xtask codegen",
        dir: root.join("crates/yosemitech/generated"),
        files,
        owns_suffix: Some(".rs"),
    }
    .ensure(check)
}

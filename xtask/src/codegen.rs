//! `cargo xtask codegen [--check]`: writes the code generated from `spec/`
//! to `crates/yosemitech/generated/` so that people can read and review it.
//!
//! The build never reads these files: `crates/yosemitech/build.rs` generates
//! the same code into `OUT_DIR`. `--check` fails when the copy is stale (CI).

use std::process::ExitCode;

const USAGE: &str = "usage: cargo xtask codegen [--check]";

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let Some(check) = crate::check_flag(args, USAGE)? else {
        return Ok(ExitCode::SUCCESS);
    };
    let root = crate::root();
    // The same configuration as crates/yosemitech/build.rs.
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

//! `cargo xtask codegen`.

use std::process::ExitCode;

/// Runs the task.
pub fn run(_args: &[String]) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`codegen` is not implemented yet")
}

//! `cargo xtask fuzz`.

use std::process::ExitCode;

/// Runs the task.
pub fn run(_args: &[String]) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`fuzz` is not implemented yet")
}

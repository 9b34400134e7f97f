//! `cargo xtask validate`.

use std::process::ExitCode;

/// Runs the task.
pub fn run(_args: &[String]) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`validate` is not implemented yet")
}

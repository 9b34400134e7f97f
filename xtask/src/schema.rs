//! `cargo xtask schema`.

use std::process::ExitCode;

/// Runs the task.
pub fn run(_args: &[String]) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`schema` is not implemented yet")
}

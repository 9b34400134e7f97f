//! `cargo xtask docs`.

use std::process::ExitCode;

/// Runs the task.
pub fn run(_args: &[String]) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`docs` is not implemented yet")
}

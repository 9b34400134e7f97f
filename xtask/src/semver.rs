//! `cargo xtask semver [--baseline REV]`: the published crates' API against
//! the last release.
//!
//! Runs `cargo semver-checks` on the crates other teams depend on, against
//! the last release: the highest `v*` tag that is an ancestor of `HEAD`,
//! chosen here only. A breaking change passes only if the workspace version
//! says so (on 0.x, a minor bump). With no such tag it fails and says why,
//! rather than skip: a clone without tags checks nothing.

use std::process::{Command, ExitCode};

use anyhow::{Context, bail};

use crate::root;

/// The crates whose API other teams consume.
pub const CHECKED_CRATES: [&str; 2] = ["yosemitech", "yosemitech-rtu"];

const USAGE: &str = "usage: cargo xtask semver [--baseline REV]

Checks yosemitech and yosemitech-rtu with cargo-semver-checks (cargo install --locked
cargo-semver-checks) against the last release: the highest v* tag that is an ancestor of
HEAD, or REV.";

pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let mut baseline = None;
    let mut args = args.iter();
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--baseline" => baseline = Some(args.next().context("--baseline takes a git revision")?.clone()),
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(ExitCode::SUCCESS);
            }
            other => bail!("unknown argument `{other}`; {USAGE}"),
        }
    }
    let baseline = match baseline {
        Some(rev) => rev,
        None => last_release()?,
    };
    let tool = Command::new(env!("CARGO")).args(["semver-checks", "--version"]).output();
    if !tool.is_ok_and(|out| out.status.success()) {
        bail!("cargo-semver-checks is not installed: cargo install --locked cargo-semver-checks");
    }
    println!("checking {} against {baseline}", CHECKED_CRATES.join(", "));
    let mut command = Command::new(env!("CARGO"));
    command.args(["semver-checks", "check-release", "--baseline-rev", &baseline]).current_dir(root());
    for krate in CHECKED_CRATES {
        command.args(["-p", krate]);
    }
    let status = command.status().context("running cargo semver-checks")?;
    Ok(if status.success() { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}

/// The highest `v*` tag (by version order) that `HEAD` descends from.
fn last_release() -> anyhow::Result<String> {
    let out = Command::new("git")
        .args(["tag", "--list", "v[0-9]*", "--merged", "HEAD", "--sort=-version:refname"])
        .current_dir(root())
        .output()
        .context("running git tag")?;
    if !out.status.success() {
        bail!("git tag failed: {}", String::from_utf8_lossy(&out.stderr).trim());
    }
    let tags = String::from_utf8(out.stdout).context("git tag printed non-UTF-8")?;
    match tags.lines().next() {
        Some(tag) => Ok(tag.to_owned()),
        None => bail!(
            "no release to compare with: no tag v* is an ancestor of HEAD (a shallow clone or one without tags? \
             `git fetch --tags --unshallow`), or pass --baseline REV"
        ),
    }
}

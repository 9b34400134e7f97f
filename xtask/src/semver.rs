//! `cargo xtask semver [--baseline REV]`: the published crates' API against
//! the last release.
//!
//! Runs `cargo semver-checks` on the crates other teams depend on, against
//! the last release: the highest `v*` tag that is an ancestor of `HEAD`,
//! chosen here only. A breaking change passes only if the workspace version
//! says so (on 0.x, a minor bump), so once the version is bumped for a
//! breaking release the check admits everything until that release is
//! tagged, and holds the API to it from then on. With no such tag it fails
//! and says why, rather than skip: a clone without tags checks nothing.

use std::path::Path;
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
        None => last_release(&root())?,
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

/// The highest `v*` tag (by version order) that `HEAD` of the repository at
/// `repo` descends from.
fn last_release(repo: &Path) -> anyhow::Result<String> {
    let out = Command::new("git")
        .args(["tag", "--list", "v[0-9]*", "--merged", "HEAD", "--sort=-version:refname"])
        .current_dir(repo)
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

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::process::Command;

    use super::last_release;

    fn git(repo: &Path, args: &[&str]) {
        let status = Command::new("git")
            .args(["-c", "user.name=xtask", "-c", "user.email=xtask@example.invalid", "-c", "tag.gpgSign=false"])
            .args(args)
            .current_dir(repo)
            .status()
            .expect("git runs");
        assert!(status.success(), "git {args:?}");
    }

    #[test]
    fn the_baseline_is_the_highest_release_tag_head_descends_from() {
        let repo = std::env::temp_dir().join(format!("xtask-semver-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&repo);
        std::fs::create_dir_all(&repo).unwrap();
        git(&repo, &["init", "--quiet", "--initial-branch=main"]);
        git(&repo, &["commit", "--quiet", "--allow-empty", "-m", "first"]);
        let none = last_release(&repo).expect_err("no tag, no baseline");
        assert!(none.to_string().contains("no release to compare with"), "{none}");

        git(&repo, &["tag", "-a", "v0.9.0", "-m", "0.9.0"]);
        git(&repo, &["tag", "-a", "v0.10.0", "-m", "0.10.0"]);
        git(&repo, &["tag", "-a", "nightly", "-m", "not a release"]);
        git(&repo, &["switch", "--quiet", "-c", "later"]);
        git(&repo, &["commit", "--quiet", "--allow-empty", "-m", "second"]);
        git(&repo, &["tag", "-a", "v0.11.0", "-m", "0.11.0"]);
        git(&repo, &["switch", "--quiet", "main"]);
        git(&repo, &["commit", "--quiet", "--allow-empty", "-m", "elsewhere"]);
        // By version, not by name (v0.10 after v0.9); v0.11.0 is not an ancestor.
        assert_eq!(last_release(&repo).unwrap(), "v0.10.0");
        let _ = std::fs::remove_dir_all(&repo);
    }
}

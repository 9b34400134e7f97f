//! `cargo xtask check [--base REV]`: the developer's quick loop, what catches
//! most failures of a change in a few minutes on a warm machine.
//!
//! In order, stopping at the first failure: `cargo fmt --check`; the spec
//! validated and the generated files' freshness (in process, as `validate`
//! and `codegen`/`docs`/`schema --check` do); clippy with `-D warnings` over
//! every target of the workspace (only what the change touches and what
//! depends on it recompiles, so a broken caller in another crate shows
//! here); then the tests of the packages the change touches, by nextest
//! where it is installed. The change is the files that differ from REV
//! (default `HEAD`: the uncommitted work, new files included). A file
//! outside every package (spec/, docs, the README) touches the
//! workspace-level suite, `yosemitech-tests`.
//!
//! `.ci/run` adds what takes longer: the whole suite with the slow tests and
//! the drop-in corpus, rustdoc, the feature powerset, semver, the firmware,
//! the Pi packages, callgrind and fuzzing.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use anyhow::{Context as _, bail};

const USAGE: &str = "usage: cargo xtask check [--base REV]

Format, spec and generated files, clippy over the workspace, and the tests of the packages
whose files differ from REV (default HEAD: the uncommitted work). .ci/run runs everything.";

/// The package a file outside every package's directory belongs to.
const WORKSPACE_SUITE: &str = "yosemitech-tests";

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let mut base = "HEAD".to_owned();
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        match arg.as_str() {
            "--base" => base = it.next().with_context(|| format!("`--base` needs a revision\n{USAGE}"))?.clone(),
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(ExitCode::SUCCESS);
            }
            other => bail!("unknown argument `{other}`\n{USAGE}"),
        }
    }
    let root = crate::root();
    let started = std::time::Instant::now();

    cargo(&root, &["fmt", "--all", "--", "--check"], "format: run `cargo fmt --all`")?;
    for (task, run) in crate::SPEC_TASKS {
        if run(&["--check".to_owned()])? != ExitCode::SUCCESS {
            bail!("`cargo xtask {task} --check` failed (above)");
        }
    }
    if crate::validate::run(&[])? != ExitCode::SUCCESS {
        bail!("the spec does not validate (above)");
    }
    cargo(&root, &["clippy", "--workspace", "--all-targets", "--quiet", "--", "-D", "warnings"], "clippy")?;

    let changed = changed_files(&root, &base)?;
    let packages = touched_packages(&root, &changed)?;
    if packages.is_empty() {
        println!("check: no package differs from {base}; no tests to run");
    } else {
        let mut args: Vec<&str> = Vec::new();
        let nextest =
            Command::new(env!("CARGO")).args(["nextest", "--version"]).output().is_ok_and(|o| o.status.success());
        args.extend(if nextest { ["nextest", "run"].as_slice() } else { ["test"].as_slice() });
        for package in &packages {
            args.extend(["-p", package.as_str()]);
        }
        println!(
            "check: testing {} (files differing from {base})",
            packages.iter().cloned().collect::<Vec<_>>().join(", ")
        );
        cargo(&root, &args, "tests")?;
    }
    println!("check: passed in {} s; `.ci/run` runs everything", started.elapsed().as_secs());
    Ok(ExitCode::SUCCESS)
}

fn cargo(root: &Path, args: &[&str], what: &str) -> anyhow::Result<()> {
    let status = Command::new(env!("CARGO"))
        .args(args)
        .current_dir(root)
        .status()
        .with_context(|| format!("running cargo {}", args.join(" ")))?;
    if !status.success() {
        bail!("{what} failed: cargo {}", args.join(" "));
    }
    Ok(())
}

/// The files that differ from `base`, tracked or new, relative to the root.
fn changed_files(root: &Path, base: &str) -> anyhow::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for args in [vec!["diff", "--name-only", base, "--"], vec!["ls-files", "--others", "--exclude-standard"]] {
        let output = Command::new("git").args(&args).current_dir(root).output().context("running git")?;
        if !output.status.success() {
            bail!("git {}: {}", args.join(" "), String::from_utf8_lossy(&output.stderr).trim());
        }
        files.extend(String::from_utf8_lossy(&output.stdout).lines().map(PathBuf::from));
    }
    Ok(files)
}

/// The workspace packages whose directory holds a changed file (the deepest
/// one, so `tests/` is the suite and `crates/x/` is `x`).
fn touched_packages(root: &Path, changed: &[PathBuf]) -> anyhow::Result<BTreeSet<String>> {
    let output = Command::new(env!("CARGO"))
        .args(["metadata", "--no-deps", "--format-version", "1"])
        .current_dir(root)
        .output()
        .context("running cargo metadata")?;
    if !output.status.success() {
        bail!("cargo metadata: {}", String::from_utf8_lossy(&output.stderr).trim());
    }
    let metadata: serde_json::Value = serde_json::from_slice(&output.stdout).context("reading cargo metadata")?;
    let mut dirs: Vec<(PathBuf, String)> = Vec::new();
    for package in metadata["packages"].as_array().into_iter().flatten() {
        let (Some(name), Some(manifest)) = (package["name"].as_str(), package["manifest_path"].as_str()) else {
            continue;
        };
        if let Some(dir) = Path::new(manifest).parent().and_then(|d| d.strip_prefix(root).ok()) {
            dirs.push((dir.to_path_buf(), name.to_owned()));
        }
    }
    let mut touched = BTreeSet::new();
    for file in changed {
        let owner = dirs
            .iter()
            .filter(|(dir, _)| file.starts_with(dir))
            .max_by_key(|(dir, _)| dir.components().count())
            .map_or(WORKSPACE_SUITE, |(_, name)| name.as_str());
        touched.insert(owner.to_owned());
    }
    Ok(touched)
}

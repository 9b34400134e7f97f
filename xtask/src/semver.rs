//! `cargo xtask semver [--baseline REV | --record TAG]`: the published
//! crates' API against the last release.
//!
//! Runs `cargo semver-checks` on the crates other teams depend on. The
//! baseline is the last release's API as rustdoc JSON, recorded in the
//! repository (`xtask/release/<tag>/<crate>.json.gz`) when the release is
//! tagged: a clone without tags or history (CI's may be either) checks
//! against the same release as a full one. A breaking change passes only if
//! the workspace version says so (on 0.x, a minor bump), so once the version
//! is bumped for a breaking release the check admits everything until that
//! release is recorded, and holds the API to it from then on. With no
//! recorded release it fails and says why, rather than skip.
//!
//! `--record TAG` writes the baseline from the tagged source (in a scratch
//! worktree, with the flags cargo-semver-checks itself documents with) and
//! removes the previous release's; `--baseline REV` checks against any git
//! revision instead, for a look at a change before it is tagged.

use std::fs;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use anyhow::{Context, bail};

use crate::root;

/// The crates whose API other teams consume.
pub const CHECKED_CRATES: [&str; 2] = ["yosemitech", "yosemitech-rtu"];

/// Where the recorded releases live, relative to the workspace root.
const RELEASES: &str = "xtask/release";

/// How cargo-semver-checks 0.51 documents a crate (its `EXTRA_RUSTDOCFLAGS`):
/// a baseline recorded otherwise would differ from the current side in what
/// it shows, not in what changed.
const RUSTDOC_FLAGS: &str =
    "-Z unstable-options --document-private-items --document-hidden-items --output-format=json --cap-lints=allow";

const USAGE: &str = "usage: cargo xtask semver [--baseline REV | --record TAG]

Checks yosemitech and yosemitech-rtu with cargo-semver-checks (cargo install --locked
cargo-semver-checks@0.51.0) against the last release recorded in xtask/release/, or against
the git revision REV. --record TAG records the release TAG (an existing tag) as the baseline.";

enum Mode {
    Recorded,
    Revision(String),
    Record(String),
}

pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let mut mode = Mode::Recorded;
    let mut args = args.iter();
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--baseline" => mode = Mode::Revision(args.next().context("--baseline takes a git revision")?.clone()),
            "--record" => mode = Mode::Record(args.next().context("--record takes a release tag")?.clone()),
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(ExitCode::SUCCESS);
            }
            other => bail!("unknown argument `{other}`; {USAGE}"),
        }
    }
    let root = root();
    match mode {
        Mode::Record(tag) => {
            record(&root, &tag)?;
            Ok(ExitCode::SUCCESS)
        }
        Mode::Revision(rev) => {
            require_tool()?;
            println!("checking {} against {rev}", CHECKED_CRATES.join(", "));
            let mut command = Command::new(env!("CARGO"));
            command.args(["semver-checks", "check-release", "--baseline-rev", &rev]).current_dir(&root);
            for krate in CHECKED_CRATES {
                command.args(["-p", krate]);
            }
            Ok(exit_code(command.status().context("running cargo semver-checks")?.success()))
        }
        Mode::Recorded => {
            require_tool()?;
            let tag = last_recorded(&root.join(RELEASES))?;
            let scratch = root.join("target/semver-baseline").join(&tag);
            fs::create_dir_all(&scratch).with_context(|| format!("creating {}", scratch.display()))?;
            let mut all_pass = true;
            for krate in CHECKED_CRATES {
                let recorded = root.join(RELEASES).join(&tag).join(format!("{krate}.json.gz"));
                let json = scratch.join(format!("{krate}.json"));
                unpack(&recorded, &json)?;
                println!(
                    "checking {krate} against {tag} ({})",
                    recorded.strip_prefix(&root).unwrap_or(&recorded).display()
                );
                let status = Command::new(env!("CARGO"))
                    .args(["semver-checks", "check-release", "-p", krate, "--baseline-rustdoc"])
                    .arg(&json)
                    .current_dir(&root)
                    .status()
                    .context("running cargo semver-checks")?;
                all_pass &= status.success();
            }
            Ok(exit_code(all_pass))
        }
    }
}

fn exit_code(success: bool) -> ExitCode {
    if success { ExitCode::SUCCESS } else { ExitCode::FAILURE }
}

fn require_tool() -> anyhow::Result<()> {
    let tool = Command::new(env!("CARGO")).args(["semver-checks", "--version"]).output();
    if !tool.is_ok_and(|out| out.status.success()) {
        bail!("cargo-semver-checks is not installed: cargo install --locked cargo-semver-checks@0.51.0");
    }
    Ok(())
}

/// The highest release (by version, `v0.10.0` after `v0.9.0`) recorded under
/// `releases`.
fn last_recorded(releases: &Path) -> anyhow::Result<String> {
    let mut tags = Vec::new();
    if releases.is_dir() {
        for entry in fs::read_dir(releases).with_context(|| format!("reading {}", releases.display()))? {
            let name = entry?.file_name().to_string_lossy().into_owned();
            if let Some(version) = release_version(&name) {
                tags.push((version, name));
            }
        }
    }
    tags.sort();
    match tags.pop() {
        Some((_, tag)) => Ok(tag),
        None => bail!(
            "no release to compare with: {} holds none; tag the release and record it with \
             `cargo xtask semver --record vX.Y.Z`, or pass --baseline REV",
            releases.display()
        ),
    }
}

/// `v1.2.3` as numbers, or `None` for a name that is not a release tag.
fn release_version(tag: &str) -> Option<(u64, u64, u64)> {
    let mut parts = tag.strip_prefix('v')?.split('.').map(|part| part.parse::<u64>().ok());
    let version = (parts.next()??, parts.next()??, parts.next()??);
    parts.next().is_none().then_some(version)
}

fn unpack(gz: &Path, json: &Path) -> anyhow::Result<()> {
    let file = fs::File::open(gz).with_context(|| format!("opening {}", gz.display()))?;
    let mut text = Vec::new();
    flate2::read::GzDecoder::new(file)
        .read_to_end(&mut text)
        .with_context(|| format!("decompressing {}", gz.display()))?;
    fs::write(json, text).with_context(|| format!("writing {}", json.display()))
}

fn git(root: &Path, args: &[&str]) -> anyhow::Result<String> {
    let out = Command::new("git").args(args).current_dir(root).output().context("running git")?;
    if !out.status.success() {
        bail!("git {} failed: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim());
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

/// Documents each checked crate at `tag` and stores the JSON, compressed,
/// as the baseline; the previous release's baseline goes.
fn record(root: &Path, tag: &str) -> anyhow::Result<()> {
    if release_version(tag).is_none() {
        bail!("`{tag}` is not a release tag (vMAJOR.MINOR.PATCH)");
    }
    git(root, &["rev-parse", "--verify", "--quiet", &format!("refs/tags/{tag}^{{commit}}")])
        .with_context(|| format!("no tag {tag} in this repository: tag the release first"))?;
    let scratch = root.join("target/semver-record");
    let worktree = scratch.join(tag);
    let _ = git(root, &["worktree", "remove", "--force", &worktree.to_string_lossy()]);
    let _ = fs::remove_dir_all(&worktree);
    fs::create_dir_all(&scratch)?;
    git(root, &["worktree", "add", "--detach", &worktree.to_string_lossy(), tag])?;
    let recorded = document(&worktree, &scratch.join("target"), tag, &root.join(RELEASES));
    let _ = git(root, &["worktree", "remove", "--force", &worktree.to_string_lossy()]);
    recorded
}

fn document(source: &Path, target_dir: &Path, tag: &str, releases: &Path) -> anyhow::Result<()> {
    let out = releases.join(tag);
    fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    for krate in CHECKED_CRATES {
        let status = Command::new(env!("CARGO"))
            .args(["doc", "--no-deps", "--all-features", "-p", krate])
            .arg("--target-dir")
            .arg(target_dir)
            .env("RUSTC_BOOTSTRAP", "1")
            .env("RUSTDOCFLAGS", RUSTDOC_FLAGS)
            .current_dir(source)
            .status()
            .context("running cargo doc")?;
        if !status.success() {
            bail!("cargo doc of {krate} at {tag} failed");
        }
        let json: PathBuf = target_dir.join("doc").join(format!("{}.json", krate.replace('-', "_")));
        let text = fs::read(&json).with_context(|| format!("reading {}", json.display()))?;
        let gz = out.join(format!("{krate}.json.gz"));
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        encoder.write_all(&text)?;
        fs::write(&gz, encoder.finish()?).with_context(|| format!("writing {}", gz.display()))?;
        println!("recorded {}", gz.display());
    }
    for entry in fs::read_dir(releases)? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name != tag && release_version(&name).is_some() {
            fs::remove_dir_all(entry.path()).with_context(|| format!("removing {}", entry.path().display()))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{last_recorded, release_version};

    #[test]
    fn release_tags_are_read_as_versions() {
        assert_eq!(release_version("v0.10.2"), Some((0, 10, 2)));
        for not_a_release in ["0.1.0", "v0.1", "v0.1.0.1", "v0.1.x", "nightly", "v"] {
            assert_eq!(release_version(not_a_release), None, "{not_a_release}");
        }
    }

    #[test]
    fn the_baseline_is_the_highest_recorded_release() {
        let releases = std::env::temp_dir().join(format!("xtask-semver-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&releases);
        let none = last_recorded(&releases).expect_err("no directory, no baseline");
        assert!(none.to_string().contains("no release to compare with"), "{none}");
        for dir in ["v0.9.0", "v0.10.0", "nightly", "v0.11"] {
            std::fs::create_dir_all(releases.join(dir)).unwrap();
        }
        // By version, not by name: v0.10.0 sorts before v0.9.0 as text.
        assert_eq!(last_recorded(&releases).unwrap(), "v0.10.0");
        let _ = std::fs::remove_dir_all(&releases);
    }
}

//! `cargo xtask codegen [--check]`: writes the code generated from `spec/`
//! to `crates/yosemitech/generated/` so that people can read and review it.
//!
//! The build never reads these files: `crates/yosemitech/build.rs` generates
//! the same code into `OUT_DIR`. `--check` fails when the copy is stale (CI).

use std::collections::BTreeSet;
use std::fs;
use std::path::Path;
use std::process::ExitCode;

use anyhow::Context as _;

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
        .generate(&[root.join("spec")])
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let dir = root.join("crates/yosemitech/generated");
    let files = generated.files();
    let wanted: BTreeSet<&str> = files.iter().map(|(name, _)| name.as_str()).collect();
    let extra = existing_rs_files(&dir)?.into_iter().filter(|f| !wanted.contains(f.as_str())).collect::<Vec<_>>();

    if check {
        let mut stale = Vec::new();
        for (name, contents) in &files {
            let path = dir.join(name);
            if fs::read_to_string(&path).ok().as_deref() != Some(*contents) {
                stale.push(format!("{} is stale or missing", display(&root, &path)));
            }
        }
        for name in &extra {
            stale.push(format!("{} is not generated from the spec any more", display(&root, &dir.join(name))));
        }
        if stale.is_empty() {
            println!("generated code is up to date ({} files)", files.len());
            return Ok(ExitCode::SUCCESS);
        }
        for s in &stale {
            eprintln!("error: {s}");
        }
        eprintln!("run `cargo xtask codegen` and commit the result");
        return Ok(ExitCode::FAILURE);
    }

    fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = 0;
    for (name, contents) in &files {
        let path = dir.join(name);
        if fs::read_to_string(&path).ok().as_deref() == Some(*contents) {
            continue;
        }
        fs::write(&path, contents).with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", display(&root, &path));
        written += 1;
    }
    for name in &extra {
        let path = dir.join(name);
        fs::remove_file(&path).with_context(|| format!("removing {}", path.display()))?;
        println!("removed {}", display(&root, &path));
    }
    if written == 0 && extra.is_empty() {
        println!("generated code is up to date ({} files)", files.len());
    }
    Ok(ExitCode::SUCCESS)
}

/// The `*.rs` files in `dir` (none if it does not exist).
fn existing_rs_files(dir: &Path) -> anyhow::Result<Vec<String>> {
    let Ok(entries) = fs::read_dir(dir) else { return Ok(Vec::new()) };
    let mut out = Vec::new();
    for entry in entries {
        let name = entry?.file_name().to_string_lossy().into_owned();
        if name.ends_with(".rs") {
            out.push(name);
        }
    }
    out.sort();
    Ok(out)
}

fn display(root: &Path, path: &Path) -> String {
    path.strip_prefix(root).unwrap_or(path).display().to_string()
}

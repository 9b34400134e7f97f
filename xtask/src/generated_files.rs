//! One write-or-check rule for every file xtask generates (the readable copy
//! of the generated code, the register maps, the JSON schema), so that
//! `--check` in CI and a plain run agree on what "fresh" means.
//!
//! A run writes the files whose contents changed (unchanged files keep their
//! timestamps) and removes files of the same kind that the spec no longer
//! produces; `--check` writes nothing and fails, naming every stale, missing
//! or orphaned file and the command that refreshes them.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;

/// A set of generated files in one directory.
pub struct GeneratedFiles<'a> {
    /// What the files are, for messages: "generated code", "register maps".
    pub what: &'a str,
    /// The task that refreshes them: `cargo xtask codegen`.
    pub command: &'a str,
    /// Their directory.
    pub dir: PathBuf,
    /// Their names and contents.
    pub files: Vec<(String, String)>,
    /// Files in `dir` with this suffix that are not in `files` are orphans
    /// (removed on a run, an error on a check); `None` leaves other files alone.
    pub owns_suffix: Option<&'a str>,
}

impl GeneratedFiles<'_> {
    /// Writes the files (or, with `check`, compares them) and reports.
    pub fn ensure(&self, check: bool) -> anyhow::Result<ExitCode> {
        let root = crate::root();
        let shown = |name: &str| display(&root, &self.dir.join(name));
        let orphans = self.orphans()?;
        if check {
            let mut problems: Vec<String> = self
                .files
                .iter()
                .filter(|(name, contents)| fs::read_to_string(self.dir.join(name)).ok().as_deref() != Some(contents))
                .map(|(name, _)| format!("{} is stale or missing", shown(name)))
                .collect();
            problems
                .extend(orphans.iter().map(|name| format!("{} is not generated from the spec any more", shown(name))));
            if problems.is_empty() {
                self.report_fresh();
                return Ok(ExitCode::SUCCESS);
            }
            for p in &problems {
                eprintln!("error: {p}");
            }
            eprintln!("run `{}` and commit the result", self.command);
            return Ok(ExitCode::FAILURE);
        }
        fs::create_dir_all(&self.dir).with_context(|| format!("creating {}", self.dir.display()))?;
        let mut changed = 0;
        for (name, contents) in &self.files {
            let path = self.dir.join(name);
            if fs::read_to_string(&path).ok().as_deref() == Some(contents) {
                continue;
            }
            fs::write(&path, contents).with_context(|| format!("writing {}", path.display()))?;
            println!("wrote {} ({} bytes)", shown(name), contents.len());
            changed += 1;
        }
        for name in &orphans {
            fs::remove_file(self.dir.join(name)).with_context(|| format!("removing {}", shown(name)))?;
            println!("removed {}", shown(name));
            changed += 1;
        }
        if changed == 0 {
            self.report_fresh();
        }
        Ok(ExitCode::SUCCESS)
    }

    fn report_fresh(&self) {
        let n = self.files.len();
        println!("{}: up to date ({n} file{})", self.what, if n == 1 { "" } else { "s" });
    }

    /// Files of the owned kind in the directory that the spec does not produce.
    fn orphans(&self) -> anyhow::Result<Vec<String>> {
        let Some(suffix) = self.owns_suffix else { return Ok(Vec::new()) };
        let wanted: BTreeSet<&str> = self.files.iter().map(|(name, _)| name.as_str()).collect();
        let Ok(entries) = fs::read_dir(&self.dir) else { return Ok(Vec::new()) };
        let mut out = Vec::new();
        for entry in entries {
            let name = entry?.file_name().to_string_lossy().into_owned();
            if name.ends_with(suffix) && !wanted.contains(name.as_str()) {
                out.push(name);
            }
        }
        out.sort();
        Ok(out)
    }
}

fn display(root: &Path, path: &Path) -> String {
    path.strip_prefix(root).unwrap_or(path).display().to_string()
}

#[cfg(test)]
mod tests {
    use std::process::ExitCode;

    /// `cargo test` fails on a stale generated copy, as CI's `--check` steps
    /// do: a spec edited without `cargo xtask codegen` / `docs` / `schema`.
    #[test]
    fn every_generated_file_is_fresh() {
        for (task, run) in crate::SPEC_TASKS {
            let code = run(&["--check".to_owned()]).unwrap_or_else(|e| panic!("cargo xtask {task} --check: {e:#}"));
            assert_eq!(code, ExitCode::SUCCESS, "stale files: run `cargo xtask {task}` and commit the result");
        }
    }
}

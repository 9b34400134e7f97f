//! House rules, held by tests (in the manner of rust-analyzer's tidy test):
//!
//! - The runtime knows no sensor: `yosemitech-rtu`'s own dependencies
//!   (normal and per target, not its tests') name no other crate of the
//!   workspace, so nothing generated, simulated or spec-derived can reach
//!   the runtime. Its tests may use the workspace test kit.
//! - A hand-written Rust file stays under a size ceiling, or says in
//!   [`LARGE_FILES`] why it does not yet.
//! - The product talks no process: no `issue #N` of ours, no path outside
//!   the repository (a spec cites its manual by title and revision).
//! - Every workspace member, and every project beside it, is in README's
//!   layout table and in ARCHITECTURE.md.
//! - Every test file is in a test binary: where a package's integration
//!   tests share one binary, `tests/main.rs` declares each file.
//! - Logging is opt-in: the default features of `yosemitech` (and so of the
//!   runtime) do not build `tracing`; its feature `tracing` does.

use std::path::PathBuf;

/// The names of the workspace's crates, from the root manifest's members
/// (`crates/*` expanded).
fn workspace_crates(root: &std::path::Path) -> Vec<String> {
    workspace_members(root).into_iter().map(|(_, name)| name).collect()
}

/// The workspace's members: (folder relative to the root, package name).
fn workspace_members(root: &std::path::Path) -> Vec<(String, String)> {
    let manifest: toml::Table = read(&root.join("Cargo.toml"));
    let members = manifest
        .get("workspace")
        .and_then(|w| w.get("members"))
        .and_then(toml::Value::as_array)
        .expect("the root manifest lists its members");
    let mut dirs = Vec::new();
    for member in members.iter().filter_map(toml::Value::as_str) {
        match member.strip_suffix("/*") {
            Some(parent) => {
                let entries = std::fs::read_dir(root.join(parent)).expect("a member folder");
                dirs.extend(entries.flatten().map(|e| e.path()).filter(|p| p.join("Cargo.toml").exists()));
            }
            None => dirs.push(root.join(member)),
        }
    }
    dirs.iter()
        .map(|dir| {
            let crate_manifest = read(&dir.join("Cargo.toml"));
            let name = crate_manifest["package"]["name"].as_str().expect("a package name").to_owned();
            let relative = dir.strip_prefix(root).unwrap_or(dir).to_string_lossy().replace('\\', "/");
            (relative, name)
        })
        .collect()
}

fn read(path: &std::path::Path) -> toml::Table {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.parse().unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_runtime_depends_on_no_crate_of_the_workspace() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let crates = workspace_crates(&root);
    assert!(crates.iter().any(|c| c == "yosemitech-rtu") && crates.len() > 5, "members read: {crates:?}");
    let runtime = read(&root.join("crates/yosemitech-rtu/Cargo.toml"));
    let mut tables = vec![runtime.get("dependencies")];
    if let Some(targets) = runtime.get("target").and_then(toml::Value::as_table) {
        tables.extend(targets.values().map(|target| target.get("dependencies")));
    }
    let dependencies: Vec<&String> =
        tables.into_iter().flatten().filter_map(toml::Value::as_table).flat_map(toml::Table::keys).collect();
    assert!(dependencies.iter().any(|d| *d == "serialport"), "dependencies read: {dependencies:?}");
    let inward: Vec<&&String> = dependencies.iter().filter(|d| crates.contains(d)).collect();
    assert!(inward.is_empty(), "the runtime depends on workspace crates: {inward:?}");
}

/// What a package's `features` turn on, following `crate/feature` entries
/// into the other manifests given: each entry as `crate:entry`.
fn enabled(manifests: &[(&str, toml::Table)], package: &str, features: &[&str]) -> Vec<String> {
    let mut todo: Vec<(String, String)> = features.iter().map(|f| (package.to_owned(), (*f).to_owned())).collect();
    let mut seen = Vec::new();
    while let Some((package, feature)) = todo.pop() {
        let entry = format!("{package}:{feature}");
        if seen.contains(&entry) {
            continue;
        }
        seen.push(entry);
        let Some((_, manifest)) = manifests.iter().find(|(name, _)| *name == package) else { continue };
        let listed = manifest.get("features").and_then(|f| f.get(&feature)).and_then(toml::Value::as_array);
        for next in listed.into_iter().flatten().filter_map(toml::Value::as_str) {
            match next.split_once('/') {
                Some((dependency, feature)) if manifests.iter().any(|(name, _)| *name == dependency) => {
                    todo.push((dependency.to_owned(), feature.to_owned()));
                }
                _ => todo.push((package.clone(), next.to_owned())),
            }
        }
    }
    seen
}

#[test]
fn logging_is_opt_in() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let manifests = [
        ("yosemitech", read(&root.join("crates/yosemitech/Cargo.toml"))),
        ("yosemitech-rtu", read(&root.join("crates/yosemitech-rtu/Cargo.toml"))),
    ];
    let builds_tracing = |entries: &[String]| entries.iter().any(|e| e.ends_with(":dep:tracing"));
    let by_default = enabled(&manifests, "yosemitech", &["default"]);
    assert!(by_default.iter().any(|e| e == "yosemitech-rtu:std"), "read: {by_default:?}");
    assert!(!builds_tracing(&by_default), "the default features build tracing: {by_default:?}");
    let asked = enabled(&manifests, "yosemitech", &["default", "tracing"]);
    assert!(builds_tracing(&asked), "feature `tracing` does not build tracing: {asked:?}");
}

/// Lines a hand-written Rust file may have.
const CEILING: usize = 1000;

/// Files over [`CEILING`], each with why and how it is to be split. A file
/// listed here that is back under the ceiling fails too: take it off.
const LARGE_FILES: &[(&str, &str)] = &[];

/// The workspace root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Files under `dir` whose name ends with one of `extensions`, skipping
/// build output, generated code and version control.
fn files(dir: &std::path::Path, extensions: &[&str], out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if path.is_dir() {
            if !matches!(name.as_str(), "target" | "generated" | ".git" | "corpus" | "artifacts") {
                files(&path, extensions, out);
            }
        } else if extensions.iter().any(|e| name.ends_with(e)) {
            out.push(path);
        }
    }
}

fn relative(path: &std::path::Path) -> String {
    let root = root();
    path.strip_prefix(&root).unwrap_or(path).to_string_lossy().replace('\\', "/")
}

#[test]
fn hand_written_files_stay_under_the_ceiling() {
    let root = root();
    let mut rust = Vec::new();
    for dir in ["crates", "xtask", "tests", "fuzz", "firmware"] {
        files(&root.join(dir), &[".rs"], &mut rust);
    }
    assert!(rust.len() > 20, "{} Rust files found", rust.len());
    let mut problems = Vec::new();
    for path in &rust {
        let name = relative(path);
        let lines = std::fs::read_to_string(path).map(|t| t.lines().count()).unwrap_or(0);
        let listed = LARGE_FILES.iter().any(|(f, _)| *f == name);
        if lines > CEILING && !listed {
            problems.push(format!("{name}: {lines} lines, over {CEILING}: split it along its own sections"));
        }
        if lines <= CEILING && listed {
            problems.push(format!("{name}: {lines} lines, back under {CEILING}: take it off LARGE_FILES"));
        }
    }
    for (name, _) in LARGE_FILES {
        if !root.join(name).exists() {
            problems.push(format!("{name}: listed in LARGE_FILES but gone"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// What the product must not say: our own issue numbers, and paths out of
/// the repository. A source's own tracker is cited by name
/// ("YosemitechModbus issue 19"), never as `issue #N`.
fn process_talk(text: &str) -> Option<String> {
    for (number, line) in text.lines().enumerate() {
        let lower = line.to_ascii_lowercase();
        if let Some(at) = lower.find("issue #")
            && lower[at + 7..].starts_with(|c: char| c.is_ascii_digit())
        {
            return Some(format!("line {}: `{}`", number + 1, line.trim()));
        }
        if line.contains("../shared") {
            return Some(format!("line {}: a path out of the repository: `{}`", number + 1, line.trim()));
        }
    }
    None
}

#[test]
fn the_product_talks_no_process() {
    let root = root();
    let mut product = Vec::new();
    files(&root.join("spec"), &[".yaml"], &mut product);
    files(&root.join("docs"), &[".md"], &mut product);
    // The importer's page documents where it reads the manuals.
    product.retain(|p| !p.ends_with("docs/importer.md"));
    files(&root.join("crates"), &[".rs", ".toml", ".md"], &mut product);
    for top in ["README.md", "ARCHITECTURE.md", "BENCHMARKS.md", "Cargo.toml"] {
        product.push(root.join(top));
    }
    // The importer reads the vendor's manuals where they are kept, beside
    // the repository: xtask and its tests may name that place; its issue
    // numbers they may not.
    let mut tooling = Vec::new();
    files(&root.join("xtask"), &[".rs", ".toml"], &mut tooling);
    files(&root.join("tests"), &[".rs", ".toml", ".md", ".yaml"], &mut tooling);
    tooling.push(root.join("docs/importer.md"));
    assert!(product.len() > 20 && !tooling.is_empty(), "{} product files", product.len());
    let mut problems = Vec::new();
    for path in &product {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        if let Some(what) = process_talk(&text) {
            problems.push(format!("{}: {what}", relative(path)));
        }
    }
    for path in &tooling {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        if let Some(what) = process_talk(&text).filter(|w| !w.contains("out of the repository")) {
            problems.push(format!("{}: {what}", relative(path)));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_process_rule_catches_what_it_is_for() {
    assert!(process_talk("Benchmarks (issue #6): shared").is_some());
    assert!(process_talk("# (../../shared/manuals/Y510.txt), with").is_some());
    assert!(process_talk("sources: [YosemitechModbus issue 19]").is_none());
    assert!(process_talk("the issue #s of a tracker").is_none());
}

#[test]
fn every_member_is_in_the_readme_layout_and_the_architecture() {
    let root = root();
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README.md");
    let architecture = std::fs::read_to_string(root.join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let manifest: toml::Table = read(&root.join("Cargo.toml"));
    // The members, and the projects kept beside the workspace (`exclude`).
    let mut members = workspace_members(&root);
    let excluded = manifest.get("workspace").and_then(|w| w.get("exclude")).and_then(toml::Value::as_array);
    for dir in excluded.into_iter().flatten().filter_map(toml::Value::as_str) {
        let name = std::fs::read_to_string(root.join(dir).join("Cargo.toml"))
            .ok()
            .and_then(|t| t.parse::<toml::Table>().ok())
            .and_then(|t| t.get("package")?.get("name")?.as_str().map(str::to_owned))
            .unwrap_or_else(|| dir.to_owned());
        members.push((dir.to_owned(), name));
    }
    assert!(members.len() > 5, "{members:?}");
    let mut missing = Vec::new();
    for (dir, name) in &members {
        let row = readme
            .lines()
            .any(|l| l.starts_with("| `") && (l.contains(&format!("`{dir}`")) || l.contains(&format!("`{dir}/`"))));
        if !row {
            missing.push(format!("{dir} has no row in README's layout table"));
        }
        if !architecture.contains(name.as_str()) && !architecture.contains(dir.as_str()) {
            missing.push(format!("{dir} ({name}) is not in ARCHITECTURE.md"));
        }
    }
    assert!(missing.is_empty(), "{}", missing.join("\n"));
}

/// The test files a package's `[[test]]` targets build: each target's file
/// and the modules it declares (`mod name;`), as paths relative to the
/// package's `tests/` folder.
fn files_in_test_targets(package: &std::path::Path, manifest: &toml::Table) -> Vec<String> {
    let mut built = Vec::new();
    let targets = manifest.get("test").and_then(toml::Value::as_array);
    for target in targets.into_iter().flatten() {
        let path = match (
            target.get("path").and_then(toml::Value::as_str),
            target.get("name").and_then(toml::Value::as_str),
        ) {
            (Some(path), _) => path.to_owned(),
            (None, Some(name)) => format!("tests/{name}.rs"),
            (None, None) => continue,
        };
        let Some(file) = path.strip_prefix("tests/") else { continue };
        built.push(file.to_owned());
        let text = std::fs::read_to_string(package.join(&path)).unwrap_or_default();
        let modules = text.lines().filter_map(|l| l.trim().strip_prefix("mod ")?.strip_suffix(';'));
        for module in modules {
            built.push(format!("{module}.rs"));
            built.push(format!("{module}/mod.rs"));
        }
    }
    built
}

/// A package whose integration tests share one binary (`autotests = false`)
/// names each test file, in `tests/main.rs` or as a `[[test]]` of its own:
/// a file it forgets would never build, and its tests never run.
#[test]
fn every_test_file_is_in_a_test_binary() {
    let root = root();
    let mut problems = Vec::new();
    let mut shared = 0;
    for (dir, _) in workspace_members(&root) {
        let package = root.join(&dir);
        let manifest = read(&package.join("Cargo.toml"));
        let autotests = manifest.get("package").and_then(|p| p.get("autotests")).and_then(toml::Value::as_bool);
        if autotests != Some(false) {
            continue;
        }
        shared += 1;
        let built = files_in_test_targets(&package, &manifest);
        let Ok(entries) = std::fs::read_dir(package.join("tests")) else { continue };
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let file = if entry.path().is_dir() { format!("{name}/mod.rs") } else { name };
            let rust = file.ends_with(".rs") && package.join("tests").join(&file).is_file();
            if rust && !built.contains(&file) {
                problems.push(format!("{dir}/tests/{file}: in no test binary: add `mod` for it to tests/main.rs"));
            }
        }
    }
    assert!(shared > 0, "no package shares a test binary");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The command a line of command `own`'s source reaches, if another:
/// `crate::commands::X`, or, in a command's top-level file, `super::X`.
fn imported_command(line: &str, own: &str, top_level: bool) -> Option<String> {
    let line = line.trim();
    if line.starts_with("//") {
        return None;
    }
    let mut names = Vec::new();
    if let Some(at) = line.find("crate::commands::") {
        names.push(&line[at + "crate::commands::".len()..]);
    }
    if top_level && let Some(at) = line.find("super::") {
        names.push(&line[at + "super::".len()..]);
    }
    names
        .into_iter()
        .map(|rest| rest.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).next().unwrap_or_default())
        .find(|name| !name.is_empty() && *name != own && *name != "self" && *name != "super")
        .map(str::to_owned)
}

/// Imports of one command by another still to be moved out, each with why
/// it remains. One that is gone fails the test too: take it off.
const COMMAND_IMPORTS_LEFT: &[(&str, &str, &str)] = &[(
    "demo",
    "measure",
    "the procedure runner (run_procedure, show) is still the measure command's; it belongs in yosemitech-ops",
)];

/// cargo's layout: each command parses its arguments, calls the library
/// and renders; what two commands share lives outside `commands/` (in the
/// CLI's modules or `yosemitech-ops`), so no command imports another. A
/// command's own sub-modules (`commands/decode/*.rs`) may use their parent;
/// `commands/mod.rs` is the dispatcher.
#[test]
fn no_command_imports_another() {
    let dir = root().join("crates/yosemitech-cli/src/commands");
    let mut sources = Vec::new();
    files(&dir, &[".rs"], &mut sources);
    assert!(sources.len() > 10, "the commands are found");
    let mut problems = Vec::new();
    let mut left = std::collections::BTreeSet::new();
    for path in &sources {
        let relative_path = path.strip_prefix(&dir).unwrap_or(path);
        let mut parts = relative_path.iter().map(|p| p.to_string_lossy().into_owned());
        let first = parts.next().unwrap_or_default();
        if first == "mod.rs" {
            continue;
        }
        let own = first.trim_end_matches(".rs").to_owned();
        let top_level = first.ends_with(".rs") || relative_path.ends_with("mod.rs");
        let text = std::fs::read_to_string(path).unwrap_or_default();
        for (number, line) in text.lines().enumerate() {
            if let Some(other) = imported_command(line, &own, top_level) {
                if COMMAND_IMPORTS_LEFT.iter().any(|(a, b, _)| *a == own && *b == other) {
                    left.insert((own.clone(), other));
                } else {
                    problems.push(format!("{}:{}: `{own}` imports the command `{other}`", relative(path), number + 1));
                }
            }
        }
    }
    for (a, b, why) in COMMAND_IMPORTS_LEFT {
        if !left.contains(&((*a).to_owned(), (*b).to_owned())) {
            problems.push(format!("`{a}` no longer imports `{b}` ({why}): take it off COMMAND_IMPORTS_LEFT"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_command_import_rule_catches_what_it_is_for() {
    assert_eq!(imported_command("use crate::commands::read::derived_json;", "poll", true).as_deref(), Some("read"));
    assert_eq!(imported_command("use super::scan::{self, Found};", "demo", true).as_deref(), Some("scan"));
    assert_eq!(
        imported_command("        return super::plan::run(catalog, args, out);", "set_address", true).as_deref(),
        Some("plan")
    );
    assert_eq!(imported_command("use super::{error_json, pretty};", "decode", false), None);
    assert_eq!(imported_command("use crate::commands::decode::DecodeArgs;", "decode", false), None);
    assert_eq!(imported_command("use crate::derived::derived_json;", "poll", true), None);
}

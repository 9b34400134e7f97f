//! The runtime knows no sensor: `yosemitech-rtu`'s own dependencies (normal
//! and per target, not its tests') name no other crate of the workspace, so
//! nothing generated, simulated or spec-derived can reach the runtime. Its
//! tests may use the workspace test kit.

use std::path::PathBuf;

/// The names of the workspace's crates, from the root manifest's members
/// (`crates/*` expanded).
fn workspace_crates(root: &std::path::Path) -> Vec<String> {
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
            crate_manifest["package"]["name"].as_str().expect("a package name").to_owned()
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

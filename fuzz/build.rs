//! Embeds every spec file of the workspace's `spec/` directory in the fuzz
//! targets: writes `OUT_DIR/spec_files.rs`, a table of `spec/<name>` paths
//! and `include_str!`s, so the targets need no files at run time.
//! Data-driven: a new `spec/*.yaml` is picked up on the next build (the
//! directory itself is watched), with no change to the targets.

use std::fmt::Write as _;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").ok_or("CARGO_MANIFEST_DIR is not set")?);
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").ok_or("OUT_DIR is not set")?);
    let spec_dir = manifest_dir.join("..").join("spec");
    println!("cargo::rerun-if-changed={}", spec_dir.display());

    let mut files = Vec::new();
    for entry in std::fs::read_dir(&spec_dir).map_err(|e| format!("cannot list {}: {e}", spec_dir.display()))? {
        let path = entry?.path();
        let is_yaml = matches!(path.extension().and_then(|e| e.to_str()), Some("yaml" | "yml"));
        if is_yaml && path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    if files.is_empty() {
        return Err(format!("{} holds no spec files", spec_dir.display()).into());
    }

    let mut code = String::from(
        "/// The spec files, compiled in so that the targets need no files at run\n\
         /// time: `spec/<file name>` and text, every `spec/*.yaml` in name order.\n\
         pub const SPEC_FILES: &[(&str, &str)] = &[\n",
    );
    for path in &files {
        println!("cargo::rerun-if-changed={}", path.display());
        let name = path.file_name().and_then(|n| n.to_str()).ok_or("spec file name is not UTF-8")?;
        let absolute = path.canonicalize()?;
        let absolute = absolute.to_str().ok_or("spec path is not UTF-8")?;
        writeln!(code, "    ({:?}, include_str!({absolute:?})),", format!("spec/{name}"))?;
    }
    code.push_str("];\n");
    std::fs::write(out_dir.join("spec_files.rs"), code)?;
    Ok(())
}

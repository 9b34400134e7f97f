//! Embeds every spec file of `spec/` (a symlink to the workspace's spec
//! directory) in the binary: writes `OUT_DIR/embedded_spec.rs`, a table of
//! file names and `include_str!`s. Data-driven: a new `spec/*.yaml` is picked
//! up on the next build (the directory itself is watched).

use std::fmt::Write as _;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").ok_or("CARGO_MANIFEST_DIR is not set")?);
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").ok_or("OUT_DIR is not set")?);
    let spec_dir = manifest_dir.join("spec");
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
        "/// The spec files compiled into the binary, by file name, in name order.\n\
         pub static EMBEDDED_SPEC: &[(&str, &str)] = &[\n",
    );
    for path in &files {
        println!("cargo::rerun-if-changed={}", path.display());
        let name = path.file_name().and_then(|n| n.to_str()).ok_or("spec file name is not UTF-8")?;
        let absolute = path.canonicalize()?;
        let absolute = absolute.to_str().ok_or("spec path is not UTF-8")?;
        writeln!(code, "    ({name:?}, include_str!({absolute:?})),")?;
    }
    code.push_str("];\n");
    std::fs::write(out_dir.join("embedded_spec.rs"), code)?;
    Ok(())
}

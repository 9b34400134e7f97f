//! The built-in spec: every `spec/*.yaml` of the workspace at build time,
//! compiled in (`build.rs`), so that a tool serves every sensor with no
//! file beside it; and spec files loaded at run time, whose includes of
//! the shared fragments (`yosemitech-common.yaml`) fall back on the
//! built-in copies.

use std::io;
use std::path::{Path, PathBuf};

use yosemitech_spec::sources::{FsSources, MemSources, Sources};
use yosemitech_spec::{Diagnostics, Spec, load_with};

include!(concat!(env!("OUT_DIR"), "/embedded_spec.rs"));

/// The virtual directory of the built-in spec files, as diagnostics name it.
pub const BUILT_IN_DIR: &str = "<built-in spec>";

/// The built-in files as a [`Sources`].
fn built_in_sources() -> MemSources {
    EMBEDDED_SPEC
        .iter()
        .fold(MemSources::default(), |sources, (name, text)| sources.with(Path::new(BUILT_IN_DIR).join(name), *text))
}

/// The file system, with the built-in files as a fallback for includes.
struct Overlay {
    built_in: MemSources,
}

impl Sources for Overlay {
    fn read(&self, path: &Path) -> io::Result<String> {
        match FsSources.read(path) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                let fallback = path.file_name().map(|name| Path::new(BUILT_IN_DIR).join(name));
                fallback.and_then(|p| self.built_in.read(&p).ok()).ok_or(e)
            }
            other => other,
        }
    }

    fn yaml_files(&self, dir: &Path) -> io::Result<Vec<PathBuf>> {
        FsSources.yaml_files(dir)
    }

    fn is_dir(&self, path: &Path) -> bool {
        FsSources.is_dir(path)
    }
}

/// The built-in sensors. Their diagnostics, should they not load, are a
/// fault of the build: the build's tests load them.
pub fn load() -> Result<Spec, Diagnostics> {
    load_with(&built_in_sources(), &[PathBuf::from(BUILT_IN_DIR)])
}

/// The sensors of `path` (a spec file, or a directory of them), its
/// includes found beside it or among the built-in files.
pub fn load_file(path: &Path) -> Result<Spec, Diagnostics> {
    load_with(&Overlay { built_in: built_in_sources() }, &[path.to_path_buf()])
}

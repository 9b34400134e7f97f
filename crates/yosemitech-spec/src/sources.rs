//! Where spec files come from: the file system, or memory (tests, fuzzing).

use std::collections::BTreeMap;
use std::io;
use std::path::{Component, Path, PathBuf};

/// The largest spec file the loader reads.
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// A store of spec files.
pub trait Sources {
    /// The text of `path`.
    fn read(&self, path: &Path) -> io::Result<String>;
    /// The `.yaml`/`.yml` files directly inside `dir`, sorted; an error if `dir` is not a directory.
    fn yaml_files(&self, dir: &Path) -> io::Result<Vec<PathBuf>>;
    /// True if `path` is a directory.
    fn is_dir(&self, path: &Path) -> bool;
}

/// The file system.
#[derive(Debug, Default, Clone, Copy)]
pub struct FsSources;

fn is_yaml(path: &Path) -> bool {
    matches!(path.extension().and_then(|e| e.to_str()), Some("yaml" | "yml"))
}

impl Sources for FsSources {
    fn read(&self, path: &Path) -> io::Result<String> {
        let len = std::fs::metadata(path)?.len();
        if len > MAX_FILE_BYTES {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("file is {len} bytes; spec files are limited to {MAX_FILE_BYTES} bytes"),
            ));
        }
        std::fs::read_to_string(path)
    }

    fn yaml_files(&self, dir: &Path) -> io::Result<Vec<PathBuf>> {
        let mut files = Vec::new();
        for entry in std::fs::read_dir(dir)? {
            let path = entry?.path();
            if path.is_file() && is_yaml(&path) {
                files.push(path);
            }
        }
        files.sort();
        Ok(files)
    }

    fn is_dir(&self, path: &Path) -> bool {
        path.is_dir()
    }
}

/// Files held in memory, by path.
#[derive(Debug, Default, Clone)]
pub struct MemSources(pub BTreeMap<PathBuf, String>);

impl MemSources {
    /// Adds a file.
    pub fn with(mut self, path: impl Into<PathBuf>, text: impl Into<String>) -> Self {
        self.0.insert(path.into(), text.into());
        self
    }
}

impl Sources for MemSources {
    fn read(&self, path: &Path) -> io::Result<String> {
        let text = self.0.get(path).ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, "no such file"))?;
        if text.len() as u64 > MAX_FILE_BYTES {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("file is {} bytes; spec files are limited to {MAX_FILE_BYTES} bytes", text.len()),
            ));
        }
        Ok(text.clone())
    }

    fn yaml_files(&self, dir: &Path) -> io::Result<Vec<PathBuf>> {
        Ok(self.0.keys().filter(|p| p.parent() == Some(dir) && is_yaml(p)).cloned().collect())
    }

    fn is_dir(&self, path: &Path) -> bool {
        self.0.keys().any(|p| p.parent() == Some(path))
    }
}

/// Joins `relative` to the directory of `file`, resolving `.` and `..` lexically.
pub fn sibling(file: &Path, relative: &str) -> PathBuf {
    let joined = file.parent().unwrap_or(Path::new("")).join(relative);
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    out.push("..");
                }
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

//! Where spec files come from: the file system, or memory (tests, fuzzing).

use std::collections::BTreeMap;
use std::io;
use std::path::{Component, Path, PathBuf};

/// The largest spec file the loader reads.
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// Why a file could not be read as text: it is not UTF-8. Carried inside
/// the [`io::Error`] that [`Sources::read`] returns (kind `InvalidData`), so
/// the loader can point at the first bad byte.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NotUtf8 {
    /// Line of the first byte that is not UTF-8 (1-based).
    pub line: u32,
    /// Its column, in characters (1-based).
    pub column: u32,
    /// That line, bad bytes replaced by U+FFFD, for display.
    pub text: String,
}

impl std::fmt::Display for NotUtf8 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "the file is not UTF-8 text (line {}, column {})", self.line, self.column)
    }
}

impl std::error::Error for NotUtf8 {}

impl NotUtf8 {
    /// Where `bytes` stop being UTF-8, or `None` if they are UTF-8.
    pub fn find(bytes: &[u8]) -> Option<Self> {
        let valid_up_to = std::str::from_utf8(bytes).err()?.valid_up_to();
        let good = String::from_utf8_lossy(bytes.get(..valid_up_to).unwrap_or(&[])).into_owned();
        let line = good.matches('\n').count() as u32 + 1;
        let line_start = good.rfind('\n').map_or(0, |i| i + 1);
        let column = good.get(line_start..).map_or(0, |l| l.chars().count()) as u32 + 1;
        let rest = bytes.get(line_start..).unwrap_or(&[]);
        let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        let text = String::from_utf8_lossy(rest.get(..end).unwrap_or(&[])).into_owned();
        Some(Self { line, column, text })
    }
}

fn too_large(bytes: Option<usize>) -> io::Error {
    let size = bytes.map_or_else(|| "more than 1 MiB".to_string(), |n| format!("{n} bytes"));
    io::Error::new(
        io::ErrorKind::FileTooLarge,
        format!("the file is {size}; spec files are limited to {MAX_FILE_BYTES} bytes (1 MiB)"),
    )
}

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
        use std::io::Read;
        let file = std::fs::File::open(path)?;
        if file.metadata()?.is_dir() {
            return Err(io::Error::new(io::ErrorKind::InvalidInput, "it is a directory"));
        }
        // Read at most one byte past the limit: the length on disk may lie
        // (a device, a growing file).
        let mut bytes = Vec::new();
        file.take(MAX_FILE_BYTES + 1).read_to_end(&mut bytes)?;
        if bytes.len() as u64 > MAX_FILE_BYTES {
            return Err(too_large(None));
        }
        String::from_utf8(bytes).map_err(|e| match NotUtf8::find(e.as_bytes()) {
            Some(bad) => io::Error::new(io::ErrorKind::InvalidData, bad),
            None => io::Error::new(io::ErrorKind::InvalidData, e),
        })
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
            return Err(too_large(Some(text.len())));
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
    normalize(&file.parent().unwrap_or(Path::new("")).join(relative))
}

/// Resolves `.` and `..` in `path` lexically (without touching the file system).
pub fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
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

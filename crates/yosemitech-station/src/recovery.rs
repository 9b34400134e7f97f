//! Knowing, at start, that the previous run of a store did not stop
//! cleanly (a power cut, a kill, a crash), so the logger checks the store
//! and says so before it goes on.
//!
//! A run leaves a marker file beside the store (`<store>.running`) from its
//! start until its clean stop. SQLite itself keeps the store consistent
//! through a power cut (WAL, `synchronous = FULL`: a committed reading is on
//! disk, a transaction cut short is discarded at the next open); the marker
//! only tells the next run that there is something to check and report.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write as _};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use crate::time::rfc3339;

/// The marker of one run; [`RunMarker::finish`] at a clean stop.
#[derive(Debug)]
pub struct RunMarker {
    path: PathBuf,
}

/// What an earlier run that did not stop cleanly left behind.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UncleanStop {
    /// The marker's text: that run's process id and start time, as it wrote them.
    pub run: String,
}

impl RunMarker {
    /// The marker file of the store at `store`.
    pub fn path_for(store: &Path) -> PathBuf {
        let mut name = store.file_name().map(|n| n.to_os_string()).unwrap_or_default();
        name.push(".running");
        store.with_file_name(name)
    }

    /// Records, durably, that a run of the store at `store` begins, and
    /// returns the previous run's marker when that run did not stop cleanly.
    ///
    /// # Errors
    ///
    /// The marker cannot be read or written (the store's directory is not
    /// writable).
    pub fn begin(store: &Path) -> io::Result<(Self, Option<UncleanStop>)> {
        let path = Self::path_for(store);
        let previous = match fs::read_to_string(&path) {
            Ok(text) => Some(UncleanStop { run: text.trim().to_owned() }),
            Err(e) if e.kind() == io::ErrorKind::NotFound => None,
            Err(e) => return Err(e),
        };
        let mut file = OpenOptions::new().write(true).create(true).truncate(true).open(&path)?;
        writeln!(file, "process {} started {}", std::process::id(), rfc3339(SystemTime::now()))?;
        file.sync_all()?;
        sync_directory(&path);
        Ok((Self { path }, previous))
    }

    /// The run stops cleanly: the marker goes.
    ///
    /// # Errors
    ///
    /// The marker cannot be removed.
    pub fn finish(self) -> io::Result<()> {
        fs::remove_file(&self.path)?;
        sync_directory(&self.path);
        Ok(())
    }
}

/// Makes a file's creation or removal durable. Best effort: not every
/// platform can open a directory to sync it, and the marker is advice, not data.
fn sync_directory(file: &Path) {
    if let Some(dir) = file.parent().filter(|d| !d.as_os_str().is_empty()) {
        let _ = File::open(dir).and_then(|d| d.sync_all());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_that_did_not_finish_is_reported_by_the_next() {
        let dir = tempfile::tempdir().unwrap();
        let store = dir.path().join("station.sqlite");
        let (first, previous) = RunMarker::begin(&store).unwrap();
        assert_eq!(previous, None);
        assert!(RunMarker::path_for(&store).exists());
        // The first run is killed: its marker stays.
        std::mem::forget(first);
        let (second, previous) = RunMarker::begin(&store).unwrap();
        let previous = previous.expect("the killed run is reported");
        assert!(previous.run.contains(&format!("process {}", std::process::id())), "{previous:?}");
        second.finish().unwrap();
        assert!(!RunMarker::path_for(&store).exists());
        let (third, previous) = RunMarker::begin(&store).unwrap();
        assert_eq!(previous, None, "a clean stop leaves nothing to report");
        third.finish().unwrap();
    }
}

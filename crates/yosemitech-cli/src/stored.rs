//! Reading a station's store for `watch` and `plot`: the readings of a time
//! range, and every probe's newest one, as [`readings`](crate::readings) data.

use std::path::Path;
use std::time::{Duration, SystemTime};

use crate::error::{CliError, Result};
use crate::readings::{Reading, Snapshot};

/// A station's store, opened for reading.
pub struct StoredReadings {
    _private: (),
}

impl StoredReadings {
    /// Opens the store at `path`, which must exist (watching or plotting
    /// never creates one).
    pub fn open(path: &Path) -> Result<Self> {
        Err(CliError::usage(format!("{}: the station store is not built in yet", path.display())))
    }

    /// Readings with `from <= time < to`.
    pub fn range(&self, _from: SystemTime, _to: SystemTime) -> Result<Vec<Reading>> {
        Ok(Vec::new())
    }

    /// Every probe's newest reading.
    pub fn latest(&self) -> Result<Vec<Reading>> {
        Ok(Vec::new())
    }

    /// Every probe's latest values, and the history and counts of `window` before `now`.
    pub fn snapshot(&self, now: SystemTime, window: Duration, history: usize) -> Result<Snapshot> {
        let from = now.checked_sub(window).unwrap_or(std::time::UNIX_EPOCH);
        Ok(Snapshot::from_readings(&self.range(from, now)?, history))
    }
}

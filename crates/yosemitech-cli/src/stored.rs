//! Reading a station's store (`yosemitech_station::Store`) for `watch` and
//! `plot`: the readings of a time range, and every probe's newest one, as
//! [`readings`](crate::readings) data.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use yosemitech_station::{Datum, Store, StoreError, StoredReading};

use crate::error::{CliError, Result};
use crate::readings::{Reading, Snapshot, Value};

/// A station's store, opened for reading.
pub struct StoredReadings {
    store: Store,
    path: PathBuf,
}

impl StoredReadings {
    /// Opens the store at `path`, which must exist: watching or plotting
    /// never creates one.
    pub fn open(path: &Path) -> Result<Self> {
        Ok(Self { store: open_existing(path)?, path: path.to_owned() })
    }

    /// Readings with `from <= time < to`, in the order they were committed.
    pub fn range(&self, from: SystemTime, to: SystemTime) -> Result<Vec<Reading>> {
        let stored = self.store.range(from, to).map_err(|e| failed(&self.path, &e))?;
        Ok(stored.into_iter().map(reading).collect())
    }

    /// Every probe's newest reading.
    pub fn latest(&self) -> Result<Vec<Reading>> {
        let stored = self.store.latest_per_probe().map_err(|e| failed(&self.path, &e))?;
        Ok(stored.into_iter().map(reading).collect())
    }

    /// Every probe's newest values, with up to `history` values per
    /// measurement and the error and retry counts of the `window` before
    /// `now`. A probe silent for longer than the window still shows, with
    /// its newest reading.
    pub fn snapshot(&self, now: SystemTime, window: Duration, history: usize) -> Result<Snapshot> {
        let from = now.checked_sub(window).unwrap_or(UNIX_EPOCH);
        // A reading committed in the same millisecond as `now` is included.
        let mut readings = self.range(from, now + Duration::from_millis(1))?;
        for newest in self.latest()? {
            if newest.at < from {
                readings.push(newest);
            }
        }
        Ok(Snapshot::from_readings(&readings, history))
    }
}

/// The station store at `path`, which must exist: the views and `export`
/// read a store and never create one, and all say so in the same words.
pub fn open_existing(path: &Path) -> Result<Store> {
    if !path.is_file() {
        return Err(CliError::usage(format!("no station store at {}", path.display())).hint(
            "pass the `[storage] path` of the station file; `yosemitech log --config station.toml` writes the store",
        ));
    }
    Store::open(path).map_err(|e| failed(path, &e))
}

fn failed(path: &Path, e: &StoreError) -> CliError {
    CliError::device(format!("{}: {e}", path.display()))
        .hint("is it a station's store (`yosemitech log` writes one)? `yosemitech export` reads it too")
}

/// A stored reading as the views see it: numbers only (text values, such as
/// enum names, have no place on a sparkline or an axis).
fn reading(stored: StoredReading) -> Reading {
    let r = stored.reading;
    Reading {
        at: r.timestamp,
        probe: r.probe,
        sensor: r.sensor,
        serial: r.serial_number,
        values: r
            .values
            .into_iter()
            .filter_map(|m| match m.value {
                Datum::Number(value) => Some(Value { measurement: m.name, unit: m.unit.unwrap_or_default(), value }),
                Datum::Text(_) | Datum::NotComputable(_) => None,
            })
            .collect(),
        retries: r.retries,
        error: r.error,
    }
}

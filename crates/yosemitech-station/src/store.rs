//! The station's storage: every reading in a SQLite file, and the outbox
//! cursors that say which of them each publisher has delivered.
//!
//! # Schema (version 4)
//!
//! ```sql
//! -- One row per reading, in the order the logger committed them: `id`
//! -- (AUTOINCREMENT, never reused) is the publish order and the reading's
//! -- identity downstream (MQTT payloads carry it).
//! CREATE TABLE reading (
//!     id            INTEGER PRIMARY KEY AUTOINCREMENT,
//!     timestamp_ms  INTEGER NOT NULL,  -- UTC, milliseconds since the Unix epoch
//!     station       TEXT    NOT NULL,  -- the configuration's station name
//!     bus           TEXT    NOT NULL,  -- the bus name
//!     probe         TEXT    NOT NULL,  -- the probe's label
//!     sensor        TEXT    NOT NULL,  -- the spec's sensor name
//!     address       INTEGER NOT NULL,  -- Modbus slave address
//!     serial_number TEXT,              -- as the probe reported it, when it did
//!     firmware      TEXT,              -- likewise
//!     retries       INTEGER NOT NULL,  -- requests repeated to get this reading
//!     error         TEXT,              -- why the reading failed (NULL: it did not)
//!     calibration_id INTEGER REFERENCES calibration (id)
//!                                      -- the calibration in force: set at insert to the latest
//!                                      -- one of this serial number and sensor at or before
//!                                      -- the reading's time (NULL: none recorded)
//! );
//! CREATE INDEX reading_time ON reading (timestamp_ms);
//! -- The values of a reading, in the order the probe's plan reads them.
//! CREATE TABLE reading_value (
//!     reading_id INTEGER NOT NULL REFERENCES reading (id),
//!     position   INTEGER NOT NULL,
//!     name       TEXT    NOT NULL,     -- the spec's field name
//!     number     REAL,                 -- a numeric value ...
//!     text       TEXT,                 -- ... or a textual one (enum names) ...
//!     unit       TEXT,                 -- the spec's unit
//!     derived    INTEGER NOT NULL DEFAULT 0,  -- 1: a derived quantity of the spec, computed by the station
//!     error      TEXT,                 -- ... or why a derived quantity has no value: exactly one of the three is set
//!     PRIMARY KEY (reading_id, position)
//! ) WITHOUT ROWID;
//! -- Every calibration of a probe the field tool performed (`yosemitech
//! -- calibrate`), one row each; the coefficients, standards, readings and
//! -- fit are JSON (see crate::calibration).
//! CREATE TABLE calibration (
//!     id            INTEGER PRIMARY KEY AUTOINCREMENT,
//!     timestamp_ms  INTEGER NOT NULL,  -- when the coefficients were written
//!     sensor        TEXT    NOT NULL,
//!     model         TEXT,
//!     serial_number TEXT,
//!     firmware      TEXT,
//!     address       INTEGER NOT NULL,
//!     port          TEXT    NOT NULL,
//!     kind          TEXT    NOT NULL,  -- linear, ph_three_point, ph_electrode, restore
//!     block         TEXT,              -- the write command calibrated (NULL: every block)
//!     note          TEXT,              -- the operator's note
//!     before        TEXT    NOT NULL,  -- coefficients before: {block: {field: value}}
//!     after         TEXT    NOT NULL,  -- coefficients after, likewise
//!     standards     TEXT    NOT NULL,  -- [value, ...]
//!     readings      TEXT    NOT NULL,  -- every reading taken, per standard
//!     fit           TEXT               -- the fit (K, B, residuals, R²), if one was made
//! );
//! CREATE INDEX calibration_probe ON calibration (serial_number, sensor, timestamp_ms);
//! -- The outbox, one cursor per publisher (`mqtt`; Monitor My Watershed
//! -- keeps one per probe, `monitor_my_watershed/<label>`, with
//! -- `reading_probe` below): every reading (of that probe) with
//! -- id <= published_up_to has been delivered by that publisher. A
//! -- publisher without a row has delivered nothing (0).
//! CREATE TABLE outbox (
//!     publisher       TEXT    PRIMARY KEY,
//!     published_up_to INTEGER NOT NULL
//! ) WITHOUT ROWID;
//! CREATE INDEX reading_probe ON reading (probe, id);
//! ```
//!
//! `PRAGMA user_version` holds the schema version. A file of version 1
//! (no `derived` and `error` columns) is migrated in place when opened:
//! its values are measured ones, which is what the new columns' defaults
//! say. A file of version 2 (or 1) gains the `calibration` table and
//! `reading.calibration_id` (NULL for the readings it holds: no calibration
//! was recorded then). A file of version 3 (or older) had one outbox
//! cursor, MQTT's: it becomes the `mqtt` publisher's row, so MQTT resumes
//! where it stopped, and any other publisher starts from the first reading
//! the file holds (a portal added to an old station receives its history).
//! A file of another version is refused rather than misread.
//!
//! The same file type, holding calibrations only, is the field tool's
//! calibration history outside a station.
//!
//! # Durability
//!
//! The file runs in WAL mode with `synchronous = FULL`: when
//! [`Store::insert`] or [`Store::mark_published`] returns, the change is
//! committed and survives a crash of the process or of the machine. Several
//! processes may open the same file (a logger writing, `export` reading);
//! a writer waits up to [`BUSY_TIMEOUT`] for another.

use std::path::Path;
use std::time::{Duration, SystemTime};

use rusqlite::{Connection, OptionalExtension as _, params};

use crate::time::{from_unix_ms, unix_ms};

/// How long a write waits for another connection's write to finish.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(10);

/// The schema version this crate writes and reads.
pub const SCHEMA_VERSION: i64 = 4;

/// The MQTT publisher's name in the outbox (the one cursor of schema 3 and before).
pub const MQTT_PUBLISHER: &str = "mqtt";

/// From version 1: values gain the derived mark and the error of a
/// derived quantity that could not be computed.
const MIGRATE_1_TO_2: &str = "
ALTER TABLE reading_value ADD COLUMN derived INTEGER NOT NULL DEFAULT 0;
ALTER TABLE reading_value ADD COLUMN error TEXT;
";

/// From version 2: the calibration history, and the calibration in force
/// for each reading.
const MIGRATE_2_TO_3: &str = "
CREATE TABLE calibration (
    id            INTEGER PRIMARY KEY AUTOINCREMENT,
    timestamp_ms  INTEGER NOT NULL,
    sensor        TEXT    NOT NULL,
    model         TEXT,
    serial_number TEXT,
    firmware      TEXT,
    address       INTEGER NOT NULL,
    port          TEXT    NOT NULL,
    kind          TEXT    NOT NULL,
    block         TEXT,
    note          TEXT,
    before        TEXT    NOT NULL,
    after         TEXT    NOT NULL,
    standards     TEXT    NOT NULL,
    readings      TEXT    NOT NULL,
    fit           TEXT
);
CREATE INDEX calibration_probe ON calibration (serial_number, sensor, timestamp_ms);
ALTER TABLE reading ADD COLUMN calibration_id INTEGER REFERENCES calibration (id);
";

/// From version 3: the single outbox cursor becomes one cursor per
/// publisher; the old cursor was MQTT's. A publisher with a cursor per
/// probe finds a probe's pending readings through `reading_probe`.
const MIGRATE_3_TO_4: &str = "
CREATE INDEX reading_probe ON reading (probe, id);
CREATE TABLE outbox_v4 (
    publisher       TEXT    PRIMARY KEY,
    published_up_to INTEGER NOT NULL
) WITHOUT ROWID;
INSERT INTO outbox_v4 (publisher, published_up_to) SELECT 'mqtt', published_up_to FROM outbox;
DROP TABLE outbox;
ALTER TABLE outbox_v4 RENAME TO outbox;
";

const SCHEMA: &str = "
CREATE TABLE reading (
    id            INTEGER PRIMARY KEY AUTOINCREMENT,
    timestamp_ms  INTEGER NOT NULL,
    station       TEXT    NOT NULL,
    bus           TEXT    NOT NULL,
    probe         TEXT    NOT NULL,
    sensor        TEXT    NOT NULL,
    address       INTEGER NOT NULL,
    serial_number TEXT,
    firmware      TEXT,
    retries       INTEGER NOT NULL,
    error         TEXT
);
CREATE INDEX reading_time ON reading (timestamp_ms);
CREATE TABLE reading_value (
    reading_id INTEGER NOT NULL REFERENCES reading (id),
    position   INTEGER NOT NULL,
    name       TEXT    NOT NULL,
    number     REAL,
    text       TEXT,
    unit       TEXT,
    derived    INTEGER NOT NULL DEFAULT 0,
    error      TEXT,
    PRIMARY KEY (reading_id, position)
) WITHOUT ROWID;
CREATE TABLE outbox (
    singleton       INTEGER PRIMARY KEY CHECK (singleton = 0),
    published_up_to INTEGER NOT NULL
);
INSERT INTO outbox (singleton, published_up_to) VALUES (0, 0);
";

/// What went wrong with the store.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// SQLite refused (the file is not a database, the disk is full, ...).
    #[error("database error: {0}")]
    Sqlite(#[from] rusqlite::Error),
    /// The file was written by another version of the schema.
    #[error("the database has schema version {found}; this logger reads versions 1 to {SCHEMA_VERSION}")]
    SchemaVersion {
        /// The file's `user_version`.
        found: i64,
    },
    /// A value to store is NaN or infinite: SQLite would keep it as NULL,
    /// which reads back as no value at all. The logger leaves such values
    /// out of a reading; a direct caller gets this instead of a row it
    /// could not read back.
    #[error("value `{name}` of probe `{probe}` is {value}, not a finite number: not stored")]
    NotFinite {
        /// The probe's label.
        probe: String,
        /// The measurement's name.
        name: String,
        /// The value.
        value: f64,
    },
    /// A row holds something this schema never writes.
    #[error("reading {id} is malformed: {what}")]
    Malformed {
        /// The reading's id.
        id: i64,
        /// What is wrong.
        what: String,
    },
}

impl StoreError {
    /// True when SQLite refused a write because the disk (or the store's
    /// [`Store::set_max_size`] cap) is full: the write can succeed once
    /// space returns.
    pub fn is_full(&self) -> bool {
        matches!(self, Self::Sqlite(rusqlite::Error::SqliteFailure(e, _)) if e.code == rusqlite::ErrorCode::DiskFull)
    }
}

/// A measured value.
#[derive(Debug, Clone, PartialEq)]
pub enum Datum {
    /// A number (every numeric field type, averaged over a procedure's readings).
    Number(f64),
    /// Text: an enum's variant name, an ASCII field.
    Text(String),
    /// No value: why a derived quantity could not be computed for this
    /// sample (an input NaN or out of its range, the formula undefined).
    NotComputable(String),
}

/// One value of a reading: a spec field's name, value and unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// The spec's field name (`temperature_c`).
    pub name: String,
    /// The value.
    pub value: Datum,
    /// The spec's unit, if the field has one.
    pub unit: Option<String>,
    /// A derived quantity of the spec computed by the station from the
    /// measured values (and its station inputs), not a value the probe sent.
    pub derived: bool,
}

/// One sample of one probe: what the logger commits.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// When the sample was taken (UTC; stored to the millisecond).
    pub timestamp: SystemTime,
    /// The station's name.
    pub station: String,
    /// The bus's name.
    pub bus: String,
    /// The probe's label.
    pub probe: String,
    /// The spec's sensor name.
    pub sensor: String,
    /// The probe's slave address.
    pub address: u8,
    /// The probe's serial number, when it answered the serial-number read.
    pub serial_number: Option<String>,
    /// The probe's firmware version, when it answered the version read.
    pub firmware: Option<String>,
    /// The values read (empty when the reading failed as a whole).
    pub values: Vec<Measurement>,
    /// Requests repeated to obtain it.
    pub retries: u32,
    /// Why (part of) the reading failed; `None` when every read succeeded.
    pub error: Option<String>,
}

/// A reading as stored, with its id: the publish order.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredReading {
    /// Unique, increasing in commit order, never reused.
    pub id: i64,
    /// The reading.
    pub reading: Reading,
    /// The calibration of the probe in force when it was taken (see the
    /// module doc); `None` when none is recorded.
    pub calibration_id: Option<i64>,
}

/// The SQLite file of a station. One `Store` is one connection: it is
/// `Send`, not `Sync`; share it behind a mutex, or open one per thread
/// (WAL lets readers run beside the writer).
#[derive(Debug)]
pub struct Store {
    pub(crate) connection: Connection,
}

impl Store {
    /// Opens (creating it, with its schema, if absent) the store at `path`.
    ///
    /// # Errors
    ///
    /// The file cannot be opened or is not a database, or it has another
    /// schema version.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, StoreError> {
        let connection = Connection::open(path)?;
        connection.busy_timeout(BUSY_TIMEOUT)?;
        connection.pragma_update(None, "journal_mode", "WAL")?;
        connection.pragma_update(None, "synchronous", "FULL")?;
        connection.pragma_update(None, "foreign_keys", true)?;
        let mut store = Self { connection };
        store.migrate()?;
        Ok(store)
    }

    /// Caps the file at about `bytes` (SQLite's `max_page_count`, for this
    /// connection): a write beyond it fails as on a full disk
    /// ([`StoreError::is_full`]) until rows are deleted. Returns the cap in
    /// pages.
    ///
    /// # Errors
    ///
    /// SQLite refused the pragma.
    pub fn set_max_size(&mut self, bytes: u64) -> Result<u64, StoreError> {
        let page_size: i64 = self.connection.pragma_query_value(None, "page_size", |row| row.get(0))?;
        let pages = i64::try_from(bytes / page_size.max(512).unsigned_abs()).unwrap_or(i64::MAX).max(1);
        let set: i64 = self.connection.pragma_update_and_check(None, "max_page_count", pages, |row| row.get(0))?;
        Ok(set.unsigned_abs())
    }

    /// The store's size in bytes as SQLite counts it (pages in use and
    /// free, whether in the file or still in its WAL).
    ///
    /// # Errors
    ///
    /// SQLite failed.
    pub fn size(&self) -> Result<u64, StoreError> {
        let pages: i64 = self.connection.pragma_query_value(None, "page_count", |row| row.get(0))?;
        let page_size: i64 = self.connection.pragma_query_value(None, "page_size", |row| row.get(0))?;
        Ok(pages.unsigned_abs() * page_size.unsigned_abs())
    }

    /// Deletes the readings with an id up to `id` and their values, to
    /// free room in a full store; returns how many went. The ids of the
    /// readings left, and of those to come, do not change. The publishers'
    /// cursors are left as they are: a reading deleted before a publisher
    /// delivered it is lost to that publisher, so a caller that must not
    /// lose one deletes at most up to [`Store::delivered_by_all`] of the
    /// station's publishers.
    ///
    /// # Errors
    ///
    /// SQLite refused the delete.
    pub fn delete_up_to(&mut self, id: i64) -> Result<u64, StoreError> {
        let tx = self.connection.transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        tx.execute("DELETE FROM reading_value WHERE reading_id <= ?1", [id])?;
        let deleted = tx.execute("DELETE FROM reading WHERE id <= ?1", [id])?;
        tx.commit()?;
        Ok(deleted as u64)
    }

    /// SQLite's own check of the whole file (`PRAGMA integrity_check`):
    /// `Ok(())` when the file is intact, else what it found (at most 10 lines).
    ///
    /// # Errors
    ///
    /// SQLite could not run the check (the file is not a database).
    pub fn check_integrity(&self) -> Result<Result<(), String>, StoreError> {
        let mut statement = self.connection.prepare("PRAGMA integrity_check(10)")?;
        let lines: Vec<String> = statement.query_map([], |row| row.get(0))?.collect::<Result<_, _>>()?;
        Ok(if lines.len() == 1 && lines[0] == "ok" { Ok(()) } else { Err(lines.join("; ")) })
    }

    /// Creates the schema in an empty file; refuses another version.
    fn migrate(&mut self) -> Result<(), StoreError> {
        let tx = self.connection.transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let found: i64 = tx.pragma_query_value(None, "user_version", |row| row.get(0))?;
        match found {
            // SCHEMA is version 2's tables.
            0 | 2 => {
                if found == 0 {
                    tx.execute_batch(SCHEMA)?;
                }
                tx.execute_batch(MIGRATE_2_TO_3)?;
                tx.execute_batch(MIGRATE_3_TO_4)?;
                tx.pragma_update(None, "user_version", SCHEMA_VERSION)?;
            }
            1 => {
                tx.execute_batch(MIGRATE_1_TO_2)?;
                tx.execute_batch(MIGRATE_2_TO_3)?;
                tx.execute_batch(MIGRATE_3_TO_4)?;
                tx.pragma_update(None, "user_version", SCHEMA_VERSION)?;
            }
            3 => {
                tx.execute_batch(MIGRATE_3_TO_4)?;
                tx.pragma_update(None, "user_version", SCHEMA_VERSION)?;
            }
            SCHEMA_VERSION => {}
            found => return Err(StoreError::SchemaVersion { found }),
        }
        tx.commit()?;
        Ok(())
    }

    /// Commits `reading` and returns its id. When this returns, the
    /// reading is durable.
    ///
    /// # Errors
    ///
    /// A value is NaN or infinite, or SQLite refused the write (disk full,
    /// read-only file, ...); nothing of the reading is stored then.
    pub fn insert(&mut self, reading: &Reading) -> Result<i64, StoreError> {
        let ids = self.insert_all(std::slice::from_ref(reading))?;
        Ok(ids.first().copied().unwrap_or_default())
    }

    /// Commits `readings` in one transaction (one disk sync for all: how a
    /// busy logger keeps up) and returns their ids, increasing in slice
    /// order. All or none are stored.
    ///
    /// # Errors
    ///
    /// A value is NaN or infinite ([`StoreError::NotFinite`]), or SQLite
    /// refused the write; nothing of the batch is stored then.
    pub fn insert_all(&mut self, readings: &[Reading]) -> Result<Vec<i64>, StoreError> {
        for reading in readings {
            for m in &reading.values {
                if let Datum::Number(n) = m.value
                    && !n.is_finite()
                {
                    return Err(StoreError::NotFinite { probe: reading.probe.clone(), name: m.name.clone(), value: n });
                }
            }
        }
        let tx = self.connection.transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let mut ids = Vec::with_capacity(readings.len());
        {
            let mut row = tx.prepare_cached(
                "INSERT INTO reading (timestamp_ms, station, bus, probe, sensor, address, serial_number, firmware, retries, error,
                                      calibration_id)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10,
                         (SELECT id FROM calibration WHERE serial_number = ?7 AND sensor = ?5 AND timestamp_ms <= ?1
                          ORDER BY timestamp_ms DESC, id DESC LIMIT 1))",
            )?;
            let mut value = tx.prepare_cached(
                "INSERT INTO reading_value (reading_id, position, name, number, text, unit, derived, error)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
            )?;
            for reading in readings {
                row.execute(params![
                    unix_ms(reading.timestamp),
                    reading.station,
                    reading.bus,
                    reading.probe,
                    reading.sensor,
                    reading.address,
                    reading.serial_number,
                    reading.firmware,
                    reading.retries,
                    reading.error,
                ])?;
                let id = tx.last_insert_rowid();
                for (position, m) in reading.values.iter().enumerate() {
                    let (number, text, error) = match &m.value {
                        Datum::Number(n) => (Some(*n), None, None),
                        Datum::Text(t) => (None, Some(t.as_str()), None),
                        Datum::NotComputable(why) => (None, None, Some(why.as_str())),
                    };
                    value.execute(params![id, position as i64, m.name, number, text, m.unit, m.derived, error])?;
                }
                ids.push(id);
            }
        }
        tx.commit()?;
        Ok(ids)
    }

    /// Readings with `from <= timestamp < to`, in id order.
    ///
    /// # Errors
    ///
    /// SQLite failed, or a row is malformed.
    pub fn range(&self, from: SystemTime, to: SystemTime) -> Result<Vec<StoredReading>, StoreError> {
        self.select("WHERE timestamp_ms >= ?1 AND timestamp_ms < ?2 ORDER BY id", [unix_ms(from), unix_ms(to)])
    }

    /// The newest reading (highest id) of every probe, by (bus, probe
    /// label), ordered by bus then label.
    ///
    /// # Errors
    ///
    /// SQLite failed, or a row is malformed.
    pub fn latest_per_probe(&self) -> Result<Vec<StoredReading>, StoreError> {
        self.select("WHERE id IN (SELECT max(id) FROM reading GROUP BY bus, probe) ORDER BY bus, probe", params![])
    }

    /// The oldest `limit` readings `publisher` has not delivered, oldest
    /// (lowest id) first.
    ///
    /// # Errors
    ///
    /// SQLite failed, or a row is malformed.
    pub fn unpublished(&self, publisher: &str, limit: usize) -> Result<Vec<StoredReading>, StoreError> {
        self.unpublished_after(publisher, 0, limit)
    }

    /// The oldest `limit` readings `publisher` has not delivered with an id
    /// above `after`, oldest first (a publisher's resume point past what it
    /// has in flight).
    ///
    /// # Errors
    ///
    /// SQLite failed, or a row is malformed.
    pub fn unpublished_after(
        &self,
        publisher: &str,
        after: i64,
        limit: usize,
    ) -> Result<Vec<StoredReading>, StoreError> {
        let limit = i64::try_from(limit).unwrap_or(i64::MAX);
        let floor = after.max(self.published_up_to(publisher)?);
        self.select("WHERE id > ?1 ORDER BY id LIMIT ?2", [floor, limit])
    }

    /// The oldest `limit` readings of `probe` (its label) that `publisher`
    /// has not delivered, oldest first: a publisher with a cursor per probe
    /// (one name per probe) drains each probe's readings on their own.
    ///
    /// # Errors
    ///
    /// SQLite failed, or a row is malformed.
    pub fn unpublished_of_probe(
        &self,
        publisher: &str,
        probe: &str,
        limit: usize,
    ) -> Result<Vec<StoredReading>, StoreError> {
        let limit = i64::try_from(limit).unwrap_or(i64::MAX);
        let floor = self.published_up_to(publisher)?;
        self.select("WHERE id > ?1 AND probe = ?2 ORDER BY id LIMIT ?3", params![floor, probe, limit])
    }

    /// The id of the oldest reading of `probe` that `publisher` has not
    /// delivered, if there is one.
    ///
    /// # Errors
    ///
    /// SQLite failed.
    pub fn oldest_unpublished_of_probe(&self, publisher: &str, probe: &str) -> Result<Option<i64>, StoreError> {
        let floor = self.published_up_to(publisher)?;
        Ok(self.connection.query_row(
            "SELECT min(id) FROM reading WHERE id > ?1 AND probe = ?2",
            params![floor, probe],
            |row| row.get(0),
        )?)
    }

    /// Records that `publisher` has delivered every reading with an id up
    /// to `up_to_id`. The cursor only moves forward: a smaller id than the
    /// current one changes nothing. Committed when it returns. Each
    /// publisher's cursor is its own: marking one never moves another.
    ///
    /// # Errors
    ///
    /// SQLite refused the write.
    pub fn mark_published(&mut self, publisher: &str, up_to_id: i64) -> Result<(), StoreError> {
        self.connection.execute(
            "INSERT INTO outbox (publisher, published_up_to) VALUES (?1, ?2)
             ON CONFLICT (publisher) DO UPDATE SET published_up_to = max(published_up_to, excluded.published_up_to)",
            params![publisher, up_to_id],
        )?;
        Ok(())
    }

    /// The id up to which `publisher` has delivered readings (0: none, or a
    /// publisher the store has not seen).
    ///
    /// # Errors
    ///
    /// SQLite failed.
    pub fn published_up_to(&self, publisher: &str) -> Result<i64, StoreError> {
        let mark: Option<i64> = self
            .connection
            .query_row("SELECT published_up_to FROM outbox WHERE publisher = ?1", [publisher], |row| row.get(0))
            .optional()?;
        Ok(mark.unwrap_or(0))
    }

    /// Every publisher's cursor, by name.
    ///
    /// # Errors
    ///
    /// SQLite failed.
    pub fn publishers(&self) -> Result<Vec<(String, i64)>, StoreError> {
        let mut statement =
            self.connection.prepare_cached("SELECT publisher, published_up_to FROM outbox ORDER BY publisher")?;
        let rows = statement.query_map([], |row| Ok((row.get(0)?, row.get(1)?)))?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// The id up to which every one of `publishers` has delivered readings:
    /// the smallest of their cursors (the last id stored when none is
    /// named). Readings up to it can go without any of them missing one.
    ///
    /// # Errors
    ///
    /// SQLite failed.
    pub fn delivered_by_all(&self, publishers: &[&str]) -> Result<i64, StoreError> {
        let mut least = self.last_id()?;
        for publisher in publishers {
            least = least.min(self.published_up_to(publisher)?);
        }
        Ok(least)
    }

    /// The number of readings stored.
    ///
    /// # Errors
    ///
    /// SQLite failed.
    pub fn count(&self) -> Result<u64, StoreError> {
        let n: i64 = self.connection.query_row("SELECT count(*) FROM reading", [], |row| row.get(0))?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    /// The reading with `id`, if stored.
    ///
    /// # Errors
    ///
    /// SQLite failed, or the row is malformed.
    pub fn get(&self, id: i64) -> Result<Option<StoredReading>, StoreError> {
        Ok(self.select("WHERE id = ?1", [id])?.pop())
    }

    /// Readings matching `filter` (a WHERE clause and ORDER BY over
    /// `reading`), with their values.
    fn select(&self, filter: &str, args: impl rusqlite::Params) -> Result<Vec<StoredReading>, StoreError> {
        let mut readings = self.connection.prepare_cached(&format!(
            "SELECT id, timestamp_ms, station, bus, probe, sensor, address, serial_number, firmware, retries, error,
                    calibration_id
             FROM reading {filter}"
        ))?;
        let mut values = self.connection.prepare_cached(
            "SELECT name, number, text, unit, derived, error FROM reading_value WHERE reading_id = ?1 ORDER BY position",
        )?;
        let rows = readings.query_map(args, |row| {
            Ok((
                row.get::<_, i64>(0)?,
                row.get::<_, i64>(1)?,
                row.get::<_, String>(2)?,
                row.get::<_, String>(3)?,
                row.get::<_, String>(4)?,
                row.get::<_, String>(5)?,
                row.get::<_, i64>(6)?,
                row.get::<_, Option<String>>(7)?,
                row.get::<_, Option<String>>(8)?,
                row.get::<_, i64>(9)?,
                row.get::<_, Option<String>>(10)?,
                row.get::<_, Option<i64>>(11)?,
            ))
        })?;
        let mut out = Vec::new();
        for row in rows {
            let (id, ms, station, bus, probe, sensor, address, serial_number, firmware, retries, error, calibration_id) =
                row?;
            let malformed = |what: &str| StoreError::Malformed { id, what: what.to_owned() };
            let address = u8::try_from(address).map_err(|_| malformed("the address is not a byte"))?;
            let retries = u32::try_from(retries).map_err(|_| malformed("the retry count is negative"))?;
            let measured = values
                .query_map([id], |row| {
                    Ok((
                        row.get::<_, String>(0)?,
                        row.get::<_, Option<f64>>(1)?,
                        row.get::<_, Option<String>>(2)?,
                        row.get::<_, Option<String>>(3)?,
                        row.get::<_, bool>(4)?,
                        row.get::<_, Option<String>>(5)?,
                    ))
                })?
                .map(|v| {
                    let (name, number, text, unit, derived, error) = v?;
                    let value = match (number, text, error) {
                        (Some(n), None, None) => Datum::Number(n),
                        (None, Some(t), None) => Datum::Text(t),
                        // Only a derived quantity is ever stored without a value.
                        (None, None, Some(why)) if derived => Datum::NotComputable(why),
                        _ => {
                            return Err(malformed(&format!(
                                "value `{name}` is not exactly one of a number, text or a derived quantity's error"
                            )));
                        }
                    };
                    Ok(Measurement { name, value, unit, derived })
                })
                .collect::<Result<Vec<_>, StoreError>>()?;
            out.push(StoredReading {
                id,
                reading: Reading {
                    timestamp: from_unix_ms(ms),
                    station,
                    bus,
                    probe,
                    sensor,
                    address,
                    serial_number,
                    firmware,
                    values: measured,
                    retries,
                    error,
                },
                calibration_id,
            });
        }
        Ok(out)
    }

    /// The newest id stored (0: none).
    ///
    /// # Errors
    ///
    /// SQLite failed.
    pub fn last_id(&self) -> Result<i64, StoreError> {
        let id: Option<i64> =
            self.connection.query_row("SELECT max(id) FROM reading", [], |row| row.get(0)).optional()?.flatten();
        Ok(id.unwrap_or(0))
    }
}

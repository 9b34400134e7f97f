//! The calibration history: every calibration the field tool performed, one
//! row of the store's `calibration` table each (see [`crate::store`]'s
//! schema). A station's readings name the one in force when they were
//! taken (`reading.calibration_id`).

use std::time::SystemTime;

use rusqlite::params;
use serde_json::{Value as Json, json};

use crate::store::{Store, StoreError};
use crate::time::{from_unix_ms, rfc3339, unix_ms};

/// One calibration of one probe.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// When the coefficients were written (stored to the millisecond).
    pub timestamp: SystemTime,
    /// The spec's sensor name.
    pub sensor: String,
    /// The probe's model, if the spec names one.
    pub model: Option<String>,
    /// The probe's serial number, when it answered.
    pub serial_number: Option<String>,
    /// Its firmware, when it answered.
    pub firmware: Option<String>,
    /// Its slave address.
    pub address: u8,
    /// The port it was calibrated on.
    pub port: String,
    /// What was done: `linear`, `ph_three_point`, `ph_electrode`, `restore`.
    pub kind: String,
    /// The write command calibrated; `None`: every coefficient block.
    pub block: Option<String>,
    /// The operator's note.
    pub note: Option<String>,
    /// Coefficients before: `{block: {field: value}}`.
    pub before: Json,
    /// Coefficients after, likewise.
    pub after: Json,
    /// The standards, in the order measured.
    pub standards: Json,
    /// Every reading taken.
    pub readings: Json,
    /// The fit, if one was made.
    pub fit: Option<Json>,
}

/// A calibration as stored, with its id.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredCalibration {
    /// Unique, increasing in the order recorded.
    pub id: i64,
    /// The calibration.
    pub calibration: Calibration,
}

impl StoredCalibration {
    /// The calibration as one JSON object (what `calibrate history --json` prints).
    pub fn to_json(&self) -> Json {
        let c = &self.calibration;
        json!({
            "id": self.id,
            "timestamp": rfc3339(c.timestamp),
            "sensor": c.sensor,
            "model": c.model,
            "serial_number": c.serial_number,
            "firmware": c.firmware,
            "address": c.address,
            "port": c.port,
            "kind": c.kind,
            "block": c.block,
            "note": c.note,
            "before": c.before,
            "after": c.after,
            "standards": c.standards,
            "readings": c.readings,
            "fit": c.fit,
        })
    }
}

const COLUMNS: &str = "id, timestamp_ms, sensor, model, serial_number, firmware, address, port, kind, block, note, \
                       before, after, standards, readings, fit";

impl Store {
    /// Records `calibration` and returns its id; committed when it returns.
    ///
    /// # Errors
    ///
    /// SQLite refused the write.
    pub fn record_calibration(&mut self, calibration: &Calibration) -> Result<i64, StoreError> {
        let c = calibration;
        self.connection.execute(
            "INSERT INTO calibration (timestamp_ms, sensor, model, serial_number, firmware, address, port, kind, block,
                                      note, before, after, standards, readings, fit)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15)",
            params![
                unix_ms(c.timestamp),
                c.sensor,
                c.model,
                c.serial_number,
                c.firmware,
                c.address,
                c.port,
                c.kind,
                c.block,
                c.note,
                c.before.to_string(),
                c.after.to_string(),
                c.standards.to_string(),
                c.readings.to_string(),
                c.fit.as_ref().map(Json::to_string),
            ],
        )?;
        Ok(self.connection.last_insert_rowid())
    }

    /// Every calibration recorded, oldest first; only those of probe
    /// `serial_number` when given.
    ///
    /// # Errors
    ///
    /// SQLite failed, or a row is malformed.
    pub fn calibrations(&self, serial_number: Option<&str>) -> Result<Vec<StoredCalibration>, StoreError> {
        let mut statement = self.connection.prepare_cached(&format!(
            "SELECT {COLUMNS} FROM calibration WHERE ?1 IS NULL OR serial_number = ?1 ORDER BY timestamp_ms, id"
        ))?;
        let rows = statement.query_map([serial_number], row_of)?;
        rows.map(|row| parse(row?)).collect()
    }

    /// The calibration with `id`, if recorded.
    ///
    /// # Errors
    ///
    /// SQLite failed, or the row is malformed.
    pub fn calibration(&self, id: i64) -> Result<Option<StoredCalibration>, StoreError> {
        let mut statement =
            self.connection.prepare_cached(&format!("SELECT {COLUMNS} FROM calibration WHERE id = ?1"))?;
        let mut rows = statement.query_map([id], row_of)?;
        rows.next().transpose()?.map(parse).transpose()
    }
}

/// A row's columns, as SQLite holds them.
type Row = (
    i64,
    i64,
    String,
    Option<String>,
    Option<String>,
    Option<String>,
    i64,
    String,
    String,
    Option<String>,
    Option<String>,
    [String; 4],
    Option<String>,
);

fn row_of(row: &rusqlite::Row<'_>) -> rusqlite::Result<Row> {
    Ok((
        row.get(0)?,
        row.get(1)?,
        row.get(2)?,
        row.get(3)?,
        row.get(4)?,
        row.get(5)?,
        row.get(6)?,
        row.get(7)?,
        row.get(8)?,
        row.get(9)?,
        row.get(10)?,
        [row.get(11)?, row.get(12)?, row.get(13)?, row.get(14)?],
        row.get(15)?,
    ))
}

/// A row as a calibration; JSON that does not parse is a malformed row.
fn parse(row: Row) -> Result<StoredCalibration, StoreError> {
    let (id, ms, sensor, model, serial_number, firmware, address, port, kind, block, note, texts, fit) = row;
    let malformed = |what: String| StoreError::Malformed { id, what: format!("calibration: {what}") };
    let json = |name: &str, text: &str| {
        serde_json::from_str::<Json>(text).map_err(|e| malformed(format!("`{name}` is not JSON ({e})")))
    };
    let [before, after, standards, readings] = texts;
    Ok(StoredCalibration {
        id,
        calibration: Calibration {
            timestamp: from_unix_ms(ms),
            sensor,
            model,
            serial_number,
            firmware,
            address: u8::try_from(address).map_err(|_| malformed("the address is not a byte".into()))?,
            port,
            kind,
            block,
            note,
            before: json("before", &before)?,
            after: json("after", &after)?,
            standards: json("standards", &standards)?,
            readings: json("readings", &readings)?,
            fit: fit.as_deref().map(|f| json("fit", f)).transpose()?,
        },
    })
}

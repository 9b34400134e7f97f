//! Stored readings as CSV or JSON lines, for `yosemitech export`.
//!
//! CSV is long (tidy) form: one row per value, the reading's columns
//! repeated, so that every row has the same columns whatever the probe; a
//! reading without values (a failed one) is one row with empty value
//! columns. JSON lines is one reading per line.
//!
//! Both carry the id of the probe's calibration in force when the reading
//! was taken (`calibration_id`, the store's calibration history; empty or
//! absent when none is recorded).
//!
//! Both mark the derived quantities the station computed (`derived`:
//! `true`), and give a derived quantity that could not be computed for a
//! sample no value and its `value_error` (CSV) or `error` (JSON).

use std::io::{self, Write};

use serde_json::{Value as Json, json};

use crate::store::{Datum, StoredReading};
use crate::time::rfc3339;

/// The CSV header row's columns.
pub const CSV_COLUMNS: [&str; 17] = [
    "id",
    "timestamp",
    "station",
    "bus",
    "probe",
    "sensor",
    "address",
    "serial_number",
    "firmware",
    "retries",
    "error",
    "name",
    "value",
    "unit",
    "derived",
    "value_error",
    "calibration_id",
];

/// A CSV field, quoted when it needs to be (RFC 4180).
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) { format!("\"{}\"", text.replace('"', "\"\"")) } else { text.to_owned() }
}

/// A value as text: numbers in Rust's shortest round-trip form.
fn datum_text(value: &Datum) -> String {
    match value {
        Datum::Number(n) => n.to_string(),
        Datum::Text(t) => t.clone(),
        Datum::NotComputable(_) => String::new(),
    }
}

/// Writes the CSV header.
///
/// # Errors
///
/// Writing failed.
pub fn write_csv_header(out: &mut dyn Write) -> io::Result<()> {
    writeln!(out, "{}", CSV_COLUMNS.join(","))
}

/// Writes `stored` as CSV rows (one per value).
///
/// # Errors
///
/// Writing failed.
pub fn write_csv(stored: &StoredReading, out: &mut dyn Write) -> io::Result<()> {
    let r = &stored.reading;
    let head = [
        stored.id.to_string(),
        rfc3339(r.timestamp),
        csv_field(&r.station),
        csv_field(&r.bus),
        csv_field(&r.probe),
        csv_field(&r.sensor),
        r.address.to_string(),
        csv_field(r.serial_number.as_deref().unwrap_or_default()),
        csv_field(r.firmware.as_deref().unwrap_or_default()),
        r.retries.to_string(),
        csv_field(r.error.as_deref().unwrap_or_default()),
    ]
    .join(",");
    let calibration = stored.calibration_id.map(|id| id.to_string()).unwrap_or_default();
    if r.values.is_empty() {
        return writeln!(out, "{head},,,,,,{calibration}");
    }
    for m in &r.values {
        let error = match &m.value {
            Datum::NotComputable(why) => why.as_str(),
            Datum::Number(_) | Datum::Text(_) => "",
        };
        writeln!(
            out,
            "{head},{},{},{},{},{},{calibration}",
            csv_field(&m.name),
            csv_field(&datum_text(&m.value)),
            csv_field(m.unit.as_deref().unwrap_or_default()),
            m.derived,
            csv_field(error)
        )?;
    }
    Ok(())
}

/// `stored` as one JSON object: the reading's columns, `timestamp` in
/// RFC 3339, `values` a list of `{name, value, unit, derived, error}`
/// (value a number or a string; a non-finite number, or a derived
/// quantity not computable, is `null`; `error` says why for the latter).
pub fn to_json(stored: &StoredReading) -> Json {
    let r = &stored.reading;
    let values: Vec<Json> = r
        .values
        .iter()
        .map(|m| {
            let (value, error) = match &m.value {
                Datum::Number(n) => (serde_json::Number::from_f64(*n).map_or(Json::Null, Json::Number), None),
                Datum::Text(t) => (Json::String(t.clone()), None),
                Datum::NotComputable(why) => (Json::Null, Some(why)),
            };
            json!({"name": m.name, "value": value, "unit": m.unit, "derived": m.derived, "error": error})
        })
        .collect();
    let mut doc = json!({
        "id": stored.id,
        "timestamp": rfc3339(r.timestamp),
        "station": r.station,
        "bus": r.bus,
        "probe": r.probe,
        "sensor": r.sensor,
        "address": r.address,
        "serial_number": r.serial_number,
        "firmware": r.firmware,
        "values": values,
        "retries": r.retries,
        "error": r.error,
    });
    // The calibration in force, where one is recorded.
    if let (Some(id), Some(object)) = (stored.calibration_id, doc.as_object_mut()) {
        object.insert("calibration_id".into(), json!(id));
    }
    doc
}

/// Writes `stored` as one JSON line.
///
/// # Errors
///
/// Writing failed.
pub fn write_jsonl(stored: &StoredReading, out: &mut dyn Write) -> io::Result<()> {
    writeln!(out, "{}", to_json(stored))
}

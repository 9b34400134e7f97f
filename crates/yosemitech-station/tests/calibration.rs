//! The calibration history in the store: calibrations recorded and read
//! back, readings naming the calibration in force when they were taken,
//! and a store of schema version 2 migrated to hold them.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use serde_json::json;
use yosemitech_station::store::SCHEMA_VERSION;
use yosemitech_station::{Calibration, Datum, Measurement, Reading, Store};

fn at(secs: u64) -> SystemTime {
    UNIX_EPOCH + Duration::from_secs(secs)
}

fn calibration(serial_number: &str, secs: u64, k: f64) -> Calibration {
    Calibration {
        timestamp: at(secs),
        sensor: "x".into(),
        model: Some("Y000".into()),
        serial_number: Some(serial_number.into()),
        firmware: Some("1.2".into()),
        address: 3,
        port: "/dev/ttyUSB0".into(),
        kind: "linear".into(),
        block: Some("set_coefficients".into()),
        note: Some("after cleaning, \"quoted\"".into()),
        before: json!({"set_coefficients": {"k_slope": 1.0, "b_offset": 0.0}}),
        after: json!({"set_coefficients": {"k_slope": k, "b_offset": -0.25}}),
        standards: json!([10.0, 100.0]),
        readings: json!([{"standard": 10.0, "readings": [9.5, 9.6]}, {"standard": 100.0, "readings": [91.0]}]),
        fit: Some(json!({"k": k, "b": -0.25, "residuals": [0.0, 0.0], "r_squared": 1.0})),
    }
}

fn reading(serial_number: Option<&str>, sensor: &str, secs: u64) -> Reading {
    Reading {
        timestamp: at(secs),
        station: "s".into(),
        bus: "b".into(),
        probe: "p".into(),
        sensor: sensor.into(),
        address: 3,
        serial_number: serial_number.map(str::to_owned),
        firmware: None,
        values: vec![Measurement { name: "a".into(), value: Datum::Number(1.5), unit: None, derived: false }],
        retries: 0,
        error: None,
    }
}

#[test]
fn calibrations_come_back_as_recorded_and_by_serial_number() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("history.sqlite");
    let recorded = [calibration("SN1", 100, 1.1), calibration("SN2", 150, 0.9), calibration("SN1", 200, 1.2)];
    let ids: Vec<i64> = {
        let mut store = Store::open(&path).unwrap();
        recorded.iter().map(|c| store.record_calibration(c).unwrap()).collect()
    };
    let store = Store::open(&path).unwrap();
    let all = store.calibrations(None).unwrap();
    assert_eq!(all.iter().map(|c| c.id).collect::<Vec<_>>(), ids);
    for (stored, want) in all.iter().zip(&recorded) {
        assert_eq!(&stored.calibration, want);
    }
    let sn1: Vec<i64> = store.calibrations(Some("SN1")).unwrap().iter().map(|c| c.id).collect();
    assert_eq!(sn1, [ids[0], ids[2]]);
    assert!(store.calibrations(Some("SN9")).unwrap().is_empty());
    let second = store.calibration(ids[1]).unwrap().unwrap();
    assert_eq!(second.calibration, recorded[1]);
    assert_eq!(second.to_json()["after"]["set_coefficients"]["k_slope"], json!(0.9));
    assert_eq!(second.to_json()["id"], json!(ids[1]));
    assert_eq!(store.calibration(ids[2] + 1).unwrap(), None);
}

#[test]
fn a_reading_names_the_calibration_in_force_when_it_was_taken() {
    let dir = tempfile::tempdir().unwrap();
    let mut store = Store::open(dir.path().join("station.sqlite")).unwrap();
    let first = store.record_calibration(&calibration("SN1", 100, 1.1)).unwrap();
    let second = store.record_calibration(&calibration("SN1", 200, 1.2)).unwrap();
    let cases = [
        (reading(Some("SN1"), "x", 50), None),          // before any calibration
        (reading(Some("SN1"), "x", 100), Some(first)),  // at the first
        (reading(Some("SN1"), "x", 150), Some(first)),  // between
        (reading(Some("SN1"), "x", 250), Some(second)), // after the second
        (reading(Some("SN2"), "x", 250), None),         // another probe
        (reading(Some("SN1"), "other", 250), None),     // another sensor with that serial number
        (reading(None, "x", 250), None),                // a probe that did not say its serial number
    ];
    for (reading, want) in &cases {
        let id = store.insert(reading).unwrap();
        let stored = store.get(id).unwrap().unwrap();
        assert_eq!(stored.calibration_id, *want, "{reading:?}");
        assert_eq!(&stored.reading, reading);
        let exported = yosemitech_station::export::to_json(&stored);
        assert_eq!(exported.get("calibration_id").and_then(serde_json::Value::as_i64), *want);
        let mut csv = Vec::new();
        yosemitech_station::export::write_csv(&stored, &mut csv).unwrap();
        let csv = String::from_utf8(csv).unwrap();
        let last = csv.trim_end().rsplit(',').next().unwrap().to_owned();
        assert_eq!(last, want.map(|id| id.to_string()).unwrap_or_default(), "{csv}");
    }
}

/// The schema of version 2, as a station of that version created it.
const SCHEMA_V2: &str = "
CREATE TABLE reading (
    id INTEGER PRIMARY KEY AUTOINCREMENT, timestamp_ms INTEGER NOT NULL, station TEXT NOT NULL,
    bus TEXT NOT NULL, probe TEXT NOT NULL, sensor TEXT NOT NULL, address INTEGER NOT NULL,
    serial_number TEXT, firmware TEXT, retries INTEGER NOT NULL, error TEXT
);
CREATE INDEX reading_time ON reading (timestamp_ms);
CREATE TABLE reading_value (
    reading_id INTEGER NOT NULL REFERENCES reading (id), position INTEGER NOT NULL, name TEXT NOT NULL,
    number REAL, text TEXT, unit TEXT, derived INTEGER NOT NULL DEFAULT 0, error TEXT,
    PRIMARY KEY (reading_id, position)
) WITHOUT ROWID;
CREATE TABLE outbox (singleton INTEGER PRIMARY KEY CHECK (singleton = 0), published_up_to INTEGER NOT NULL);
INSERT INTO outbox (singleton, published_up_to) VALUES (0, 1);
INSERT INTO reading VALUES (1, 1700000000000, 's', 'b', 'p', 'x', 3, 'SN1', NULL, 0, NULL);
INSERT INTO reading_value VALUES (1, 0, 'a', 7.25, NULL, 'mg/L', 0, NULL);
PRAGMA user_version = 2;
";

#[test]
fn a_store_of_version_2_gains_the_calibration_history() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v2.sqlite");
    rusqlite::Connection::open(&path).unwrap().execute_batch(SCHEMA_V2).unwrap();
    let mut store = Store::open(&path).unwrap();
    let version: i64 =
        rusqlite::Connection::open(&path).unwrap().pragma_query_value(None, "user_version", |r| r.get(0)).unwrap();
    assert_eq!(version, SCHEMA_VERSION);
    let old = store.get(1).unwrap().unwrap();
    assert_eq!(old.calibration_id, None, "no calibration was recorded then");
    assert_eq!(old.reading.values[0].value, Datum::Number(7.25));
    assert_eq!(store.published_up_to("mqtt").unwrap(), 1);
    // A publisher new to the file starts at its first reading.
    assert_eq!(store.published_up_to("monitor_my_watershed").unwrap(), 0);
    assert_eq!(store.unpublished("monitor_my_watershed", 10).unwrap().len(), 1);
    let id = store.record_calibration(&calibration("SN1", 1_700_000_100, 1.1)).unwrap();
    let new = store.insert(&reading(Some("SN1"), "x", 1_700_000_200)).unwrap();
    assert_eq!(new, 2, "ids go on from the old ones");
    assert_eq!(store.get(new).unwrap().unwrap().calibration_id, Some(id));
    drop(store);
    assert_eq!(Store::open(&path).unwrap().calibrations(None).unwrap().len(), 1, "opens again as the current version");
}

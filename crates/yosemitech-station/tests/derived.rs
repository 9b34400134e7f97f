//! Derived quantities in the station: the station file's inputs checked
//! against the spec, the logger storing each sample's derived quantities
//! beside its values in a real SQLite file, marked derived, exported and
//! published so, and a store of the previous schema migrated with its
//! readings intact. Sensors and inputs are picked by role: every sensor
//! with a derived quantity, every station input of it.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use yosemitech_sim::{Bus, ServeConfig, Simulator, serve_pty};
use yosemitech_spec::beside::station_inputs;
use yosemitech_spec::{Derived, InputSource, Sensor, Value};
use yosemitech_station::config::{self, StationConfig};
use yosemitech_station::{Datum, Store, StoredReading, export, logger, outbox, plan};

fn spec() -> yosemitech_spec::Spec {
    yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()]).unwrap()
}

/// Every sensor with a derived quantity whose fields its measurements cover.
fn deriving_sensors() -> Vec<Arc<Sensor>> {
    spec()
        .sensors
        .into_iter()
        .filter(|s| {
            let plan = plan::plan(s, &plan::measurements(s));
            s.derived.iter().any(|d| covered(&plan, d))
        })
        .map(Arc::new)
        .collect()
}

fn covered(plan: &plan::Plan<'_>, d: &Derived) -> bool {
    d.inputs.iter().all(|i| match &i.source {
        InputSource::Field { command, field } => {
            plan.reads.iter().any(|r| r.command.name == *command && r.fields.contains(&field.as_str()))
        }
        InputSource::Station(_) => true,
    })
}

/// The narrowest range the sensor's quantities take station input `name` in.
fn range(sensor: &Sensor, name: &str) -> (f64, f64) {
    let inputs = station_inputs(sensor);
    let input = inputs.iter().find(|i| i.name == name).unwrap();
    input.uses.iter().filter_map(|(_, i)| i.range).fold((-1e6, 1e6), |(a, b), (lo, hi)| (a.max(lo), b.min(hi)))
}

/// A value of station input `name` inside its range, `at` of the way from its minimum.
fn inside(sensor: &Sensor, name: &str, at: f64) -> f64 {
    let (min, max) = range(sensor, name);
    min + (max - min) * at
}

fn write(dir: &Path, text: &str) -> std::path::PathBuf {
    let path = dir.join("station.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn header(dir: &Path, port: &str) -> String {
    format!(
        "station = \"test\"\n[storage]\npath = \"{}\"\n[[bus]]\nname = \"bus\"\nport = \"{port}\"\n\
         baud = 9600\nparity = \"none\"\ntimeout = \"200ms\"\nretries = 1\n",
        dir.join("station.sqlite").display()
    )
}

fn probe(label: &str, sensor: &Sensor, address: u8, inputs: &[(&str, f64)]) -> String {
    let table: Vec<String> = inputs.iter().map(|(n, v)| format!("{n} = {v}")).collect();
    format!(
        "[[bus.probe]]\nlabel = \"{label}\"\nsensor = \"{}\"\naddress = {address}\ninterval = \"200ms\"\n\
         procedure = false\ninputs = {{ {} }}\n",
        sensor.name,
        table.join(", ")
    )
}

#[test]
fn check_takes_the_inputs_a_probe_uses_and_refuses_the_others() {
    let dir = tempfile::tempdir().unwrap();
    let sensors: Vec<Arc<Sensor>> = spec().sensors.into_iter().map(Arc::new).collect();
    let mut checked = 0;
    for sensor in sensors.iter().filter(|s| !plan::measurements(s).is_empty()) {
        let inputs = station_inputs(sensor);
        let names: Vec<&str> = inputs.iter().map(|i| i.name).collect();
        let own: Vec<(&str, f64)> = names.iter().map(|n| (*n, inside(sensor, n, 0.25))).collect();
        // Station-wide values under the probe's own: the probe's win, the others come from the station.
        let mut text = header(dir.path(), "/dev/null");
        let station_wide: Vec<(&str, f64)> = names.iter().map(|n| (*n, inside(sensor, n, 0.75))).collect();
        text += &probe("p", sensor, sensor.default_address, own.get(..1).unwrap_or_default());
        if !station_wide.is_empty() {
            text += "[inputs]\n";
            for (n, v) in &station_wide {
                text += &format!("{n} = {v}\n");
            }
        }
        let config = config::load(&write(dir.path(), &text), &sensors).unwrap_or_else(|e| panic!("{e}\n{text}"));
        let p = &config.buses[0].probes[0];
        for (i, (name, station)) in station_wide.iter().enumerate() {
            let want = if i == 0 { own[0].1 } else { *station };
            assert_eq!(p.inputs.get(*name), Some(&want), "{name}: {:?}", p.inputs);
        }
        assert_eq!(p.inputs.len(), names.len());

        // A name no quantity of the probe takes: located, the probe named.
        let text = header(dir.path(), "/dev/null") + &probe("p", sensor, sensor.default_address, &[("no_such_q", 1.0)]);
        let err = config::load(&write(dir.path(), &text), &sensors).unwrap_err().to_string();
        assert!(err.contains("station.toml:") && err.contains("probe `p`") && err.contains("no_such_q"), "{err}");
        for name in &names {
            assert!(err.contains(name), "the probe's inputs are named: {err}");
        }
        // The same at the station level, where no probe takes it.
        let text = header(dir.path(), "/dev/null")
            + &probe("p", sensor, sensor.default_address, &[])
            + "[inputs]\nno_such_q = 1\n";
        let err = config::load(&write(dir.path(), &text), &sensors).unwrap_err().to_string();
        assert!(err.contains("station.toml:") && err.contains("[inputs]") && err.contains("no_such_q"), "{err}");
        // A value outside an input's range, in the probe's table and the station's.
        for name in &names {
            let (_, max) = range(sensor, name);
            let bad = max + 1.0;
            let text = header(dir.path(), "/dev/null") + &probe("p", sensor, sensor.default_address, &[(name, bad)]);
            let err = config::load(&write(dir.path(), &text), &sensors).unwrap_err().to_string();
            assert!(err.contains("probe `p`") && err.contains(name) && err.contains("outside"), "{err}");
            let text = header(dir.path(), "/dev/null")
                + &probe("p", sensor, sensor.default_address, &[])
                + &format!("[inputs]\n{name} = {bad}\n");
            let err = config::load(&write(dir.path(), &text), &sensors).unwrap_err().to_string();
            assert!(err.contains("probe `p`") && err.contains("outside"), "{err}");
            checked += 1;
        }
        checked += 1;
    }
    assert!(checked > 0);
}

/// The fields of a CSV row (RFC 4180 quoting, no line breaks in a field).
fn cells(line: &str) -> Vec<String> {
    let (mut out, mut cell, mut quoted, mut chars) = (Vec::new(), String::new(), false, line.chars().peekable());
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cell.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(std::mem::take(&mut cell)),
            (c, _) => cell.push(c),
        }
    }
    out.push(cell);
    out
}

/// What the interpreter computes for `d` from simulator `sim`'s values and the probe's inputs.
fn expected(sim: &Simulator, d: &Derived, inputs: &std::collections::BTreeMap<String, f64>) -> Result<f32, String> {
    let mut values = Vec::new();
    for i in &d.inputs {
        let v = match &i.source {
            InputSource::Field { command, field } => match sim.get(command, field) {
                Ok(Value::Float(v)) => f64::from(v),
                Ok(Value::Int(v)) => v as f64,
                other => return Err(format!("{other:?}")),
            },
            InputSource::Station(name) => inputs.get(name).copied().or(i.default).ok_or("no default")?,
        };
        values.push(v as f32);
    }
    d.compute(&values).map_err(|e| e.to_string())
}

fn run_until(config: &StationConfig, store: &Mutex<Store>, mut until: impl FnMut(&Mutex<Store>) -> bool) {
    let stop = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let logger = scope.spawn(|| logger::run(config, store, &stop, &|_, _| {}));
        let deadline = Instant::now() + Duration::from_secs(60);
        while !until(store) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(100));
        }
        stop.store(true, Ordering::SeqCst);
        logger.join().unwrap().unwrap();
    });
}

fn rows(store: &Mutex<Store>) -> Vec<StoredReading> {
    store.lock().unwrap().range(UNIX_EPOCH, SystemTime::now() + Duration::from_secs(60)).unwrap()
}

#[test]
fn the_logger_stores_derived_quantities_marked_and_export_and_mqtt_carry_the_mark() {
    let sensors = deriving_sensors();
    if sensors.is_empty() {
        eprintln!("    no sensor of the spec has a derived quantity its measurements give");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // Each sensor twice: one probe serving plausible water, its inputs
    // given; one whose every field input is out of the quantity's range,
    // so that nothing is computable for it.
    let mut bus = Bus::new();
    let mut probes = Vec::new();
    let mut spoiled = 0;
    for (k, sensor) in sensors.iter().enumerate() {
        let good = u8::try_from(2 * k + 1).unwrap();
        let bad = good + 1;
        bus = bus.with(Simulator::new(Arc::clone(sensor)).with_address(good));
        let mut broken = Simulator::new(Arc::clone(sensor)).with_address(bad);
        for d in &sensor.derived {
            for i in &d.inputs {
                if let (InputSource::Field { command, field }, Some((_, max))) = (&i.source, i.range)
                    && broken.set(command, field, Value::Float((max + 10.0) as f32)).is_ok()
                {
                    spoiled += 1;
                }
            }
        }
        bus = bus.with(broken);
        let inputs: Vec<(&str, f64)> =
            station_inputs(sensor).iter().map(|i| (i.name, inside(sensor, i.name, 0.4))).collect();
        probes.push((format!("good-{k}"), Arc::clone(sensor), good, inputs));
        probes.push((format!("bad-{k}"), Arc::clone(sensor), bad, Vec::new()));
    }
    let server = serve_pty(bus, ServeConfig::default()).unwrap();
    let port = server.tty_path().unwrap().to_owned();
    let mut text = header(dir.path(), &port);
    for (label, sensor, address, inputs) in &probes {
        text += &probe(label, sensor, *address, inputs);
    }
    let config = config::load(&write(dir.path(), &text), &sensors).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let store = Mutex::new(Store::open(&config.storage).unwrap());
    run_until(&config, &store, |store| {
        let rows = rows(store);
        probes.iter().all(|(label, ..)| rows.iter().any(|r| r.reading.probe == *label && r.reading.error.is_none()))
    });
    // Reopened from the file: what a later `export` sees.
    drop(store);
    let store = Store::open(dir.path().join("station.sqlite")).unwrap();
    let stored = store.range(UNIX_EPOCH, SystemTime::now() + Duration::from_secs(60)).unwrap();
    let (mut numbers, mut errors) = (0, 0);
    for (label, sensor, address, _) in &probes {
        let row = stored.iter().find(|r| r.reading.probe == *label && r.reading.error.is_none()).unwrap_or_else(|| {
            let errors: Vec<_> = stored
                .iter()
                .filter(|r| r.reading.probe == *label)
                .filter_map(|r| r.reading.error.as_deref())
                .collect();
            panic!("no good reading of {label}; its errors: {errors:?}")
        });
        let p = config.probes().map(|(_, p)| p).find(|p| p.label == *label).unwrap();
        let sim = server.device();
        let sim = sim.device(*address).unwrap();
        let planned = plan::plan(sensor, &plan::measurements(sensor));
        let want: Vec<&Derived> = sensor.derived.iter().filter(|d| covered(&planned, d)).collect();
        let derived: Vec<_> = row.reading.values.iter().filter(|m| m.derived).collect();
        assert_eq!(derived.len(), want.len(), "{label}: {:?}", row.reading.values);
        // Measured values are not marked.
        for m in row.reading.values.iter().filter(|m| !m.derived) {
            assert!(want.iter().all(|d| d.name != m.name), "{label}: {m:?}");
            assert!(!matches!(m.value, Datum::NotComputable(_)), "{m:?}");
        }
        let json = export::to_json(row);
        let mut csv = Vec::new();
        export::write_csv(row, &mut csv).unwrap();
        let csv = String::from_utf8(csv).unwrap();
        let message = outbox::message(row);
        for d in want {
            let m = derived.iter().find(|m| m.name == d.name).unwrap_or_else(|| panic!("{label}: no {}", d.name));
            assert_eq!(m.unit, d.unit);
            let entry = json["values"].as_array().unwrap().iter().find(|v| v["name"] == d.name.as_str()).unwrap();
            assert_eq!(entry["derived"], true, "{entry}");
            let published = message.values.iter().find(|v| v.name == d.name).unwrap();
            assert!(published.derived, "{published:?}");
            let (line, cells) = csv
                .lines()
                .map(|l| (l, cells(l)))
                .find(|(_, c)| c.get(11).map(String::as_str) == Some(d.name.as_str()))
                .unwrap();
            assert_eq!(cells.len(), export::CSV_COLUMNS.len(), "{line}");
            assert_eq!(cells[14], "true", "{line}");
            match (expected(sim, d, &p.inputs), &m.value) {
                (Ok(v), Datum::Number(n)) => {
                    assert_eq!((*n as f32).to_bits(), v.to_bits(), "{label} {}", d.name);
                    assert_eq!(entry["value"].as_f64().map(|x| x as f32), Some(v));
                    assert_eq!(published.value.map(|x| x as f32), Some(v));
                    assert!(published.error.is_none() && cells[15].is_empty(), "{line}");
                    numbers += 1;
                }
                (Err(_), Datum::NotComputable(why)) => {
                    assert!(!why.is_empty());
                    assert!(entry["value"].is_null() && entry["error"] == why.as_str(), "{entry}");
                    assert!(published.value.is_none() && published.error.as_deref() == Some(why), "{published:?}");
                    assert!(cells[12].is_empty() && cells[15] == *why, "{line}");
                    errors += 1;
                }
                (want, got) => panic!("{label} {}: want {want:?}, stored {got:?}", d.name),
            }
        }
    }
    assert!(numbers > 0, "some derived quantity was computed");
    assert!(spoiled == 0 || errors > 0, "out-of-range inputs were stored as errors");
    eprintln!("    {numbers} derived values and {errors} not computable, stored, exported and published");
}

/// The schema of version 1, as a station of that version created it.
const SCHEMA_V1: &str = "
CREATE TABLE reading (
    id INTEGER PRIMARY KEY AUTOINCREMENT, timestamp_ms INTEGER NOT NULL, station TEXT NOT NULL,
    bus TEXT NOT NULL, probe TEXT NOT NULL, sensor TEXT NOT NULL, address INTEGER NOT NULL,
    serial_number TEXT, firmware TEXT, retries INTEGER NOT NULL, error TEXT
);
CREATE INDEX reading_time ON reading (timestamp_ms);
CREATE TABLE reading_value (
    reading_id INTEGER NOT NULL REFERENCES reading (id), position INTEGER NOT NULL, name TEXT NOT NULL,
    number REAL, text TEXT, unit TEXT, PRIMARY KEY (reading_id, position)
) WITHOUT ROWID;
CREATE TABLE outbox (singleton INTEGER PRIMARY KEY CHECK (singleton = 0), published_up_to INTEGER NOT NULL);
INSERT INTO outbox (singleton, published_up_to) VALUES (0, 0);
INSERT INTO reading VALUES (1, 1700000000000, 's', 'b', 'p', 'x', 3, 'SN1', NULL, 1, NULL);
INSERT INTO reading VALUES (2, 1700000060000, 's', 'b', 'p', 'x', 3, NULL, '1.2', 0, 'no reply');
INSERT INTO reading_value VALUES (1, 0, 'a', 7.25, NULL, 'mg/L');
INSERT INTO reading_value VALUES (1, 1, 'b', NULL, 'ok', NULL);
UPDATE outbox SET published_up_to = 1;
PRAGMA user_version = 1;
";

#[test]
fn a_store_of_the_previous_schema_is_migrated_with_its_readings_intact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.sqlite");
    rusqlite::Connection::open(&path).unwrap().execute_batch(SCHEMA_V1).unwrap();
    let mut store = Store::open(&path).unwrap();
    assert_eq!(store.count().unwrap(), 2);
    assert_eq!(store.published_up_to("mqtt").unwrap(), 1, "the outbox cursor survives");
    // A publisher new to the file starts at its first reading.
    assert_eq!(store.published_up_to("monitor_my_watershed").unwrap(), 0);
    assert_eq!(store.unpublished("monitor_my_watershed", 10).unwrap().len(), 2);
    let first = store.get(1).unwrap().unwrap();
    let values: Vec<(&str, &Datum, Option<&str>, bool)> =
        first.reading.values.iter().map(|m| (m.name.as_str(), &m.value, m.unit.as_deref(), m.derived)).collect();
    assert_eq!(
        values,
        [("a", &Datum::Number(7.25), Some("mg/L"), false), ("b", &Datum::Text("ok".into()), None, false)]
    );
    assert_eq!(first.reading.serial_number.as_deref(), Some("SN1"));
    assert_eq!(first.reading.timestamp, UNIX_EPOCH + Duration::from_millis(1_700_000_000_000));
    let second = store.get(2).unwrap().unwrap();
    assert_eq!(second.reading.error.as_deref(), Some("no reply"));
    assert!(second.reading.values.is_empty());
    // The migrated file takes derived values, and opens again as the new version.
    let mut reading = first.reading.clone();
    reading.values.push(yosemitech_station::Measurement {
        name: "c".into(),
        value: Datum::NotComputable("input `t` is NaN".into()),
        unit: None,
        derived: true,
    });
    let id = store.insert(&reading).unwrap();
    assert_eq!(id, 3, "ids go on from the old ones");
    drop(store);
    let store = Store::open(&path).unwrap();
    assert_eq!(store.get(3).unwrap().unwrap().reading, reading);
    let version: i64 =
        rusqlite::Connection::open(&path).unwrap().pragma_query_value(None, "user_version", |r| r.get(0)).unwrap();
    assert_eq!(version, yosemitech_station::store::SCHEMA_VERSION);
}

#[test]
fn a_store_of_a_later_schema_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("new.sqlite");
    let later = yosemitech_station::store::SCHEMA_VERSION + 1;
    rusqlite::Connection::open(&path).unwrap().pragma_update(None, "user_version", later).unwrap();
    assert!(
        matches!(Store::open(&path), Err(yosemitech_station::StoreError::SchemaVersion { found }) if found == later)
    );
}

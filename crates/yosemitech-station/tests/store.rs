//! The store on real SQLite files in a temporary directory: what is
//! inserted is what comes back, after the store is dropped and reopened,
//! and the outbox hands out every reading once, oldest first.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use yosemitech_station::store::SCHEMA_VERSION;
use yosemitech_station::{Datum, Measurement, Reading, Store, StoreError};

/// A reading of probe `probe` at `secs` after the epoch, with values that
/// depend on `n` (so that a mix-up shows).
fn reading(probe: &str, secs: u64, n: u32) -> Reading {
    Reading {
        timestamp: UNIX_EPOCH + Duration::from_millis(secs * 1000 + u64::from(n % 1000)),
        station: "river".into(),
        bus: "bus, \"one\"".into(),
        probe: probe.into(),
        sensor: "sensor".into(),
        address: (n % 247 + 1) as u8,
        serial_number: n.is_multiple_of(2).then(|| format!("YL{n:010}")),
        firmware: n.is_multiple_of(3).then(|| "1.7".into()),
        values: (0..n % 4)
            .map(|i| Measurement {
                name: format!("field_{i}"),
                value: if i == 2 { Datum::Text(format!("state {n}")) } else { Datum::Number(f64::from(n) + 0.25) },
                unit: (i != 1).then(|| "mg/L".into()),
                derived: false,
            })
            .collect(),
        retries: n % 3,
        error: n.is_multiple_of(4).then(|| "no reply within 1s".into()),
    }
}

#[test]
fn readings_survive_drop_and_reopen_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("station.sqlite");
    let written: Vec<Reading> =
        (0..50).map(|n| reading(["a", "b", "c"][n as usize % 3], 1_000 + u64::from(n), n)).collect();
    let mut ids = Vec::new();
    {
        let mut store = Store::open(&path).unwrap();
        for r in &written {
            ids.push(store.insert(r).unwrap());
        }
    }
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "ids increase in commit order: {ids:?}");
    let store = Store::open(&path).unwrap();
    assert_eq!(store.count().unwrap(), 50);
    let back = store.range(UNIX_EPOCH, SystemTime::now()).unwrap();
    assert_eq!(back.iter().map(|s| s.id).collect::<Vec<_>>(), ids);
    for (stored, original) in back.iter().zip(&written) {
        assert_eq!(&stored.reading, original, "reading {}", stored.id);
    }
}

#[test]
fn range_is_half_open_on_time() {
    let dir = tempfile::tempdir().unwrap();
    let mut store = Store::open(dir.path().join("s.db")).unwrap();
    for n in 0..10u32 {
        store.insert(&reading("a", 100 + u64::from(n) * 10, 0)).unwrap();
    }
    let at = |secs: u64| UNIX_EPOCH + Duration::from_secs(secs);
    let got = store.range(at(120), at(150)).unwrap();
    let times: Vec<_> = got.iter().map(|s| s.reading.timestamp).collect();
    assert_eq!(times, vec![at(120), at(130), at(140)]);
    assert!(store.range(at(200), at(300)).unwrap().is_empty());
}

#[test]
fn latest_per_probe_is_each_probes_newest_reading() {
    let dir = tempfile::tempdir().unwrap();
    let mut store = Store::open(dir.path().join("s.db")).unwrap();
    let mut newest = std::collections::BTreeMap::new();
    for n in 0..30u32 {
        let probe = ["c", "a", "b"][n as usize % 3];
        let id = store.insert(&reading(probe, 10 + u64::from(n), n)).unwrap();
        newest.insert(probe.to_owned(), id);
    }
    let latest = store.latest_per_probe().unwrap();
    let got: Vec<(String, i64)> = latest.iter().map(|s| (s.reading.probe.clone(), s.id)).collect();
    assert_eq!(got, newest.into_iter().collect::<Vec<_>>());
}

#[test]
fn outbox_hands_out_each_reading_once_in_order_across_reopen() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.db");
    let mut store = Store::open(&path).unwrap();
    for n in 0..25u32 {
        store.insert(&reading("a", u64::from(n), n)).unwrap();
    }
    let mut seen = Vec::new();
    for _ in 0..3 {
        let batch = store.unpublished("mqtt", 4).unwrap();
        assert_eq!(batch.len(), 4);
        seen.extend(batch.iter().map(|s| s.id));
        store.mark_published("mqtt", batch.last().unwrap().id).unwrap();
    }
    // A cursor never moves back.
    store.mark_published("mqtt", 1).unwrap();
    drop(store);

    let mut store = Store::open(&path).unwrap();
    assert_eq!(store.published_up_to("mqtt").unwrap(), *seen.last().unwrap());
    loop {
        let batch = store.unpublished("mqtt", 7).unwrap();
        let Some(last) = batch.last() else { break };
        seen.extend(batch.iter().map(|s| s.id));
        store.mark_published("mqtt", last.id).unwrap();
    }
    let all: Vec<i64> = store.range(UNIX_EPOCH, SystemTime::now()).unwrap().iter().map(|s| s.id).collect();
    assert_eq!(seen, all, "every reading once, oldest first");
    assert!(store.unpublished("mqtt", 10).unwrap().is_empty());
}

#[test]
fn a_second_connection_sees_committed_readings_while_the_first_stays_open() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.db");
    let mut writer = Store::open(&path).unwrap();
    let reader = Store::open(&path).unwrap();
    let id = writer.insert(&reading("a", 5, 3)).unwrap();
    assert_eq!(reader.get(id).unwrap().map(|s| s.reading), Some(reading("a", 5, 3)));
}

#[test]
fn refuses_files_it_cannot_read() {
    let dir = tempfile::tempdir().unwrap();
    let not_a_db = dir.path().join("text.db");
    std::fs::write(&not_a_db, "this is not a database, just some text that is long enough to have a header").unwrap();
    assert!(matches!(Store::open(&not_a_db), Err(StoreError::Sqlite(_))));

    let other = dir.path().join("other.db");
    drop(Store::open(&other).unwrap());
    let c = rusqlite::Connection::open(&other).unwrap();
    c.pragma_update(None, "user_version", SCHEMA_VERSION + 1).unwrap();
    drop(c);
    assert!(matches!(Store::open(&other), Err(StoreError::SchemaVersion { found }) if found == SCHEMA_VERSION + 1));
}

#[test]
fn a_value_that_is_not_a_finite_number_is_refused_and_nothing_of_the_batch_is_stored() {
    let dir = tempfile::tempdir().unwrap();
    let mut store = Store::open(dir.path().join("s.db")).unwrap();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let good = reading("a", 1_000, 5);
        let mut broken = reading("b", 1_001, 5);
        broken.values[0].value = Datum::Number(bad);
        match store.insert_all(&[good, broken]) {
            Err(StoreError::NotFinite { probe, name, .. }) => {
                assert_eq!((probe.as_str(), name.as_str()), ("b", "field_0"))
            }
            other => panic!("{bad}: expected NotFinite, got {other:?}"),
        }
        assert_eq!(store.count().unwrap(), 0, "{bad}: all or none");
    }
    // What is stored still reads back.
    store.insert(&reading("a", 1_002, 5)).unwrap();
    assert_eq!(store.range(UNIX_EPOCH, SystemTime::now()).unwrap().len(), 1);
}

/// A store as version 3 wrote it: three readings, MQTT's cursor at 2.
const SCHEMA_V3: &str = "
CREATE TABLE reading (
    id INTEGER PRIMARY KEY AUTOINCREMENT, timestamp_ms INTEGER NOT NULL, station TEXT NOT NULL,
    bus TEXT NOT NULL, probe TEXT NOT NULL, sensor TEXT NOT NULL, address INTEGER NOT NULL,
    serial_number TEXT, firmware TEXT, retries INTEGER NOT NULL, error TEXT,
    calibration_id INTEGER REFERENCES calibration (id)
);
CREATE INDEX reading_time ON reading (timestamp_ms);
CREATE TABLE reading_value (
    reading_id INTEGER NOT NULL REFERENCES reading (id), position INTEGER NOT NULL, name TEXT NOT NULL,
    number REAL, text TEXT, unit TEXT, derived INTEGER NOT NULL DEFAULT 0, error TEXT,
    PRIMARY KEY (reading_id, position)
) WITHOUT ROWID;
CREATE TABLE calibration (
    id INTEGER PRIMARY KEY AUTOINCREMENT, timestamp_ms INTEGER NOT NULL, sensor TEXT NOT NULL, model TEXT,
    serial_number TEXT, firmware TEXT, address INTEGER NOT NULL, port TEXT NOT NULL, kind TEXT NOT NULL,
    block TEXT, note TEXT, before TEXT NOT NULL, after TEXT NOT NULL, standards TEXT NOT NULL,
    readings TEXT NOT NULL, fit TEXT
);
CREATE INDEX calibration_probe ON calibration (serial_number, sensor, timestamp_ms);
CREATE TABLE outbox (singleton INTEGER PRIMARY KEY CHECK (singleton = 0), published_up_to INTEGER NOT NULL);
INSERT INTO outbox (singleton, published_up_to) VALUES (0, 2);
INSERT INTO reading VALUES (1, 1700000000000, 's', 'b', 'p', 'x', 3, NULL, NULL, 0, NULL, NULL);
INSERT INTO reading VALUES (2, 1700000060000, 's', 'b', 'p', 'x', 3, NULL, NULL, 0, NULL, NULL);
INSERT INTO reading VALUES (3, 1700000120000, 's', 'b', 'p', 'x', 3, NULL, NULL, 0, NULL, NULL);
INSERT INTO reading_value VALUES (1, 0, 'a', 7.25, NULL, 'mg/L', 0, NULL);
INSERT INTO reading_value VALUES (2, 0, 'a', 7.5, NULL, 'mg/L', 0, NULL);
INSERT INTO reading_value VALUES (3, 0, 'a', 7.75, NULL, 'mg/L', 0, NULL);
PRAGMA user_version = 3;
";

#[test]
fn a_version_3_store_keeps_its_cursor_as_mqtts_and_a_new_publisher_starts_at_the_first_reading() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v3.sqlite");
    rusqlite::Connection::open(&path).unwrap().execute_batch(SCHEMA_V3).unwrap();
    let mut store = Store::open(&path).unwrap();
    let version: i64 =
        rusqlite::Connection::open(&path).unwrap().pragma_query_value(None, "user_version", |r| r.get(0)).unwrap();
    assert_eq!(version, yosemitech_station::store::SCHEMA_VERSION);
    assert_eq!(store.publishers().unwrap(), [("mqtt".to_owned(), 2)]);
    assert_eq!(store.published_up_to("mqtt").unwrap(), 2);
    let ids = |v: Vec<yosemitech_station::StoredReading>| v.iter().map(|s| s.id).collect::<Vec<_>>();
    assert_eq!(ids(store.unpublished("mqtt", 10).unwrap()), [3]);
    assert_eq!(ids(store.unpublished("monitor_my_watershed", 10).unwrap()), [1, 2, 3], "the history goes out");
    store.mark_published("monitor_my_watershed", 1).unwrap();
    drop(store);
    let store = Store::open(&path).unwrap();
    assert_eq!(store.publishers().unwrap(), [("monitor_my_watershed".to_owned(), 1), ("mqtt".to_owned(), 2)]);
    assert_eq!(store.delivered_by_all(&["mqtt", "monitor_my_watershed"]).unwrap(), 1);
    assert_eq!(store.delivered_by_all(&["mqtt"]).unwrap(), 2);
    assert_eq!(store.delivered_by_all(&[]).unwrap(), 3);
}

#[test]
fn each_publisher_moves_only_its_own_cursor() {
    let dir = tempfile::tempdir().unwrap();
    let mut store = Store::open(dir.path().join("s.db")).unwrap();
    for n in 0..10u32 {
        store.insert(&reading("a", u64::from(n), n)).unwrap();
    }
    assert_eq!(store.publishers().unwrap(), [("mqtt".to_owned(), 0)], "a new store has MQTT's cursor at 0");
    store.mark_published("mqtt", 8).unwrap();
    store.mark_published("portal", 3).unwrap();
    store.mark_published("portal", 2).unwrap();
    assert_eq!(store.published_up_to("mqtt").unwrap(), 8);
    assert_eq!(store.published_up_to("portal").unwrap(), 3, "a cursor never moves back");
    assert_eq!(store.unpublished("mqtt", 10).unwrap().len(), 2);
    assert_eq!(store.unpublished("portal", 10).unwrap().len(), 7);
    assert_eq!(store.unpublished_after("portal", 5, 10).unwrap().first().map(|s| s.id), Some(6));
    assert_eq!(store.unpublished("nobody", 100).unwrap().len(), 10);
}

/// A reading of `probe` with one number, the same measurement every time.
fn one_value(probe: &str, n: u32) -> Reading {
    Reading {
        values: vec![Measurement {
            name: "level".into(),
            value: Datum::Number(f64::from(n)),
            unit: Some("mm".into()),
            derived: false,
        }],
        error: None,
        ..reading(probe, 1_000 + u64::from(n), n)
    }
}

#[test]
fn interleaved_probes_go_to_the_portal_probe_by_probe_in_full_batches() {
    use yosemitech_portal::body::next_batch;
    use yosemitech_portal::{Outbox as _, PortalConfig, TokenSource};
    use yosemitech_station::portal::{PortalOutbox, cursor_of};

    const BATCH: usize = 4;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.db");
    let probes = ["a", "b", "unbound"];
    let mut by_probe: std::collections::BTreeMap<&str, Vec<i64>> = Default::default();
    {
        let mut store = Store::open(&path).unwrap();
        for n in 0..41u32 {
            let probe = probes[n as usize % probes.len()];
            by_probe.entry(probe).or_default().push(store.insert(&one_value(probe, n)).unwrap());
        }
    }
    let mut config = PortalConfig::new(TokenSource::Environment, "0a1b2c3d-0000-4000-8000-00000000feed");
    for (probe, uuid) in [("a", "aaaaaaaa-0000-4000-8000-000000000001"), ("b", "bbbbbbbb-0000-4000-8000-000000000002")]
    {
        config.results.insert(probe.into(), [("level".to_owned(), uuid.to_owned())].into());
    }

    // Drained in two runs of the publisher, as across a restart.
    let mut requests: Vec<Vec<i64>> = Vec::new();
    for run in 0..2 {
        let mut outbox = PortalOutbox::new(Store::open(&path).unwrap(), config.clone());
        for _ in 0..100 {
            let pending = outbox.pending(4 * BATCH).unwrap();
            let Some(batch) = next_batch(&pending, BATCH) else { break };
            requests.push(batch.records.iter().map(|r| r.id).collect());
            outbox.mark_sent(batch.up_to).unwrap();
            if run == 0 && requests.len() == 3 {
                break;
            }
        }
    }
    let probe_of = |id: i64| *by_probe.iter().find(|(_, ids)| ids.contains(&id)).unwrap().0;
    for request in &requests {
        assert!(request.windows(2).all(|w| w[0] < w[1]), "{requests:?}");
        assert!(request.iter().all(|&id| probe_of(id) == probe_of(request[0])), "one probe per request: {requests:?}");
        assert_ne!(probe_of(request[0]), "unbound");
    }
    for probe in ["a", "b"] {
        let sent: Vec<i64> = requests.iter().flatten().copied().filter(|&id| probe_of(id) == probe).collect();
        assert_eq!(sent, by_probe[probe], "each of {probe}'s readings once, in order");
        let sizes: Vec<usize> = requests.iter().filter(|r| probe_of(r[0]) == probe).map(Vec::len).collect();
        assert!(sizes[..sizes.len() - 1].iter().all(|&n| n == BATCH), "full batches: {sizes:?}");
        let store = Store::open(&path).unwrap();
        assert_eq!(store.published_up_to(&cursor_of(probe)).unwrap(), *by_probe[probe].last().unwrap());
    }
    assert_eq!(Store::open(&path).unwrap().published_up_to(&cursor_of("unbound")).unwrap(), 0);
    assert_eq!(probe_of(requests[0][0]), "a", "the oldest unsent reading's probe goes first");
}

//! Storing batches: each reading once, its probe and station, the months'
//! partitions, rejected messages kept once; and reading them back.

use std::time::{Duration, UNIX_EPOCH};

use yosemitech_ingest::{Database, Delivery, month_of, schema};
use yosemitech_mqtt::ReadingMessage;
use yosemitech_tests::broker::reading;
use yosemitech_tests::postgres::Postgres;

/// `count` readings of the test kit's station, ids from 1, a day apart (so
/// that they span months).
fn readings(count: usize) -> Vec<ReadingMessage> {
    (0..count)
        .map(|i| {
            let mut m = reading(i);
            m.reading_id = i64::try_from(i).unwrap() + 1;
            m.timestamp_ms += i64::try_from(i).unwrap() * 86_400_000;
            m
        })
        .collect()
}

#[test]
fn a_batch_is_stored_once_however_often_it_is_delivered() {
    let Some(cluster) = Postgres::start("ingest-database", &[("fsync", "off")]) else { return };
    let config = cluster.create_database("fleet");
    let mut db = Database::open(&config).unwrap();
    let sent = readings(60);
    let garbage = Delivery::parse("yosemitech/v1/s/p/reading", b"{not json");
    assert!(matches!(garbage, Delivery::Rejected { .. }));
    let mut batch: Vec<Delivery> = sent.iter().cloned().map(Delivery::Reading).collect();
    // A delivery repeated within the batch, and a message that is no reading.
    batch.push(Delivery::Reading(sent[3].clone()));
    batch.push(garbage.clone());

    let first = db.store(&batch).unwrap();
    assert_eq!((first.new, first.duplicates, first.rejected), (60, 1, 1));
    // The whole batch again (a worker killed between commit and acknowledgement).
    let again = db.store(&batch).unwrap();
    assert_eq!((again.new, again.duplicates, again.rejected), (0, 61, 1));
    // A second worker's connection finds the schema in place.
    let mut other = Database::open(&config).unwrap();
    assert_eq!(other.store(&batch[..10]).unwrap().new, 0);

    let client = db.client();
    let count = |client: &mut postgres::Client, sql: &str| client.query_one(sql, &[]).unwrap().get::<_, i64>(0);
    assert_eq!(count(client, "SELECT count(*) FROM readings"), 60);
    assert_eq!(count(client, "SELECT count(*) FROM rejected_messages"), 1, "a rejected message kept once");
    let probes: usize =
        sent.iter().map(|m| (&m.probe, m.address, &m.calibration_id)).collect::<std::collections::BTreeSet<_>>().len();
    assert_eq!(count(client, "SELECT count(*) FROM probes") as usize, probes);
    // Every month the readings span has its partition, and none went to the default one.
    let months = sent.iter().map(|m| month_of(m.timestamp_ms)).collect::<std::collections::BTreeSet<_>>().len();
    assert!(months > 1, "the readings span months");
    assert_eq!(count(client, "SELECT count(*) FROM readings_default"), 0);
    let partitions = count(client, "SELECT count(*) FROM pg_inherits WHERE inhparent = 'readings'::regclass");
    assert_eq!(partitions as usize, months + 1, "a partition per month and the default");

    // Read back as they were published.
    let back = db.readings_between(UNIX_EPOCH, UNIX_EPOCH + Duration::from_secs(1 << 40)).unwrap();
    assert_eq!(back, sent);
    let (from, to) = (sent[10].timestamp_ms, sent[20].timestamp_ms);
    let at = |ms: i64| UNIX_EPOCH + Duration::from_millis(u64::try_from(ms).unwrap());
    assert_eq!(db.readings_between(at(from), at(to)).unwrap(), sent[10..20]);
}

#[test]
fn an_empty_database_is_migrated_and_one_of_a_newer_schema_refused() {
    let Some(cluster) = Postgres::start("ingest-schema", &[("fsync", "off")]) else { return };
    let config = cluster.create_database("fleet");
    drop(Database::open(&config).unwrap());
    let mut client = config.connect(postgres::NoTls).unwrap();
    let version: i32 = client.query_one("SELECT version FROM yosemitech_schema", &[]).unwrap().get(0);
    assert_eq!(version, schema::current_version());
    client.execute("UPDATE yosemitech_schema SET version = version + 1", &[]).unwrap();
    let refused = Database::open(&config).err().expect("a newer schema is refused");
    assert!(refused.to_string().contains("upgrade"), "{refused}");
}

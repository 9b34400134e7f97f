//! Two workers of one group on mosquitto: the stations' readings split
//! between them, each stored once.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use yosemitech_ingest::{IngestConfig, Totals, run};
use yosemitech_mqtt::{MemoryOutbox, Publisher};
use yosemitech_tests::broker::{Broker, BrokerKind, DEADLINE, available, reading};
use yosemitech_tests::postgres::Postgres;

const STATIONS: usize = 5;
const READINGS: usize = 80;

fn config(broker: &Broker, client_id: &str) -> IngestConfig {
    let station = broker.config("unused", 20);
    IngestConfig {
        host: station.host,
        port: station.port.unwrap_or(1883),
        tls: None,
        credentials: None,
        client_id: client_id.to_owned(),
        topic_prefix: station.topic_prefix,
        group: Some("ingest".into()),
        batch_size: 50,
        batch_wait: Duration::from_millis(100),
        session_expiry: Duration::from_secs(3600),
    }
}

#[test]
fn two_workers_of_a_group_share_the_readings_and_store_each_once() {
    if !available(BrokerKind::Mosquitto) {
        eprintln!("    skipped: the shared subscription needs mosquitto");
        return;
    }
    let Some(cluster) = Postgres::start("ingest-worker", &[("fsync", "off")]) else { return };
    let database = cluster.create_database("fleet");
    let broker = Broker::start(BrokerKind::Mosquitto, None);
    let stop = Arc::new(AtomicBool::new(false));
    let latest: Vec<Arc<Mutex<Totals>>> = (0..2).map(|_| Arc::default()).collect();
    let workers: Vec<_> = (0..2)
        .map(|i| {
            let (config, database, stop) =
                (config(&broker, &format!("ingest-{i}")), database.clone(), Arc::clone(&stop));
            let latest = Arc::clone(&latest[i]);
            std::thread::spawn(move || {
                run(&config, &database, &stop, |totals| *latest.lock().unwrap() = *totals).unwrap()
            })
        })
        .collect();
    let deadline = Instant::now() + DEADLINE;
    while !latest.iter().all(|t| t.lock().unwrap().subscribed) {
        assert!(Instant::now() < deadline, "the workers subscribe");
        std::thread::sleep(Duration::from_millis(20));
    }

    let mut publishers = Vec::new();
    for s in 0..STATIONS {
        let outbox = MemoryOutbox::new();
        for i in 0..READINGS {
            outbox.push(yosemitech_mqtt::ReadingMessage { station: format!("station-{s}"), ..reading(i) });
        }
        publishers.push(Publisher::start(&broker.config(&format!("station-{s}"), 20), outbox).unwrap());
    }
    let mut client = database.connect(postgres::NoTls).unwrap();
    let stored = |client: &mut postgres::Client| -> i64 {
        client.query_one("SELECT count(*) FROM readings", &[]).unwrap().get(0)
    };
    while stored(&mut client) < (STATIONS * READINGS) as i64 {
        assert!(
            Instant::now() < deadline,
            "every reading is stored ({} of {})",
            stored(&mut client),
            STATIONS * READINGS
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    for publisher in publishers {
        publisher.shutdown(Duration::from_secs(5));
    }
    stop.store(true, Ordering::SeqCst);
    let totals: Vec<Totals> = workers.into_iter().map(|w| w.join().unwrap()).collect();
    let new: u64 = totals.iter().map(|t| t.stored.new).sum();
    assert_eq!(new, (STATIONS * READINGS) as u64, "{totals:?}");
    assert!(totals.iter().all(|t| t.stored.new > 0), "the group shares the load: {totals:?}");
    let distinct: i64 =
        client.query_one("SELECT count(DISTINCT (station, reading_id)) FROM readings", &[]).unwrap().get(0);
    assert_eq!(distinct, (STATIONS * READINGS) as i64);
}

/// A broker that grants the worker's subscription only at QoS 0 (mosquitto's
/// `max_qos 0`) would deliver readings no acknowledgement guards: the worker
/// stops with the broker's answer rather than store some and lose others.
/// (mosquitto's access control lists never refuse a subscription: they
/// filter what is delivered.)
#[test]
fn a_subscription_granted_below_qos_1_stops_the_worker_with_the_brokers_answer() {
    if !available(BrokerKind::Mosquitto) {
        eprintln!("    skipped: max_qos is mosquitto's");
        return;
    }
    let Some(cluster) = Postgres::start("ingest-qos0", &[("fsync", "off")]) else { return };
    let database = cluster.create_database("fleet");
    let mut broker = Broker::start(BrokerKind::Mosquitto, None);
    broker.stop();
    broker.set_extra_config("max_qos 0\n");
    broker.restart();
    let config = config(&broker, "ingest-qos0");
    let stop = Arc::new(AtomicBool::new(false));
    let (done, result) = std::sync::mpsc::channel();
    let worker = std::thread::spawn({
        let (config, database, stop) = (config.clone(), database.clone(), Arc::clone(&stop));
        move || {
            let _ = done.send(run(&config, &database, &stop, |_| {}).map(|_| ()));
        }
    });
    let result = result.recv_timeout(DEADLINE);
    stop.store(true, Ordering::SeqCst);
    let error = match result {
        Ok(Err(error)) => error.to_string(),
        other => panic!("the worker stops with an error: {other:?}"),
    };
    worker.join().unwrap();
    assert!(error.contains("refused the subscription") && error.contains("AtMostOnce"), "{error}");
    assert!(error.contains(&config.filter()), "names what it subscribed to: {error}");
}

//! Readings per second from the broker into PostgreSQL, with one ingest
//! worker and with two, in the same run; and, with the workers running,
//! each reading's latency from its station's outbox to its row
//! (`stored_at - taken_at`: the publisher's poll of its outbox, the broker,
//! the batch's wait, the transaction).
//!
//! A real mosquitto and a real PostgreSQL cluster (fsync on, as a server
//! runs) started by the test kit; stations are in-process publishers, each
//! with its own outbox and client id. Each run first lets the stations
//! hand their readings to the broker with no worker connected (the
//! workers' sessions queue them), then starts the workers: what is timed
//! is the workers draining the queue, not the stations publishing.
//!
//! `cargo bench -p yosemitech-ingest --bench ingest` runs it (a minute or
//! so); without `--bench` (as under `cargo test --benches`) it moves a few
//! readings once. Without mosquitto or PostgreSQL it says so and exits.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use yosemitech_ingest::{IngestConfig, Totals, run};
use yosemitech_mqtt::{MemoryOutbox, Publisher, ReadingMessage};
use yosemitech_tests::broker::{Broker, BrokerKind, mosquitto_binary, reading};
use yosemitech_tests::postgres::{Postgres, binaries};

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    if mosquitto_binary().is_none() || binaries().is_none() {
        println!("ingest: needs mosquitto and PostgreSQL (apt-get install mosquitto postgresql)");
        return;
    }
    // The test kit's mosquitto queues 10,000 messages a client at most:
    // the readings wait in the workers' sessions, so fewer than that.
    let (stations, per_station) = if measuring { (40, 200) } else { (2, 5) };
    for workers in [1, 2] {
        let run = measure(workers, stations, per_station);
        println!(
            "ingest: {workers} worker(s): {} readings in {:.2} s: {:.0} readings/s; \
             outbox to row: median {} ms, 90 % {} ms, longest {} ms; {} transactions",
            run.readings,
            run.elapsed.as_secs_f64(),
            run.readings as f64 / run.elapsed.as_secs_f64(),
            run.latency_ms[0],
            run.latency_ms[1],
            run.latency_ms[2],
            run.batches
        );
    }
}

struct Run {
    readings: usize,
    elapsed: Duration,
    latency_ms: [i64; 3],
    batches: u64,
}

/// Waits until `done`, or gives up (the benchmark exits, saying what it waited for).
fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(300);
    while !done() {
        if Instant::now() > deadline {
            eprintln!("ingest: gave up waiting for {what}");
            std::process::exit(1);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn measure(workers: usize, stations: usize, per_station: usize) -> Run {
    let cluster = Postgres::start("ingest-bench", &[]).expect("PostgreSQL starts");
    let database = cluster.create_database("fleet");
    let broker = Broker::start(BrokerKind::Mosquitto, None);
    let config = |i: usize| IngestConfig {
        host: "127.0.0.1".into(),
        port: broker.port,
        tls: None,
        credentials: None,
        client_id: format!("ingest-{i}"),
        topic_prefix: yosemitech_mqtt::topic::DEFAULT_TOPIC_PREFIX.into(),
        group: Some("bench".into()),
        batch_size: 500,
        batch_wait: Duration::from_millis(100),
        session_expiry: Duration::from_secs(3600),
    };
    // The workers' sessions and subscriptions, then away: the broker queues for them.
    for i in 0..workers {
        let stop = Arc::new(AtomicBool::new(false));
        let subscribed = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&subscribed);
        let (config, database, stopping) = (config(i), database.clone(), Arc::clone(&stop));
        let worker = std::thread::spawn(move || {
            run(&config, &database, &stopping, |t| flag.store(t.subscribed, Ordering::SeqCst)).expect("worker")
        });
        wait_for("a worker's subscription", || subscribed.load(Ordering::SeqCst));
        stop.store(true, Ordering::SeqCst);
        worker.join().expect("the worker stops");
    }
    let now_ms = unix_ms(SystemTime::now());
    let outboxes: Vec<MemoryOutbox> = (0..stations).map(|_| MemoryOutbox::new()).collect();
    for (s, outbox) in outboxes.iter().enumerate() {
        for i in 0..per_station {
            outbox.push(ReadingMessage { station: format!("station-{s:03}"), timestamp_ms: now_ms, ..reading(i) });
        }
    }
    let publishers: Vec<Publisher> = outboxes
        .iter()
        .enumerate()
        .map(|(s, o)| Publisher::start(&broker.config(&format!("station-{s:03}"), 100), o.clone()).expect("publisher"))
        .collect();
    wait_for("the stations' readings to reach the broker", || {
        outboxes.iter().all(|o| o.published_up_to() == i64::try_from(o.len()).ok())
    });
    for publisher in publishers {
        publisher.shutdown(Duration::from_secs(5));
    }
    // The readings now wait in the workers' sessions: time the drain.
    let total = stations * per_station;
    let started = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));
    let totals: Vec<Arc<Mutex<Totals>>> = (0..workers).map(|_| Arc::default()).collect();
    let threads: Vec<_> = (0..workers)
        .map(|i| {
            let (config, database, stop, latest) =
                (config(i), database.clone(), Arc::clone(&stop), Arc::clone(&totals[i]));
            std::thread::spawn(move || {
                run(&config, &database, &stop, |t| *latest.lock().unwrap_or_else(|e| e.into_inner()) = *t)
            })
        })
        .collect();
    let stored = |t: &[Arc<Mutex<Totals>>]| -> u64 {
        t.iter().map(|t| t.lock().unwrap_or_else(|e| e.into_inner()).stored.new).sum()
    };
    wait_for("the queued readings to be stored", || stored(&totals) >= total as u64);
    let elapsed = started.elapsed();
    // Latency: stations publishing a reading every 20 ms while the workers run.
    let live: Vec<MemoryOutbox> = (0..stations.min(10)).map(|_| MemoryOutbox::new()).collect();
    let publishers: Vec<Publisher> = live
        .iter()
        .enumerate()
        .map(|(s, o)| Publisher::start(&broker.config(&format!("live-{s:03}"), 100), o.clone()).expect("publisher"))
        .collect();
    let rounds = if per_station > 100 { 100 } else { 3 };
    for i in 0..rounds {
        for (s, outbox) in live.iter().enumerate() {
            let at = unix_ms(SystemTime::now());
            outbox.push(ReadingMessage { station: format!("live-{s:03}"), timestamp_ms: at, ..reading(i) });
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    wait_for("the live readings to be stored", || stored(&totals) >= (total + rounds * live.len()) as u64);
    for publisher in publishers {
        publisher.shutdown(Duration::from_secs(5));
    }
    stop.store(true, Ordering::SeqCst);
    let batches = threads.into_iter().map(|t| t.join().ok().and_then(Result::ok).map_or(0, |t| t.batches)).sum();
    let mut client = database.connect(postgres::NoTls).expect("a connection");
    let row = client
        .query_one(
            "SELECT percentile_disc(ARRAY[0.5, 0.9, 1.0]) WITHIN GROUP
                (ORDER BY (extract(epoch FROM stored_at - taken_at) * 1000)::bigint)
             FROM readings WHERE station LIKE 'live-%'",
            &[],
        )
        .expect("latencies");
    let latencies: Vec<i64> = row.get(0);
    Run { readings: total, elapsed, latency_ms: [latencies[0], latencies[1], latencies[2]], batches }
}

fn unix_ms(at: SystemTime) -> i64 {
    at.duration_since(UNIX_EPOCH).map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

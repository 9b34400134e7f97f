//! `yosemitech ingest`: a fleet of stations publishing into one broker,
//! two ingest workers sharing the readings into one PostgreSQL database;
//! one worker SIGKILLed mid-stream and restarted, the broker restarted
//! once. At the end every reading published is in the database exactly
//! once. Needs mosquitto (shared subscriptions, persistent sessions) and
//! PostgreSQL: without them it skips with a note (`.ci/run` requires both).
//!
//! The broker is restarted while the stations publish. mosquitto 2.0 does
//! not restore a shared subscription from its persistence file, so a reading
//! published between its restart and the workers' new subscription matches
//! no subscriber: the broker acknowledges it with reason 0x10 and drops it.
//! The stations run with `require_subscriber` (docs/postgres.md) and send
//! such readings again.

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use yosemitech_mqtt::{MemoryOutbox, MqttConfig, Publisher, ReadingMessage};
use yosemitech_tests::broker::{Broker, BrokerKind, available, reading};
use yosemitech_tests::cli::{Binary, interrupt};
use yosemitech_tests::postgres::Postgres;

const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

const STATIONS: usize = 100;
/// Readings each station publishes, one a round.
const ROUNDS: usize = 24;
/// Rounds at which the faults happen.
const KILL_AT: usize = 6;
const RESTART_WORKER_AT: usize = 10;
const RESTART_BROKER_AT: usize = 16;
/// The fleet's readings all land in the database within this (a loaded 2-core machine).
const DEADLINE: Duration = Duration::from_secs(240);

/// An ingest worker, and a channel that hears each time it says it is subscribed.
struct Worker {
    /// `None` once stopped.
    child: Option<Child>,
    subscribed: mpsc::Receiver<()>,
}

impl Drop for Worker {
    /// A test that fails leaves no worker running.
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

impl Worker {
    fn wait_subscribed(&self, name: &str) {
        self.subscribed.recv_timeout(DEADLINE).unwrap_or_else(|_| panic!("{name} says it is subscribed"));
    }
}

/// An ingest worker as an operator starts it; returns once it says it is
/// subscribed, with its stderr still drained (a full pipe would stop it).
fn start_worker(broker: &Broker, cluster: &Postgres, client_id: &str) -> Worker {
    let mut child = YOSEMITECH
        .command()
        .args(["ingest", "--mqtt", &format!("mqtt://127.0.0.1:{}", broker.port), "--postgres"])
        .arg(cluster.conninfo("fleet"))
        .args(["--client-id", client_id, "--batch", "100", "--batch-wait", "100ms"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let (subscribed, said) = mpsc::channel();
    let name = client_id.to_owned();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            // Shown with the test's output when it fails.
            eprintln!("    {name}: {line}");
            if line.contains("subscribed") {
                let _ = subscribed.send(());
            }
        }
    });
    let worker = Worker { child: Some(child), subscribed: said };
    worker.wait_subscribed(client_id);
    worker
}

/// What a worker stopped with Ctrl-C says it did (its one stdout line).
fn stop_worker(mut worker: Worker) -> String {
    let mut child = worker.child.take().unwrap();
    let mut out = child.stdout.take().unwrap();
    interrupt(child);
    let mut said = String::new();
    out.read_to_string(&mut said).unwrap();
    said.trim().to_owned()
}

/// Every stored reading's identity, one per row (a reading stored twice twice).
fn stored_ids(client: &mut postgres::Client) -> Vec<(String, i64)> {
    let rows = client.query("SELECT station, reading_id FROM readings ORDER BY station, reading_id", &[]).unwrap();
    rows.iter().map(|row| (row.get(0), row.get(1))).collect()
}

/// Repeated deliveries a worker's closing line counts.
fn repeated(line: &str) -> u64 {
    line.split(", ").find_map(|part| part.strip_suffix(" repeated deliveries")?.parse().ok()).unwrap_or(0)
}

#[test]
fn a_fleet_of_stations_lands_in_postgres_once_through_a_killed_worker_and_a_broker_restart() {
    if !available(BrokerKind::Mosquitto) {
        eprintln!("    skipped: the shared subscription needs mosquitto");
        return;
    }
    let Some(cluster) = Postgres::start("ingest-fleet", &[("fsync", "off")]) else { return };
    cluster.create_database("fleet");
    let mut broker = Broker::start(BrokerKind::Mosquitto, None);
    let first = start_worker(&broker, &cluster, "ingest-a");
    let second = start_worker(&broker, &cluster, "ingest-b");

    // A hundred stations, each with its own outbox and client id.
    let outboxes: Vec<MemoryOutbox> = (0..STATIONS).map(|_| MemoryOutbox::new()).collect();
    let publishers: Vec<Publisher> = outboxes
        .iter()
        .enumerate()
        .map(|(s, outbox)| {
            let config = MqttConfig { require_subscriber: true, ..broker.config(&format!("station-{s:03}"), 20) };
            Publisher::start(&config, outbox.clone()).unwrap()
        })
        .collect();
    let now_ms = i64::try_from(SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_millis()).unwrap();
    let mut published: BTreeSet<(String, i64)> = BTreeSet::new();
    let mut first = Some(first);
    let mut restarted = None;
    for round in 0..ROUNDS {
        for (s, outbox) in outboxes.iter().enumerate() {
            let station = format!("station-{s:03}");
            let message = ReadingMessage {
                station: station.clone(),
                timestamp_ms: now_ms + i64::try_from(round).unwrap() * 60_000,
                ..reading(round)
            };
            published.insert((station, outbox.push(message)));
        }
        match round {
            KILL_AT => {
                // SIGKILL: no chance to store or acknowledge what it holds.
                let mut worker = first.take().unwrap().child.take().unwrap();
                worker.kill().unwrap();
                worker.wait().unwrap();
            }
            RESTART_WORKER_AT => restarted = Some(start_worker(&broker, &cluster, "ingest-a")),
            RESTART_BROKER_AT => {
                // Once the broker has every reading (see the module's documentation).
                let deadline = Instant::now() + DEADLINE;
                while !outboxes.iter().all(|o| o.published_up_to() == Some(i64::try_from(o.len()).unwrap())) {
                    assert!(Instant::now() < deadline, "the stations' readings reach the broker");
                    std::thread::sleep(Duration::from_millis(20));
                }
                broker.stop();
                broker.restart();
                restarted.as_ref().unwrap().wait_subscribed("ingest-a");
                second.wait_subscribed("ingest-b");
            }
            _ => {}
        }
        std::thread::sleep(Duration::from_millis(100));
    }

    let mut client = cluster.config("fleet").connect(postgres::NoTls).unwrap();
    let count = |client: &mut postgres::Client| -> usize {
        client.query_one("SELECT count(*) FROM readings", &[]).unwrap().get::<_, i64>(0) as usize
    };
    let deadline = Instant::now() + DEADLINE;
    while count(&mut client) < published.len() {
        if Instant::now() > deadline {
            let stored: BTreeSet<(String, i64)> = stored_ids(&mut client).into_iter().collect();
            let mut missing_by_id = std::collections::BTreeMap::new();
            for (_, id) in published.difference(&stored) {
                *missing_by_id.entry(*id).or_insert(0) += 1;
            }
            panic!(
                "{} of {} readings stored; missing, by reading id: {missing_by_id:?}",
                stored.len(),
                published.len()
            );
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let undelivered: u64 = publishers.iter().map(|p| p.status().undelivered).sum();
    for publisher in publishers {
        publisher.shutdown(Duration::from_secs(5));
    }
    let absorbed = repeated(&stop_worker(restarted.unwrap())) + repeated(&stop_worker(second));

    let stored = stored_ids(&mut client);
    let distinct: BTreeSet<(String, i64)> = stored.iter().cloned().collect();
    let lost = published.difference(&distinct).count();
    let duplicates = stored.len() - distinct.len();
    eprintln!(
        "    fleet: {} readings published by {STATIONS} stations, {} stored, {duplicates} stored twice, {lost} lost; \
         one worker SIGKILLed at round {KILL_AT} and restarted at {RESTART_WORKER_AT}, the broker restarted at \
         {RESTART_BROKER_AT}; {undelivered} publications the broker had no subscriber for, sent again; \
         {absorbed} repeated deliveries absorbed by the surviving workers",
        published.len(),
        stored.len()
    );
    assert_eq!((lost, duplicates), (0, 0));
    assert_eq!(distinct, published, "nothing stored that was not published");
}

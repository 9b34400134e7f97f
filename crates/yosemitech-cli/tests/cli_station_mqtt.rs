//! `yosemitech log` publishing to a real broker (rumqttd always, mosquitto
//! when installed; mandatory with `YOSEMITECH_REQUIRE_MOSQUITTO=1`): the
//! broker goes away, the logger keeps logging, is SIGKILLed with a backlog
//! and started again on the same store once the broker is back. Nothing
//! committed is lost, no reading is published under two ids, and a
//! subscriber that keeps the first copy per reading id (MQTT QoS 1 is
//! at-least-once: a reading in flight at the kill may arrive again,
//! byte-identical) sees every reading the store marks published exactly
//! once, in order; a clean stop leaves the rest in the outbox.

use crate::station;

use std::collections::BTreeMap;
use std::time::Duration;

use station::{Station, start_logger, stored_ids, terminate};
use yosemitech_station::Store;
use yosemitech_tests::broker::{Broker, BrokerKind, Subscriber, available, ids_and_first_occurrences, wait_until};

/// Readings allowed in flight: the copies one interruption can cause.
const MAX_IN_FLIGHT: usize = 4;

fn killed_and_restarted_logger_loses_nothing(kind: BrokerKind) {
    if !available(kind) {
        return;
    }
    let broker = Broker::start(kind, None);
    let subscriber = Subscriber::start(&broker, &format!("{}/#", yosemitech_mqtt::topic::DEFAULT_TOPIC_PREFIX));

    let mut station = Station::simulated("river", "100ms");
    let db = station.db.clone();
    station.toml += &format!(
        "[mqtt]\nhost = \"127.0.0.1\"\nport = {}\nclient_id = \"station-river-{kind:?}\"\nkeep_alive_secs = 5\n\
         [mqtt.publisher]\nmax_in_flight = {MAX_IN_FLIGHT}\npoll_interval_ms = 50\nreconnect_min_ms = 100\nreconnect_max_ms = 1000\n",
        broker.port
    );
    let config = station.write_config();

    // First run: readings flow, then the broker goes away and a backlog
    // builds up in the store; the logger is killed without warning.
    let mut broker = broker;
    let mut logger = start_logger(&config);
    assert!(wait_until(|| subscriber.count() >= 5), "{kind:?}: readings reach the broker");
    // A broker acknowledges a reading when it receives it and forwards it
    // after: what it acknowledged in its last moments dies with it (rumqttd
    // is SIGKILLed and keeps nothing). Everything acknowledged before those
    // moments must reach the subscriber.
    let acked_before_stop = Store::open(&db).unwrap().published_up_to("mqtt").unwrap();
    let forwarded = |up_to: i64| {
        let first = ids_and_first_occurrences(&subscriber.received()).1;
        stored_ids(&db).iter().filter(|id| **id <= up_to).all(|id| first.contains(id))
    };
    assert!(wait_until(|| forwarded(acked_before_stop)), "{kind:?}: the broker forwards what it acknowledged");
    broker.stop();
    let at_outage = stored_ids(&db).len();
    assert!(wait_until(|| stored_ids(&db).len() >= at_outage + 10), "{kind:?}: logging goes on without the broker");
    logger.kill().unwrap();
    logger.wait().unwrap();
    let after_kill = stored_ids(&db);
    let published_at_kill = Store::open(&db).unwrap().published_up_to("mqtt").unwrap();
    assert!(published_at_kill < *after_kill.last().unwrap(), "{kind:?}: the kill left readings unpublished");

    // The broker comes back, the subscriber with it.
    broker.restart();
    subscriber.wait_for_subscriptions(2);

    // Second run on the same store: resumes publishing and catches up with
    // the backlog and ten new readings, then stops cleanly. A clean stop
    // sends nothing new (what is stored later waits in the outbox for the
    // next run), so the test waits for the catch-up rather than assume it.
    let said = config.with_extension("stderr");
    let mut logger = station::command()
        .args(["log", "--config", config.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .stderr(std::fs::File::create(&said).unwrap())
        .spawn()
        .unwrap();
    let target = after_kill.len() + 10;
    assert!(wait_until(|| stored_ids(&db).len() >= target), "{kind:?}: the second run logs");
    let caught_up = stored_ids(&db)[target - 1];
    assert!(
        wait_until(|| ids_and_first_occurrences(&subscriber.received()).1.contains(&caught_up)),
        "{kind:?}: the backlog and the new readings are published"
    );
    assert_eq!(terminate(&mut logger, Duration::from_secs(30)), 0, "{kind:?}: SIGTERM stops cleanly");

    let stored = stored_ids(&db);
    assert!(stored.starts_with(&after_kill), "{kind:?}: nothing committed before the kill is lost");
    let published = Store::open(&db).unwrap().published_up_to("mqtt").unwrap();
    assert!(published >= caught_up, "{kind:?}: marked up to {published}, {caught_up} was acknowledged");
    let said = std::fs::read_to_string(&said).unwrap();
    assert!(said.contains(&format!("mqtt: readings published up to id {published}; ")), "{kind:?}: {said}");
    // Marked published: acknowledged by the broker. Those acknowledged just
    // before it stopped may have died with it, and only those.
    let died_with_the_broker = |id: i64| id > acked_before_stop && id <= published_at_kill;
    let marked: Vec<i64> = stored.iter().copied().filter(|id| *id <= published).collect();
    let must_arrive = marked.iter().filter(|id| !died_with_the_broker(**id)).count();
    assert!(
        wait_until(|| {
            let first = ids_and_first_occurrences(&subscriber.received()).1;
            first.iter().filter(|id| !died_with_the_broker(**id)).count() >= must_arrive
        }),
        "{kind:?}: every reading marked published reached the subscriber, but those the broker had when it stopped"
    );
    let received = subscriber.received();
    let (ids, first) = ids_and_first_occurrences(&received);
    let marked: Vec<i64> = marked.into_iter().filter(|id| !died_with_the_broker(*id) || first.contains(id)).collect();
    assert!(first.starts_with(&marked), "{kind:?}: first copies are the stored readings, in order, none missing");
    assert!(stored.starts_with(&first), "{kind:?}: nothing published that is not stored, nothing out of order");
    // Copies: only from the kill (the clean stop waited for its PUBACKs),
    // at most what was in flight, each identical to the first.
    let copies = ids.len() - first.len();
    assert!(copies <= MAX_IN_FLIGHT, "{kind:?}: {copies} copies");
    let mut payloads: BTreeMap<i64, &[u8]> = BTreeMap::new();
    for r in &received {
        let id = r.message().reading_id;
        let first = payloads.entry(id).or_insert(&r.payload);
        assert_eq!(*first, r.payload.as_slice(), "{kind:?}: a copy of {id} is identical");
    }
    eprintln!(
        "    {kind:?}: {} readings, {} stored before the kill ({} of them unpublished), {copies} copies, \
         {} lost with the broker",
        stored.len(),
        after_kill.len(),
        after_kill.iter().filter(|id| **id > published_at_kill).count(),
        stored.iter().filter(|id| died_with_the_broker(**id) && !first.contains(id)).count()
    );
}

#[test]
fn killed_and_restarted_logger_loses_nothing_rumqttd() {
    killed_and_restarted_logger_loses_nothing(BrokerKind::Rumqttd);
}

#[test]
fn killed_and_restarted_logger_loses_nothing_mosquitto() {
    killed_and_restarted_logger_loses_nothing(BrokerKind::Mosquitto);
}

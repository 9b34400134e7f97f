//! The publisher against real brokers started by the tests: rumqttd always,
//! mosquitto when installed (mandatory with `YOSEMITECH_REQUIRE_MOSQUITTO=1`).
//!
//! MQTT QoS 1 is at-least-once: readings in flight when a connection drops
//! may reach a subscriber twice, with the same `reading_id` and payload.
//! The tests check exactly what the crate promises: every reading arrives,
//! the first copies are in id order with none missing (what a consumer
//! deduplicating by `reading_id` sees, exactly once), copies are identical,
//! no more than `max_in_flight` per interruption, and never of a reading
//! already marked published; without an interruption, no copy at all.

use std::convert::Infallible;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use yosemitech_mqtt::topic::DEFAULT_TOPIC_PREFIX;
use yosemitech_mqtt::{MemoryOutbox, MqttConfig, Outbox, Publisher, ReadingMessage, ShutdownReport};
use yosemitech_tests::broker::{
    Broker, BrokerKind, DEADLINE, Received, Subscriber, available, capture_logs, credentials_file,
    ids_and_first_occurrences, reading, wait_until,
};

const ALL_READINGS: &str = "yosemitech/v1/+/+/reading";

/// One test per broker kind for a scenario.
macro_rules! on_every_broker {
    ($($scenario:ident),* $(,)?) => {$(
        mod $scenario {
            use super::*;

            #[test]
            fn rumqttd() {
                super::$scenario(BrokerKind::Rumqttd);
            }

            #[test]
            fn mosquitto() {
                if available(BrokerKind::Mosquitto) {
                    super::$scenario(BrokerKind::Mosquitto);
                }
            }
        }
    )*};
}

on_every_broker!(
    delivers_every_reading_once_in_order_with_the_documented_topic_and_payload,
    survives_a_broker_outage_mid_run,
    a_publisher_dropped_mid_run_is_resumed_by_a_new_one,
    a_publisher_shut_down_cleanly_hands_over_without_copies,
    authenticates_with_a_password_file,
    retained_messages_and_the_last_will_go_beside_the_readings,
);

/// Pushes `count` readings, returning them with their ids.
fn push_readings(outbox: &MemoryOutbox, range: std::ops::Range<usize>) -> Vec<ReadingMessage> {
    range
        .map(|index| {
            let mut message = reading(index);
            message.reading_id = outbox.push(message.clone());
            message
        })
        .collect()
}

fn delivers_every_reading_once_in_order_with_the_documented_topic_and_payload(kind: BrokerKind) {
    const COUNT: usize = 200;
    let broker = Broker::start(kind, None);
    let subscriber = Subscriber::start(&broker, ALL_READINGS);
    let outbox = MemoryOutbox::new();
    let sent = push_readings(&outbox, 0..COUNT);
    let publisher = Publisher::start(&broker.config("station-order", 16), outbox.clone()).unwrap();
    assert!(
        wait_until(|| subscriber.count() >= COUNT && outbox.published_up_to() == Some(COUNT as i64)),
        "{kind:?}: {} of {COUNT} received, published up to {:?}",
        subscriber.count(),
        outbox.published_up_to()
    );
    let report = publisher.shutdown(DEADLINE);
    assert_eq!(report, ShutdownReport { published_up_to: Some(COUNT as i64), unacknowledged: 0 });
    let received = subscriber.received();
    assert_eq!(received.len(), COUNT, "{kind:?}: a reading arrived twice");
    for (got, want) in received.iter().zip(&sent) {
        assert_eq!(got.topic, want.topic(DEFAULT_TOPIC_PREFIX));
        assert_eq!(got.message(), *want);
    }
    // The layout as docs/mqtt.md states it, escaping included.
    assert_eq!(received[0].topic, "yosemitech/v1/river%2001/left%20bank/reading");
    assert_eq!(received[1].topic, "yosemitech/v1/river%2001/inlet%2Fdeep%20%232/reading");
    let json: serde_json::Value = serde_json::from_slice(&received[0].payload).unwrap();
    assert_eq!(json["schema"], 1);
    assert_eq!(json["reading_id"], 1);
    assert_eq!(json["probe"], "left bank");
    assert_eq!(json["values"][1]["unit"], "°C");
}

/// Retained messages of the station's own topics (Home Assistant
/// discovery) share the connection with the readings: each topic's last
/// payload is what the broker retains, the readings still arrive once each
/// in order and are all marked, the status topic says `online`, and a
/// publisher that dies without a DISCONNECT leaves its last will `offline`.
fn retained_messages_and_the_last_will_go_beside_the_readings(kind: BrokerKind) {
    const COUNT: usize = 50;
    let broker = Broker::start(kind, None);
    let readings = Subscriber::start(&broker, ALL_READINGS);
    let outbox = MemoryOutbox::new();
    let status = "yosemitech/v1/river/status".to_owned();
    let config = broker.config("station-retained", 4);
    let publisher = Publisher::start_with_status(&config, outbox.clone(), Some(status.clone())).unwrap();
    let own = |level: &str| format!("yosemitech/v1/river/own/{level}");
    publisher.publish_retained([(own("a"), b"first".to_vec()), (own("b"), b"kept".to_vec())]);
    let sent = push_readings(&outbox, 0..COUNT);
    publisher.wake();
    publisher.publish_retained([(own("a"), b"last".to_vec()), (own("c"), Vec::new())]);
    assert!(
        wait_until(|| readings.count() >= COUNT && outbox.published_up_to() == Some(COUNT as i64)),
        "{kind:?}: the readings go on"
    );
    let ids: Vec<i64> = readings.received().iter().map(|r| r.message().reading_id).collect();
    assert_eq!(ids, sent.iter().map(|m| m.reading_id).collect::<Vec<_>>(), "{kind:?}: once each, in order");

    // What a subscriber arriving now gets: the retained messages only.
    let retained = |subscriber: &Subscriber| -> std::collections::BTreeMap<String, Vec<u8>> {
        subscriber.received().into_iter().map(|r| (r.topic, r.payload)).collect()
    };
    let late = Subscriber::start(&broker, "yosemitech/v1/river/#");
    assert!(wait_until(|| retained(&late).len() >= 3), "{kind:?}: retained messages");
    let got = retained(&late);
    assert_eq!(got.get(&own("a")).map(Vec::as_slice), Some(&b"last"[..]), "{kind:?}: the last payload of a topic");
    assert_eq!(got.get(&own("b")).map(Vec::as_slice), Some(&b"kept"[..]), "{kind:?}");
    assert!(!got.contains_key(&own("c")), "{kind:?}: an empty payload retains nothing");
    assert_eq!(got.get(&status).map(Vec::as_slice), Some(&b"online"[..]), "{kind:?}: online");

    // Dropped: no DISCONNECT, so the broker sends the last will.
    drop(publisher);
    assert!(
        wait_until(|| retained(&late).get(&status).map(Vec::as_slice) == Some(&b"offline"[..])),
        "{kind:?}: the last will"
    );
}

/// An outbox that offers nothing while closed: the test holds the publisher
/// back until its subscriber is subscribed again after a broker restart
/// (a broker without persistence forwards nothing to an absent subscriber).
#[derive(Clone)]
struct GatedOutbox {
    inner: MemoryOutbox,
    open: Arc<AtomicBool>,
}

impl Outbox for GatedOutbox {
    type Error = Infallible;

    fn unpublished(&mut self, after: Option<i64>, limit: usize) -> Result<Vec<ReadingMessage>, Infallible> {
        if self.open.load(Ordering::SeqCst) { self.inner.unpublished(after, limit) } else { Ok(Vec::new()) }
    }

    fn mark_published(&mut self, up_to_id: i64) -> Result<(), Infallible> {
        self.inner.mark_published(up_to_id)
    }
}

/// Checks what the crate promises after interruptions, and returns how many
/// readings are missing:
///
/// * the first copies of the readings are in id order;
/// * every reading of `1..=total` arrived, except possibly readings the
///   broker itself had acknowledged and then lost (ids up to
///   `broker_may_have_lost_up_to`, 0 for none:
///   a broker without persistence killed before forwarding them);
/// * every copy is identical to the first;
/// * copies resent by the publisher (not the broker's own redeliveries,
///   flagged DUP) are at most `max_in_flight` and never of a reading marked
///   published before the interruption (`marked_before`).
fn check_delivery(
    received: &[Received],
    total: usize,
    max_in_flight: u16,
    marked_before: i64,
    broker_may_have_lost_up_to: i64,
) -> usize {
    let (ids, first) = ids_and_first_occurrences(received);
    assert!(first.is_sorted(), "first copies out of order: {first:?}");
    let arrived: std::collections::HashSet<i64> = first.iter().copied().collect();
    let missing: Vec<i64> = (1..=total as i64).filter(|id| !arrived.contains(id)).collect();
    assert!(
        missing.iter().all(|id| *id <= broker_may_have_lost_up_to),
        "readings lost that the broker never acknowledged: {missing:?}"
    );
    assert!(first.iter().all(|id| (1..=total as i64).contains(id)), "{first:?}");
    let mut first_copies = std::collections::HashMap::new();
    let mut publisher_copies = 0;
    for (id, message) in ids.iter().zip(received) {
        if let Some(first_payload) = first_copies.insert(*id, &message.payload) {
            assert_eq!(first_payload, &message.payload, "reading {id} sent with two payloads");
            if !message.redelivered {
                publisher_copies += 1;
                assert!(*id > marked_before, "reading {id} was resent after being marked published");
            }
        }
    }
    eprintln!(
        "{total} readings: {publisher_copies} resent by the publisher, {} redelivered by the broker, {} lost by the broker",
        ids.len() - first.len() - publisher_copies,
        missing.len()
    );
    assert!(publisher_copies <= usize::from(max_in_flight), "{publisher_copies} resent copies");
    missing.len()
}

/// The broker goes away mid-stream and comes back. mosquitto is stopped with
/// SIGTERM and keeps the subscriber's persistent session: every reading
/// arrives. rumqttd is killed and keeps nothing: readings it had
/// acknowledged but not yet forwarded can only be lost by the broker,
/// never ones it had not acknowledged; those the publisher resends.
fn survives_a_broker_outage_mid_run(kind: BrokerKind) {
    const BEFORE: usize = 300;
    const DURING: usize = 100;
    const MAX_IN_FLIGHT: u16 = 8;
    let mut broker = Broker::start(kind, None);
    let open = Arc::new(AtomicBool::new(true));
    let stopped = Arc::new(AtomicBool::new(false));
    // The broker goes away while the publisher is streaming: right after
    // the subscriber's 100th message, with readings in flight behind it.
    let subscriber = {
        let (killer, open, stopped) = (broker.killer(), open.clone(), stopped.clone());
        Subscriber::start_with_hook(&broker, ALL_READINGS, 100, move || {
            killer.kill();
            open.store(false, Ordering::SeqCst);
            stopped.store(true, Ordering::SeqCst);
        })
    };
    let memory = MemoryOutbox::new();
    push_readings(&memory, 0..BEFORE);
    let outbox = GatedOutbox { inner: memory.clone(), open: open.clone() };
    let publisher = Publisher::start(&broker.config("station-outage", MAX_IN_FLIGHT), outbox).unwrap();
    assert!(wait_until(|| stopped.load(Ordering::SeqCst)), "the subscriber never got 100 readings");
    broker.stop();
    assert!(
        wait_until(|| !publisher.status().connected && publisher.status().last_error.is_some()),
        "the publisher did not notice the outage"
    );
    // What the dead broker acknowledged; everything after it must be resent.
    let marked_at_outage = memory.published_up_to().unwrap_or(0);
    assert!(marked_at_outage < BEFORE as i64, "the broker stopped after the run, not during it");

    // Readings keep being committed while the broker is away.
    push_readings(&memory, BEFORE..BEFORE + DURING);
    std::thread::sleep(Duration::from_secs(2));
    assert!(!publisher.status().connected);
    assert_eq!(memory.published_up_to().unwrap_or(0), marked_at_outage);

    broker.restart();
    subscriber.wait_for_subscriptions(2);
    open.store(true, Ordering::SeqCst);
    publisher.wake();
    let total = BEFORE + DURING;
    let resent = |id: i64| id > marked_at_outage;
    assert!(
        wait_until(|| memory.published_up_to() == Some(total as i64)
            && ids_and_first_occurrences(&subscriber.received()).1.iter().filter(|id| resent(**id)).count()
                == total - marked_at_outage as usize),
        "{kind:?}: published up to {:?}, {} received, {} subscriptions: {:?}",
        memory.published_up_to(),
        subscriber.count(),
        subscriber.subscriptions(),
        ids_and_first_occurrences(&subscriber.received()).0
    );
    let status = publisher.status();
    assert!(status.connections >= 2, "{status:?}");
    assert_eq!(publisher.shutdown(DEADLINE).unacknowledged, 0);
    let broker_may_have_lost_up_to = match kind {
        BrokerKind::Mosquitto => {
            // The broker's own redeliveries after its restart may still be on their way.
            assert!(wait_until(|| ids_and_first_occurrences(&subscriber.received()).1.len() == total));
            0
        }
        BrokerKind::Rumqttd => marked_at_outage,
    };
    check_delivery(&subscriber.received(), total, MAX_IN_FLIGHT, marked_at_outage, broker_may_have_lost_up_to);
}

fn a_publisher_dropped_mid_run_is_resumed_by_a_new_one(kind: BrokerKind) {
    const COUNT: usize = 600;
    const MAX_IN_FLIGHT: u16 = 16;
    let broker = Broker::start(kind, None);
    let (reached, at_reached) = std::sync::mpsc::channel();
    let subscriber = Subscriber::start_with_hook(&broker, ALL_READINGS, 150, move || {
        let _ = reached.send(());
    });
    let outbox = MemoryOutbox::new();
    push_readings(&outbox, 0..COUNT);
    let config = broker.config("station-restart", MAX_IN_FLIGHT);
    let first = Publisher::start(&config, outbox.clone()).unwrap();
    at_reached.recv_timeout(DEADLINE).expect("the subscriber never got 150 readings");
    // As a crash would: no waiting for the acknowledgements in flight.
    drop(first);
    let marked_at_drop = outbox.published_up_to().unwrap_or(0);
    assert!(marked_at_drop < COUNT as i64, "the publisher finished before it was dropped");

    let second = Publisher::start(&config, outbox.clone()).unwrap();
    assert!(
        wait_until(|| outbox.published_up_to() == Some(COUNT as i64)
            && ids_and_first_occurrences(&subscriber.received()).1.len() == COUNT),
        "{kind:?}: published up to {:?}, {} received",
        outbox.published_up_to(),
        subscriber.count()
    );
    assert_eq!(second.shutdown(DEADLINE).unacknowledged, 0);
    let lost = check_delivery(&subscriber.received(), COUNT, MAX_IN_FLIGHT, marked_at_drop, 0);
    assert_eq!(lost, 0);
}

fn a_publisher_shut_down_cleanly_hands_over_without_copies(kind: BrokerKind) {
    const COUNT: usize = 400;
    let broker = Broker::start(kind, None);
    let (reached, at_reached) = std::sync::mpsc::channel();
    let subscriber = Subscriber::start_with_hook(&broker, ALL_READINGS, 100, move || {
        let _ = reached.send(());
    });
    let outbox = MemoryOutbox::new();
    push_readings(&outbox, 0..COUNT);
    let config = broker.config("station-handover", 16);
    let first = Publisher::start(&config, outbox.clone()).unwrap();
    at_reached.recv_timeout(DEADLINE).expect("the subscriber never got 100 readings");
    let report = first.shutdown(DEADLINE);
    assert_eq!(report.unacknowledged, 0, "{report:?}");
    assert_eq!(report.published_up_to, outbox.published_up_to());

    let second = Publisher::start(&config, outbox.clone()).unwrap();
    assert!(
        wait_until(|| outbox.published_up_to() == Some(COUNT as i64) && subscriber.count() >= COUNT),
        "{kind:?}: published up to {:?}, {} received",
        outbox.published_up_to(),
        subscriber.count()
    );
    assert_eq!(second.shutdown(DEADLINE).unacknowledged, 0);
    let (ids, _) = ids_and_first_occurrences(&subscriber.received());
    assert_eq!(ids, (1..=COUNT as i64).collect::<Vec<_>>(), "{kind:?}: a copy or a gap");
}

fn authenticates_with_a_password_file(kind: BrokerKind) {
    const USER: &str = "station-river";
    const PASSWORD: &str = "s3cret-Pa55word";
    const WRONG: &str = "wr0ng-Pa55word";
    let logs = capture_logs();
    let broker = Broker::start(kind, Some((USER, PASSWORD)));
    let subscriber = Subscriber::start(&broker, ALL_READINGS);

    // A wrong password: refused, retried, nothing marked, the password in no status or log.
    let wrong_outbox = MemoryOutbox::new();
    push_readings(&wrong_outbox, 0..5);
    let mut config = broker.config("station-wrong", 4);
    config.credentials = credentials_file(broker.dir(), "wrong", USER, WRONG);
    let refused = Publisher::start(&config, wrong_outbox.clone()).unwrap();
    assert!(wait_until(|| refused.status().last_error.is_some()), "{kind:?}: a wrong password was not refused");
    let status = refused.status();
    assert_eq!(status.connections, 0, "{status:?}");
    assert!(!format!("{status:?}").contains(WRONG));
    drop(refused);
    assert_eq!(wrong_outbox.published_up_to(), None);

    // The right password: delivered.
    let outbox = MemoryOutbox::new();
    let sent = push_readings(&outbox, 0..20);
    let mut config = broker.config("station-right", 4);
    config.credentials = credentials_file(broker.dir(), "right", USER, PASSWORD);
    let publisher = Publisher::start(&config, outbox.clone()).unwrap();
    assert!(
        wait_until(|| outbox.published_up_to() == Some(20) && subscriber.count() >= 20),
        "{kind:?}: {:?}",
        publisher.status()
    );
    publisher.shutdown(DEADLINE);
    let received: Vec<ReadingMessage> = subscriber.received().iter().map(Received::message).collect();
    assert_eq!(received, sent);

    let logs = logs.contents();
    assert!(logs.contains("MQTT broker"), "no publisher log captured: {logs}");
    assert!(!logs.contains(PASSWORD) && !logs.contains(WRONG), "a password was logged");
}

/// A certificate authority and a server certificate for 127.0.0.1 signed by
/// it: (CA PEM, server chain PEM, server key PEM).
fn test_pki(name: &str) -> (String, String, String) {
    use rcgen::{BasicConstraints, CertificateParams, DnType, IsCa, Issuer, KeyPair};
    let ca_key = KeyPair::generate().unwrap();
    let mut ca_params = CertificateParams::new(Vec::<String>::new()).unwrap();
    ca_params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    ca_params.distinguished_name.push(DnType::CommonName, format!("{name} test CA"));
    let ca = ca_params.self_signed(&ca_key).unwrap();
    let issuer = Issuer::new(ca_params, ca_key);
    let server_key = KeyPair::generate().unwrap();
    let server = CertificateParams::new(vec!["127.0.0.1".to_owned(), "localhost".to_owned()])
        .unwrap()
        .signed_by(&server_key, &issuer)
        .unwrap();
    (ca.pem(), server.pem() + &ca.pem(), server_key.serialize_pem())
}

/// TLS needs a broker with a TLS listener: mosquitto's, started with a
/// certificate made here; rumqttd runs without its TLS feature.
#[test]
fn publishes_over_tls_and_refuses_a_broker_its_ca_did_not_sign() {
    if !available(BrokerKind::Mosquitto) {
        return;
    }
    let (ca, chain, key) = test_pki("broker");
    let (other_ca, _, _) = test_pki("other");
    let broker = Broker::start_with_tls(BrokerKind::Mosquitto, None, Some((&chain, &key)));
    let tls_port = broker.tls_port.unwrap();
    let subscriber = Subscriber::start(&broker, ALL_READINGS);
    let ca_file = broker.dir().join("ca.pem");
    std::fs::write(&ca_file, ca).unwrap();
    let other_ca_file = broker.dir().join("other-ca.pem");
    std::fs::write(&other_ca_file, other_ca).unwrap();

    // A CA that did not sign the broker's certificate: no connection, nothing marked.
    let refused_outbox = MemoryOutbox::new();
    push_readings(&refused_outbox, 0..3);
    let mut config = broker.config("station-wrong-ca", 4);
    config.port = Some(tls_port);
    config.tls = Some(yosemitech_mqtt::TlsConfig { ca_file: Some(other_ca_file) });
    let refused = Publisher::start(&config, refused_outbox.clone()).unwrap();
    assert!(wait_until(|| refused.status().last_error.is_some()));
    assert_eq!(refused.status().connections, 0);
    let error = refused.status().last_error.unwrap();
    assert!(error.contains("certificate"), "{error}");
    drop(refused);
    assert_eq!(refused_outbox.published_up_to(), None);

    // The broker's own CA: delivered over TLS.
    let outbox = MemoryOutbox::new();
    let sent = push_readings(&outbox, 0..50);
    config.client_id = "station-tls".into();
    config.tls = Some(yosemitech_mqtt::TlsConfig { ca_file: Some(ca_file) });
    let publisher = Publisher::start(&config, outbox.clone()).unwrap();
    assert!(
        wait_until(|| outbox.published_up_to() == Some(50) && subscriber.count() >= 50),
        "{:?}",
        publisher.status()
    );
    assert_eq!(publisher.shutdown(DEADLINE).unacknowledged, 0);
    let received: Vec<ReadingMessage> = subscriber.received().iter().map(Received::message).collect();
    assert_eq!(received, sent);
}

/// A broker acknowledges a reading that matches no subscription and drops
/// it (MQTT 5 reason 0x10). With `require_subscriber` the station keeps
/// such readings and sends them again until a subscriber takes them; without
/// it, as before, they count as published. mosquitto says 0x10; rumqttd
/// never does, so this runs on mosquitto only.
#[test]
fn readings_nobody_subscribed_to_wait_for_a_subscriber_when_required() {
    const COUNT: usize = 20;
    const IN_FLIGHT: u16 = 4;
    if !available(BrokerKind::Mosquitto) {
        return;
    }
    let broker = Broker::start(BrokerKind::Mosquitto, None);

    let dropped = MemoryOutbox::new();
    push_readings(&dropped, 0..COUNT);
    let publisher = Publisher::start(&broker.config("station-not-required", IN_FLIGHT), dropped.clone()).unwrap();
    assert!(wait_until(|| dropped.published_up_to() == Some(COUNT as i64)), "without a subscriber, as acknowledged");
    assert_eq!(publisher.status().undelivered, 0);
    drop(publisher);

    let kept = MemoryOutbox::new();
    let sent = push_readings(&kept, 0..COUNT);
    let config = MqttConfig { require_subscriber: true, ..broker.config("station-required", IN_FLIGHT) };
    let publisher = Publisher::start(&config, kept.clone()).unwrap();
    // The status says why, naming the oldest reading it keeps.
    let says_why = || publisher.status().last_error.is_some_and(|e| e.contains("reading 1 (NoMatchingSubscribers)"));
    assert!(wait_until(says_why), "{:?}", publisher.status());
    assert!(wait_until(|| publisher.status().undelivered > u64::from(IN_FLIGHT)), "sent again while nobody subscribes");
    assert_eq!(kept.published_up_to(), None, "no reading counts as published while nobody subscribes");

    let subscriber = Subscriber::start(&broker, ALL_READINGS);
    assert!(
        wait_until(|| kept.published_up_to() == Some(COUNT as i64)),
        "published once a subscriber came: up to {:?}",
        kept.published_up_to()
    );
    assert!(wait_until(|| subscriber.count() >= COUNT), "{} of {COUNT} received", subscriber.count());
    let (_, first_copies) = ids_and_first_occurrences(&subscriber.received());
    assert_eq!(first_copies, sent.iter().map(|m| m.reading_id).collect::<Vec<_>>(), "every reading, in order");
    assert_eq!(publisher.shutdown(DEADLINE).unacknowledged, 0);
}

/// A broker that refuses a reading (an access control list without the
/// station's write) acknowledges it with a reason (MQTT 5, 0x87): the
/// station keeps it, says why, and sends it again until it is taken.
/// mosquitto's access control lists; rumqttd has none.
#[test]
fn a_reading_the_broker_refuses_is_kept_until_the_broker_takes_it() {
    const COUNT: usize = 10;
    if !available(BrokerKind::Mosquitto) {
        return;
    }
    let mut broker = Broker::start(BrokerKind::Mosquitto, None);
    broker.stop();
    broker.set_acl(Some("topic read #\n"));
    broker.restart();
    let subscriber = Subscriber::start(&broker, ALL_READINGS);
    let outbox = MemoryOutbox::new();
    let sent = push_readings(&outbox, 0..COUNT);
    let publisher = Publisher::start(&broker.config("station-refused", 4), outbox.clone()).unwrap();
    let says_why = || publisher.status().last_error.is_some_and(|e| e.contains("reading 1 (NotAuthorized)"));
    assert!(wait_until(says_why), "{:?}", publisher.status());
    assert_eq!(outbox.published_up_to(), None, "a refused reading is not published");

    broker.stop();
    broker.set_acl(None);
    broker.restart();
    assert!(
        wait_until(|| outbox.published_up_to() == Some(COUNT as i64)),
        "published once allowed: up to {:?}",
        outbox.published_up_to()
    );
    assert!(wait_until(|| subscriber.count() >= COUNT), "{} of {COUNT} received", subscriber.count());
    let (_, first_copies) = ids_and_first_occurrences(&subscriber.received());
    assert_eq!(first_copies, sent.iter().map(|m| m.reading_id).collect::<Vec<_>>(), "every reading, in order");
    drop(publisher);
}

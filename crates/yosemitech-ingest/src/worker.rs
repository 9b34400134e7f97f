//! The ingest worker: the stations' readings from the broker into the
//! database, acknowledged only once committed.
//!
//! The worker holds an MQTT 5 session of its own on the broker (its client
//! id, clean start off, a session expiry), subscribed at QoS 1 to every
//! station's reading topic, through a shared subscription when it has a
//! group (`$share/<group>/...`), so that several workers split the
//! readings between them. Acknowledgements are manual: a batch of
//! deliveries is stored in one transaction, and only after the commit is
//! each delivery acknowledged (PUBACK). So:
//!
//! * a worker killed before its commit leaves the batch unacknowledged;
//!   the broker delivers it again (to the worker's session when it comes
//!   back, as MQTT keeps a session's unacknowledged messages);
//! * a worker killed between commit and acknowledgement gets the batch
//!   again, and the database keeps each reading once: a reading's identity
//!   is its station's `(station, reading_id)`, and an insert of a stored
//!   reading does nothing.
//!
//! The broker must keep sessions across its own restarts (mosquitto:
//! `persistence true`), as it must for the stations' QoS 1 in any case.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use rumqttc::Transport;
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::mqttbytes::v5::{Packet, Publish, SubscribeReasonCode};
use rumqttc::v5::{Client, Connection, Event, MqttOptions, RecvTimeoutError};
use yosemitech_mqtt::{Credentials, TlsConfig, tls_client_config, topic};

use crate::database::{Database, DatabaseError, Delivery, Stored};

/// Where the worker connects and how it batches.
#[derive(Debug, Clone)]
pub struct IngestConfig {
    /// Broker host name or address.
    pub host: String,
    /// Broker port.
    pub port: u16,
    /// TLS to the broker (rustls), when present.
    pub tls: Option<TlsConfig>,
    /// The broker user name and password, when it asks for them.
    pub credentials: Option<Credentials>,
    /// The worker's MQTT client id: its session on the broker. Every
    /// worker needs its own, kept across its restarts.
    pub client_id: String,
    /// The stations' first topic levels (`mqtt.topic_prefix`).
    pub topic_prefix: String,
    /// The shared subscription's group: workers of one group split the
    /// readings. `None`: this worker gets every reading.
    pub group: Option<String>,
    /// Deliveries stored in one transaction at most.
    pub batch_size: usize,
    /// How long the first delivery of a batch waits for the batch to fill.
    pub batch_wait: Duration,
    /// How long the broker keeps the worker's session while it is away.
    pub session_expiry: Duration,
}

impl IngestConfig {
    /// The subscription: every station's reading topic, shared by the group.
    pub fn filter(&self) -> String {
        let readings = format!("{}/+/+/{}", self.topic_prefix, topic::READING_LEVEL);
        match &self.group {
            Some(group) => format!("$share/{group}/{readings}"),
            None => readings,
        }
    }
}

/// What a worker did, so far or in all.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Totals {
    /// Messages received on the reading topics (every delivery, repeats included).
    pub delivered: u64,
    /// What storing them did.
    pub stored: Stored,
    /// Transactions committed.
    pub batches: u64,
    /// Broker connections made (1 after the first, +1 per reconnection).
    pub connections: u64,
    /// Whether the subscription is in place on the broker (acknowledged
    /// on the current connection).
    pub subscribed: bool,
}

/// Why a worker stopped before it was asked to.
#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    /// The database refused the schema or the first connection.
    #[error(transparent)]
    Database(#[from] DatabaseError),
    /// The broker configuration (TLS) is unusable.
    #[error("{0}")]
    Broker(String),
}

/// Pause before retrying a broker or database that failed, doubling up to the most.
const RETRY_FIRST: Duration = Duration::from_millis(200);
const RETRY_MOST: Duration = Duration::from_secs(5);

/// Runs a worker until `stop` is set: connects to the database (migrating
/// its schema) and to the broker, and stores what arrives. `progress` is
/// called with the totals so far after each committed batch, at each
/// connection and when the subscription is in place. Broker and database
/// failures after the start are retried, forever; a subscription the
/// broker refuses ends the worker with an error.
pub fn run(
    config: &IngestConfig,
    database: &postgres::Config,
    stop: &Arc<AtomicBool>,
    mut progress: impl FnMut(&Totals),
) -> Result<Totals, IngestError> {
    let mut db = Database::open(database)?;
    let (client, mut connection) = Client::new(options(config)?, config.batch_size.max(1) * 2 + 16);
    let mut totals = Totals::default();
    let mut batch: Vec<Publish> = Vec::new();
    let mut batch_started: Option<Instant> = None;
    let mut retry = RETRY_FIRST;
    while !stop.load(Ordering::SeqCst) {
        match connection.recv_timeout(Duration::from_millis(50)) {
            Ok(Ok(Event::Incoming(Packet::Publish(publish)))) => {
                totals.delivered += 1;
                batch.push(publish);
                batch_started.get_or_insert_with(Instant::now);
            }
            Ok(Ok(Event::Incoming(Packet::ConnAck(ack)))) => {
                totals.connections += 1;
                retry = RETRY_FIRST;
                tracing::info!(session_present = ack.session_present, "connected to the broker");
                // Subscribed again even when the session was kept: a broker
                // restored from its persistence file may have kept the
                // session's messages but not a shared subscription (mosquitto
                // 2.0). Subscribing again to the same filter changes nothing else.
                totals.subscribed = false;
                let _ = client.try_subscribe(config.filter(), QoS::AtLeastOnce);
                progress(&totals);
            }
            Ok(Ok(Event::Incoming(Packet::SubAck(ack)))) => {
                // A refusal (no shared subscriptions, not authorised) would
                // leave the worker connected and idle, and a grant of QoS 0
                // would deliver readings that no acknowledgement after the
                // commit guards: it stops instead.
                let at_least_once = |code: &&SubscribeReasonCode| {
                    matches!(code, SubscribeReasonCode::Success(QoS::AtLeastOnce | QoS::ExactlyOnce))
                };
                if let Some(refused) = ack.return_codes.iter().find(|code| !at_least_once(code)) {
                    disconnect(&client, &mut connection);
                    return Err(IngestError::Broker(format!(
                        "the broker refused the subscription to {} at QoS 1: {refused:?}",
                        config.filter()
                    )));
                }
                totals.subscribed = true;
                progress(&totals);
            }
            Ok(Ok(_)) | Err(RecvTimeoutError::Timeout) => {}
            Ok(Err(error)) => {
                // Unacknowledged deliveries come again on the next connection.
                batch.clear();
                batch_started = None;
                tracing::warn!(%error, "broker connection lost; reconnecting");
                wait(stop, retry);
                retry = (retry * 2).min(RETRY_MOST);
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(IngestError::Broker("the MQTT client stopped".into()));
            }
        }
        let full = batch.len() >= config.batch_size.max(1);
        let due = batch_started.is_some_and(|at| at.elapsed() >= config.batch_wait);
        if full || due {
            if !store(&mut db, database, &batch, stop, &mut totals) {
                break;
            }
            acknowledge(&client, batch.drain(..));
            batch_started = None;
            progress(&totals);
        }
    }
    // What is held is stored and acknowledged before leaving.
    if !batch.is_empty() && store(&mut db, database, &batch, stop, &mut totals) {
        acknowledge(&client, batch.drain(..));
        progress(&totals);
    }
    disconnect(&client, &mut connection);
    Ok(totals)
}

/// Stores `batch`, retrying (reconnecting) until it is committed; false
/// when `stop` is set first.
fn store(
    db: &mut Database,
    config: &postgres::Config,
    batch: &[Publish],
    stop: &AtomicBool,
    totals: &mut Totals,
) -> bool {
    let deliveries: Vec<Delivery> =
        batch.iter().map(|p| Delivery::parse(&String::from_utf8_lossy(&p.topic), &p.payload)).collect();
    let mut retry = RETRY_FIRST;
    loop {
        match db.store(&deliveries) {
            Ok(stored) => {
                totals.stored += stored;
                totals.batches += 1;
                return true;
            }
            Err(error) => {
                tracing::warn!(%error, "cannot store a batch; retrying");
                if stop.load(Ordering::SeqCst) {
                    return false;
                }
                wait(stop, retry);
                retry = (retry * 2).min(RETRY_MOST);
                if let Ok(fresh) = Database::open(config) {
                    *db = fresh;
                }
            }
        }
    }
}

/// Acknowledges committed deliveries. The client's queue holds two
/// batches, and the loop drains it between batches, so it has room; were
/// it full, the delivery would come again on the next connection.
fn acknowledge(client: &Client, committed: impl Iterator<Item = Publish>) {
    for publish in committed {
        if let Err(error) = client.try_ack(&publish) {
            tracing::warn!(%error, "cannot queue an acknowledgement; the broker will deliver it again");
        }
    }
}

/// Sleeps `pause`, or less when `stop` is set.
fn wait(stop: &AtomicBool, pause: Duration) {
    let until = Instant::now() + pause;
    while !stop.load(Ordering::SeqCst) && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Sends the acknowledgements still queued, then disconnects.
fn disconnect(client: &Client, connection: &mut Connection) {
    let _ = client.try_disconnect();
    let until = Instant::now() + Duration::from_secs(2);
    while Instant::now() < until {
        match connection.recv_timeout(Duration::from_millis(100)) {
            Ok(Ok(Event::Outgoing(rumqttc::Outgoing::Disconnect))) | Ok(Err(_)) => break,
            Err(RecvTimeoutError::Disconnected) => break,
            _ => {}
        }
    }
}

/// The MQTT options of a worker: its own session, manual acknowledgements.
fn options(config: &IngestConfig) -> Result<MqttOptions, IngestError> {
    let mut options = MqttOptions::new(&config.client_id, &config.host, config.port);
    options.set_keep_alive(Duration::from_secs(30));
    options.set_clean_start(false);
    options.set_session_expiry_interval(Some(u32::try_from(config.session_expiry.as_secs()).unwrap_or(u32::MAX)));
    options.set_manual_acks(true);
    // Enough in flight for a full batch while the one before it is stored.
    options.set_receive_maximum(Some(u16::try_from(config.batch_size.max(1) * 2).unwrap_or(u16::MAX)));
    if let Some(credentials) = &config.credentials {
        options.set_credentials(credentials.username.clone(), credentials.password.expose().to_owned());
    }
    if let Some(tls) = &config.tls {
        let tls = tls_client_config(tls).map_err(|e| IngestError::Broker(e.to_string()))?;
        options.set_transport(Transport::tls_with_config(rumqttc::TlsConfiguration::Rustls(tls)));
    }
    Ok(options)
}

//! The publisher: drains an [`Outbox`] to the broker, in order, QoS 1, over MQTT 5.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::mqttbytes::v5::{LastWill, Packet, PubAck, PubAckReason};
use rumqttc::v5::{AsyncClient, ConnectionError, Event, MqttOptions};
use rumqttc::{Outgoing, Transport};
use tokio::sync::{Notify, mpsc, watch};
use tokio::time::Instant;

use crate::config::{ConfigError, Credentials, MqttConfig, PublisherTuning};
use crate::home_assistant::{OFFLINE, ONLINE, Retained};
use crate::outbox::Outbox;

/// Publishes the readings of an [`Outbox`] to the broker from a thread of
/// its own, until shut down or dropped.
///
/// # What is guaranteed
///
/// * **Order.** Readings are published in ascending `reading_id`, one MQTT
///   connection at a time; after a reconnection the publisher resends from
///   the oldest reading not yet acknowledged. A broker keeps one client's
///   QoS 1 messages in order, so a subscriber sees the ids ascending, except
///   that resent readings (below) can follow readings it already has.
/// * **Nothing lost.** A reading is marked published in the outbox
///   ([`Outbox::mark_published`]) only after the broker's PUBACK accepting
///   it and every older reading. Whatever is not marked is sent again: after
///   a broker outage (reconnection with exponential backoff, forever), after
///   [`Publisher::shutdown`] hit its deadline, after the publisher was
///   dropped, after the process was killed. A PUBACK that refuses a reading
///   (an MQTT 5 reason code of 0x80 or above: not authorized, quota
///   exceeded), or says nobody subscribed to it when
///   [`MqttConfig::require_subscriber`] is on, leaves it and every later
///   reading unpublished: they are sent again after a pause that doubles
///   from `reconnect_min_ms` to `reconnect_max_ms` while the broker keeps
///   refusing ([`PublisherStatus::undelivered`] counts these refusals).
/// * **No reading under two ids, no acknowledged reading resent.** A
///   reading's payload is rebuilt from the outbox with its `reading_id`, so
///   every copy is identical. The only copies are resends of readings that
///   were in flight (sent, not yet acknowledged) when a connection dropped
///   or a publisher stopped, or that followed a refused reading: at most
///   `max_in_flight` per such event. MQTT
///   QoS 1 is at-least-once; a consumer that keeps the first message per
///   `(station, reading_id)` sees every reading exactly once, in order.
/// * **Credentials** are handed to the MQTT client and never logged;
///   errors and [`PublisherStatus::last_error`] name no secret.
///
/// Each connection is a clean MQTT session (the broker keeps no state for
/// the publisher): the outbox, not the broker, is the durable queue.
///
/// Beside the readings it can publish retained messages on the station's
/// own topics ([`Publisher::publish_retained`]: Home Assistant discovery,
/// states, availability) and keep the logger's availability on a status
/// topic with an MQTT last will ([`Publisher::start_with_status`]). They
/// take in-flight slots like readings and change nothing of the above.
pub struct Publisher {
    shared: Arc<Shared>,
    stop: watch::Sender<Stop>,
    thread: Option<JoinHandle<ShutdownReport>>,
}

/// Why a publisher could not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The configuration or its credentials or CA file.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The runtime or the thread could not be created.
    #[error("cannot start the MQTT publisher thread: {0}")]
    Thread(#[from] std::io::Error),
}

/// A snapshot of what the publisher is doing.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PublisherStatus {
    /// Whether a broker connection is up (CONNACK received, not yet lost).
    pub connected: bool,
    /// Successful connections so far (1 after the first, +1 per reconnection).
    pub connections: u64,
    /// The highest `reading_id` this publisher marked published.
    pub published_up_to: Option<i64>,
    /// Readings sent and not yet acknowledged.
    pub in_flight: usize,
    /// Readings the broker acknowledged without taking them (refused, or no
    /// subscriber when [`MqttConfig::require_subscriber`] is on), each sent
    /// again later: the count of such acknowledgements so far.
    pub undelivered: u64,
    /// The last connection or outbox error, if any since the last
    /// successful connection. It names no credential.
    pub last_error: Option<String>,
}

/// What [`Publisher::shutdown`] left behind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShutdownReport {
    /// The highest `reading_id` this publisher marked published.
    pub published_up_to: Option<i64>,
    /// Readings sent but not acknowledged when it stopped; the next
    /// publisher on the same outbox sends them again.
    pub unacknowledged: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stop {
    Run,
    /// Send nothing new; wait for the PUBACKs in flight until the deadline.
    Drain(Instant),
    Abort,
}

#[derive(Default)]
struct Shared {
    wake: Notify,
    status: Mutex<PublisherStatus>,
    retained: Mutex<RetainedState>,
}

/// The retained messages of the station's own topics (Home Assistant
/// discovery, states, availability): the last payload of each topic, sent
/// again after every connection (a broker restarted without persistence
/// has forgotten them), and those not yet sent on this connection.
#[derive(Default)]
struct RetainedState {
    latest: Vec<Retained>,
    pending: Vec<Retained>,
}

/// Puts `message` in `list`, replacing (and moving to the end) an earlier
/// payload of its topic: only the last payload of a retained topic matters.
fn replace_or_push(list: &mut Vec<Retained>, message: Retained) {
    list.retain(|(topic, _)| *topic != message.0);
    list.push(message);
}

impl Shared {
    fn update(&self, change: impl FnOnce(&mut PublisherStatus)) {
        change(&mut self.status.lock().unwrap_or_else(PoisonError::into_inner));
    }

    fn retained(&self) -> std::sync::MutexGuard<'_, RetainedState> {
        self.retained.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Everything a connection attempt needs, credentials included; not `Debug`.
struct Settings {
    host: String,
    port: u16,
    client_id: String,
    keep_alive: Duration,
    topic_prefix: String,
    tls: Option<Arc<rustls::ClientConfig>>,
    credentials: Option<Credentials>,
    tuning: PublisherTuning,
    require_subscriber: bool,
    /// The logger's availability topic: last will `offline`, `online` after
    /// each connection, `offline` at a clean stop.
    status_topic: Option<String>,
}

impl Publisher {
    /// Checks `config` (as [`MqttConfig::check`]), loads the credentials and
    /// the CA file, and starts publishing `outbox` from a new thread. It
    /// connects in the background: an unreachable broker is not an error
    /// here, it is retried (see [`Publisher::status`]).
    pub fn start<O>(config: &MqttConfig, outbox: O) -> Result<Self, StartError>
    where
        O: Outbox + Send + 'static,
    {
        Self::start_with_status(config, outbox, None)
    }

    /// [`Publisher::start`], with the logger's availability on
    /// `status_topic` (retained): `offline` as the MQTT last will (the
    /// broker sends it when the connection dies) and at a clean stop,
    /// `online` after each connection.
    pub fn start_with_status<O>(
        config: &MqttConfig,
        outbox: O,
        status_topic: Option<String>,
    ) -> Result<Self, StartError>
    where
        O: Outbox + Send + 'static,
    {
        config.check_static()?;
        let credentials = config.credentials.load().map_err(ConfigError::from)?;
        let tls = config.tls.as_ref().map(crate::tls::client_config).transpose()?;
        let settings = Settings {
            host: config.host.clone(),
            port: config.port(),
            client_id: config.client_id.clone(),
            keep_alive: Duration::from_secs(u64::from(config.keep_alive_secs)),
            topic_prefix: config.topic_prefix.clone(),
            tls,
            credentials,
            tuning: config.publisher.clone(),
            require_subscriber: config.require_subscriber,
            status_topic,
        };
        let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
        let shared = Arc::new(Shared::default());
        let (stop, stop_rx) = watch::channel(Stop::Run);
        let thread_shared = Arc::clone(&shared);
        let thread = std::thread::Builder::new().name("mqtt-publisher".into()).spawn(move || {
            let resend_pause = Duration::from_millis(settings.tuning.reconnect_min_ms);
            let worker = Worker {
                outbox,
                settings,
                shared: thread_shared,
                stop: stop_rx,
                acked_up_to: None,
                resend_at: None,
                resend_pause,
            };
            runtime.block_on(worker.run())
        })?;
        Ok(Self { shared, stop, thread: Some(thread) })
    }

    /// Tells the publisher that new readings were committed, so it looks at
    /// the outbox now instead of at its next poll.
    pub fn wake(&self) {
        self.shared.wake.notify_one();
    }

    /// Publishes `messages` retained (QoS 1) on the station's own topics,
    /// after the readings in flight and before the next ones; an empty
    /// payload clears a topic. Each topic's last payload is sent again after
    /// every reconnection. Nothing here is stored: a message is lost with
    /// the process, and its sender announces it again at the next start.
    pub fn publish_retained(&self, messages: impl IntoIterator<Item = Retained>) {
        {
            let mut retained = self.shared.retained();
            for message in messages {
                replace_or_push(&mut retained.latest, message.clone());
                replace_or_push(&mut retained.pending, message);
            }
        }
        self.wake();
    }

    /// What the publisher is doing now.
    pub fn status(&self) -> PublisherStatus {
        self.shared.status.lock().unwrap_or_else(PoisonError::into_inner).clone()
    }

    /// Stops cleanly: sends nothing new, waits for the acknowledgements of
    /// the readings in flight (at most `deadline`), disconnects, and returns
    /// what is left. Readings still unacknowledged stay unpublished in the
    /// outbox and are sent again by the next publisher.
    pub fn shutdown(mut self, deadline: Duration) -> ShutdownReport {
        self.stop.send_replace(Stop::Drain(Instant::now() + deadline));
        self.join()
    }

    fn join(&mut self) -> ShutdownReport {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(report)) => report,
            // The thread panicked (a bug in an outbox implementation): report
            // what it last published.
            Some(Err(_)) | None => {
                let status = self.status();
                ShutdownReport { published_up_to: status.published_up_to, unacknowledged: status.in_flight }
            }
        }
    }
}

impl Drop for Publisher {
    /// Stops at once, without waiting for acknowledgements (what is in
    /// flight is sent again by the next publisher), and joins the thread.
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.stop.send_replace(Stop::Abort);
            self.join();
        }
    }
}

/// A message sent on the current connection.
struct InFlight {
    /// The reading's id; `None` for a retained message of the station's own topics.
    reading_id: Option<i64>,
    /// The MQTT packet id, once the client has sent the PUBLISH.
    packet_id: Option<u16>,
    outcome: Outcome,
}

/// What the broker's PUBACK said of a message in flight.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Waiting,
    Delivered,
    /// Acknowledged but not taken, for this reason: the reading is sent again.
    Undelivered(PubAckReason),
}

enum SessionEnd {
    Stopped(ShutdownReport),
    Lost { was_connected: bool },
}

struct Worker<O> {
    outbox: O,
    settings: Settings,
    shared: Arc<Shared>,
    stop: watch::Receiver<Stop>,
    /// The highest id marked published by this worker.
    acked_up_to: Option<i64>,
    /// After the broker did not take a reading: when to send it again.
    resend_at: Option<Instant>,
    /// The next pause after an undelivered reading; doubles while the broker
    /// keeps refusing, back to `reconnect_min_ms` once it takes one.
    resend_pause: Duration,
}

impl<O: Outbox> Worker<O> {
    async fn run(mut self) -> ShutdownReport {
        let tuning = self.settings.tuning.clone();
        let min_backoff = Duration::from_millis(tuning.reconnect_min_ms);
        let max_backoff = Duration::from_millis(tuning.reconnect_max_ms);
        let mut backoff = min_backoff;
        loop {
            if *self.stop.borrow() != Stop::Run {
                return self.report(0);
            }
            match self.session().await {
                SessionEnd::Stopped(report) => return report,
                SessionEnd::Lost { was_connected } => {
                    if was_connected {
                        backoff = min_backoff;
                    }
                    tracing::debug!(?backoff, "reconnecting to the MQTT broker after a pause");
                    let mut stop = self.stop.clone();
                    tokio::select! {
                        () = tokio::time::sleep(backoff) => {}
                        _ = stop.wait_for(|stop| *stop != Stop::Run) => {}
                    }
                    backoff = (backoff * 2).min(max_backoff);
                }
            }
        }
    }

    fn report(&self, unacknowledged: usize) -> ShutdownReport {
        ShutdownReport { published_up_to: self.acked_up_to, unacknowledged }
    }

    fn options(&self) -> MqttOptions {
        let settings = &self.settings;
        let mut options = MqttOptions::new(&settings.client_id, &settings.host, settings.port);
        options
            .set_keep_alive(settings.keep_alive)
            .set_clean_start(true)
            .set_outgoing_inflight_upper_limit(settings.tuning.max_in_flight)
            .set_max_packet_size(Some(256 * 1024));
        if let Some(credentials) = &settings.credentials {
            options.set_credentials(&credentials.username, credentials.password.expose());
        }
        if let Some(topic) = &settings.status_topic {
            options.set_last_will(LastWill::new(topic, OFFLINE, QoS::AtLeastOnce, true, None));
        }
        if let Some(tls) = &settings.tls {
            options.set_transport(Transport::tls_with_config(rumqttc::TlsConfiguration::Rustls(Arc::clone(tls))));
        }
        options
    }

    /// One connection, from connecting to losing it or being stopped.
    async fn session(&mut self) -> SessionEnd {
        let max_in_flight = usize::from(self.settings.tuning.max_in_flight);
        let (client, mut event_loop) = AsyncClient::new(self.options(), max_in_flight + 4);
        // The event loop runs in its own task so that waiting for it is
        // cancel-safe; it ends at the first error, and a new connection gets a
        // new client, so nothing queued for a lost connection is ever sent.
        let (events_tx, mut events) = mpsc::unbounded_channel();
        let driver = tokio::spawn(async move {
            loop {
                let event = event_loop.poll().await;
                let failed = event.is_err();
                if events_tx.send(event).is_err() || failed {
                    break;
                }
            }
        });
        let _driver = AbortOnDrop(driver);

        let mut in_flight = VecDeque::new();
        let mut connected = false;
        // A new connection may reach the subscriber the last one did not.
        self.resend_at = None;
        let mut poll = tokio::time::interval(self.settings.tuning.poll_interval());
        poll.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let shared = Arc::clone(&self.shared);
        let mut stop = self.stop.clone();
        let end = 'session: loop {
            let current_stop = *stop.borrow_and_update();
            match current_stop {
                Stop::Abort => {
                    self.mark_acknowledged(&mut in_flight);
                    break SessionEnd::Stopped(self.report(readings_in(&in_flight)));
                }
                Stop::Drain(deadline) if in_flight.is_empty() || Instant::now() >= deadline => {
                    if connected {
                        // A clean DISCONNECT cancels the last will: say it ourselves.
                        if let Some(topic) = &self.settings.status_topic {
                            let _ = client.try_publish(topic, QoS::AtLeastOnce, true, OFFLINE);
                        }
                        disconnect(&client, &mut events, deadline).await;
                    }
                    break SessionEnd::Stopped(self.report(readings_in(&in_flight)));
                }
                _ => {}
            }
            let drain_deadline = match current_stop {
                Stop::Drain(deadline) => deadline,
                _ => Instant::now() + Duration::from_secs(3600),
            };
            let may_send = connected && current_stop == Stop::Run;
            tokio::select! {
                event = events.recv() => {
                    // Everything that has arrived is handled before the outbox
                    // is touched: one mark (one store commit) per burst of
                    // PUBACKs rather than one per reading.
                    let mut next = event;
                    loop {
                        match next {
                            Some(Ok(event)) => self.on_event(event, &mut connected, &mut in_flight),
                            // PUBACKs that came before the loss still count.
                            Some(Err(error)) => {
                                self.mark_acknowledged(&mut in_flight);
                                break 'session self.lost(connected, &error);
                            }
                            None => {
                                self.mark_acknowledged(&mut in_flight);
                                break 'session SessionEnd::Lost { was_connected: connected };
                            }
                        }
                        match events.try_recv() {
                            Ok(event) => next = Some(event),
                            Err(_) => break,
                        }
                    }
                    self.mark_acknowledged(&mut in_flight);
                    if connected && current_stop == Stop::Run {
                        self.fill(&client, &mut in_flight);
                    }
                }
                () = shared.wake.notified(), if may_send => self.fill(&client, &mut in_flight),
                _ = poll.tick() => {
                    // Retries a mark that failed, and finds readings nobody woke us for.
                    self.mark_acknowledged(&mut in_flight);
                    if may_send {
                        self.fill(&client, &mut in_flight);
                    }
                }
                _ = stop.changed() => {}
                () = tokio::time::sleep_until(drain_deadline) => {}
            }
            let count = readings_in(&in_flight);
            shared.update(|status| status.in_flight = count);
        };
        shared.update(|status| {
            status.connected = false;
            status.in_flight = 0;
        });
        end
    }

    /// Follows the connection and the packet ids of the readings in flight.
    fn on_event(&self, event: Event, connected: &mut bool, in_flight: &mut VecDeque<InFlight>) {
        match event {
            Event::Incoming(Packet::ConnAck(_)) => {
                *connected = true;
                tracing::info!(
                    host = %self.settings.host,
                    port = self.settings.port,
                    "connected to the MQTT broker"
                );
                self.shared.update(|status| {
                    status.connected = true;
                    status.connections += 1;
                    status.last_error = None;
                });
                // A new connection: every retained topic again, the logger online first.
                let mut retained = self.shared.retained();
                retained.pending = retained.latest.clone();
                if let Some(topic) = &self.settings.status_topic {
                    retained.pending.insert(0, (topic.clone(), ONLINE.as_bytes().to_vec()));
                }
            }
            // The client sends PUBLISHes in the order they were queued.
            Event::Outgoing(Outgoing::Publish(packet_id)) => {
                if let Some(entry) = in_flight.iter_mut().find(|entry| entry.packet_id.is_none()) {
                    entry.packet_id = Some(packet_id);
                }
            }
            Event::Incoming(Packet::PubAck(ack)) => {
                match in_flight.iter_mut().find(|e| e.outcome == Outcome::Waiting && e.packet_id == Some(ack.pkid)) {
                    Some(entry) => entry.outcome = self.outcome(entry.reading_id, &ack),
                    None => tracing::warn!(packet_id = ack.pkid, "PUBACK for no message in flight"),
                }
            }
            _ => {}
        }
    }

    /// Whether the broker took the message `ack` acknowledges. A retained
    /// message of the station's own topics is kept by the broker whoever
    /// subscribes, and one it refuses is sent again at the next connection.
    fn outcome(&self, reading_id: Option<i64>, ack: &PubAck) -> Outcome {
        let no_subscriber = ack.reason == PubAckReason::NoMatchingSubscribers;
        if ack.reason == PubAckReason::Success || (no_subscriber && !self.settings.require_subscriber) {
            return Outcome::Delivered;
        }
        let Some(reading_id) = reading_id else {
            if !no_subscriber {
                tracing::warn!(reason = ?ack.reason, "the MQTT broker refused a retained message");
            }
            return Outcome::Delivered;
        };
        tracing::debug!(reading_id, reason = ?ack.reason, "the MQTT broker did not take a reading");
        self.shared.update(|status| status.undelivered += 1);
        Outcome::Undelivered(ack.reason)
    }

    fn lost(&self, connected: bool, error: &ConnectionError) -> SessionEnd {
        // ConnectionError's text names the host, the refusal code or the I/O
        // error: never the credentials.
        let message = error.to_string();
        if connected {
            tracing::warn!(error = %message, "lost the MQTT broker connection");
        } else {
            tracing::warn!(error = %message, "cannot connect to the MQTT broker");
        }
        self.shared.update(|status| status.last_error = Some(message));
        SessionEnd::Lost { was_connected: connected }
    }

    /// Sends the retained messages waiting, then unpublished readings,
    /// until `max_in_flight` are in flight.
    fn fill(&mut self, client: &AsyncClient, in_flight: &mut VecDeque<InFlight>) {
        let max_in_flight = usize::from(self.settings.tuning.max_in_flight);
        {
            let mut retained = self.shared.retained();
            let mut sent = 0;
            for (topic, payload) in &retained.pending {
                if in_flight.len() >= max_in_flight
                    || client.try_publish(topic, QoS::AtLeastOnce, true, payload.clone()).is_err()
                {
                    break;
                }
                in_flight.push_back(InFlight { reading_id: None, packet_id: None, outcome: Outcome::Waiting });
                sent += 1;
            }
            retained.pending.drain(..sent);
        }
        if self.resend_at.is_some_and(|at| Instant::now() < at) {
            return;
        }
        let last_reading = |in_flight: &VecDeque<InFlight>| in_flight.iter().rev().find_map(|entry| entry.reading_id);
        while in_flight.len() < max_in_flight {
            let after = last_reading(in_flight).or(self.acked_up_to);
            let limit = max_in_flight - in_flight.len();
            let batch = match self.outbox.unpublished(after, limit) {
                Ok(batch) => batch,
                Err(error) => {
                    self.outbox_error("read", &error);
                    return;
                }
            };
            if batch.is_empty() {
                return;
            }
            for message in batch.into_iter().take(limit) {
                if after.is_some_and(|after| message.reading_id <= after)
                    || last_reading(in_flight).is_some_and(|last| message.reading_id <= last)
                {
                    tracing::error!(
                        reading_id = message.reading_id,
                        ?after,
                        "the outbox returned a reading out of order; not publishing it"
                    );
                    self.shared.update(|status| {
                        status.last_error = Some(format!(
                            "outbox returned reading {} out of order (after {after:?})",
                            message.reading_id
                        ));
                    });
                    return;
                }
                let payload = match message.to_payload() {
                    Ok(payload) => payload,
                    Err(error) => {
                        self.outbox_error("encode", &error);
                        return;
                    }
                };
                let topic = message.topic(&self.settings.topic_prefix);
                if client.try_publish(topic, QoS::AtLeastOnce, false, payload).is_err() {
                    // The request queue is full or the connection is gone: the
                    // reading is not in flight and the next fill takes it again.
                    return;
                }
                in_flight.push_back(InFlight {
                    reading_id: Some(message.reading_id),
                    packet_id: None,
                    outcome: Outcome::Waiting,
                });
            }
        }
    }

    /// Marks the delivered prefix of `in_flight` published in the outbox.
    /// Once a reading the broker did not take heads what is left, and every
    /// message sent after it is acknowledged too, they are all forgotten:
    /// the next fill, after a pause, sends them again from that reading.
    fn mark_acknowledged(&mut self, in_flight: &mut VecDeque<InFlight>) {
        self.mark_delivered(in_flight);
        let Some(&InFlight { reading_id: Some(reading_id), outcome: Outcome::Undelivered(reason), .. }) =
            in_flight.front()
        else {
            return;
        };
        if in_flight.iter().any(|entry| entry.outcome == Outcome::Waiting) {
            return;
        }
        in_flight.clear();
        let pause = self.resend_pause;
        self.resend_at = Some(Instant::now() + pause);
        self.resend_pause = (pause * 2).min(Duration::from_millis(self.settings.tuning.reconnect_max_ms));
        let message = format!(
            "the broker did not take reading {reading_id} ({reason:?}): it and those after it are sent again in {} ms",
            pause.as_millis()
        );
        tracing::warn!("{message}");
        self.shared.update(|status| status.last_error = Some(message));
    }

    fn mark_delivered(&mut self, in_flight: &mut VecDeque<InFlight>) {
        let delivered = in_flight.iter().take_while(|entry| entry.outcome == Outcome::Delivered).count();
        let Some(up_to) = in_flight.iter().take(delivered).filter_map(|entry| entry.reading_id).next_back() else {
            // Only retained messages (or nothing) acknowledged: no reading to mark.
            in_flight.drain(..delivered);
            return;
        };
        match self.outbox.mark_published(up_to) {
            Ok(()) => {
                in_flight.drain(..delivered);
                self.acked_up_to = Some(up_to);
                self.resend_pause = Duration::from_millis(self.settings.tuning.reconnect_min_ms);
                self.shared.update(|status| status.published_up_to = Some(up_to));
            }
            Err(error) => self.outbox_error("mark published", &error),
        }
    }

    fn outbox_error(&self, action: &str, error: &dyn std::error::Error) {
        tracing::warn!(%error, "MQTT outbox: cannot {action}");
        let message = format!("outbox: cannot {action}: {error}");
        self.shared.update(|status| status.last_error = Some(message));
    }
}

/// Sends DISCONNECT and waits (until `deadline`, at most a few seconds) for
/// it to leave.
async fn disconnect(
    client: &AsyncClient,
    events: &mut mpsc::UnboundedReceiver<Result<Event, ConnectionError>>,
    deadline: Instant,
) {
    if client.try_disconnect().is_err() {
        return;
    }
    let limit = deadline.max(Instant::now() + Duration::from_millis(100)).min(Instant::now() + Duration::from_secs(5));
    while let Ok(Some(Ok(event))) = tokio::time::timeout_at(limit, events.recv()).await {
        if matches!(event, Event::Outgoing(Outgoing::Disconnect)) {
            return;
        }
    }
}

/// The readings among the messages in flight.
fn readings_in(in_flight: &VecDeque<InFlight>) -> usize {
    in_flight.iter().filter(|entry| entry.reading_id.is_some()).count()
}

struct AbortOnDrop(tokio::task::JoinHandle<()>);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.abort();
    }
}

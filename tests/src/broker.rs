//! Real MQTT brokers for the publisher's and the station logger's tests,
//! started by the tests themselves on a free loopback port, and a
//! subscriber that records what it receives.
//!
//! Two kinds: `rumqttd` (always; the test binary re-runs itself as the
//! broker process, see [`rumqttd_child_main`], so a test can kill and
//! restart it) and Debian's `mosquitto` (when installed; mandatory when
//! `YOSEMITECH_REQUIRE_MOSQUITTO=1`). A test binary that starts a broker
//! defines the ignored test [`CHILD_TEST_NAME`] calling
//! [`rumqttd_child_main`].

use std::net::{Ipv4Addr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::mqttbytes::v5::Packet;
use rumqttc::v5::{Client, Event, MqttOptions};
use yosemitech_mqtt::{CredentialsSource, MeasuredValue, MqttConfig, PublisherTuning, ReadingMessage, SCHEMA_VERSION};

/// The environment variable that makes the mosquitto runs mandatory.
pub const REQUIRE_MOSQUITTO: &str = "YOSEMITECH_REQUIRE_MOSQUITTO";
/// Set in the re-run test binary: the port the rumqttd child listens on.
const CHILD_PORT_VAR: &str = "YOSEMITECH_TEST_RUMQTTD_PORT";
/// Set in the re-run test binary: `user:password` the rumqttd child requires.
const CHILD_AUTH_VAR: &str = "YOSEMITECH_TEST_RUMQTTD_AUTH";
/// The name of the ignored test each broker test binary defines to run
/// [`rumqttd_child_main`].
pub const CHILD_TEST_NAME: &str = "rumqttd_child_process";

/// Generous bound for anything the tests wait for (a loaded 2-core machine).
pub const DEADLINE: Duration = Duration::from_secs(90);

/// Which broker a test runs against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BrokerKind {
    /// rumqttd, in a child process (this test binary re-run).
    Rumqttd,
    /// Debian's mosquitto, when installed.
    Mosquitto,
}

/// The mosquitto binary, if installed.
pub fn mosquitto_binary() -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain([PathBuf::from("/usr/sbin"), PathBuf::from("/usr/local/sbin")])
        .map(|dir| dir.join("mosquitto"))
        .find(|candidate| candidate.is_file())
}

/// Whether the tests should run against `kind` here. Panics (fails the
/// test) when mosquitto is required and missing.
pub fn available(kind: BrokerKind) -> bool {
    match kind {
        BrokerKind::Rumqttd => true,
        BrokerKind::Mosquitto => {
            let required = std::env::var(REQUIRE_MOSQUITTO).is_ok_and(|value| value == "1");
            let found = mosquitto_binary().is_some();
            assert!(
                found || !required,
                "{REQUIRE_MOSQUITTO}=1 but no mosquitto binary in PATH or /usr/sbin: install it (apt-get install mosquitto)"
            );
            if !found {
                eprintln!("mosquitto is not installed: this run covers rumqttd only");
            }
            found
        }
    }
}

/// The rumqttd broker process: called by the ignored test [`CHILD_TEST_NAME`]
/// when the test binary is re-run by [`Broker::start`]; returns at once
/// otherwise.
pub fn rumqttd_child_main() {
    let Ok(port) = std::env::var(CHILD_PORT_VAR) else {
        return;
    };
    let auth = std::env::var(CHILD_AUTH_VAR).ok().map(|pair| {
        let (user, password) = pair.split_once(':').unwrap();
        serde_json::json!({ user: password })
    });
    let config = serde_json::json!({
        "id": 0,
        "router": {
            "max_connections": 64,
            "max_outgoing_packet_count": 1000,
            "max_segment_size": 104857600,
            "max_segment_count": 10,
        },
        "v5": {
            "1": {
                "name": "v5-1",
                "listen": format!("127.0.0.1:{port}"),
                "next_connection_delay_ms": 1,
                "connections": {
                    "connection_timeout_ms": 60000,
                    "max_payload_size": 262144,
                    "max_inflight_count": 100,
                    "auth": auth,
                    "dynamic_filters": true,
                },
            },
        },
    });
    let config: rumqttd::Config = serde_json::from_value(config).unwrap();
    let mut broker = rumqttd::Broker::new(config);
    broker.start().unwrap();
}

/// A broker process on a loopback port that a test can stop and restart.
pub struct Broker {
    /// Which broker.
    pub kind: BrokerKind,
    /// Its plain-TCP loopback port.
    pub port: u16,
    dir: PathBuf,
    auth: Option<(String, String)>,
    /// A second, TLS listener (mosquitto only): its port.
    pub tls_port: Option<u16>,
    tls: Option<(String, String)>,
    /// mosquitto's access control list, if any ([`Broker::set_acl`]).
    acl: Option<String>,
    /// More lines of mosquitto's configuration ([`Broker::set_extra_config`]).
    extra_config: String,
    process: Arc<Mutex<Process>>,
}

/// The broker process, or while it is stopped a listener holding its port,
/// so that no other test's broker can take the port in the meantime (the
/// restarted broker and the clients would otherwise meet a stranger).
enum Process {
    Running(Child),
    Stopped(Option<TcpListener>),
}

/// Stops a broker from another thread (a subscriber hook).
#[derive(Clone)]
pub struct BrokerKiller {
    kind: BrokerKind,
    port: u16,
    process: Arc<Mutex<Process>>,
}

impl BrokerKiller {
    /// Stops the broker process as [`Broker::stop`] does, waits for it to
    /// be gone, and holds its port until [`Broker::restart`].
    pub fn kill(&self) {
        let mut process = self.process.lock().unwrap();
        if let Process::Running(child) = &mut *process {
            match self.kind {
                // mosquitto saves its persistence file on SIGTERM: queued
                // messages and persistent sessions survive the restart.
                BrokerKind::Mosquitto => {
                    let pid = nix::unistd::Pid::from_raw(i32::try_from(child.id()).unwrap());
                    let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM);
                    let started = Instant::now();
                    while child.try_wait().unwrap().is_none() {
                        if started.elapsed() > DEADLINE {
                            let _ = child.kill();
                        }
                        std::thread::sleep(Duration::from_millis(10));
                    }
                }
                // rumqttd keeps nothing across a restart; SIGKILL it is.
                BrokerKind::Rumqttd => {
                    let _ = child.kill();
                    let _ = child.wait();
                }
            }
            let started = Instant::now();
            let reservation = loop {
                match TcpListener::bind((Ipv4Addr::LOCALHOST, self.port)) {
                    Ok(listener) => break Some(listener),
                    Err(_) if started.elapsed() < Duration::from_secs(5) => {
                        std::thread::sleep(Duration::from_millis(20));
                    }
                    Err(_) => break None,
                }
            };
            *process = Process::Stopped(reservation);
        }
    }
}

/// A loopback port free now and never handed out before in this process
/// (a stopped broker's port stays reserved for its restart).
pub fn free_port() -> u16 {
    static HANDED_OUT: Mutex<Vec<u16>> = Mutex::new(Vec::new());
    let mut handed_out = HANDED_OUT.lock().unwrap();
    loop {
        let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
        let port = listener.local_addr().unwrap().port();
        if !handed_out.contains(&port) {
            handed_out.push(port);
            return port;
        }
    }
}

impl Broker {
    /// Starts a broker of `kind`, requiring `auth` (user, password) if given.
    pub fn start(kind: BrokerKind, auth: Option<(&str, &str)>) -> Broker {
        Self::start_with_tls(kind, auth, None)
    }

    /// [`Broker::start`], with a second listener on [`Broker::tls_port`]
    /// serving TLS with `(certificate chain PEM, private key PEM)`
    /// (mosquitto only).
    pub fn start_with_tls(kind: BrokerKind, auth: Option<(&str, &str)>, tls: Option<(&str, &str)>) -> Broker {
        assert!(tls.is_none() || kind == BrokerKind::Mosquitto, "TLS listeners are mosquitto's here");
        let mut broker = Broker {
            kind,
            port: free_port(),
            dir: crate::scratch_dir("broker"),
            auth: auth.map(|(user, password)| (user.to_owned(), password.to_owned())),
            tls_port: tls.map(|_| free_port()),
            tls: tls.map(|(chain, key)| (chain.to_owned(), key.to_owned())),
            acl: None,
            extra_config: String::new(),
            process: Arc::new(Mutex::new(Process::Stopped(None))),
        };
        if kind == BrokerKind::Mosquitto {
            broker.write_mosquitto_config();
        }
        broker.restart();
        broker
    }

    /// Gives mosquitto an access control list (`None`: none, everything
    /// allowed), in force from the next [`Broker::restart`]. Its lines
    /// before any `user` line are the anonymous clients': `topic read #`
    /// lets them subscribe to everything and publish nothing.
    pub fn set_acl(&mut self, acl: Option<&str>) {
        assert_eq!(self.kind, BrokerKind::Mosquitto, "access control lists are mosquitto's here");
        self.acl = acl.map(str::to_owned);
        self.write_mosquitto_config();
    }

    /// Adds `lines` to mosquitto's configuration (`max_qos 0`), in force
    /// from the next [`Broker::restart`].
    pub fn set_extra_config(&mut self, lines: &str) {
        assert_eq!(self.kind, BrokerKind::Mosquitto, "configuration files are mosquitto's here");
        self.extra_config = lines.to_owned();
        self.write_mosquitto_config();
    }

    fn write_mosquitto_config(&self) {
        let mut config = format!(
            "per_listener_settings false\npersistence true\npersistence_location {}/\nautosave_interval 0\n\
             max_inflight_messages 20\nlog_dest stderr\nlog_type error\nlog_type warning\n\
             max_queued_messages 10000\nuser root\nlistener {} 127.0.0.1\n",
            self.dir.display(),
            self.port
        );
        if let (Some((chain, key)), Some(port)) = (&self.tls, self.tls_port) {
            let (chain_path, key_path) = (self.dir.join("server.pem"), self.dir.join("server.key"));
            std::fs::write(&chain_path, chain).unwrap();
            std::fs::write(&key_path, key).unwrap();
            config.push_str(&format!(
                "listener {port} 127.0.0.1\ncertfile {}\nkeyfile {}\n",
                chain_path.display(),
                key_path.display()
            ));
        }
        match &self.auth {
            None => config.push_str("allow_anonymous true\n"),
            Some((user, password)) => {
                let password_file = self.dir.join("passwd");
                let status = Command::new("mosquitto_passwd")
                    .args(["-b", "-c"])
                    .arg(&password_file)
                    .args([user, password])
                    .status()
                    .expect("mosquitto_passwd (Debian package mosquitto) is needed with mosquitto");
                assert!(status.success(), "mosquitto_passwd failed");
                config.push_str(&format!("allow_anonymous false\npassword_file {}\n", password_file.display()));
            }
        }
        config.push_str(&self.extra_config);
        if let Some(acl) = &self.acl {
            let acl_file = self.dir.join("acl");
            std::fs::write(&acl_file, acl).unwrap();
            config.push_str(&format!("acl_file {}\n", acl_file.display()));
        }
        std::fs::write(self.dir.join("mosquitto.conf"), config).unwrap();
    }

    /// Starts the broker process again on the same port and waits until it
    /// accepts connections.
    pub fn restart(&mut self) {
        let mut process = self.process.lock().unwrap();
        let Process::Stopped(reservation) = &mut *process else {
            panic!("broker already running");
        };
        drop(reservation.take());
        let mut command = match self.kind {
            BrokerKind::Rumqttd => {
                let mut command = Command::new(std::env::current_exe().unwrap());
                command
                    .args(["--ignored", "--exact", CHILD_TEST_NAME, "--nocapture"])
                    .env(CHILD_PORT_VAR, self.port.to_string());
                match &self.auth {
                    Some((user, password)) => command.env(CHILD_AUTH_VAR, format!("{user}:{password}")),
                    None => command.env_remove(CHILD_AUTH_VAR),
                };
                command
            }
            BrokerKind::Mosquitto => {
                let mut command = Command::new(mosquitto_binary().unwrap());
                command.arg("-c").arg(self.dir.join("mosquitto.conf"));
                command
            }
        };
        command
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::from(std::fs::File::create(self.dir.join("broker.log")).unwrap()));
        let mut child = command.spawn().unwrap();
        let started = Instant::now();
        while TcpStream::connect((Ipv4Addr::LOCALHOST, self.port)).is_err() {
            if let Some(status) = child.try_wait().unwrap() {
                panic!(
                    "{:?} exited with {status} before listening: {}",
                    self.kind,
                    std::fs::read_to_string(self.dir.join("broker.log")).unwrap_or_default()
                );
            }
            assert!(started.elapsed() < DEADLINE, "{:?} never listened on {}", self.kind, self.port);
            std::thread::sleep(Duration::from_millis(50));
        }
        *process = Process::Running(child);
    }

    /// Stops the broker process and waits for it to be gone: mosquitto with
    /// SIGTERM (it saves its persistence file), rumqttd with SIGKILL.
    pub fn stop(&mut self) {
        self.killer().kill();
    }

    /// A handle that kills the broker from another thread.
    pub fn killer(&self) -> BrokerKiller {
        BrokerKiller { kind: self.kind, port: self.port, process: Arc::clone(&self.process) }
    }

    /// A publisher configuration for this broker, with short backoffs.
    pub fn config(&self, client_id: &str, max_in_flight: u16) -> MqttConfig {
        MqttConfig {
            host: "127.0.0.1".into(),
            port: Some(self.port),
            client_id: client_id.into(),
            keep_alive_secs: 5,
            topic_prefix: yosemitech_mqtt::topic::DEFAULT_TOPIC_PREFIX.into(),
            tls: None,
            credentials: CredentialsSource::None,
            require_subscriber: false,
            publisher: PublisherTuning {
                max_in_flight,
                poll_interval_ms: 50,
                reconnect_min_ms: 100,
                reconnect_max_ms: 1000,
            },
            home_assistant: None,
        }
    }

    /// The broker's own directory (configuration, persistence), for the test's files too.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        self.stop();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// One message as the subscriber got it.
#[derive(Debug, Clone)]
pub struct Received {
    /// The topic it was published to.
    pub topic: String,
    /// Its payload, as received.
    pub payload: Vec<u8>,
    /// The broker's DUP flag: a redelivery of the broker's own (after a
    /// restart with the subscriber's persistent session), not a publisher's
    /// resend.
    pub redelivered: bool,
}

impl Received {
    /// The payload as a reading message; panics when it is not one.
    pub fn message(&self) -> ReadingMessage {
        ReadingMessage::from_payload(&self.payload).unwrap()
    }
}

/// A QoS 1 subscriber with a persistent session on its own thread that
/// reconnects and resubscribes after a broker restart and records every
/// PUBLISH it receives. (A broker that persists sessions, mosquitto here,
/// keeps what arrives for it while it reconnects.)
pub struct Subscriber {
    received: Arc<Mutex<Vec<Received>>>,
    subscriptions: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    client: Client,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Subscriber {
    /// Connects to `broker`, subscribes to `filter`, and waits for the SUBACK.
    pub fn start(broker: &Broker, filter: &str) -> Subscriber {
        Self::start_with_hook(broker, filter, usize::MAX, || {})
    }

    /// [`Subscriber::start`], and runs `hook` on the subscriber's thread
    /// right after the `at`-th message arrives (before it takes the next),
    /// to act mid-stream: kill the broker, stop a publisher.
    pub fn start_with_hook(
        broker: &Broker,
        filter: &str,
        at: usize,
        hook: impl FnOnce() + Send + 'static,
    ) -> Subscriber {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let id = format!("test-subscriber-{}-{}", std::process::id(), COUNTER.fetch_add(1, Ordering::Relaxed));
        let mut options = MqttOptions::new(id, "127.0.0.1", broker.port);
        // A session the broker keeps for an hour: what arrives while the
        // subscriber reconnects waits for it.
        options
            .set_keep_alive(Duration::from_secs(5))
            .set_clean_start(false)
            .set_session_expiry_interval(Some(3600))
            .set_max_packet_size(Some(256 * 1024));
        if let Some((user, password)) = &broker.auth {
            options.set_credentials(user, password);
        }
        let (client, mut connection) = Client::new(options, 64);
        let received = Arc::new(Mutex::new(Vec::new()));
        let subscriptions = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (client, received, subscriptions, stop) =
                (client.clone(), received.clone(), subscriptions.clone(), stop.clone());
            let filter = filter.to_owned();
            let mut hook = Some(hook);
            std::thread::spawn(move || {
                for event in connection.iter() {
                    if stop.load(Ordering::Relaxed) {
                        break;
                    }
                    match event {
                        // A clean session each time: subscribe on every connection.
                        Ok(Event::Incoming(Packet::ConnAck(_))) => {
                            client.try_subscribe(&filter, QoS::AtLeastOnce).unwrap();
                        }
                        Ok(Event::Incoming(Packet::SubAck(_))) => {
                            subscriptions.fetch_add(1, Ordering::SeqCst);
                        }
                        Ok(Event::Incoming(Packet::Publish(publish))) => {
                            let count = {
                                let mut received = received.lock().unwrap();
                                received.push(Received {
                                    topic: String::from_utf8_lossy(&publish.topic).into_owned(),
                                    payload: publish.payload.to_vec(),
                                    redelivered: publish.dup,
                                });
                                received.len()
                            };
                            if count == at
                                && let Some(hook) = hook.take()
                            {
                                hook();
                            }
                        }
                        Ok(_) => {}
                        Err(_) => std::thread::sleep(Duration::from_millis(100)),
                    }
                }
            })
        };
        let subscriber = Subscriber { received, subscriptions, stop, client, thread: Some(thread) };
        subscriber.wait_for_subscriptions(1);
        subscriber
    }

    /// Waits until the subscriber has been acknowledged `count` subscriptions
    /// in all (one per connection).
    pub fn wait_for_subscriptions(&self, count: u64) {
        assert!(
            wait_until(|| self.subscriptions.load(Ordering::SeqCst) >= count),
            "subscriber never got SUBACK number {count}"
        );
    }

    /// SUBACKs received so far (one per connection).
    pub fn subscriptions(&self) -> u64 {
        self.subscriptions.load(Ordering::SeqCst)
    }

    /// Every message received so far, in arrival order.
    pub fn received(&self) -> Vec<Received> {
        self.received.lock().unwrap().clone()
    }

    /// How many messages were received so far.
    pub fn count(&self) -> usize {
        self.received.lock().unwrap().len()
    }
}

impl Drop for Subscriber {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        let _ = self.client.try_disconnect();
        // The thread ends at its next event (the DISCONNECT, or a ping); it
        // is not joined so that a dead broker cannot hang a test.
        drop(self.thread.take());
    }
}

/// Polls `condition` every 20 ms until it holds (true) or [`DEADLINE`] passes (false).
pub fn wait_until(mut condition: impl FnMut() -> bool) -> bool {
    let started = Instant::now();
    while !condition() {
        if started.elapsed() > DEADLINE {
            return false;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    true
}

/// Reading number `index` of a station with a few probes, some of whose
/// labels need escaping in a topic.
pub fn reading(index: usize) -> ReadingMessage {
    const PROBES: [&str; 3] = ["left bank", "inlet/deep #2", "outlet"];
    let probe = PROBES[index % PROBES.len()];
    ReadingMessage {
        schema: SCHEMA_VERSION,
        reading_id: 0,
        timestamp_ms: 1_795_900_500_000 + i64::try_from(index).unwrap() * 1000,
        station: "river 01".into(),
        probe: probe.into(),
        sensor: "probe-model".into(),
        address: u8::try_from(1 + index % PROBES.len()).unwrap(),
        serial_number: Some(format!("SN{:04}", index % PROBES.len())),
        firmware: Some("1.0".into()),
        values: vec![
            MeasuredValue::new("value", index as f64 / 8.0, Some("unit".into())),
            MeasuredValue::new("temperature", 15.0 + (index % 10) as f64, Some("°C".into())),
        ],
        retries: u32::try_from(index % 3).unwrap(),
        error: index.is_multiple_of(17).then(|| "probe did not answer".to_owned()),
        bus: Some("river".into()),
        calibration_id: index.is_multiple_of(2).then_some(7),
    }
}

/// The ids of `received` in arrival order, and the first occurrence of each
/// (what a consumer deduplicating by reading id keeps).
pub fn ids_and_first_occurrences(received: &[Received]) -> (Vec<i64>, Vec<i64>) {
    let ids: Vec<i64> = received.iter().map(|r| r.message().reading_id).collect();
    let mut seen = std::collections::HashSet::new();
    let first = ids.iter().copied().filter(|id| seen.insert(*id)).collect();
    (ids, first)
}

/// A credentials file `user:password` with mode 0600 in `dir`.
pub fn credentials_file(dir: &Path, name: &str, user: &str, password: &str) -> CredentialsSource {
    use std::os::unix::fs::PermissionsExt;
    let path = dir.join(format!("{name}.credentials"));
    std::fs::write(&path, format!("{user}:{password}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
    CredentialsSource::File(path)
}

/// Everything logged through `tracing` by any thread of this test binary
/// from the first call on, at every level.
pub struct CapturedLogs(Arc<Mutex<Vec<u8>>>);

impl CapturedLogs {
    /// What was logged so far, as text.
    pub fn contents(&self) -> String {
        String::from_utf8_lossy(&self.0.lock().unwrap()).into_owned()
    }
}

struct LogWriter(Arc<Mutex<Vec<u8>>>);

impl std::io::Write for LogWriter {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(bytes);
        Ok(bytes.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Starts capturing (once per test binary) and returns the capture.
pub fn capture_logs() -> CapturedLogs {
    static BUFFER: std::sync::OnceLock<Arc<Mutex<Vec<u8>>>> = std::sync::OnceLock::new();
    let buffer = BUFFER.get_or_init(|| {
        let buffer = Arc::new(Mutex::new(Vec::new()));
        let writer = buffer.clone();
        tracing_subscriber::fmt()
            .with_max_level(tracing::Level::TRACE)
            .with_ansi(false)
            .with_writer(move || LogWriter(writer.clone()))
            .init();
        buffer
    });
    CapturedLogs(buffer.clone())
}

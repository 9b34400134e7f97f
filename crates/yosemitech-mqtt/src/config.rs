//! The `[mqtt]` section of a station's configuration, and where credentials come from.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;

use crate::home_assistant::HomeAssistantConfig;
use crate::secret::Secret;
use crate::topic;

/// Environment variable holding the broker user name when
/// `credentials = "environment"`.
pub const USERNAME_VAR: &str = "YOSEMITECH_MQTT_USERNAME";
/// Environment variable holding the broker password when
/// `credentials = "environment"`.
pub const PASSWORD_VAR: &str = "YOSEMITECH_MQTT_PASSWORD";

/// The broker connection and publishing settings: the `[mqtt]` section of
/// `station.toml`.
///
/// ```
/// let config: yosemitech_mqtt::MqttConfig = toml::from_str(r#"
///     host = "broker.example.org"
///     client_id = "station-river-01"
///     credentials = { file = "/etc/yosemitech/mqtt.credentials" }
///     [tls]
///     ca_file = "/etc/yosemitech/broker-ca.pem"
/// "#).unwrap();
/// assert_eq!(config.port(), 8883); // TLS default port
/// ```
///
/// Unknown keys are rejected (a misspelt `keep_alive_sec` is an error, not a
/// silent default). The config holds no secret itself: credentials are
/// loaded from the environment or an owner-only file by
/// [`CredentialsSource::load`] when the publisher starts, so printing this
/// struct with `{:?}` shows where they come from, never what they are.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MqttConfig {
    /// Broker host name or IP address.
    pub host: String,
    /// Broker TCP port; when absent 8883 with TLS, 1883 without.
    #[serde(default)]
    pub port: Option<u16>,
    /// MQTT client id. It must be unique on the broker: a broker disconnects
    /// the older of two connections with the same id. One per station.
    pub client_id: String,
    /// Seconds between MQTT keep-alive pings when idle (MQTT keep-alive).
    #[serde(default = "default_keep_alive_secs")]
    pub keep_alive_secs: u16,
    /// First topic levels; see [`crate::topic`]. Default `yosemitech/v1`.
    #[serde(default = "default_topic_prefix")]
    pub topic_prefix: String,
    /// Present: connect with TLS (rustls). Absent: plain TCP.
    #[serde(default)]
    pub tls: Option<TlsConfig>,
    /// Where the user name and password come from. Default: none (anonymous).
    #[serde(default)]
    pub credentials: CredentialsSource,
    /// Count a reading delivered only when the broker had a subscriber for
    /// it. A broker acknowledges a reading that matches no subscription and
    /// drops it (MQTT 5 PUBACK reason 0x10, "no matching subscribers"): with
    /// this on, the reading stays in the outbox and is sent again after a
    /// pause, until a subscriber takes it. For readings that must reach a
    /// consumer, such as `yosemitech ingest`'s workers, whose shared
    /// subscriptions a restarted broker may not restore before stations
    /// publish. Off by default: where nobody subscribes to the readings,
    /// they would wait forever.
    #[serde(default)]
    pub require_subscriber: bool,
    /// How the publisher paces itself.
    #[serde(default)]
    pub publisher: PublisherTuning,
    /// Present: Home Assistant MQTT discovery (`[mqtt.home_assistant]`).
    #[serde(default)]
    pub home_assistant: Option<HomeAssistantConfig>,
}

fn default_keep_alive_secs() -> u16 {
    30
}

fn default_topic_prefix() -> String {
    topic::DEFAULT_TOPIC_PREFIX.to_owned()
}

/// TLS settings (`[mqtt.tls]`; an empty table enables TLS with the
/// operating system's root certificates).
#[derive(Debug, Clone, PartialEq, Eq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlsConfig {
    /// PEM file of the certificate authorities to trust instead of the
    /// operating system's roots (a private CA, a self-signed broker).
    #[serde(default)]
    pub ca_file: Option<PathBuf>,
}

/// Where the broker user name and password come from.
///
/// In TOML: `credentials = "none"` (the default), `credentials =
/// "environment"` ([`USERNAME_VAR`] and [`PASSWORD_VAR`]), or `credentials =
/// { file = "/path" }`: a file holding one line `username:password` (split
/// at the first `:`, a trailing newline ignored) that only its owner may
/// read or write (mode `0600` or `0400`; anything with group or other bits
/// is refused).
#[derive(Debug, Clone, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum CredentialsSource {
    /// Connect without user name and password.
    #[default]
    None,
    /// [`USERNAME_VAR`] and [`PASSWORD_VAR`] from the process environment.
    Environment,
    /// An owner-only file holding `username:password`.
    File(PathBuf),
}

/// A broker user name and its password.
///
/// `Debug` shows the user name and `[redacted]` for the password.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Credentials {
    /// The MQTT user name.
    pub username: String,
    /// The MQTT password.
    pub password: Secret,
}

/// Pacing of the publisher. Every field has a default.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PublisherTuning {
    /// Readings sent and not yet acknowledged at most (1 to 1000). A
    /// connection loss can deliver at most this many readings twice.
    pub max_in_flight: u16,
    /// How often the outbox is looked at when nobody calls
    /// [`crate::Publisher::wake`], in milliseconds.
    pub poll_interval_ms: u64,
    /// First wait before reconnecting after a failure, in milliseconds; it
    /// doubles after each failed attempt up to `reconnect_max_ms`.
    pub reconnect_min_ms: u64,
    /// Longest wait between reconnection attempts, in milliseconds.
    pub reconnect_max_ms: u64,
}

impl Default for PublisherTuning {
    fn default() -> Self {
        Self { max_in_flight: 16, poll_interval_ms: 1000, reconnect_min_ms: 500, reconnect_max_ms: 30_000 }
    }
}

impl PublisherTuning {
    /// [`Self::poll_interval_ms`] as a duration.
    pub fn poll_interval(&self) -> Duration {
        Duration::from_millis(self.poll_interval_ms)
    }
}

/// A problem with the `[mqtt]` settings. Its messages name files and
/// variables, never a credential's content.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The host is empty.
    #[error("mqtt.host is empty")]
    EmptyHost,
    /// The client id is empty.
    #[error("mqtt.client_id is empty: give each station its own id")]
    EmptyClientId,
    /// The topic prefix cannot be used as the first levels of a topic.
    #[error("mqtt.topic_prefix {prefix:?}: {reason}")]
    TopicPrefix {
        /// The prefix as configured.
        prefix: String,
        /// Why it is refused.
        reason: &'static str,
    },
    /// The Home Assistant discovery prefix cannot start a topic.
    #[error("mqtt.home_assistant.prefix {prefix:?}: {reason}")]
    DiscoveryPrefix {
        /// The prefix as configured.
        prefix: String,
        /// Why it is refused.
        reason: &'static str,
    },
    /// A publisher tuning value is out of range.
    #[error("mqtt.publisher.{field}: {reason}")]
    Tuning {
        /// The offending key.
        field: &'static str,
        /// The accepted range.
        reason: &'static str,
    },
    /// The credentials could not be loaded.
    #[error(transparent)]
    Credentials(#[from] CredentialsError),
    /// The TLS CA file could not be used.
    #[error("mqtt.tls.ca_file {}: {reason}", path.display())]
    CaFile {
        /// The CA file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
}

/// Why credentials could not be loaded. No variant carries any part of the
/// file's or the variables' content.
#[derive(Debug, thiserror::Error)]
pub enum CredentialsError {
    /// An environment variable is unset or not UTF-8.
    #[error("mqtt credentials = \"environment\" but {0} is not set (or not UTF-8)")]
    MissingVariable(&'static str),
    /// The credentials file is readable or writable by group or others.
    #[error(
        "credentials file {} is accessible to group or others (mode {mode:04o}); \
         run `chmod 600 {}` so that only its owner can read it",
        path.display(),
        path.display()
    )]
    FileNotOwnerOnly {
        /// The file.
        path: PathBuf,
        /// Its permission bits.
        mode: u32,
    },
    /// The credentials path is not a regular file.
    #[error("credentials file {} is not a regular file", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
    },
    /// The file could not be read.
    #[error("cannot read credentials file {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error (it holds no file content).
        source: std::io::Error,
    },
    /// The file is not one line `username:password`.
    #[error(
        "credentials file {} must hold one line `username:password` (UTF-8, non-empty user name)",
        path.display()
    )]
    Malformed {
        /// The file.
        path: PathBuf,
    },
}

impl MqttConfig {
    /// The broker port: [`Self::port`], or 8883 with TLS and 1883 without.
    pub fn port(&self) -> u16 {
        self.port.unwrap_or(if self.tls.is_some() { 8883 } else { 1883 })
    }

    /// Checks everything that can be checked without a broker: names, the
    /// topic prefix, tuning ranges, the credentials (loaded from their
    /// source, then dropped) and the CA file (parsed). For `--check`; the
    /// publisher runs the same checks when it starts.
    pub fn check(&self) -> Result<(), ConfigError> {
        self.check_static()?;
        self.credentials.load()?;
        if let Some(tls) = &self.tls {
            crate::tls::client_config(tls)?;
        }
        Ok(())
    }

    /// The checks that need neither the environment nor a file.
    pub(crate) fn check_static(&self) -> Result<(), ConfigError> {
        if self.host.trim().is_empty() {
            return Err(ConfigError::EmptyHost);
        }
        if self.client_id.trim().is_empty() {
            return Err(ConfigError::EmptyClientId);
        }
        topic::check_prefix(&self.topic_prefix)
            .map_err(|reason| ConfigError::TopicPrefix { prefix: self.topic_prefix.clone(), reason })?;
        if let Some(home_assistant) = &self.home_assistant {
            topic::check_prefix(&home_assistant.prefix)
                .map_err(|reason| ConfigError::DiscoveryPrefix { prefix: home_assistant.prefix.clone(), reason })?;
        }
        let tuning = &self.publisher;
        if !(1..=1000).contains(&tuning.max_in_flight) {
            return Err(ConfigError::Tuning { field: "max_in_flight", reason: "must be 1 to 1000" });
        }
        if tuning.poll_interval_ms == 0 {
            return Err(ConfigError::Tuning { field: "poll_interval_ms", reason: "must be at least 1" });
        }
        if tuning.reconnect_min_ms == 0 || tuning.reconnect_max_ms < tuning.reconnect_min_ms {
            return Err(ConfigError::Tuning {
                field: "reconnect_min_ms",
                reason: "must be at least 1 and at most reconnect_max_ms",
            });
        }
        Ok(())
    }
}

impl CredentialsSource {
    /// Loads the credentials from the process environment or the file.
    /// `Ok(None)` for [`CredentialsSource::None`].
    pub fn load(&self) -> Result<Option<Credentials>, CredentialsError> {
        self.load_with(|name| std::env::var(name).ok())
    }

    /// [`Self::load`] with the environment given as a lookup function
    /// (tests, or a caller with its own environment).
    pub fn load_with(&self, env: impl Fn(&str) -> Option<String>) -> Result<Option<Credentials>, CredentialsError> {
        match self {
            Self::None => Ok(None),
            Self::Environment => {
                let username = env(USERNAME_VAR)
                    .filter(|name| !name.is_empty())
                    .ok_or(CredentialsError::MissingVariable(USERNAME_VAR))?;
                let password =
                    env(PASSWORD_VAR).map(Secret::new).ok_or(CredentialsError::MissingVariable(PASSWORD_VAR))?;
                Ok(Some(Credentials { username, password }))
            }
            Self::File(path) => read_credentials_file(path).map(Some),
        }
    }
}

fn read_credentials_file(path: &Path) -> Result<Credentials, CredentialsError> {
    let read_error = |source| CredentialsError::Read { path: path.to_owned(), source };
    let metadata = std::fs::metadata(path).map_err(read_error)?;
    if !metadata.is_file() {
        return Err(CredentialsError::NotAFile { path: path.to_owned() });
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = metadata.permissions().mode() & 0o7777;
        if mode & 0o077 != 0 {
            return Err(CredentialsError::FileNotOwnerOnly { path: path.to_owned(), mode });
        }
    }
    let bytes = std::fs::read(path).map_err(read_error)?;
    let malformed = || CredentialsError::Malformed { path: path.to_owned() };
    // The content goes into no error: a wrong file must not leak into a log.
    let text = String::from_utf8(bytes).map_err(|_| malformed())?;
    let line = text.strip_suffix('\n').map(|line| line.strip_suffix('\r').unwrap_or(line)).unwrap_or(&text);
    if line.contains('\n') {
        return Err(malformed());
    }
    let (username, password) = line.split_once(':').ok_or_else(malformed)?;
    if username.is_empty() {
        return Err(malformed());
    }
    Ok(Credentials { username: username.to_owned(), password: Secret::new(password) })
}

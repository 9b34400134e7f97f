//! Store-and-forward publishing of station readings to an existing MQTT
//! broker.
//!
//! A station commits every reading to its store first; the store implements
//! [`Outbox`]; a [`Publisher`] drains it to the broker in order with QoS 1
//! and marks a reading published only after the broker's PUBACK. The topic
//! layout is in [`topic`], the JSON payload in [`message`], the `[mqtt]`
//! configuration in [`MqttConfig`]; [`home_assistant`] announces a station's
//! probes to Home Assistant (`[mqtt.home_assistant]`); `docs/mqtt.md` tells
//! how stations, brokers and consumers fit together.
//!
//! ```no_run
//! use yosemitech_mqtt::{MemoryOutbox, MqttConfig, Publisher, ReadingMessage, SCHEMA_VERSION};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let config: MqttConfig = toml::from_str(r#"
//!     host = "127.0.0.1"
//!     client_id = "station-river-01"
//!     credentials = "environment"   # YOSEMITECH_MQTT_USERNAME / _PASSWORD
//! "#)?;
//! let outbox = MemoryOutbox::new(); // a station uses its SQLite store
//! let publisher = Publisher::start(&config, outbox.clone())?;
//! outbox.push(ReadingMessage {
//!     schema: SCHEMA_VERSION,
//!     reading_id: 0, // MemoryOutbox assigns ids
//!     timestamp_ms: 1_795_900_500_000,
//!     station: "river-01".into(),
//!     probe: "left bank".into(),
//!     sensor: "<spec sensor name>".into(),
//!     address: 1,
//!     serial_number: None,
//!     firmware: None,
//!     values: vec![],
//!     retries: 0,
//!     error: None,
//!     bus: None,
//!     calibration_id: None,
//! });
//! publisher.wake();
//! let report = publisher.shutdown(std::time::Duration::from_secs(10));
//! println!("published up to {:?}", report.published_up_to);
//! # Ok(())
//! # }
//! ```
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod config;
pub mod home_assistant;
pub mod message;
mod outbox;
mod publisher;
mod secret;
mod tls;
pub mod topic;

pub use config::{
    ConfigError, Credentials, CredentialsError, CredentialsSource, MqttConfig, PASSWORD_VAR, PublisherTuning,
    TlsConfig, USERNAME_VAR,
};
pub use message::{MeasuredValue, PayloadError, ReadingMessage, SCHEMA_VERSION};
pub use outbox::{MemoryOutbox, Outbox};
pub use publisher::{Publisher, PublisherStatus, ShutdownReport, StartError};
pub use secret::Secret;
pub use tls::client_config as tls_client_config;

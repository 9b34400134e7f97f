//! A station logger for Yosemitech probes: several probes on several
//! RS-485 buses (or RTU-over-TCP gateways), each sampled on its own
//! schedule, every reading committed to a SQLite file before anything else
//! happens with it.
//!
//! * [`store`]: the SQLite store and its outbox (what each publisher has not yet delivered).
//! * [`config`]: the station file (`station.toml`), validated against the spec.
//! * [`derive`](mod@derive): the derived quantities of a sample, stored beside its values.
//! * [`plan`]: the fewest reads that cover the measurements chosen for a probe.
//! * [`logger`]: the scheduler, one thread and one master per bus.
//! * [`link`]: a bus's master and its requests through the spec interpreter.
//! * [`outbox`]: the store as the MQTT publisher's outbox.
//! * [`portal`]: the store as the Monitor My Watershed publisher's outbox.
//! * [`recovery`]: telling, at start, that the previous run did not stop cleanly.
//! * [`export`]: stored readings as CSV or JSON lines.
//! * [`time`]: UTC instants as the store keeps them and people write them.
//!
//! Nothing here names a sensor: probes, commands and fields come from the
//! loaded spec (`yosemitech_spec`).
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod amounts;
pub mod calibration;
pub mod config;
pub mod derive;
pub mod export;
pub mod link;
pub mod logger;
pub mod outbox;
pub mod plan;
pub mod portal;
pub mod preflight;
pub mod recovery;
pub mod store;
pub mod time;
pub mod units;

pub use calibration::{Calibration, StoredCalibration};
pub use store::{Datum, Measurement, Reading, Store, StoreError, StoredReading};

//! The readings of a fleet of stations in one PostgreSQL database.
//!
//! Stations publish each reading over MQTT (QoS 1, `yosemitech_mqtt`);
//! `yosemitech ingest` runs [`worker::run`]: it subscribes to every
//! station's reading topic and stores what arrives with [`Database`],
//! acknowledging each delivery to the broker only once its transaction is
//! committed. A reading's identity is `(station, reading_id)`, and storing
//! a reading already stored does nothing, so a delivery repeated (a
//! worker killed between commit and acknowledgement, a station resending
//! after a broker restart) is stored once, and a delivery acknowledged is
//! stored. Several workers share the load through an MQTT 5 shared
//! subscription; any of them may be killed at any moment.
//!
//! The schema ([`schema`]) is created and migrated by the workers
//! themselves, and described in `docs/postgres.md`.

#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod database;
pub mod schema;
pub mod worker;

pub use database::{Database, DatabaseError, Delivery, Stored, month_of, taken_at};
pub use worker::{IngestConfig, IngestError, Totals, run};

//! The store as the MQTT publisher's outbox (`yosemitech_mqtt::Outbox`).
//!
//! The publisher gets a connection of its own to the station's SQLite file
//! (WAL: it reads beside the logger's writer). A reading's message is
//! rebuilt from its row every time, so a resend is identical; ids are the
//! store's, increasing in commit order. Text values (enumeration names)
//! have no place in the payload's numeric values and are left out of it;
//! they stay in the store and in `export`. Derived quantities are
//! published marked so; one not computable for a sample has no value and
//! its error.

use yosemitech_mqtt::{MeasuredValue, Outbox, ReadingMessage, SCHEMA_VERSION};

use crate::store::{Datum, MQTT_PUBLISHER, Measurement, Reading, Store, StoreError, StoredReading};
use crate::time::{from_unix_ms, unix_ms};

/// A [`Store`] connection serving as the MQTT publisher's outbox: its
/// cursor is the store's [`MQTT_PUBLISHER`] one, which no other publisher
/// moves.
#[derive(Debug)]
pub struct StoreOutbox(pub Store);

impl StoreOutbox {
    /// The publisher's name in the store's outbox.
    pub const PUBLISHER: &'static str = MQTT_PUBLISHER;
}

/// The published message of a stored reading.
pub fn message(stored: &StoredReading) -> ReadingMessage {
    let r = &stored.reading;
    ReadingMessage {
        schema: SCHEMA_VERSION,
        reading_id: stored.id,
        timestamp_ms: unix_ms(r.timestamp),
        station: r.station.clone(),
        probe: r.probe.clone(),
        sensor: r.sensor.clone(),
        address: r.address,
        serial_number: r.serial_number.clone(),
        firmware: r.firmware.clone(),
        values: r
            .values
            .iter()
            .filter_map(|m| {
                let mut v = match &m.value {
                    Datum::Number(n) => MeasuredValue::new(m.name.clone(), *n, m.unit.clone()),
                    Datum::NotComputable(why) => MeasuredValue {
                        name: m.name.clone(),
                        value: None,
                        unit: m.unit.clone(),
                        derived: false,
                        error: Some(why.clone()),
                    },
                    Datum::Text(_) => return None,
                };
                v.derived = m.derived;
                Some(v)
            })
            .collect(),
        retries: r.retries,
        error: r.error.clone(),
        bus: Some(r.bus.clone()),
        calibration_id: stored.calibration_id,
    }
}

/// A published reading as the station stored it (for `export` of a
/// fleet's database): the inverse of [`message`], but for the text values
/// a message does not carry. A value published as `null` without an error
/// (the probe's NaN) is NaN again; a bus unknown to the message is empty.
pub fn stored_of(message: &ReadingMessage) -> StoredReading {
    StoredReading {
        id: message.reading_id,
        reading: Reading {
            timestamp: from_unix_ms(message.timestamp_ms),
            station: message.station.clone(),
            bus: message.bus.clone().unwrap_or_default(),
            probe: message.probe.clone(),
            sensor: message.sensor.clone(),
            address: message.address,
            serial_number: message.serial_number.clone(),
            firmware: message.firmware.clone(),
            values: message
                .values
                .iter()
                .map(|v| Measurement {
                    name: v.name.clone(),
                    value: match (&v.value, &v.error) {
                        (Some(n), _) => Datum::Number(*n),
                        (None, Some(why)) => Datum::NotComputable(why.clone()),
                        (None, None) => Datum::Number(f64::NAN),
                    },
                    unit: v.unit.clone(),
                    derived: v.derived,
                })
                .collect(),
            retries: message.retries,
            error: message.error.clone(),
        },
        calibration_id: message.calibration_id,
    }
}

impl Outbox for StoreOutbox {
    type Error = StoreError;

    fn unpublished(&mut self, after: Option<i64>, limit: usize) -> Result<Vec<ReadingMessage>, StoreError> {
        Ok(self.0.unpublished_after(Self::PUBLISHER, after.unwrap_or(0), limit)?.iter().map(message).collect())
    }

    fn mark_published(&mut self, up_to_id: i64) -> Result<(), StoreError> {
        self.0.mark_published(Self::PUBLISHER, up_to_id)
    }
}

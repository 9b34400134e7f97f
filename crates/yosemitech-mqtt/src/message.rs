//! The JSON payload of a reading (schema version 1).
//!
//! ```json
//! {
//!   "schema": 1,
//!   "reading_id": 1042,
//!   "timestamp_ms": 1795900500000,
//!   "station": "river-01",
//!   "probe": "left bank",
//!   "sensor": "<spec sensor name>",
//!   "address": 1,
//!   "serial_number": "0A1B2C3D4E5F6071",
//!   "firmware": "1.2",
//!   "values": [
//!     { "name": "<measurement>", "value": 7.02, "unit": "<unit>", "derived": false, "error": null },
//!     { "name": "temperature", "value": 18.4, "unit": "°C", "derived": false, "error": null },
//!     { "name": "<derived quantity>", "value": 8.9, "unit": "mg/L", "derived": true, "error": null }
//!   ],
//!   "retries": 0,
//!   "error": null,
//!   "bus": "river",
//!   "calibration_id": 7
//! }
//! ```
//!
//! Every key is always present (`null` when unknown), except in payloads
//! of stations that predate `bus` and `calibration_id` (read as `null`). `reading_id` is the
//! station's store id: unique per station, increasing in the order readings
//! were committed, and the same in every copy of a message, so a consumer
//! deduplicates by `(station, reading_id)`. A consumer should refuse a
//! `schema` it does not know; a new key that old consumers can ignore does
//! not change the version, a changed meaning does.

use serde::{Deserialize, Serialize};

/// The payload schema version this crate writes and reads.
pub const SCHEMA_VERSION: u32 = 1;

/// One reading of one probe, as published.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReadingMessage {
    /// Always [`SCHEMA_VERSION`] for messages built by this version.
    pub schema: u32,
    /// The station's store id of the reading: unique per station, increasing
    /// in commit order (the outbox order), identical in every copy.
    pub reading_id: i64,
    /// When the reading was taken, milliseconds since the Unix epoch (UTC).
    pub timestamp_ms: i64,
    /// The station's name (the `<station>` topic level, unescaped).
    pub station: String,
    /// The probe's label in the station (the `<probe>` topic level, unescaped).
    pub probe: String,
    /// The spec's sensor name.
    pub sensor: String,
    /// The probe's Modbus slave address.
    pub address: u8,
    /// The probe's serial number, if it was read.
    pub serial_number: Option<String>,
    /// The probe's firmware version, if it was read.
    pub firmware: Option<String>,
    /// The measured values, in the order the station reads them. Empty when
    /// the reading failed (`error` says why).
    pub values: Vec<MeasuredValue>,
    /// Retries the reading needed (0 when the first attempt succeeded).
    pub retries: u32,
    /// Why the reading failed or is incomplete; `None` for a good reading.
    pub error: Option<String>,
    /// The station's name of the bus the probe is on.
    #[serde(default)]
    pub bus: Option<String>,
    /// The station's id of the probe's calibration in force when the
    /// reading was taken (its store's calibration history), if one is recorded.
    #[serde(default)]
    pub calibration_id: Option<i64>,
}

/// One quantity of a reading: measured by the probe, or derived by the
/// station from measured values (`derived`; `derived` and `error` are
/// absent from payloads of stations that predate them, hence their
/// defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasuredValue {
    /// The measurement's name in the spec (e.g. `temperature`).
    pub name: String,
    /// The value; `None` (`null`) when the probe returned NaN or infinity,
    /// which JSON cannot carry.
    pub value: Option<f64>,
    /// The unit the spec states, if any.
    pub unit: Option<String>,
    /// A derived quantity of the spec, computed by the station from the
    /// measured values and its station inputs, not a value the probe sent.
    #[serde(default)]
    pub derived: bool,
    /// Why a derived quantity has no value for this reading (an input NaN
    /// or outside its range); `value` is then `None`.
    #[serde(default)]
    pub error: Option<String>,
}

impl MeasuredValue {
    /// A value, with a non-finite `value` stored as `None`.
    pub fn new(name: impl Into<String>, value: f64, unit: Option<String>) -> Self {
        Self { name: name.into(), value: value.is_finite().then_some(value), unit, derived: false, error: None }
    }
}

/// A payload that is not a reading this crate understands.
#[derive(Debug, thiserror::Error)]
pub enum PayloadError {
    /// Not JSON of the reading's shape.
    #[error("payload is not a reading message: {0}")]
    Json(#[from] serde_json::Error),
    /// A schema version this crate does not know.
    #[error("payload has schema version {found}, this reader knows {SCHEMA_VERSION}")]
    UnknownSchema {
        /// The version in the payload.
        found: u32,
    },
}

impl ReadingMessage {
    /// The payload bytes (compact JSON).
    pub fn to_payload(&self) -> Result<Vec<u8>, PayloadError> {
        Ok(serde_json::to_vec(self)?)
    }

    /// Parses a payload, refusing another schema version.
    pub fn from_payload(payload: &[u8]) -> Result<Self, PayloadError> {
        #[derive(Deserialize)]
        struct Version {
            schema: u32,
        }
        let Version { schema } = serde_json::from_slice(payload)?;
        if schema != SCHEMA_VERSION {
            return Err(PayloadError::UnknownSchema { found: schema });
        }
        Ok(serde_json::from_slice(payload)?)
    }

    /// The topic of this reading under `prefix` (see [`crate::topic`]).
    pub fn topic(&self, prefix: &str) -> String {
        crate::topic::reading_topic(prefix, &self.station, &self.probe)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> ReadingMessage {
        ReadingMessage {
            schema: SCHEMA_VERSION,
            reading_id: 7,
            timestamp_ms: 1_795_900_500_000,
            station: "river-01".into(),
            probe: "left".into(),
            sensor: "any".into(),
            address: 3,
            serial_number: Some("00FF".into()),
            firmware: None,
            values: vec![MeasuredValue::new("t", 18.25, Some("°C".into())), MeasuredValue::new("x", f64::NAN, None)],
            retries: 2,
            error: None,
            bus: Some("b".into()),
            calibration_id: Some(4),
        }
    }

    #[test]
    fn payload_round_trips_and_keeps_every_key() {
        let message = sample();
        let payload = message.to_payload().unwrap();
        assert_eq!(ReadingMessage::from_payload(&payload).unwrap(), message);
        let json: serde_json::Value = serde_json::from_slice(&payload).unwrap();
        for key in [
            "schema",
            "reading_id",
            "timestamp_ms",
            "station",
            "probe",
            "sensor",
            "address",
            "serial_number",
            "firmware",
            "values",
            "retries",
            "error",
            "bus",
            "calibration_id",
        ] {
            assert!(json.get(key).is_some(), "{key} missing from {json}");
        }
        assert_eq!(json["values"][1]["value"], serde_json::Value::Null);
    }

    #[test]
    fn derived_values_carry_their_mark_and_error_and_old_payloads_still_parse() {
        let mut message = sample();
        message.values.push(MeasuredValue { derived: true, ..MeasuredValue::new("d", 8.5, Some("mg/L".into())) });
        message.values.push(MeasuredValue {
            derived: true,
            error: Some("input out of range".into()),
            value: None,
            ..MeasuredValue::new("e", 0.0, None)
        });
        let payload = message.to_payload().unwrap();
        assert_eq!(ReadingMessage::from_payload(&payload).unwrap(), message);
        let json: serde_json::Value = serde_json::from_slice(&payload).unwrap();
        assert_eq!(json["values"][0]["derived"], false);
        assert_eq!(json["values"][2]["derived"], true);
        assert_eq!(json["values"][3]["error"], "input out of range");
        // A station before derived values sent neither key.
        let mut old = json.clone();
        for v in old["values"].as_array_mut().unwrap() {
            let v = v.as_object_mut().unwrap();
            v.remove("derived");
            v.remove("error");
        }
        let parsed = ReadingMessage::from_payload(&serde_json::to_vec(&old).unwrap()).unwrap();
        assert!(parsed.values.iter().all(|v| !v.derived && v.error.is_none()));
        // A station before the bus and the calibration sent neither key.
        let object = old.as_object_mut().unwrap();
        object.remove("bus");
        object.remove("calibration_id");
        let parsed = ReadingMessage::from_payload(&serde_json::to_vec(&old).unwrap()).unwrap();
        assert_eq!((parsed.bus, parsed.calibration_id), (None, None));
    }

    #[test]
    fn other_schema_versions_and_garbage_are_refused() {
        let mut json: serde_json::Value = serde_json::to_value(sample()).unwrap();
        json["schema"] = 2.into();
        let payload = serde_json::to_vec(&json).unwrap();
        assert!(matches!(ReadingMessage::from_payload(&payload), Err(PayloadError::UnknownSchema { found: 2 })));
        for garbage in [&b""[..], b"{", b"[]", b"{\"schema\":1}"] {
            assert!(ReadingMessage::from_payload(garbage).is_err());
        }
    }
}

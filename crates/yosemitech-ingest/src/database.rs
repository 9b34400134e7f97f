//! The PostgreSQL side: a connection that stores batches of readings in
//! one transaction each, idempotently, and reads them back for `export`.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use postgres::types::ToSql;
use postgres::{Client, NoTls};
use serde_json::Value as Json;
use yosemitech_mqtt::{MeasuredValue, ReadingMessage, SCHEMA_VERSION};

use crate::schema::{self, SchemaError};

/// What arrived on a reading topic.
#[derive(Debug, Clone, PartialEq)]
pub enum Delivery {
    /// A reading.
    Reading(ReadingMessage),
    /// Not a reading this build can store: kept in `rejected_messages`.
    Rejected {
        /// Its topic.
        topic: String,
        /// Its bytes.
        payload: Vec<u8>,
        /// Why it is not a reading.
        reason: String,
    },
}

impl Delivery {
    /// Reads a message of `topic`.
    pub fn parse(topic: &str, payload: &[u8]) -> Self {
        match ReadingMessage::from_payload(payload) {
            Ok(reading) => match taken_at(reading.timestamp_ms) {
                Some(_) => Delivery::Reading(reading),
                None => Delivery::Rejected {
                    topic: topic.to_owned(),
                    payload: payload.to_vec(),
                    reason: format!("timestamp_ms {} is outside the years 1970 to 9999", reading.timestamp_ms),
                },
            },
            Err(error) => {
                Delivery::Rejected { topic: topic.to_owned(), payload: payload.to_vec(), reason: error.to_string() }
            }
        }
    }
}

/// What storing a batch did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stored {
    /// Readings stored for the first time.
    pub new: u64,
    /// Readings already stored (a delivery repeated), left as they were.
    pub duplicates: u64,
    /// Messages kept as rejected.
    pub rejected: u64,
}

impl std::ops::AddAssign for Stored {
    fn add_assign(&mut self, other: Self) {
        self.new += other.new;
        self.duplicates += other.duplicates;
        self.rejected += other.rejected;
    }
}

/// Why the database could not be used.
#[derive(Debug, thiserror::Error)]
pub enum DatabaseError {
    /// The schema is not one this build can write.
    #[error(transparent)]
    Schema(#[from] SchemaError),
    /// The server refused, or the connection failed.
    #[error("PostgreSQL: {0}")]
    Postgres(#[from] postgres::Error),
}

/// What identifies a probe's row: every column of `probes_identity`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
struct ProbeKey {
    station: String,
    label: String,
    bus: Option<String>,
    sensor: String,
    address: i16,
    serial_number: Option<String>,
    firmware: Option<String>,
    calibration_id: Option<i64>,
}

impl ProbeKey {
    fn of(m: &ReadingMessage) -> Self {
        Self {
            station: m.station.clone(),
            label: m.probe.clone(),
            bus: m.bus.clone(),
            sensor: m.sensor.clone(),
            address: i16::from(m.address),
            serial_number: m.serial_number.clone(),
            firmware: m.firmware.clone(),
            calibration_id: m.calibration_id,
        }
    }
}

/// One connection to the fleet's database.
pub struct Database {
    client: Client,
    /// Probe rows known to exist (their ids never change).
    probes: HashMap<ProbeKey, i64>,
    /// Months whose partition is known to exist.
    months: BTreeSet<(i64, u32)>,
}

impl Database {
    /// Connects (no TLS: a Unix socket, or a server on the same host or
    /// network) and brings the schema to this build's version.
    pub fn open(config: &postgres::Config) -> Result<Self, DatabaseError> {
        let mut client = config.connect(NoTls)?;
        let mut tx = client.transaction()?;
        schema::migrate(&mut tx)?;
        tx.commit()?;
        Ok(Self { client, probes: HashMap::new(), months: BTreeSet::new() })
    }

    /// The connection, for queries of its own (tests, reports).
    pub fn client(&mut self) -> &mut Client {
        &mut self.client
    }

    /// Stores `batch` in one transaction: each reading once (a reading
    /// already stored is left as it is), its station and probe rows, and
    /// the rejected messages. Nothing is stored when it fails.
    pub fn store(&mut self, batch: &[Delivery]) -> Result<Stored, DatabaseError> {
        // Each reading once, even when a batch holds two deliveries of it.
        let mut readings: BTreeMap<(&str, i64), &ReadingMessage> = BTreeMap::new();
        let mut rejected = Vec::new();
        for delivery in batch {
            match delivery {
                Delivery::Reading(m) => {
                    readings.entry((m.station.as_str(), m.reading_id)).or_insert(m);
                }
                Delivery::Rejected { topic, payload, reason } => rejected.push((topic, payload, reason)),
            }
        }
        let deliveries = batch.len() - rejected.len();
        let mut tx = self.client.transaction()?;
        let mut stored = Stored { rejected: rejected.len() as u64, ..Stored::default() };
        for (topic, payload, reason) in &rejected {
            tx.execute(
                "INSERT INTO rejected_messages (topic, payload, reason) VALUES ($1, $2, $3)
                 ON CONFLICT (topic, md5(payload)) DO NOTHING",
                &[topic, payload, reason],
            )?;
        }
        // Rows locked in one order by every worker: stations, then probes.
        let stations: BTreeSet<&str> = readings.keys().map(|(station, _)| *station).collect();
        for station in &stations {
            tx.execute(
                "INSERT INTO stations (station) VALUES ($1) ON CONFLICT (station) DO UPDATE SET last_seen = now()",
                &[station],
            )?;
        }
        let keys: BTreeSet<ProbeKey> = readings.values().map(|m| ProbeKey::of(m)).collect();
        let mut new_probes = Vec::new();
        for key in keys {
            if self.probes.contains_key(&key) {
                continue;
            }
            let row = tx.query_one(
                "INSERT INTO probes (station, label, bus, sensor, address, serial_number, firmware, calibration_id)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8)
                 ON CONFLICT ON CONSTRAINT probes_identity DO UPDATE SET label = EXCLUDED.label
                 RETURNING probe_id",
                &[
                    &key.station,
                    &key.label,
                    &key.bus,
                    &key.sensor,
                    &key.address,
                    &key.serial_number,
                    &key.firmware,
                    &key.calibration_id,
                ],
            )?;
            new_probes.push((key, row.get::<_, i64>(0)));
        }
        let months: BTreeSet<(i64, u32)> =
            readings.values().map(|m| month_of(m.timestamp_ms)).filter(|m| !self.months.contains(m)).collect();
        if !months.is_empty() {
            // Two workers creating one month's partition would collide.
            tx.execute("SELECT pg_advisory_xact_lock(hashtext('yosemitech_partitions'))", &[])?;
            for &(year, month) in &months {
                let (to_year, to_month) = if month == 12 { (year + 1, 1) } else { (year, month + 1) };
                tx.batch_execute(&format!(
                    "CREATE TABLE IF NOT EXISTS readings_y{year:04}m{month:02} PARTITION OF readings
                     FOR VALUES FROM ('{year:04}-{month:02}-01 00:00:00+00') TO ('{to_year:04}-{to_month:02}-01 00:00:00+00')"
                ))?;
            }
        }
        let probe_id = |m: &ReadingMessage| {
            let key = ProbeKey::of(m);
            self.probes.get(&key).copied().or_else(|| new_probes.iter().find(|(k, _)| *k == key).map(|(_, id)| *id))
        };
        let mut columns = Columns::default();
        for m in readings.values() {
            let (Some(at), Some(probe)) = (taken_at(m.timestamp_ms), probe_id(m)) else { continue };
            columns.station.push(m.station.clone());
            columns.reading_id.push(m.reading_id);
            columns.taken_at.push(at);
            columns.probe_id.push(probe);
            columns.measurements.push(measurements_json(&m.values));
            columns.retries.push(i32::try_from(m.retries).unwrap_or(i32::MAX));
            columns.error.push(m.error.clone());
        }
        let params: [&(dyn ToSql + Sync); 7] = [
            &columns.station,
            &columns.reading_id,
            &columns.taken_at,
            &columns.probe_id,
            &columns.measurements,
            &columns.retries,
            &columns.error,
        ];
        stored.new = tx.execute(
            "INSERT INTO readings (station, reading_id, taken_at, probe_id, measurements, retries, error)
             SELECT * FROM unnest($1::text[], $2::int8[], $3::timestamptz[], $4::int8[], $5::jsonb[], $6::int4[], $7::text[])
             ON CONFLICT DO NOTHING",
            &params,
        )?;
        stored.duplicates = deliveries as u64 - stored.new;
        tx.commit()?;
        // Only what a committed transaction made is known to exist.
        self.probes.extend(new_probes);
        self.months.extend(months);
        Ok(stored)
    }

    /// The readings taken in `[from, to)`, oldest first, as messages.
    pub fn readings_between(&mut self, from: SystemTime, to: SystemTime) -> Result<Vec<ReadingMessage>, DatabaseError> {
        let rows = self.client.query(
            "SELECT r.station, r.reading_id, r.taken_at, p.label, p.bus, p.sensor, p.address, p.serial_number,
                    p.firmware, p.calibration_id, r.measurements, r.retries, r.error
             FROM readings r JOIN probes p USING (probe_id)
             WHERE r.taken_at >= $1 AND r.taken_at < $2
             ORDER BY r.taken_at, r.station, r.reading_id",
            &[&from, &to],
        )?;
        Ok(rows
            .iter()
            .map(|row| {
                let taken_at: SystemTime = row.get(2);
                let measurements: Json = row.get(10);
                ReadingMessage {
                    schema: SCHEMA_VERSION,
                    reading_id: row.get(1),
                    timestamp_ms: unix_ms(taken_at),
                    station: row.get(0),
                    probe: row.get(3),
                    sensor: row.get(5),
                    address: u8::try_from(row.get::<_, i16>(6)).unwrap_or(0),
                    serial_number: row.get(7),
                    firmware: row.get(8),
                    values: serde_json::from_value::<Vec<MeasuredValue>>(measurements).unwrap_or_default(),
                    retries: u32::try_from(row.get::<_, i32>(11)).unwrap_or(0),
                    error: row.get(12),
                    bus: row.get(4),
                    calibration_id: row.get(9),
                }
            })
            .collect())
    }
}

/// The readings table's columns of a batch, as arrays for `unnest`.
#[derive(Default)]
struct Columns {
    station: Vec<String>,
    reading_id: Vec<i64>,
    taken_at: Vec<SystemTime>,
    probe_id: Vec<i64>,
    measurements: Vec<Json>,
    retries: Vec<i32>,
    error: Vec<Option<String>>,
}

fn measurements_json(values: &[MeasuredValue]) -> Json {
    serde_json::to_value(values).unwrap_or(Json::Array(Vec::new()))
}

/// The first millisecond of the year 10000: later times are not readings.
const END_OF_9999_MS: i64 = 253_402_300_800_000;

/// When a reading of `timestamp_ms` was taken, if it is in the years 1970 to 9999.
pub fn taken_at(timestamp_ms: i64) -> Option<SystemTime> {
    let ms = u64::try_from(timestamp_ms).ok().filter(|ms| *ms < END_OF_9999_MS as u64)?;
    UNIX_EPOCH.checked_add(Duration::from_millis(ms))
}

fn unix_ms(at: SystemTime) -> i64 {
    at.duration_since(UNIX_EPOCH).map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

/// The (year, month) of a time in milliseconds since the epoch, in UTC.
pub fn month_of(timestamp_ms: i64) -> (i64, u32) {
    let days = timestamp_ms.div_euclid(86_400_000);
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, u32::try_from(month).unwrap_or(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn months_are_utc_calendar_months() {
        assert_eq!(month_of(0), (1970, 1));
        assert_eq!(month_of(1_795_900_500_000), (2026, 11));
        // 2024-02-29T23:59:59.999Z and the next millisecond.
        assert_eq!(month_of(1_709_251_199_999), (2024, 2));
        assert_eq!(month_of(1_709_251_200_000), (2024, 3));
        assert_eq!(month_of(END_OF_9999_MS - 1), (9999, 12));
    }

    #[test]
    fn times_outside_the_years_1970_to_9999_are_not_readings() {
        assert!(taken_at(-1).is_none());
        assert!(taken_at(END_OF_9999_MS).is_none());
        assert!(taken_at(i64::MAX).is_none());
        assert_eq!(taken_at(1000), Some(UNIX_EPOCH + Duration::from_secs(1)));
    }

    #[test]
    fn garbage_and_other_schemas_are_rejected_with_their_reason() {
        match Delivery::parse("t", b"not json") {
            Delivery::Rejected { topic, payload, reason } => {
                assert_eq!((topic.as_str(), payload.as_slice()), ("t", &b"not json"[..]));
                assert!(reason.contains("not a reading"), "{reason}");
            }
            other => panic!("{other:?}"),
        }
        let Delivery::Rejected { reason, .. } = Delivery::parse("t", br#"{"schema": 99}"#) else { panic!() };
        assert!(reason.contains("99"), "{reason}");
    }
}

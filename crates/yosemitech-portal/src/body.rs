//! Request bodies, without I/O: which stored readings go in the next
//! request, and the JSON the portal takes for them.
//!
//! The portal takes one record as `{"sampling_feature": S, "timestamp": T,
//! "<result uuid>": value, ...}` and several as parallel arrays: `timestamp`
//! and every result UUID an array of the same length. Every record of one
//! request must therefore carry the same result UUIDs: a request is the
//! longest run of pending records (in store order) with one set of result
//! UUIDs, at most a batch long. Records with no bound value (a probe the
//! portal does not take, a reading that failed) are passed over, so the
//! cursor moves past them; a value that is not a number (a text, a derived
//! quantity that could not be computed) is not sent, never replaced by a
//! placeholder.

use std::collections::BTreeSet;

use serde_json::{Map, Value};

/// One stored reading as the portal sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// The store's id: increasing in commit order.
    pub id: i64,
    /// When it was taken, milliseconds since the Unix epoch (UTC).
    pub timestamp_ms: i64,
    /// `(result uuid, value)` for every bound value the reading has, each
    /// UUID once; finite values only.
    pub values: Vec<(String, f64)>,
}

/// What the next request carries.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch<'a> {
    /// The records to send (empty: nothing to send, only to pass over).
    pub records: Vec<&'a Record>,
    /// The cursor once the portal accepted them: the id of the last record
    /// taken, sent or passed over.
    pub up_to: i64,
}

/// The next request from `pending` (ascending ids), at most `max` records;
/// `None` when `pending` is empty.
pub fn next_batch(pending: &[Record], max: usize) -> Option<Batch<'_>> {
    let mut up_to = pending.first()?.id;
    let mut key: Option<BTreeSet<&str>> = None;
    let mut records = Vec::new();
    for record in pending {
        if record.values.is_empty() {
            up_to = record.id;
            continue;
        }
        let this: BTreeSet<&str> = record.values.iter().map(|(uuid, _)| uuid.as_str()).collect();
        match &key {
            Some(key) if *key != this || records.len() >= max.max(1) => break,
            Some(_) => {}
            None => key = Some(this),
        }
        records.push(record);
        up_to = record.id;
    }
    Some(Batch { records, up_to })
}

/// Days since 1970-01-01 to (year, month, day), proleptic Gregorian.
fn civil(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(month <= 2), month, day)
}

/// `timestamp_ms` as ISO 8601 local time at `offset_hours` from UTC, with
/// the offset: `2026-12-02T15:34:05+00:00`, and `.123` before the offset
/// when the instant is not on a whole second.
pub fn timestamp(timestamp_ms: i64, offset_hours: i8) -> String {
    let local = timestamp_ms + i64::from(offset_hours) * 3_600_000;
    let (days, ms) = (local.div_euclid(86_400_000), local.rem_euclid(86_400_000));
    let (year, month, day) = civil(days);
    let (h, m, s, milli) = (ms / 3_600_000, ms / 60_000 % 60, ms / 1000 % 60, ms % 1000);
    let fraction = if milli == 0 { String::new() } else { format!(".{milli:03}") };
    let sign = if offset_hours < 0 { '-' } else { '+' };
    let offset = offset_hours.unsigned_abs();
    format!("{year:04}-{month:02}-{day:02}T{h:02}:{m:02}:{s:02}{fraction}{sign}{offset:02}:00")
}

/// The body for `records` (from one [`Batch`], so all with the same result
/// UUIDs): scalars for one record, parallel arrays for several.
pub fn body(sampling_feature: &str, offset_hours: i8, records: &[&Record]) -> Value {
    let mut body = Map::new();
    body.insert("sampling_feature".into(), Value::from(sampling_feature));
    if let [one] = records {
        body.insert("timestamp".into(), Value::from(timestamp(one.timestamp_ms, offset_hours)));
        for (uuid, value) in &one.values {
            body.insert(uuid.clone(), Value::from(*value));
        }
        return Value::Object(body);
    }
    let stamps = records.iter().map(|r| Value::from(timestamp(r.timestamp_ms, offset_hours))).collect();
    body.insert("timestamp".into(), Value::Array(stamps));
    let uuids: BTreeSet<&str> =
        records.first().map(|r| r.values.iter().map(|(u, _)| u.as_str()).collect()).unwrap_or_default();
    for uuid in uuids {
        let column = records
            .iter()
            .map(|r| r.values.iter().find(|(u, _)| u == uuid).map_or(Value::Null, |(_, v)| Value::from(*v)))
            .collect();
        body.insert(uuid.to_owned(), Value::Array(column));
    }
    Value::Object(body)
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    const A: &str = "aaaaaaaa-0000-4000-8000-000000000001";
    const B: &str = "bbbbbbbb-0000-4000-8000-000000000002";

    fn record(id: i64, values: &[(&str, f64)]) -> Record {
        Record {
            id,
            timestamp_ms: 1_795_900_500_000 + id * 1000,
            values: values.iter().map(|(u, v)| ((*u).to_owned(), *v)).collect(),
        }
    }

    #[test]
    fn timestamps_carry_their_offset_in_whole_hours() {
        assert_eq!(timestamp(0, 0), "1970-01-01T00:00:00+00:00");
        assert_eq!(timestamp(1_795_900_500_123, 0), "2026-11-28T21:15:00.123+00:00");
        assert_eq!(timestamp(1_795_900_500_000, -5), "2026-11-28T16:15:00-05:00");
        assert_eq!(timestamp(1_795_900_500_000, 10), "2026-11-29T07:15:00+10:00");
        assert_eq!(timestamp(951_782_400_000, 0), "2000-02-29T00:00:00+00:00");
    }

    #[test]
    fn one_record_is_scalars_several_are_parallel_arrays() {
        let one = record(1, &[(A, 7.5), (B, 20.25)]);
        assert_eq!(
            body("s", 0, &[&one]),
            serde_json::json!({"sampling_feature": "s", "timestamp": "2026-11-28T21:15:01+00:00", A: 7.5, B: 20.25})
        );
        let two = record(2, &[(B, 21.0), (A, 7.25)]);
        assert_eq!(
            body("s", 0, &[&one, &two]),
            serde_json::json!({
                "sampling_feature": "s",
                "timestamp": ["2026-11-28T21:15:01+00:00", "2026-11-28T21:15:02+00:00"],
                A: [7.5, 7.25],
                B: [20.25, 21.0],
            })
        );
    }

    #[test]
    fn a_batch_is_a_run_of_one_set_of_uuids_passing_over_records_without_values() {
        let pending = [
            record(1, &[]),
            record(2, &[(A, 1.0)]),
            record(3, &[]),
            record(4, &[(A, 2.0)]),
            record(5, &[(A, 3.0), (B, 4.0)]),
        ];
        let batch = next_batch(&pending, 10).unwrap();
        assert_eq!(batch.records.iter().map(|r| r.id).collect::<Vec<_>>(), [2, 4]);
        assert_eq!(batch.up_to, 4);
        let batch = next_batch(&pending[4..], 10).unwrap();
        assert_eq!((batch.records.len(), batch.up_to), (1, 5));
        let batch = next_batch(&pending, 1).unwrap();
        assert_eq!(
            (batch.records.len(), batch.up_to),
            (1, 3),
            "at most a batch, and the records without values after it"
        );
        let nothing = next_batch(&pending[..1], 10).unwrap();
        assert_eq!((nothing.records.len(), nothing.up_to), (0, 1), "passed over");
        assert_eq!(next_batch(&[], 10), None);
    }

    fn records() -> impl Strategy<Value = Vec<Record>> {
        let uuids = [A, B, "cccccccc-0000-4000-8000-000000000003"];
        prop::collection::vec(prop::collection::btree_map(0..uuids.len(), -1e6..1e6f64, 0..3), 0..40).prop_map(
            move |rows| {
                rows.into_iter()
                    .enumerate()
                    .map(|(i, values)| Record {
                        id: i as i64 + 1,
                        timestamp_ms: 1_795_900_500_000 + i as i64 * 250,
                        values: values.into_iter().map(|(u, v)| (uuids[u].to_owned(), v)).collect(),
                    })
                    .collect()
            },
        )
    }

    proptest! {
        /// Draining the pending records batch by batch sends every value
        /// once, in arrays as long as the timestamps, with no placeholder.
        #[test]
        fn every_value_once_in_equal_arrays(pending in records(), max in 1usize..8) {
            let mut rest: &[Record] = &pending;
            let mut sent = Vec::new();
            while let Some(batch) = next_batch(rest, max) {
                prop_assert!(batch.records.len() <= max);
                let body = body("s", 0, &batch.records);
                let object = body.as_object().unwrap();
                if batch.records.len() > 1 {
                    let n = object["timestamp"].as_array().unwrap().len();
                    prop_assert_eq!(n, batch.records.len());
                    for (key, column) in object {
                        if key != "sampling_feature" && key != "timestamp" {
                            let column = column.as_array().unwrap();
                            prop_assert_eq!(column.len(), n, "{}", key);
                            prop_assert!(column.iter().all(Value::is_number));
                        }
                    }
                }
                for r in &batch.records {
                    sent.extend(r.values.iter().map(|(u, v)| (r.id, u.clone(), *v)));
                }
                let next = rest.iter().position(|r| r.id > batch.up_to).unwrap_or(rest.len());
                prop_assert!(next > 0, "progress");
                rest = &rest[next..];
            }
            let all: Vec<(i64, String, f64)> =
                pending.iter().flat_map(|r| r.values.iter().map(move |(u, v)| (r.id, u.clone(), *v))).collect();
            prop_assert_eq!(sent, all);
        }
    }
}

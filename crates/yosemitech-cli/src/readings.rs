//! What `watch` and `plot` show, as plain data: a [`Snapshot`] of every
//! probe's latest values and recent history, and [`Series`] of one
//! measurement of one probe over a time range.
//!
//! Both are built from [`Reading`]s, one per probe visit as a logger stores
//! it, so that drawing never depends on how the readings are stored.

use std::collections::BTreeMap;
use std::time::SystemTime;

/// One visit of a logger to one probe: its values, or why there are none.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// When the values were taken.
    pub at: SystemTime,
    /// The probe's label in the station's configuration.
    pub probe: String,
    /// The spec's sensor name.
    pub sensor: String,
    /// The probe's serial number, when it was read.
    pub serial: Option<String>,
    /// Every value read, in the order the logger stored them.
    pub values: Vec<Value>,
    /// Retries the visit needed (timeouts, corrupt replies).
    pub retries: u32,
    /// Why the visit failed, if it did.
    pub error: Option<String>,
}

/// One measured value with its unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Value {
    /// The measurement's name (the spec's field name).
    pub measurement: String,
    /// Its unit, as the spec states it.
    pub unit: String,
    /// The value; may be NaN or infinite when the probe sent one.
    pub value: f64,
}

/// Every probe's state, for the terminal view.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Snapshot {
    /// Probes, by label.
    pub probes: Vec<ProbeStatus>,
}

/// One probe's latest values, recent history and failures.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeStatus {
    /// The probe's label.
    pub label: String,
    /// The spec's sensor name.
    pub sensor: String,
    /// The serial number last read.
    pub serial: Option<String>,
    /// The last visit, successful or not.
    pub last_visit: Option<SystemTime>,
    /// Measurements, in the order the logger first stored them.
    pub measurements: Vec<MeasurementStatus>,
    /// Visits that failed.
    pub errors: u64,
    /// Retries over every visit.
    pub retries: u64,
    /// The last visit's error, when the last visit failed.
    pub last_error: Option<String>,
}

/// One measurement of one probe.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementStatus {
    /// The measurement's name.
    pub name: String,
    /// Its unit.
    pub unit: String,
    /// The latest value and when it was taken.
    pub latest: Option<(SystemTime, f64)>,
    /// Values oldest first, the latest last; may hold NaN.
    pub history: Vec<f64>,
}

/// The values of one measurement of one probe over a time range.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The probe's label.
    pub probe: String,
    /// The measurement's name.
    pub measurement: String,
    /// Its unit.
    pub unit: String,
    /// Points in time order; values may be NaN.
    pub points: Vec<(SystemTime, f64)>,
}

impl Snapshot {
    /// Builds the view of `readings` (any order): each probe's latest values,
    /// up to `history` values per measurement, and its error and retry counts.
    pub fn from_readings<'a>(readings: impl IntoIterator<Item = &'a Reading>, history: usize) -> Self {
        let mut sorted: Vec<&Reading> = readings.into_iter().collect();
        sorted.sort_by_key(|r| r.at);
        let mut probes: BTreeMap<&str, ProbeStatus> = BTreeMap::new();
        for reading in sorted {
            let probe = probes.entry(&reading.probe).or_insert_with(|| ProbeStatus {
                label: reading.probe.clone(),
                sensor: reading.sensor.clone(),
                serial: None,
                last_visit: None,
                measurements: Vec::new(),
                errors: 0,
                retries: 0,
                last_error: None,
            });
            probe.sensor.clone_from(&reading.sensor);
            if reading.serial.is_some() {
                probe.serial.clone_from(&reading.serial);
            }
            probe.last_visit = Some(reading.at);
            probe.retries += u64::from(reading.retries);
            probe.last_error.clone_from(&reading.error);
            if reading.error.is_some() {
                probe.errors += 1;
            }
            for value in &reading.values {
                let index =
                    match probe.measurements.iter().position(|m| m.name == value.measurement && m.unit == value.unit) {
                        Some(i) => i,
                        None => {
                            probe.measurements.push(MeasurementStatus {
                                name: value.measurement.clone(),
                                unit: value.unit.clone(),
                                latest: None,
                                history: Vec::new(),
                            });
                            probe.measurements.len() - 1
                        }
                    };
                let m = &mut probe.measurements[index];
                m.latest = Some((reading.at, value.value));
                m.history.push(value.value);
            }
        }
        let mut probes: Vec<ProbeStatus> = probes.into_values().collect();
        for m in probes.iter_mut().flat_map(|p| p.measurements.iter_mut()) {
            let excess = m.history.len().saturating_sub(history);
            m.history.drain(..excess);
        }
        Self { probes }
    }
}

/// Which series to take from the readings.
#[derive(Debug, Clone, Default)]
pub struct SeriesFilter {
    /// Only this probe (by label).
    pub probe: Option<String>,
    /// Only this measurement (by name).
    pub measurement: Option<String>,
}

/// Splits `readings` into one series per probe and measurement (and unit),
/// by probe label then in the order the measurements first appear, each
/// in time order. Failed visits contribute nothing.
pub fn series(readings: &[Reading], filter: &SeriesFilter) -> Vec<Series> {
    let mut sorted: Vec<&Reading> =
        readings.iter().filter(|r| filter.probe.as_deref().is_none_or(|p| p == r.probe)).collect();
    sorted.sort_by_key(|r| r.at);
    let mut by_probe: BTreeMap<&str, Vec<Series>> = BTreeMap::new();
    for reading in sorted {
        let list = by_probe.entry(&reading.probe).or_default();
        for value in &reading.values {
            if filter.measurement.as_deref().is_some_and(|m| m != value.measurement) {
                continue;
            }
            let found = list.iter_mut().find(|s| s.measurement == value.measurement && s.unit == value.unit);
            let series = match found {
                Some(s) => s,
                None => {
                    list.push(Series {
                        probe: reading.probe.clone(),
                        measurement: value.measurement.clone(),
                        unit: value.unit.clone(),
                        points: Vec::new(),
                    });
                    let last = list.len() - 1;
                    &mut list[last]
                }
            };
            series.points.push((reading.at, value.value));
        }
    }
    by_probe.into_values().flatten().collect()
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, UNIX_EPOCH};

    use super::*;

    fn reading(secs: u64, probe: &str, values: &[(&str, f64)], error: Option<&str>) -> Reading {
        Reading {
            at: UNIX_EPOCH + Duration::from_secs(secs),
            probe: probe.into(),
            sensor: "s".into(),
            serial: Some(format!("SN-{probe}")),
            values: values
                .iter()
                .map(|(m, v)| Value { measurement: (*m).into(), unit: "u".into(), value: *v })
                .collect(),
            retries: 1,
            error: error.map(Into::into),
        }
    }

    #[test]
    fn snapshot_keeps_the_latest_value_bounded_history_and_counts() {
        let readings = [
            reading(3, "b", &[("x", 3.0)], None),
            reading(1, "b", &[("x", 1.0)], None),
            reading(2, "b", &[("x", 2.0)], None),
            reading(4, "b", &[], Some("no reply")),
            reading(1, "a", &[("y", f64::NAN)], None),
        ];
        let snap = Snapshot::from_readings(&readings, 2);
        let labels: Vec<&str> = snap.probes.iter().map(|p| p.label.as_str()).collect();
        assert_eq!(labels, ["a", "b"]);
        let b = &snap.probes[1];
        assert_eq!(b.measurements[0].latest, Some((UNIX_EPOCH + Duration::from_secs(3), 3.0)));
        assert_eq!(b.measurements[0].history, [2.0, 3.0]);
        assert_eq!((b.errors, b.retries), (1, 4));
        assert_eq!(b.last_error.as_deref(), Some("no reply"));
        assert!(snap.probes[0].measurements[0].history[0].is_nan());
    }

    #[test]
    fn series_are_split_by_probe_and_measurement_and_filtered() {
        let readings = [
            reading(2, "a", &[("x", 2.0), ("y", 20.0)], None),
            reading(1, "a", &[("x", 1.0), ("y", 10.0)], None),
            reading(1, "b", &[("x", 5.0)], None),
        ];
        let all = series(&readings, &SeriesFilter::default());
        let names: Vec<(&str, &str, usize)> =
            all.iter().map(|s| (s.probe.as_str(), s.measurement.as_str(), s.points.len())).collect();
        assert_eq!(names, [("a", "x", 2), ("a", "y", 2), ("b", "x", 1)]);
        assert_eq!(all[0].points[0].1, 1.0);
        let only = series(&readings, &SeriesFilter { probe: Some("a".into()), measurement: Some("y".into()) });
        assert_eq!(only.len(), 1);
        assert_eq!(only[0].points.iter().map(|p| p.1).collect::<Vec<_>>(), [10.0, 20.0]);
    }
}

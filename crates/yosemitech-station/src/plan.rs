//! Read planning: the fewest transactions that cover the measurements
//! chosen for a probe.
//!
//! A measurement is a named field of a measurement read
//! ([`Sensor::is_measurement`]); reads that carry a field of the same name
//! carry the same measurement (a combined read of two quantities
//! duplicates the fields of the single reads). The plan is a minimum set
//! cover of the chosen names by the sensor's measurement reads: fewest
//! reads first, then fewest registers on the wire, then spec order. Every
//! name is taken from the first read of the plan that carries it.
//!
//! The search is exact (subsets by increasing size) for sensors with up to
//! [`EXACT_LIMIT`] measurement reads carrying a chosen field, and greedy
//! (the read covering most uncovered names) above; every sensor of the
//! shipped spec is well under the limit.

use std::collections::BTreeSet;

use yosemitech_spec::{Command, Sensor};

/// Above this many candidate reads the planner is greedy instead of exact.
pub const EXACT_LIMIT: usize = 16;

/// What cannot be planned.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PlanError {
    /// The sensor has no measurement read.
    #[error("sensor `{sensor}` has no measurement reads")]
    NoMeasurements {
        /// The sensor.
        sensor: String,
    },
    /// A name is neither a measurement nor a measurement read of the sensor.
    #[error("`{name}` is not a measurement of sensor `{sensor}`; it has: {known}")]
    Unknown {
        /// The sensor.
        sensor: String,
        /// The name given.
        name: String,
        /// The measurement names and reads the sensor has, comma-separated.
        known: String,
    },
}

/// One transaction of a plan: a read and the chosen measurements taken from it.
#[derive(Debug, Clone)]
pub struct PlannedRead<'s> {
    /// The read command.
    pub command: &'s Command,
    /// The chosen field names taken from this read's reply, in field order.
    pub fields: Vec<&'s str>,
}

/// The reads that cover a probe's chosen measurements.
#[derive(Debug, Clone)]
pub struct Plan<'s> {
    /// The transactions, in spec order.
    pub reads: Vec<PlannedRead<'s>>,
}

impl<'s> Plan<'s> {
    /// Every chosen measurement name, in the order the plan yields them.
    pub fn measurements(&self) -> impl Iterator<Item = &'s str> + '_ {
        self.reads.iter().flat_map(|r| r.fields.iter().copied())
    }

    /// Registers read per sample (a proxy for time on the wire).
    pub fn registers(&self) -> u32 {
        self.reads.iter().map(|r| u32::from(r.command.count)).sum()
    }
}

/// Every measurement name of `sensor`: the named fields of its measurement
/// reads, each once, in spec order.
pub fn measurements(sensor: &Sensor) -> Vec<&str> {
    let mut seen = BTreeSet::new();
    sensor
        .measurement_reads()
        .flat_map(|c| c.named_fields())
        .filter_map(|f| f.name.as_deref())
        .filter(|name| seen.insert(*name))
        .collect()
}

/// The measurement names that `names` choose: a measurement name is
/// itself, a measurement read's name stands for its named fields. Empty
/// `names` choose every measurement. The result has each name once, in
/// the sensor's order.
///
/// # Errors
///
/// A name is neither a measurement nor a measurement read of `sensor`, or
/// the sensor has no measurement read at all.
pub fn choose<'s>(sensor: &'s Sensor, names: &[impl AsRef<str>]) -> Result<Vec<&'s str>, PlanError> {
    let all = measurements(sensor);
    if all.is_empty() {
        return Err(PlanError::NoMeasurements { sensor: sensor.name.clone() });
    }
    if names.is_empty() {
        return Ok(all);
    }
    let mut chosen = BTreeSet::new();
    for name in names {
        let name = name.as_ref();
        if let Some(m) = all.iter().find(|m| **m == name) {
            chosen.insert(*m);
        } else if let Some(read) = sensor.measurement_reads().find(|c| c.name == name) {
            chosen.extend(read.named_fields().filter_map(|f| f.name.as_deref()));
        } else {
            let known: Vec<&str> =
                all.iter().copied().chain(sensor.measurement_reads().map(|c| c.name.as_str())).collect();
            return Err(PlanError::Unknown {
                sensor: sensor.name.clone(),
                name: name.to_owned(),
                known: known.join(", "),
            });
        }
    }
    Ok(all.into_iter().filter(|m| chosen.contains(m)).collect())
}

/// The plan of fewest reads covering `chosen` (measurement names of
/// `sensor`, as [`choose`] returns them; unknown names are left uncovered).
pub fn plan<'s>(sensor: &'s Sensor, chosen: &[&str]) -> Plan<'s> {
    let wanted: BTreeSet<&str> = chosen.iter().copied().collect();
    let candidates: Vec<&Command> = sensor
        .measurement_reads()
        .filter(|c| c.named_fields().any(|f| f.name.as_deref().is_some_and(|n| wanted.contains(n))))
        .collect();
    let sets: Vec<BTreeSet<&str>> = candidates
        .iter()
        .map(|c| c.named_fields().filter_map(|f| f.name.as_deref()).filter(|n| wanted.contains(n)).collect())
        .collect();
    let picked: Vec<usize> =
        if candidates.len() <= EXACT_LIMIT { exact_cover(&sets, &candidates, &wanted) } else { greedy_cover(&sets, &wanted) };
    assign(picked.into_iter().map(|i| candidates[i]).collect(), &wanted)
}

/// The naive plan: every measurement read carrying a chosen name (what a
/// reader without planning sends).
pub fn naive<'s>(sensor: &'s Sensor, chosen: &[&str]) -> Plan<'s> {
    let wanted: BTreeSet<&str> = chosen.iter().copied().collect();
    let reads = sensor
        .measurement_reads()
        .filter(|c| c.named_fields().any(|f| f.name.as_deref().is_some_and(|n| wanted.contains(n))))
        .collect();
    assign(reads, &wanted)
}

/// The plan of `reads` (in spec order): each wanted name from the first read carrying it.
fn assign<'s>(reads: Vec<&'s Command>, wanted: &BTreeSet<&str>) -> Plan<'s> {
    let mut taken = BTreeSet::new();
    let reads = reads
        .into_iter()
        .map(|command| PlannedRead {
            command,
            fields: command
                .named_fields()
                .filter_map(|f| f.name.as_deref())
                .filter(|n| wanted.contains(n) && taken.insert(*n))
                .collect(),
        })
        .collect();
    Plan { reads }
}

/// The smallest set of candidates covering `wanted` (fewest registers on
/// ties, then the first in spec order); indexes in increasing order.
fn exact_cover(sets: &[BTreeSet<&str>], reads: &[&Command], wanted: &BTreeSet<&str>) -> Vec<usize> {
    let n = sets.len();
    let covers = |mask: u32| {
        let mut got = BTreeSet::new();
        for (i, s) in sets.iter().enumerate() {
            if mask & (1 << i) != 0 {
                got.extend(s.iter().copied());
            }
        }
        wanted.iter().all(|w| got.contains(w))
    };
    let registers = |mask: u32| -> u32 {
        reads.iter().enumerate().filter(|(i, _)| mask & (1 << i) != 0).map(|(_, c)| u32::from(c.count)).sum()
    };
    for size in 0..=n as u32 {
        // Masks in increasing order: among equal register counts, the
        // first is the one whose reads come earliest in the spec.
        let best = (0u32..(1u32 << n)).filter(|m| m.count_ones() == size && covers(*m)).min_by_key(|m| registers(*m));
        if let Some(mask) = best {
            return (0..n).filter(|i| mask & (1 << i) != 0).collect();
        }
    }
    (0..n).collect()
}

/// Greedy set cover: repeatedly the candidate covering most uncovered names.
fn greedy_cover(sets: &[BTreeSet<&str>], wanted: &BTreeSet<&str>) -> Vec<usize> {
    let mut left: BTreeSet<&str> = wanted.clone();
    let mut picked = Vec::new();
    while !left.is_empty() {
        let best = (0..sets.len()).max_by_key(|i| (sets[*i].intersection(&left).count(), std::cmp::Reverse(*i)));
        match best {
            Some(i) if sets[i].intersection(&left).count() > 0 => {
                left.retain(|n| !sets[i].contains(n));
                picked.push(i);
            }
            _ => break,
        }
    }
    picked.sort_unstable();
    picked
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> yosemitech_spec::Spec {
        yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()]).unwrap()
    }

    /// Every non-empty subset of a sensor's measurements when there are
    /// few, else every single one and all of them.
    fn choices<'s>(sensor: &'s Sensor) -> Vec<Vec<&'s str>> {
        let all = measurements(sensor);
        if all.len() <= 10 {
            (1u32..(1 << all.len()))
                .map(|mask| all.iter().enumerate().filter(|(i, _)| mask & (1 << i) != 0).map(|(_, m)| *m).collect())
                .collect()
        } else {
            all.iter().map(|m| vec![*m]).chain(std::iter::once(all.clone())).collect()
        }
    }

    #[test]
    fn never_reads_more_than_naive_and_covers_every_choice_for_every_sensor() {
        let spec = spec();
        let (mut sensors, mut cases, mut saved) = (0, 0, 0);
        for sensor in spec.sensors.iter().filter(|s| s.measurement_reads().next().is_some()) {
            sensors += 1;
            for chosen in choices(sensor) {
                let planned = plan(sensor, &chosen);
                let naive = naive(sensor, &chosen);
                assert!(planned.reads.len() <= naive.reads.len(), "{}: {chosen:?}", sensor.name);
                let mut got: Vec<&str> = planned.measurements().collect();
                got.sort_unstable();
                let mut want = chosen.clone();
                want.sort_unstable();
                assert_eq!(got, want, "{}: the plan yields each chosen measurement once", sensor.name);
                for r in &planned.reads {
                    assert!(sensor.is_measurement(r.command));
                    assert!(!r.fields.is_empty(), "{}: no read is planned for nothing", sensor.name);
                    for f in &r.fields {
                        assert!(r.command.field(f).is_some(), "{}: {f} comes from a read that carries it", sensor.name);
                    }
                }
                saved += naive.reads.len() - planned.reads.len();
                cases += 1;
            }
        }
        assert!(sensors > 0 && cases > 0);
        eprintln!("    {sensors} sensors, {cases} choices, {saved} transactions saved over the naive plans");
    }

    #[test]
    fn a_combined_read_replaces_the_single_reads_it_duplicates() {
        // Wherever the spec has a read whose fields are each carried by
        // another measurement read, choosing exactly its fields plans it
        // alone: one transaction instead of one per field.
        let spec = spec();
        let mut found = 0;
        for sensor in &spec.sensors {
            for combined in sensor.measurement_reads() {
                let names: Vec<&str> = combined.named_fields().filter_map(|f| f.name.as_deref()).collect();
                let elsewhere = |n: &str| sensor.measurement_reads().any(|c| c.name != combined.name && c.field(n).is_some());
                if names.len() < 2 || !names.iter().all(|n| elsewhere(n)) {
                    continue;
                }
                let planned = plan(sensor, &names);
                assert_eq!(planned.reads.len(), 1, "{}: {names:?}", sensor.name);
                assert!(naive(sensor, &names).reads.len() > 1);
                found += 1;
            }
        }
        eprintln!("    {found} combined reads in the spec");
    }

    #[test]
    fn choose_accepts_measurements_and_reads_and_names_what_is_wrong() {
        let spec = spec();
        for sensor in spec.sensors.iter().filter(|s| s.measurement_reads().next().is_some()) {
            let all = measurements(sensor);
            assert_eq!(choose(sensor, &[] as &[&str]).unwrap(), all);
            for read in sensor.measurement_reads() {
                let got = choose(sensor, &[read.name.as_str()]).unwrap();
                let want: Vec<&str> = all.iter().copied().filter(|m| read.field(m).is_some()).collect();
                assert_eq!(got, want);
            }
            let err = choose(sensor, &["no_such_measurement"]).unwrap_err();
            assert!(err.to_string().contains(all[0]), "{err}");
        }
        for sensor in spec.sensors.iter().filter(|s| s.measurement_reads().next().is_none()) {
            assert!(matches!(choose(sensor, &[] as &[&str]), Err(PlanError::NoMeasurements { .. })));
        }
    }

    #[test]
    fn greedy_and_exact_agree_on_the_spec() {
        let spec = spec();
        for sensor in &spec.sensors {
            let all = measurements(sensor);
            let wanted: BTreeSet<&str> = all.iter().copied().collect();
            let reads: Vec<&Command> = sensor.measurement_reads().collect();
            if reads.len() > EXACT_LIMIT {
                continue;
            }
            let sets: Vec<BTreeSet<&str>> = reads
                .iter()
                .map(|c| c.named_fields().filter_map(|f| f.name.as_deref()).collect())
                .collect();
            assert!(exact_cover(&sets, &reads, &wanted).len() <= greedy_cover(&sets, &wanted).len());
        }
    }
}

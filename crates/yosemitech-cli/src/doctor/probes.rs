//! The frames the doctor sends, chosen from the spec by role, never by
//! sensor: without a sensor named, the frames most loaded sensors share.

use yosemitech_spec::{CommandSpec, Role, Sensor};

/// The requests of a diagnosis. All are reads but the trigger, which
/// starts a measurement and changes no setting.
#[derive(Debug, Clone)]
pub struct Probes<'c> {
    /// Role `serial_number`, sent to the probe's own address: the read every
    /// probe answers.
    pub identify: &'c CommandSpec,
    /// Role `version`, a second read to tell a damaged reply from two probes' replies.
    pub version: Option<&'c CommandSpec>,
    /// Role `start_measurement`: each distinct request, the most common
    /// first, sent to a probe that answers reads until one is answered.
    pub starts: Vec<&'c CommandSpec>,
    /// Role `get_slave_address` at a fixed wildcard address (0xFF): a lone
    /// probe answers it whatever its own address.
    pub wildcard: Option<&'c CommandSpec>,
}

/// True when two commands send the same request frame.
fn same_request(a: &CommandSpec, b: &CommandSpec) -> bool {
    (a.function, a.address, a.count, a.fixed_slave) == (b.function, b.address, b.count, b.fixed_slave)
}

/// The command with `role` (at a fixed address or not, as `fixed` says)
/// whose request the most of `sensors` send; ties go to the first seen.
fn most_common<'c>(sensors: &[&'c Sensor], role: Role, fixed: bool) -> Option<&'c CommandSpec> {
    let commands: Vec<&CommandSpec> = sensors
        .iter()
        .filter_map(|s| s.commands.iter().find(|c| c.role == Some(role) && c.fixed_slave.is_some() == fixed))
        .collect();
    let sharing = |c: &CommandSpec| commands.iter().filter(|o| same_request(o, c)).count();
    commands.iter().copied().fold(None, |best: Option<&CommandSpec>, c| match best {
        Some(b) if sharing(b) >= sharing(c) => Some(b),
        _ => Some(c),
    })
}

/// Every distinct request with `role` among `sensors`, the one most send first.
fn distinct<'c>(sensors: &[&'c Sensor], role: Role) -> Vec<&'c CommandSpec> {
    let commands: Vec<&CommandSpec> = sensors
        .iter()
        .filter_map(|s| s.commands.iter().find(|c| c.role == Some(role) && c.fixed_slave.is_none()))
        .collect();
    let mut out: Vec<&CommandSpec> = Vec::new();
    for c in &commands {
        if !out.iter().any(|o| same_request(o, c)) {
            out.push(c);
        }
    }
    out.sort_by_key(|c| std::cmp::Reverse(commands.iter().filter(|o| same_request(o, c)).count()));
    out
}

impl<'c> Probes<'c> {
    /// The frames of `sensors`: one sensor's own, or those most of them share.
    /// `None` when none has a serial-number read at its own address.
    pub fn of(sensors: &[&'c Sensor]) -> Option<Self> {
        Some(Self {
            identify: most_common(sensors, Role::SerialNumber, false)?,
            version: most_common(sensors, Role::Version, false),
            starts: distinct(sensors, Role::StartMeasurement),
            wildcard: most_common(sensors, Role::GetSlaveAddress, true),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::Catalog;

    #[test]
    fn picks_the_request_most_sensors_send_for_each_role() {
        let catalog = Catalog::load(&[]).unwrap();
        let sensors: Vec<&Sensor> = catalog.entries().iter().map(|e| e.sensor.as_ref()).collect();
        let probes = Probes::of(&sensors).unwrap();
        let count = |role: Role, chosen: &CommandSpec| {
            sensors.iter().filter_map(|s| s.command_with_role(role)).filter(|c| same_request(c, chosen)).count()
        };
        // Every start request once, the most common first.
        for (i, start) in probes.starts.iter().enumerate() {
            assert!(probes.starts[i + 1..].iter().all(|o| !same_request(o, start)));
            assert!(
                probes.starts[i + 1..]
                    .iter()
                    .all(|o| count(Role::StartMeasurement, start) >= count(Role::StartMeasurement, o))
            );
        }
        let every_start = sensors.iter().filter_map(|s| s.command_with_role(Role::StartMeasurement));
        assert!(
            every_start.clone().all(|c| c.fixed_slave.is_some() || probes.starts.iter().any(|o| same_request(o, c)))
        );
        for (role, chosen) in [
            (Role::SerialNumber, Some(probes.identify)),
            (Role::Version, probes.version),
            (Role::GetSlaveAddress, probes.wildcard),
        ] {
            let Some(chosen) = chosen else { continue };
            assert_eq!(chosen.role, Some(role));
            for s in &sensors {
                if let Some(other) = s.command_with_role(role) {
                    assert!(count(role, chosen) >= count(role, other), "{role:?}: {} is rarer", chosen.name);
                }
            }
        }
        assert!(probes.identify.fixed_slave.is_none() && probes.identify.is_read());
        assert!(probes.wildcard.is_none_or(|w| w.fixed_slave.is_some()));
        // One sensor: its own commands.
        for s in &sensors {
            if let Some(own) = Probes::of(&[s]) {
                assert_eq!(
                    Some(own.identify.name.as_str()),
                    s.command_with_role(Role::SerialNumber).map(|c| c.name.as_str())
                );
            }
        }
    }
}

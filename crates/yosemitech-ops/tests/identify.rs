//! Every sensor of the spec, simulated alone on an in-memory line, is
//! identified as itself, or, where sensors share its serial-number read and
//! model code and no read tells them apart, left unidentified among
//! candidates that include it, with the reason; its firmware names the
//! manual that covers it; an address nobody answers is `None`.

use std::time::Duration;

use yosemitech_ops::identify::{can_tell_apart, manual_for};
use yosemitech_ops::{Identifier, common_serial};
use yosemitech_rtu::{Client, ClientConfig, ResponderTransport};
use yosemitech_sim::Simulator;
use yosemitech_spec::{Role, Sensor};
use yosemitech_tests::rtu::unpaced_config;

fn config() -> ClientConfig {
    unpaced_config(Duration::from_millis(50))
}

/// The loaded sensors `scan` cannot tell from `sensor` by its serial number:
/// those that send the same request and declare the model code it sends.
fn twins<'s>(loaded: &[&'s Sensor], sensor: &Sensor) -> Vec<&'s Sensor> {
    let (Some(own), Some(code)) = (sensor.command_with_role(Role::SerialNumber), sensor.model_code.as_deref()) else {
        return Vec::new();
    };
    loaded
        .iter()
        .copied()
        .filter(|other| {
            other.declares_model_code(code)
                && other.command_with_role(Role::SerialNumber).is_some_and(|c| {
                    (c.function, c.address, c.count, c.fixed_slave)
                        == (own.function, own.address, own.count, own.fixed_slave)
                })
        })
        .collect()
}

#[test]
fn each_simulated_sensor_is_identified_as_itself_or_among_its_twins() {
    let loaded: Vec<&Sensor> = yosemitech_tests::spec().sensors.iter().collect();
    let identifier = Identifier::new(loaded.iter().copied());
    assert!(!identifier.requests().is_empty(), "the spec has serial-number reads");
    let mut identified = 0;
    for sensor in &loaded {
        let Some(sn_read) = sensor.command_with_role(Role::SerialNumber) else { continue };
        if sn_read.fixed_slave.is_some() {
            continue;
        }
        let address = sensor.default_address;
        let mut client = Client::with_config(
            ResponderTransport::new(Simulator::new((*sensor).clone()).with_address(address)),
            config(),
        );
        let found =
            identifier.identify(&mut client, address).unwrap().unwrap_or_else(|| panic!("{} answers", sensor.name));
        assert_eq!(found.address, address);
        assert!(
            found.candidates.iter().any(|c| c.name == sensor.name),
            "{}: among {:?}",
            sensor.name,
            found.candidates
        );
        let twins = twins(&loaded, sensor);
        match found.identified {
            Some(named) => {
                assert_eq!(named.name, sensor.name, "{} identified as another", sensor.name);
                identified += 1;
            }
            None => {
                assert!(found.reason.is_some(), "{}: not identified, and why", sensor.name);
                assert!(
                    (twins.len() > 1 && !can_tell_apart(&twins)) || sensor.model_code.is_none(),
                    "{}: identifiable but not identified: {:?}",
                    sensor.name,
                    found.reason
                );
            }
        }
        if let (Some(software), Some(named)) = (found.software, found.identified) {
            assert_eq!(
                found.manual.map(|m| &m.title),
                manual_for(named, software).map(|m| &m.title),
                "{}",
                sensor.name
            );
        }

        // Nobody at the next address.
        let other = if address == 247 { 1 } else { address + 1 };
        assert!(identifier.identify(&mut client, other).unwrap().is_none(), "{}: silence at {other}", sensor.name);
    }
    assert!(identified > 0, "some sensor of the spec is identified alone");
}

#[test]
fn the_common_serial_settings_are_those_of_most_sensors() {
    let sensors = &yosemitech_tests::spec().sensors;
    let common = common_serial(sensors);
    let count = |settings| sensors.iter().filter(|s| s.serial == settings).count();
    assert!(sensors.iter().all(|s| count(s.serial) <= count(common)));
    assert_eq!(common_serial([]), yosemitech_rtu::LineSettings::default());
}

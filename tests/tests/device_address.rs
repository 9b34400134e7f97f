//! The generated `Device::set_slave_address` of every sensor of the spec
//! with a `set_slave_address` write and a `serial_number` read (both sent to
//! the probe's own address), against the simulator: the probe moves, the
//! handle follows, and a refused change writes nothing.

use std::time::Duration;

use yosemitech::procedures::address::AddressChangeError;
use yosemitech::{Client, ClientConfig, ResponderTransport, RetryPolicy};
use yosemitech_sim::Simulator;
use yosemitech_spec::{Role, Sensor};
use yosemitech_tests::devices::change_address_through_device;
use yosemitech_tests::sim::free_address;
use yosemitech_tests::spec;

fn fast() -> ClientConfig {
    ClientConfig {
        timeout: Duration::from_millis(50),
        inter_frame_delay: Some(Duration::ZERO),
        retry: RetryPolicy::NONE,
        ..ClientConfig::default()
    }
}

/// Whether `sensor` has a command with `role` sent to its own address.
fn has_own(sensor: &Sensor, role: Role) -> bool {
    sensor.commands.iter().any(|c| c.role == Some(role) && c.fixed_slave.is_none())
}

fn with_both_roles(sensor: &Sensor) -> bool {
    has_own(sensor, Role::SetSlaveAddress) && has_own(sensor, Role::SerialNumber)
}

#[test]
fn every_device_with_both_roles_moves_its_probe_and_follows_it() {
    let mut moved = 0;
    for sensor in &spec().sensors {
        // To an address the probe accepts, from another one.
        let to = free_address(sensor, &[]).unwrap_or(sensor.default_address);
        let from = free_address(sensor, &[to]).unwrap_or(if to == 1 { 2 } else { 1 });
        let sim = Simulator::new(sensor.clone()).with_address(from);
        let mut client = Client::with_config(ResponderTransport::new(sim), fast());
        let result = change_address_through_device(&sensor.name, &mut client, from, to);
        let sim = client.into_transport().into_responder();
        if !with_both_roles(sensor) {
            assert!(result.is_none(), "{}: a set_slave_address without the roles it needs", sensor.name);
            continue;
        }
        let result = result.unwrap_or_else(|| panic!("{}: the generated Device has no set_slave_address", sensor.name));
        assert_eq!(
            result.unwrap_or_else(|e| panic!("{}: {e}", sensor.name)),
            to,
            "{}: the handle follows",
            sensor.name
        );
        assert_eq!(sim.address(), to, "{}: the probe answers at the new address", sensor.name);
        assert_eq!(sim.stats().writes, 1, "{}: one address write", sensor.name);
        moved += 1;
    }
    assert!(moved > 0, "the spec has sensors with both roles");
    yosemitech_tests::report!(
        "{moved} generated Device handles moved their simulated probe to an address of its sensor's; {} sensors \
         without both roles have no such method",
        spec().sensors.len() - moved
    );
}

#[test]
fn a_refused_change_writes_nothing_and_the_handle_stays() {
    for sensor in spec().sensors.iter().filter(|s| with_both_roles(s)) {
        for (from, to, refused) in [(5u8, 5u8, "same"), (5, 0, "invalid"), (5, 248, "invalid"), (9, 20, "absent")] {
            let sim = Simulator::new(sensor.clone()).with_address(5);
            let mut client = Client::with_config(ResponderTransport::new(sim), fast());
            let result = change_address_through_device(&sensor.name, &mut client, from, to);
            let sim = client.into_transport().into_responder();
            let context = format!("{}: {from} -> {to}: {result:?}", sensor.name);
            let ok = match (refused, result) {
                ("same", Some(Err(AddressChangeError::SameAddress(a)))) => a == to,
                ("invalid", Some(Err(AddressChangeError::InvalidAddress(a)))) => a == to,
                ("absent", Some(Err(AddressChangeError::NotFound { address, .. }))) => address == from,
                _ => false,
            };
            assert!(ok, "{context}: refused as {refused}");
            assert_eq!(sim.address(), 5, "{context}: the probe stays");
            assert_eq!(sim.stats().writes, 0, "{context}: nothing written");
        }
    }
}

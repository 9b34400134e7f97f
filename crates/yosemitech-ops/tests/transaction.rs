//! One request of a spec command against a simulated probe: every read of
//! every sensor returns the values the simulator holds; a request that
//! cannot be built, and a probe that stays silent, are told apart.

use std::collections::BTreeMap;
use std::time::Duration;

use yosemitech_ops::{TransactionError, call, target};
use yosemitech_rtu::{Client, ClientConfig, Error as RtuError, ResponderTransport};
use yosemitech_sim::Simulator;
use yosemitech_tests::rtu::unpaced_config;

fn config() -> ClientConfig {
    unpaced_config(Duration::from_millis(50))
}

#[test]
fn every_read_returns_the_values_the_probe_holds() {
    let mut reads = 0;
    for sensor in &yosemitech_tests::spec().sensors {
        let address = sensor.default_address;
        let sim = Simulator::new(sensor.clone()).with_address(address);
        let mut client = Client::with_config(ResponderTransport::new(sim), config());
        for command in sensor.commands.iter().filter(|c| c.is_read() && !c.trigger) {
            let values = call(&mut client, command, target(command, address), &BTreeMap::new())
                .unwrap_or_else(|e| panic!("{}.{}: {e}", sensor.name, command.name));
            let held = client.transport().responder().values(&command.name).unwrap();
            // Compared as printed, so that a NaN the probe holds equals itself.
            assert_eq!(format!("{values:?}"), format!("{held:?}"), "{}.{}", sensor.name, command.name);
            reads += 1;
        }
    }
    assert!(reads > 0, "the spec has reads");
}

#[test]
fn a_request_that_cannot_be_built_and_a_silent_probe_are_told_apart() {
    let spec = yosemitech_tests::spec();
    let mut client = Client::with_config(ResponderTransport::new(|_: &[u8], _: &mut Vec<u8>| {}), config());
    // A write without its values: refused before anything is sent.
    for command in
        spec.sensors.iter().flat_map(|s| &s.commands).filter(|c| !c.is_read() && c.named_fields().next().is_some())
    {
        match call(&mut client, command, 1, &BTreeMap::new()) {
            Err(e @ TransactionError::Request { .. }) => {
                assert_eq!(e.command(), command.name);
                assert!(e.bus_error().is_none());
            }
            other => panic!("{}: {other:?}", command.name),
        }
    }
    // Nobody answers: the client's timeout, as the bus's error.
    let read = spec.sensors.iter().flat_map(|s| &s.commands).find(|c| c.is_read() && c.fixed_slave.is_none()).unwrap();
    match call(&mut client, read, 1, &BTreeMap::new()) {
        Err(e @ TransactionError::Bus { .. }) => {
            assert!(matches!(e.bus_error(), Some(RtuError::Timeout { received: 0, .. })), "{e}");
            assert_eq!(e.command(), read.name);
        }
        other => panic!("{}: {other:?}", read.name),
    }
}

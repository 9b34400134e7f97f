//! The simulator against the manuals: every example request yields exactly
//! the example's true reply frame.

mod sim_common;

use sim_common::{exchange, spec};
use yosemitech_rtu::Hex;
use yosemitech_sim::Simulator;
use yosemitech_spec::Value;

/// The address a fresh simulator needs to answer `example` as printed: the
/// request's slave, or for a fixed-slave command (get_slave_id at 0xFF) the
/// `slave_address` the example reports.
fn address_for(command: &yosemitech_spec::Command, example: &yosemitech_spec::Example) -> u8 {
    if command.fixed_slave.is_some() {
        match example.values.get("slave_address") {
            Some(Value::Int(a)) => u8::try_from(*a).expect("an address"),
            other => panic!("{}: a fixed-slave example states its slave_address, got {other:?}", command.name),
        }
    } else {
        example.slave()
    }
}

#[test]
fn every_example_request_yields_the_true_reply() {
    let spec = spec();
    let mut checked = 0;
    for sensor in &spec.sensors {
        for command in &sensor.commands {
            for example in &command.examples {
                let Some((true_request, true_response)) = example.true_pair() else { continue };
                let mut sim = Simulator::new(sensor.clone()).with_address(address_for(command, example));
                let reply = exchange(&mut sim, true_request);
                if command.trigger {
                    // A trigger's reply carries no value: the simulator answers
                    // the manuals' form, which the command accepts like any other.
                    assert!(command.decode_response(example.slave(), &reply).is_ok(), "{}", Hex(&reply));
                    checked += 1;
                    continue;
                }
                assert_eq!(
                    reply,
                    true_response,
                    "{}.{} (figures {:?}): sent {}, got {}, manual (true) {}",
                    sensor.name,
                    command.name,
                    example.figures,
                    Hex(true_request),
                    Hex(&reply),
                    Hex(true_response)
                );
                checked += 1;
            }
        }
    }
    let complete = spec.sensors.iter().flat_map(|s| &s.commands).flat_map(|c| &c.examples).filter(|e| e.true_pair().is_some()).count();
    assert_eq!(checked, complete, "every example with both frames complete");
    assert!(checked > 0);
    yosemitech_tests::report!("{checked} example exchanges match the manuals");
}

#[test]
fn examples_replayed_in_order_on_one_device_per_sensor() {
    // One device per sensor, examples in spec order, as a bench session
    // would send them: the address follows set_slave_id, so each request is
    // re-addressed to the device's current address; reads of state that an
    // earlier example changed (calibration status after one point) are the
    // only allowed differences, and they are checked by name.
    let spec = spec();
    for sensor in &spec.sensors {
        let mut sim = Simulator::new(sensor.clone());
        for command in &sensor.commands {
            for example in &command.examples {
                let Some((true_request, true_response)) = example.true_pair() else { continue };
                let mut request = true_request.to_vec();
                if command.fixed_slave.is_none() {
                    request[0] = sim.address();
                    let n = request.len() - 2;
                    let crc = yosemitech_rtu::crc16(&request[..n]).to_le_bytes();
                    request[n..].copy_from_slice(&crc);
                }
                let before = sim.address();
                let reply = exchange(&mut sim, &request);
                assert!(!reply.is_empty(), "{}.{}: no reply", sensor.name, command.name);
                assert_eq!(reply[0], command.fixed_slave.unwrap_or(before), "reply from the old address");
                assert_eq!(reply[1], true_response[1], "{}.{}: {}", sensor.name, command.name, Hex(&reply));
                if command.name == "get_slave_id" {
                    assert_eq!(reply[3], sim.address(), "get_slave_id reports the current address");
                }
            }
        }
        assert_eq!(sim.address(), 20, "{}: set_slave_id's example moved the device to 20", sensor.name);
        assert_eq!(sim.stats().exceptions, 0, "{}", sensor.name);
    }
}

#[test]
fn byte_count_quirk_reproduces_the_printed_frame() {
    // pH Fig 54 prints byte count 0x0C over 24 data bytes, with a CRC over
    // that count: the firmware the manual was printed from. The quirk option
    // reproduces it exactly.
    let spec = spec();
    let sensor = spec.sensor("ph_orp").unwrap();
    let command = sensor.command("get_ph_electrode_coefficients").unwrap();
    let example = &command.examples[0];
    let mut sim = Simulator::new(sensor.clone());
    sim.set_byte_count_quirk(true);
    let (request, reply) = example.true_pair().unwrap();
    let printed = example.response.as_ref().and_then(|f| f.complete.clone()).unwrap();
    assert_eq!(exchange(&mut sim, request), printed, "the printed (quirky) frame");
    sim.set_byte_count_quirk(false);
    assert_eq!(exchange(&mut sim, request), reply);
}

//! The simulator against the manuals: every example request yields exactly
//! the example's true reply frame (with the serial number as printed), and
//! the serial number as a real probe sends it differs from the manual's only
//! by the model code.

use yosemitech_tests::sim as sim_common;

use sim_common::{exchange, reseeded_later, spec};
use yosemitech_rtu::Hex;
use yosemitech_sim::{SerialNumberPolicy, Simulator};
use yosemitech_spec::{CommandSpec, Example, FieldKind, Role, Sensor, Value};

/// The address a fresh simulator needs to answer `example` as printed: the
/// request's slave, or for a fixed-slave command (get_slave_id at 0xFF) the
/// address the example reports (its first named field).
fn address_for(sensor: &Sensor, command: &CommandSpec, example: &Example) -> u8 {
    if command.fixed_slave.is_some() {
        let field = command.named_fields().next().map(|f| f.display_name());
        match field.and_then(|f| example.values.get(f)) {
            Some(Value::Int(a)) => u8::try_from(*a).unwrap_or(sensor.default_address),
            _ => sensor.default_address,
        }
    } else {
        example.slave()
    }
}

/// Loads the reply data of a read's `example` into `sim` when it is not the
/// example the simulator serves from power-on (the last one with a reply,
/// unless a later read's example covers a register of it): two examples of
/// one read, or of two reads sharing registers, may show two states of the
/// probe.
fn load_state(sim: &mut Simulator, sensor: &Sensor, command: &CommandSpec, example: &Example) -> bool {
    let served = command.examples.iter().rev().find(|e| e.true_response().is_some());
    let Some(reply) = example.true_response() else { return false };
    let is_served = served.is_some_and(|s| std::ptr::eq(s, example)) && !reseeded_later(sensor, command);
    if !command.is_read() || command.trigger || is_served {
        return false;
    }
    let data = reply.get(3..reply.len().saturating_sub(2)).unwrap_or_default();
    if data.len() != 2 * usize::from(command.count) {
        return false;
    }
    sim.registers_mut().write_bytes(command.address, 0, data);
    true
}

/// A fresh simulator of `sensor` that answers exactly as the manual prints.
fn as_printed(sensor: &Sensor) -> Simulator {
    let mut sim = Simulator::new(sensor.clone());
    sim.set_serial_number_policy(SerialNumberPolicy::AsPrinted);
    sim
}

#[test]
fn every_example_request_yields_the_true_reply() {
    let spec = spec();
    let (mut checked, mut loaded) = (0, 0);
    for sensor in &spec.sensors {
        for command in &sensor.commands {
            for example in &command.examples {
                let Some((true_request, true_response)) = example.true_pair() else { continue };
                let mut sim = as_printed(sensor).with_address(address_for(sensor, command, example));
                loaded += usize::from(load_state(&mut sim, sensor, command, example));
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
    let complete = spec
        .sensors
        .iter()
        .flat_map(|s| &s.commands)
        .flat_map(|c| &c.examples)
        .filter(|e| e.true_pair().is_some())
        .count();
    assert_eq!(checked, complete, "every example with both frames complete");
    assert!(checked > 0);
    yosemitech_tests::report!(
        "{checked} example exchanges match the manuals ({loaded} with another example's state loaded first)"
    );
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
        // Where set_slave_id's examples leave the device.
        let mut expected_address = sim.address();
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
                if command.role == Some(Role::GetSlaveAddress) {
                    // The address field, wherever and however wide the command has it.
                    let values = command.decode_response(reply[0], &reply).unwrap();
                    let field = command.named_fields().next().map(|f| f.display_name());
                    let reported = values.iter().find(|(n, _)| Some(n.as_str()) == field).map(|(_, v)| v);
                    assert_eq!(
                        reported,
                        Some(&Value::Int(i64::from(sim.address()))),
                        "{}.{}: the address read reports the current address",
                        sensor.name,
                        command.name
                    );
                }
                if command.role == Some(Role::SetSlaveAddress) {
                    let field = command.named_fields().next().and_then(|f| f.name.as_deref()).unwrap();
                    if let Some(Value::Int(a)) = example.values.get(field) {
                        expected_address = u8::try_from(*a).unwrap();
                    }
                }
            }
        }
        assert_eq!(
            sim.address(),
            expected_address,
            "{}: where the address write's examples moved the device",
            sensor.name
        );
        assert_eq!(sim.stats().exceptions, 0, "{}", sensor.name);
        assert_eq!(sim.stats().ignored_unknown, 0, "{}: every example request matches a command", sensor.name);
    }
}

#[test]
fn byte_count_quirk_reproduces_the_printed_frame() {
    // A manual may print a byte count other than 2 * count over the data,
    // with a CRC over that count (pH Fig 54: 0x0C over 24 bytes): the
    // firmware it was printed from. The spec declares it as an extra byte
    // count; the quirk option reproduces every such printed frame exactly.
    let mut checked = 0;
    for sensor in &spec().sensors {
        for command in sensor.commands.iter().filter(|c| !c.extra_byte_counts.is_empty()) {
            for example in &command.examples {
                let Some(printed) = example.response.as_ref().and_then(|f| f.complete.clone()) else { continue };
                let Some((request, reply)) = example.true_pair() else { continue };
                // The quirk sends the first extra count: the frames printed with it.
                if printed.get(2) != command.extra_byte_counts.first() {
                    continue;
                }
                let context = format!("{}.{}", sensor.name, command.name);
                assert_ne!(printed, reply, "{context}: the printed frame carries the quirky count");
                let mut sim = Simulator::new(sensor.clone()).with_address(example.slave());
                // The state the example shows (another example may show another).
                sim.registers_mut().write_bytes(command.address, 0, &reply[3..reply.len() - 2]);
                sim.set_byte_count_quirk(true);
                assert_eq!(exchange(&mut sim, request), printed, "{context}: the printed (quirky) frame");
                sim.set_byte_count_quirk(false);
                assert_eq!(exchange(&mut sim, request), reply, "{context}");
                checked += 1;
            }
        }
    }
    assert!(checked > 0, "the spec declares a byte-count quirk with a printed example");
}

#[test]
fn the_serial_number_carries_the_model_code_and_differs_from_the_manual_only_there() {
    // Real probes send the model code in the byte before the serial number
    // (0x09 on a Y520 whose serial number is YL09...), where the manuals
    // print 0x00, and their own code in the serial number, where several
    // manuals print a sibling's.
    let spec = spec();
    let (mut checked, mut other_states) = (0, 0);
    for sensor in &spec.sensors {
        let Some(command) = sensor.command_with_role(Role::SerialNumber) else { continue };
        let text = command.fields.iter().find(|f| matches!(f.kind, FieldKind::Ascii { .. })).expect("an ascii field");
        let has_byte_before = command.fields.iter().any(|f| f.is_reserved() && f.offset + f.size() == text.offset);
        for example in &command.examples {
            let Some((request, printed)) = example.true_pair() else { continue };
            // The example the simulator holds (two examples may print two
            // serial numbers; it is seeded from one).
            if exchange(&mut as_printed(sensor).with_address(example.slave()), request) != printed {
                other_states += 1;
                continue;
            }
            let mut sim = Simulator::new(sensor.clone()).with_address(example.slave());
            let reply = exchange(&mut sim, request);
            let context = format!(
                "{} (figures {:?}): got {}, manual {}",
                sensor.name,
                example.figures,
                Hex(&reply),
                Hex(printed)
            );
            assert_eq!(reply.len(), printed.len(), "{context}");
            let Some(code) = &sensor.model_code else {
                assert_eq!(reply, printed, "{context}: no model code, the manual's bytes");
                checked += 1;
                continue;
            };
            // Register data starts at byte 3 of a read reply.
            let text_at = 3 + text.offset;
            // The code replaces characters 3-4 of a serial number that has them.
            let in_text = printed.get(text_at..text_at + text.size().min(4)).unwrap_or_default();
            let replaced = in_text.len() == 4 && in_text.iter().all(u8::is_ascii_graphic);
            let mut changed: Vec<usize> = Vec::new();
            if replaced {
                assert_eq!(&reply[text_at + 2..text_at + 4], code.as_bytes(), "{context}: the own model code");
                changed.extend([text_at + 2, text_at + 3]);
            }
            if has_byte_before {
                assert_eq!(reply[text_at - 1], u8::from_str_radix(code, 16).unwrap(), "{context}: the model code byte");
                changed.push(text_at - 1);
            }
            // Everything else but the CRC is the manual's.
            let body = reply.len() - 2;
            for at in (0..body).filter(|at| !changed.contains(at)) {
                assert_eq!(reply[at], printed[at], "{context}: byte {at}");
            }
            let text_of = |frame: &[u8]| {
                let values = command.decode_response(example.slave(), frame).unwrap();
                match values.into_iter().find(|(n, _)| n == text.display_name()).map(|(_, v)| v) {
                    Some(Value::Text(t)) => t,
                    other => panic!("{context}: the serial number decodes to {other:?}"),
                }
            };
            let (sn, manual) = (text_of(&reply), text_of(printed));
            let own = if replaced { format!("{}{code}{}", &manual[..2], &manual[4..]) } else { manual };
            assert_eq!(sn, own, "{context}");
            checked += 1;
        }
    }
    assert!(checked > 0);
    yosemitech_tests::report!(
        "{checked} serial-number replies carry the probe's own model code ({other_states} examples of a serial \
         number the simulator does not hold skipped)"
    );
}

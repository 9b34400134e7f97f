//! The device's tests: registers from the examples, addresses, refusals,
//! unknown requests and the manuals' forms.

use yosemitech_rtu::{codec, crc16};
use yosemitech_spec::FieldKind;
use yosemitech_tests::{spec, with_crc};

use super::frames::prints_empty_reply;
use super::*;
use crate::FrameHandler;
use crate::fault::Rng;

fn exchange(sim: &mut Simulator, request: &[u8]) -> Vec<u8> {
    let mut reply = Vec::new();
    assert_eq!(sim.handle(request, &mut reply), Duration::ZERO);
    reply
}

/// True when the registers of `a` and `b` share a register.
fn overlap(a: &CommandSpec, b: &CommandSpec) -> bool {
    let end = |c: &CommandSpec| u32::from(c.address) + u32::from(c.count);
    u32::from(a.address) < end(b) && u32::from(b.address) < end(a)
}

#[test]
fn starts_from_the_examples_at_the_factory_address() {
    let (mut reads, mut over_writes, mut overridden) = (0, 0, 0);
    for sensor in spec().sensors.clone() {
        let sim = Simulator::new(sensor.clone());
        assert_eq!(sim.address(), sensor.default_address, "{}", sensor.name);
        // A read that shares no register with another read's example
        // reads back its last example, over what write examples wrote
        // (the serial number and the address have rules of their own,
        // below and in the next test).
        for read in sensor.commands.iter().filter(|c| c.is_read() && !c.trigger) {
            if matches!(read.role, Some(Role::SerialNumber | Role::GetSlaveAddress | Role::SetSlaveAddress))
                || sensor
                    .commands
                    .iter()
                    .any(|c| c.is_read() && c.name != read.name && !c.examples.is_empty() && overlap(c, read))
            {
                continue;
            }
            let layout = read.layout();
            let Some(example) = read
                .examples
                .iter()
                .rev()
                .find(|e| e.true_response().is_some_and(|f| layout.decode_response(e.slave(), f).is_ok()))
            else {
                continue;
            };
            for (field, stated) in &example.values {
                let what = format!("{}.{}.{field}", sensor.name, read.name);
                assert_eq!(&sim.get(&read.name, field).unwrap(), stated, "{what}");
            }
            reads += 1;
            over_writes += usize::from(sensor.commands.iter().any(|w| !w.is_read() && overlap(w, read)));
        }
        // The live address wins over what the examples wrote and read.
        for role in [Role::SetSlaveAddress, Role::GetSlaveAddress] {
            let Some(command) = sensor.command_with_role(role) else { continue };
            let field = command.named_fields().next().unwrap().name.clone().unwrap();
            let live = Value::Int(i64::from(sensor.default_address));
            assert_eq!(sim.get(&command.name, &field).unwrap(), live, "{}.{}", sensor.name, command.name);
            overridden += command.examples.iter().filter(|e| e.values.get(&field).is_some_and(|v| *v != live)).count();
        }
    }
    assert!(reads > 0 && over_writes > 0, "no read example to start from ({reads}, {over_writes} over writes)");
    assert!(overridden > 0, "no example states another address than the factory one");
}

#[test]
fn the_address_lives_in_the_slave_address_role_fields_of_every_sensor() {
    for sensor in spec().sensors.clone() {
        let sim = Simulator::new(sensor.clone()).with_address(42);
        for role in [Role::SetSlaveAddress, Role::GetSlaveAddress] {
            let Some(command) = sensor.command_with_role(role) else { continue };
            let field = command.named_fields().next().unwrap();
            let value = sim.get(&command.name, field.name.as_deref().unwrap()).unwrap();
            assert_eq!(value, Value::Int(42), "{}.{}", sensor.name, command.name);
            // In the bytes the field's type gives, where a read finds them.
            let bytes = address_bytes(field, 42).unwrap();
            let registers = sim.registers().read(command.address, command.count);
            assert_eq!(registers[field.offset..field.offset + bytes.len()], bytes, "{}", command.name);
        }
    }
}

#[test]
fn measurement_reads_are_the_uncovered_ones_with_units() {
    // The reads a sensor's procedure takes its measurements from.
    let mut measured = 0;
    for sensor in spec().sensors.clone() {
        for name in sensor.procedure.iter().flat_map(|p| &p.read) {
            assert!(sensor.is_measurement(sensor.command(name).unwrap()), "{}.{name}", sensor.name);
            measured += 1;
        }
    }
    assert!(measured > 0);
    // Reads without a unit (serial numbers, versions) and reads a write
    // covers (calibration blocks, settings) are not measurements; the
    // simulator classifies every command as the spec does.
    let (mut unitless, mut written) = (0, 0);
    for sensor in spec().sensors.clone() {
        let sim = Simulator::new(sensor.clone());
        for read in sensor.commands.iter().filter(|c| c.is_read()) {
            let what = format!("{}.{}", sensor.name, read.name);
            let covered = sensor.commands.iter().any(|w| !w.is_read() && w.count > 0 && overlap(w, read));
            if read.fields.iter().all(|f| f.unit.is_none()) {
                assert!(!sensor.is_measurement(read), "{what}: no unit");
                unitless += 1;
            } else if covered {
                assert!(!sensor.is_measurement(read), "{what}: a write sets it");
                written += 1;
            } else {
                assert!(sensor.is_measurement(read), "{what}: uncovered, with a unit");
            }
        }
        for command in &sensor.commands {
            assert_eq!(sim.is_measurement(&command.name), sensor.is_measurement(command), "{}", command.name);
        }
    }
    assert!(unitless > 0 && written > 0, "both kinds of non-measurement reads are in the spec");
}

/// `frame` with its CRC recomputed over the rest.
fn recrc(frame: &[u8]) -> Vec<u8> {
    with_crc(&frame[..frame.len() - 2])
}

#[test]
fn nan_and_out_of_range_writes_are_refused() {
    let mut fields = 0;
    for sensor in spec().sensors.clone() {
        for write in sensor.commands.iter().filter(|c| !c.is_read()) {
            let Some(request) = write.examples.iter().find_map(|e| e.true_request()) else { continue };
            for field in &write.fields {
                let (FieldKind::F32 { order }, Some((min, max))) = (&field.kind, field.range) else { continue };
                let what = format!("{}.{}.{}", sensor.name, write.name, field.display_name());
                let with = |value: f32| {
                    let mut frame = request.to_vec();
                    let at = 7 + field.offset;
                    frame[at..at + 4].copy_from_slice(&codec::f32_to_wire(*order, value));
                    recrc(&frame)
                };
                let (min, max) = (min as f32, max as f32);
                for bad in [f32::NAN, min - 0.5, max + 0.5, f32::INFINITY, f32::NEG_INFINITY] {
                    let mut sim = Simulator::new(sensor.clone()).with_address(request[0]);
                    let reply = exchange(&mut sim, &with(bad));
                    assert_eq!(reply, with_crc(&[request[0], 0x90, 0x03]), "{what} = {bad}");
                }
                // The bounds themselves are fine.
                for ok in [min, max] {
                    let mut sim = Simulator::new(sensor.clone()).with_address(request[0]);
                    assert_eq!(exchange(&mut sim, &with(ok)).get(1), Some(&0x10), "{what} = {ok}");
                }
                fields += 1;
            }
        }
    }
    assert!(fields > 0, "no write of the spec has a float field with a range");
}

#[test]
fn arbitrary_bytes_never_panic() {
    for sensor in &spec().sensors {
        for policy in [UnknownRequestPolicy::Silent, UnknownRequestPolicy::Exception] {
            arbitrary_bytes_never_panic_with(sensor, policy);
        }
    }
}

fn arbitrary_bytes_never_panic_with(sensor: &Sensor, policy: UnknownRequestPolicy) {
    let mut sim = Simulator::new(sensor.clone()).with_faults(FaultConfig::uniform(5, 0.5));
    sim.set_unknown_request_policy(policy);
    let mut rng = Rng::new(77);
    for _ in 0..20_000 {
        let len = rng.below(40) as usize;
        let mut frame: Vec<u8> = (0..len).map(|_| rng.byte()).collect();
        if rng.chance(0.5) && frame.len() >= 4 {
            // Mostly valid headers for this device, valid CRC.
            frame[0] = if rng.chance(0.8) { sim.address() } else { 0 };
            frame[1] = [0x03, 0x10, 0x04][rng.below(3) as usize];
            let n = frame.len() - 2;
            let crc = crc16(&frame[..n]).to_le_bytes();
            frame[n..].copy_from_slice(&crc);
        }
        let mut reply = Vec::new();
        sim.handle(&frame, &mut reply);
        assert!(reply.len() <= yosemitech_rtu::frame::MAX_ADU + 4, "{}", sensor.name);
    }
    let stats = sim.stats();
    match policy {
        UnknownRequestPolicy::Silent => {
            assert!(stats.ignored_unknown > 0 && stats.exceptions == 0, "{}", sensor.name)
        }
        UnknownRequestPolicy::Exception => {
            assert!(stats.exceptions > 0 && stats.ignored_unknown == 0, "{}", sensor.name)
        }
    }
}

/// Requests to `sensor` that match none of its commands: a function it
/// does not serve (read input registers), a register no read starts at,
/// and a read's register with a count no read of it has; with the
/// exception code each earns.
fn unknown_requests(sensor: &Sensor, slave: u8) -> [(Vec<u8>, u8); 3] {
    assert!(sensor.commands.iter().all(|c| c.function.code() != 0x04), "{} serves function 0x04", sensor.name);
    let reads: Vec<&CommandSpec> = sensor.commands.iter().filter(|c| c.is_read()).collect();
    let read = reads.iter().find(|c| c.fixed_slave.is_none()).expect("a read to the unit's own address");
    let free =
        (1..).map(|k| read.address.wrapping_sub(k * 0x100)).find(|a| reads.iter().all(|c| c.address != *a)).unwrap();
    let other_count = (read.count + 1..).find(|n| reads.iter().all(|c| c.address != read.address || c.count != *n));
    let frame = |function: u8, address: u16, count: u16| {
        let [a, b] = address.to_be_bytes();
        let [c, d] = count.to_be_bytes();
        with_crc(&[slave, function, a, b, c, d])
    };
    [
        (frame(0x04, read.address, read.count), 0x01),
        (frame(0x03, free, read.count), 0x02),
        (frame(0x03, read.address, other_count.unwrap()), 0x03),
    ]
}

#[test]
fn unknown_requests_are_silent_unless_exceptions_are_asked_for() {
    for sensor in spec().sensors.clone() {
        let mut sim = Simulator::new(sensor.clone());
        let unknown = unknown_requests(&sensor, sim.address());
        assert_eq!(sim.unknown_request_policy(), UnknownRequestPolicy::Silent);
        for (request, _) in &unknown {
            assert!(exchange(&mut sim, request).is_empty(), "{}", sensor.name);
        }
        assert_eq!(sim.stats().ignored_unknown, unknown.len() as u64);
        assert_eq!((sim.stats().replies, sim.stats().exceptions), (0, 0));
        assert_eq!(sim.faults().replies(), 0, "no reply, no fault drawn");
        sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
        for (request, code) in &unknown {
            let reply = exchange(&mut sim, request);
            assert_eq!(reply, with_crc(&[request[0], request[1] | 0x80, *code]), "{}", sensor.name);
        }
        assert_eq!(sim.stats().exceptions, unknown.len() as u64);
    }
}

#[test]
fn the_serial_number_carries_the_model_code_unless_printed_is_asked_for() {
    let (mut sensors, mut siblings, mut code_bytes, mut as_printed) = (0, 0, 0, 0);
    for sensor in spec().sensors.clone() {
        let (Some(command), Some(printed), Some(code)) = (
            sensor.command_with_role(Role::SerialNumber).cloned(),
            sensor.example_serial_number(),
            sensor.model_code.clone(),
        ) else {
            continue;
        };
        let what = format!("{}.{}", sensor.name, command.name);
        let text = command.fields.iter().find(|f| matches!(f.kind, FieldKind::Ascii { .. })).unwrap();
        let name = text.name.as_deref().unwrap();
        let mut sim = Simulator::new(sensor.clone());
        let own = format!("{}{code}{}", &printed[..2], &printed[4..]);
        siblings += usize::from(printed[2..4] != code);
        assert_eq!(sim.serial_number_policy(), SerialNumberPolicy::ModelCode);
        assert_eq!(sim.get(&command.name, name).unwrap(), Value::Text(own), "{what}");
        let request = command.encode_request(sim.address(), &BTreeMap::new()).unwrap();
        let reply = exchange(&mut sim, &request);
        let reserved_before =
            command.fields.iter().any(|f| f.is_reserved() && text.offset > 0 && f.offset + f.size() == text.offset);
        if reserved_before {
            let byte = 3 + text.offset - 1;
            assert_eq!(reply[byte], u8::from_str_radix(&code, 16).unwrap(), "{what}: the byte before the text");
            code_bytes += 1;
        }
        // As printed: the manual's reply, byte for byte.
        sim.set_serial_number_policy(SerialNumberPolicy::AsPrinted);
        assert_eq!(sim.get(&command.name, name).unwrap(), Value::Text(printed.clone()), "{what}");
        let manual = command
            .examples
            .iter()
            .find(|e| e.slave() == sim.address() && e.values.get(name) == Some(&Value::Text(printed.clone())))
            .and_then(|e| e.true_response());
        if let Some(manual) = manual {
            assert_eq!(exchange(&mut sim, &request), manual, "{what}");
            as_printed += 1;
        }
        sensors += 1;
    }
    assert!(sensors > 0 && code_bytes > 0, "no serial number with a model code");
    assert!(siblings > 0, "no manual prints a sibling's serial number");
    assert!(as_printed > 0, "no serial number reply compared with the manual's");
}

#[test]
fn trigger_reads_are_answered_in_the_manuals_form() {
    let mut stops = 0;
    for sensor in spec().sensors.clone() {
        let Some(stop) = sensor.command_with_role(Role::StopMeasurement).filter(|c| c.is_read()).cloned() else {
            continue;
        };
        let mut sim = Simulator::new(sensor.clone()).with_manual_clock();
        if sim.measurement_state() != MeasurementState::Measuring {
            let start = sensor.command_with_role(Role::StartMeasurement).unwrap();
            let request = start.encode_request(sim.address(), &BTreeMap::new()).unwrap();
            exchange(&mut sim, &request);
            let warm_up = sensor.procedure.as_ref().map_or(0, |p| p.warm_up_ms);
            sim.advance(Duration::from_millis(u64::from(warm_up)));
        }
        assert_eq!(sim.measurement_state(), MeasurementState::Measuring, "{}", sensor.name);
        let address = sim.address();
        let reply = exchange(&mut sim, &stop.encode_request(address, &BTreeMap::new()).unwrap());
        let long = yosemitech_rtu::Frame::fill(|b| stop.layout().encode_response(address, &[], b)).unwrap();
        if prints_empty_reply(&stop) {
            assert_eq!(reply, with_crc(&[address, 0x03, 0]), "{}: the printed short form", stop.name);
        } else {
            assert_eq!(reply, long.as_bytes(), "{}: byte count 0 and the meaningless registers", stop.name);
        }
        // Every byte the manual prints of the reply (a spec may print none).
        let printed: Vec<_> = stop.examples.iter().filter_map(|e| e.response.as_ref()).collect();
        for frame in printed {
            for (i, got) in reply.iter().enumerate() {
                assert!(frame.byte(i).is_none_or(|want| want == *got), "{}: byte {i}", stop.name);
            }
        }
        assert_eq!(sim.measurement_state(), MeasurementState::Idle);
        assert_eq!(sim.stats().exceptions, 0);
        stops += 1;
    }
    yosemitech_tests::report!(
        "trigger-read stops answered in the printed form: {stops} sensors (0: the spec has none)"
    );
}

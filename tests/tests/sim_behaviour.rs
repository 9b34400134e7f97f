//! The simulator's device behaviour: state, addressing, exceptions,
//! calibration, measurement trigger, the bus.

use yosemitech_tests::sim as sim_common;

use std::collections::BTreeMap;
use std::time::Duration;

use sim_common::{
    client, command, example_reading, exception, exchange, f32_bytes, first_field, float_read,
    float_write_with_readback, free_address, is_f32, is_float_read, measurement_float_read, request, same,
    seeded_from_example, spec, with_crc, with_role,
};
use yosemitech_rtu::{Error, Function, ResponderTransport};
use yosemitech_sim::{Bus, FrameHandler, MeasurementState, Simulator, UnknownRequestPolicy, Variation, WarmUpPolicy};
use yosemitech_spec::{CommandSpec, Role, Sensor, Value};

fn f(v: f32) -> Value {
    Value::Float(v)
}

#[test]
fn writes_are_read_back() {
    // Every float write the spec reads back at the same registers, both directions.
    let (mut checked, mut from_examples) = (0, 0);
    for sensor in &spec().sensors {
        let Some((set, get)) = float_write_with_readback(sensor) else { continue };
        let slave = sensor.default_address;
        let mut sim = Simulator::new(sensor.clone());
        // Before any write: the manual's example, where the simulator is seeded from it.
        if let Some(reading) = example_reading(&get).filter(|_| seeded_from_example(sensor, &get)) {
            from_examples += 1;
            assert!(
                same(&sim.values(&get.name).unwrap(), &reading),
                "{}.{}: the manual's example",
                sensor.name,
                get.name
            );
        }
        let written: Vec<(String, Value)> = set
            .fields
            .iter()
            .enumerate()
            .map(|(i, field)| (field.name.clone().unwrap(), f(if i % 2 == 0 { 1.25 } else { -0.5 })))
            .collect();
        let values: Vec<(&str, Value)> = written.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
        let write = request(&set, slave, &values);
        assert_eq!(exchange(&mut sim, &write), set.encode_response(slave, &Default::default()).unwrap(), "echo");
        let reply = exchange(&mut sim, &request(&get, slave, &[]));
        let values = get.decode_response(slave, &reply).unwrap();
        assert!(same(&values, &written), "{}.{}: {values:?}", sensor.name, get.name);
        assert_eq!(sim.stats().writes, 1);
        assert_eq!(sim.stats().reads, 1);
        checked += 1;
    }
    yosemitech_tests::report!(
        "writes read back: {checked} float writes ({from_examples} first read as their manual's example)"
    );
    assert!(checked > 0, "the spec has a float write read back");
}

#[test]
fn readings_set_by_name_are_served() {
    let (probe, get) = float_read(spec());
    let (slave, name) = (probe.default_address, first_field(&get));
    let mut sim = Simulator::new(probe.clone());
    sim.set(&get.name, &name, f(7.0)).unwrap();
    let reply = exchange(&mut sim, &request(&get, slave, &[]));
    let mut expected = vec![slave, 0x03, 0x04];
    expected.extend_from_slice(&f32_bytes(&get.fields[0], 7.0));
    assert_eq!(reply, with_crc(&expected));
    let with_field: Vec<&CommandSpec> =
        probe.commands.iter().filter(|c| c.is_read() && c.field(&name).is_some()).collect();
    assert_eq!(sim.set_everywhere(&name, f(8.5)).unwrap(), with_field.len());
    for read in &with_field {
        assert_eq!(sim.get(&read.name, &name).unwrap(), f(8.5), "{}", read.name);
    }
    assert!(sim.set(&get.name, "nope", f(1.0)).is_err());
    assert!(sim.set("nope", &name, f(1.0)).is_err());
    // A write field's range is enforced.
    if let Some((write, field, max)) = probe
        .commands
        .iter()
        .filter(|c| !c.is_read())
        .find_map(|c| c.fields.iter().find(|fl| is_f32(fl)).and_then(|fl| Some((c, fl.name.clone()?, fl.range?.1))))
    {
        assert!(sim.set(&write.name, &field, f(max as f32 + 1.0)).is_err(), "outside the write field's range");
    }
    // A read's range is the measuring range, which a probe may leave: a client test may set it.
    let (_, max) = get.fields[0].range.unwrap_or((0.0, 14.0));
    sim.set(&get.name, &name, f(max as f32 + 5.0)).unwrap();
    assert_eq!(sim.get(&get.name, &name).unwrap(), f(max as f32 + 5.0));
    // The simulator classifies the read as the spec does (a read that no write covers, with a unit).
    assert_eq!(sim.is_measurement(&get.name), probe.is_measurement(&get), "{}", get.name);
    if let Some((_, readback)) = float_write_with_readback(&probe) {
        assert!(!sim.is_measurement(&readback.name), "{}", readback.name);
    }
    if let Some(sn) = probe.command_with_role(Role::SerialNumber) {
        assert!(!sim.is_measurement(&sn.name));
    }
}

/// A sensor with slave address commands (the getter answering the 0xFF
/// wildcard) and a float read.
fn addressable() -> (Sensor, CommandSpec) {
    let sensor = spec()
        .sensors
        .iter()
        .find(|s| {
            s.command_with_role(Role::SetSlaveAddress).is_some()
                && s.command_with_role(Role::GetSlaveAddress).is_some_and(|c| c.fixed_slave == Some(0xFF))
                && s.commands.iter().any(is_float_read)
        })
        .expect("a sensor with slave address commands")
        .clone();
    let read = sensor.commands.iter().find(|c| is_float_read(c)).unwrap().clone();
    (sensor, read)
}

#[test]
fn address_write_takes_effect_after_the_reply() {
    let (probe, read) = addressable();
    let slave = probe.default_address;
    let set_id = with_role(&probe, Role::SetSlaveAddress);
    let field = first_field(&set_id);
    let Some(new) = free_address(&probe, &[slave]) else {
        return yosemitech_tests::report!("{}: one address only, nothing to move to", probe.name);
    };
    let mut sim = Simulator::new(probe.clone());
    let to = [(field.as_str(), Value::Int(i64::from(new)))];
    let reply = exchange(&mut sim, &request(&set_id, slave, &to));
    assert_eq!(reply, set_id.encode_response(slave, &Default::default()).unwrap(), "from the old address");
    assert_eq!(sim.address(), new);
    assert!(exchange(&mut sim, &request(&read, slave, &[])).is_empty(), "the old address is silent");
    let reply = exchange(&mut sim, &request(&read, new, &[]));
    assert_eq!(reply[0], new);
    assert_eq!(sim.stats().address_changes, 1);
    // Outside the sensor's addresses: exception 03, address kept.
    let outside = probe.max_address.checked_add(1).or_else(|| probe.min_address.checked_sub(1));
    let address_field = set_id.named_fields().next().unwrap();
    if let Some(outside) = outside.filter(|_| address_field.size() == 1) {
        let mut frame = request(&set_id, new, &to);
        frame[7 + address_field.offset] = outside;
        let frame = with_crc(&frame[..frame.len() - 2]);
        assert_eq!(exchange(&mut sim, &frame), exception(new, 0x10, 0x03));
        assert_eq!(sim.address(), new);
    }
}

#[test]
fn fixed_slave_read_via_the_wildcard_reports_the_current_address() {
    let (probe, read) = addressable();
    let get_id = with_role(&probe, Role::GetSlaveAddress);
    let mut sim = Simulator::new(probe.clone()).with_address(7);
    let wildcard = exchange(&mut sim, &request(&get_id, 0xFF, &[]));
    let reply = wildcard.clone();
    assert_eq!(reply[0], 0xFF, "the reply comes from the fixed slave 0xFF");
    let values = get_id.decode_response(0xFF, &reply).unwrap();
    let address = values.iter().find(|(n, _)| *n == first_field(&get_id)).map(|(_, v)| v);
    assert_eq!(address, Some(&Value::Int(7)), "{values:?}");
    // The same registers at the device's own address: answered from it.
    let mut own = request(&get_id, 0xFF, &[])[..6].to_vec();
    own[0] = 7;
    let reply = exchange(&mut sim, &with_crc(&own));
    assert_eq!(reply[..3], [7, 0x03, 2 * get_id.count as u8]);
    assert_eq!(reply[3..reply.len() - 2], wildcard[3..wildcard.len() - 2], "the same address data");
    // 0xFF with anything but the wildcard command is not for us.
    let mut other = request(&read, 7, &[])[..6].to_vec();
    assert!(other[1..] != own[1..], "another command than the wildcard's");
    other[0] = 0xFF;
    let other = with_crc(&other);
    assert!(exchange(&mut sim, &other).is_empty());
    // A sensor without a fixed-slave command: 0xFF is nobody's address,
    // even when exceptions are asked for.
    for sensor in spec().sensors.iter().filter(|s| s.commands.iter().all(|c| c.fixed_slave.is_none())) {
        let mut other = Simulator::new(sensor.clone());
        other.set_unknown_request_policy(UnknownRequestPolicy::Exception);
        assert!(exchange(&mut other, &request(&get_id, 0xFF, &[])).is_empty(), "{}", sensor.name);
        assert_eq!(other.stats().ignored_other_slave, 1);
    }
}

/// Requests that match no command of `sensor`, with the exception code each
/// gets under [`UnknownRequestPolicy::Exception`]: an unknown function, a
/// read at an address no read uses, a known read with another count, a
/// write to a register no write uses.
fn unknown_requests(sensor: &Sensor, slave: u8) -> Vec<(&'static str, Vec<u8>, u8)> {
    let exists = |function: Function, address: u16| {
        sensor.commands.iter().any(|c| c.function == function && c.address == address)
    };
    let free = |function: Function| (0..=u16::MAX).find(|a| !exists(function, *a)).expect("a free address");
    let [hi, lo] = free(Function::Read).to_be_bytes();
    let mut unknown = vec![
        ("unknown function", with_crc(&[slave, 0x04, 0x00, 0x00, 0x00, 0x01]), 0x01),
        ("unknown address", with_crc(&[slave, 0x03, hi, lo, 0x00, 0x01]), 0x02),
    ];
    let read_with_another_count = sensor.commands.iter().filter(|c| c.is_read() && c.fixed_slave.is_none()).find(|c| {
        !sensor.commands.iter().any(|o| o.is_read() && o.address == c.address && o.count == c.count + 1)
            && c.count < 125
    });
    if let Some(c) = read_with_another_count {
        let [hi, lo] = c.address.to_be_bytes();
        let [ch, cl] = (c.count + 1).to_be_bytes();
        unknown.push(("wrong count", with_crc(&[slave, 0x03, hi, lo, ch, cl]), 0x03));
    }
    if let Some(read_only) = sensor.commands.iter().find(|c| c.is_read() && !exists(Function::Write, c.address)) {
        let [hi, lo] = read_only.address.to_be_bytes();
        unknown.push(("write to a read-only block", with_crc(&[slave, 0x10, hi, lo, 0x00, 0x01, 0x02, 0, 0]), 0x02));
    }
    unknown
}

#[test]
fn every_sensor_ignores_requests_that_match_no_command_by_default() {
    for sensor in &spec().sensors {
        let slave = sensor.default_address;
        let unknown = unknown_requests(sensor, slave);
        let mut sim = Simulator::new(sensor.clone());
        for (what, frame, _) in &unknown {
            assert!(exchange(&mut sim, frame).is_empty(), "{}: {what} answered", sensor.name);
        }
        let stats = *sim.stats();
        assert_eq!(stats.ignored_unknown, unknown.len() as u64, "{}", sensor.name);
        assert_eq!((stats.replies, stats.exceptions), (0, 0), "{}", sensor.name);
        // The same requests with exceptions asked for.
        sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
        for (what, frame, code) in &unknown {
            assert_eq!(exchange(&mut sim, frame), exception(slave, frame[1], *code), "{}: {what}", sensor.name);
        }
        assert_eq!(sim.stats().exceptions, unknown.len() as u64, "{}", sensor.name);
        assert_eq!(sim.stats().ignored_unknown, unknown.len() as u64, "{}: unchanged", sensor.name);
    }
}

#[test]
fn a_client_asking_for_a_register_the_probe_lacks_times_out() {
    // A read of one sensor sent to another that has no such register.
    let sensors = spec().sensors.clone();
    let (probe, foreign) = sensors
        .iter()
        .flat_map(|p| sensors.iter().filter(move |o| o.name != p.name).map(move |o| (p, o)))
        .find_map(|(p, o)| {
            let lacks =
                |c: &&CommandSpec| !p.commands.iter().any(|q| q.function == c.function && q.address == c.address);
            o.commands
                .iter()
                .filter(|c| c.is_read() && c.fixed_slave.is_none())
                .find(lacks)
                .map(|c| (p.clone(), c.clone()))
        })
        .expect("a read of one sensor at an address another lacks");
    let slave = probe.default_address;
    let mut client = client(ResponderTransport::new(Simulator::new(probe.clone())), Duration::from_millis(20));
    match client.call_raw(&request(&foreign, slave, &[]), &foreign.layout()) {
        Err(Error::Timeout { received, .. }) => assert_eq!(received, 0),
        other => panic!("expected a timeout, got {other:?}"),
    }
    let stats = *client.transport().responder().stats();
    assert!(stats.ignored_unknown >= 1 && stats.replies == 0, "{stats:?}");
    // With exceptions asked for: 02, at once.
    client.transport_mut().responder_mut().set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let err = client.call_raw(&request(&foreign, slave, &[]), &foreign.layout()).unwrap_err();
    assert_eq!(err.exception(), Some(yosemitech_rtu::ExceptionCode::IllegalDataAddress), "{err}");
}

/// Every sensor whose calibration the simulator runs (a calibration point,
/// a status enum with the rule's variants, one list of standards in the
/// point's unit), with its point command, the point field and the standards.
fn calibrating() -> Vec<(Sensor, CommandSpec, String, Vec<f32>)> {
    let mut out = Vec::new();
    for probe in spec().sensors.iter().filter(|s| yosemitech_sim::behaviour::simulates_calibration(s)) {
        let point = with_role(probe, Role::CalibrationPoint);
        let field = point.named_fields().next().expect("a point field").clone();
        let standards = yosemitech_sim::behaviour::calibration_standards(probe, &field)
            .expect("the calibration standards")
            .values
            .iter()
            .map(|v| *v as f32)
            .collect();
        out.push((probe.clone(), point, field.display_name().to_owned(), standards));
    }
    out
}

#[test]
fn exceptions_for_unknown_function_address_and_bad_counts_when_asked_for() {
    let mut checked = 0;
    for probe in &spec().sensors {
        // A read-only float read, and a write whose first field is a float with a range.
        let read = probe.commands.iter().find(|c| {
            is_float_read(c)
                && !probe.commands.iter().any(|o| o.is_read() && o.address == c.address && o.count == c.count + 1)
                && !probe.commands.iter().any(|o| !o.is_read() && o.address == c.address)
        });
        let point = probe
            .commands
            .iter()
            .find(|c| !c.is_read() && c.named_fields().next().is_some_and(|f| is_f32(f) && f.range.is_some()));
        let (Some(read), Some(point)) = (read, point) else { continue };
        exceptions_of(probe, read, point);
        checked += 1;
    }
    yosemitech_tests::report!("exceptions: {checked} sensors with a read-only float read and a ranged float write");
}

fn exceptions_of(probe: &Sensor, read: &CommandSpec, point: &CommandSpec) {
    let standard = first_field(point);
    let slave = probe.default_address;
    let mut sim = Simulator::new(probe.clone());
    sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let [rh, rl] = read.address.to_be_bytes();
    let [ch, cl] = read.count.to_be_bytes();
    // Unknown function (0x04, read input registers): 01.
    assert_eq!(exchange(&mut sim, &with_crc(&[slave, 0x04, rh, rl, ch, cl])), exception(slave, 0x04, 0x01));
    // No command at a free address: 02.
    let free = (0..=u16::MAX).find(|a| !probe.commands.iter().any(|c| c.is_read() && c.address == *a)).unwrap();
    let [fh, fl] = free.to_be_bytes();
    assert_eq!(exchange(&mut sim, &with_crc(&[slave, 0x03, fh, fl, ch, cl])), exception(slave, 0x03, 0x02));
    // A read's address, wrong count: 03.
    let [wh, wl] = (read.count + 1).to_be_bytes();
    assert_eq!(exchange(&mut sim, &with_crc(&[slave, 0x03, rh, rl, wh, wl])), exception(slave, 0x03, 0x03));
    // A write to a read-only block: 02.
    let mut write = vec![slave, 0x10, rh, rl, ch, cl, 2 * read.count as u8];
    write.resize(write.len() + 2 * usize::from(read.count), 0);
    assert_eq!(exchange(&mut sim, &with_crc(&write)), exception(slave, 0x10, 0x02));
    // Byte count inconsistent with the register count: 03.
    let [ph, pl] = point.address.to_be_bytes();
    let [pch, pcl] = point.count.to_be_bytes();
    let bytes = 2 * point.count as u8;
    let mut write = vec![slave, 0x10, ph, pl, pch, pcl, bytes - 2];
    write.resize(write.len() + usize::from(bytes - 2), 0);
    assert_eq!(exchange(&mut sim, &with_crc(&write)), exception(slave, 0x10, 0x03));
    // Byte count inconsistent with the frame's length: 03.
    let mut write = vec![slave, 0x10, ph, pl, pch, pcl, bytes];
    write.resize(write.len() + usize::from(bytes - 2), 0);
    write.push(0x80);
    assert_eq!(exchange(&mut sim, &with_crc(&write)), exception(slave, 0x10, 0x03));
    // A read frame of the wrong length: 03.
    assert_eq!(exchange(&mut sim, &with_crc(&[slave, 0x03, rh, rl, ch, cl, 0x00])), exception(slave, 0x03, 0x03));
    // A point outside its field's range: 03, nothing stored.
    let field = point.field(&standard).unwrap();
    let (_, max) = field.range.expect("the point's range");
    let values = yosemitech_tests::values::sample_values(point);
    let mut bad = point.encode_request(slave, &values).unwrap();
    bad[7 + field.offset..11 + field.offset].copy_from_slice(&f32_bytes(field, max as f32 + 6.0));
    let bad = with_crc(&bad[..bad.len() - 2]);
    assert_eq!(exchange(&mut sim, &bad), exception(slave, 0x10, 0x03));
    assert_eq!(sim.calibration_points(), [] as [f32; 0]);
    assert_eq!(sim.stats().exceptions, 8);
    assert_eq!(sim.stats().ignored_unknown, 0);
    // Exceptions to another slave or broadcast: nothing.
    assert!(exchange(&mut sim, &with_crc(&[slave + 1, 0x04, rh, rl, ch, cl])).is_empty());
    assert!(exchange(&mut sim, &with_crc(&[0, 0x04, rh, rl, ch, cl])).is_empty());
}

#[test]
fn bad_crc_and_noise_are_ignored_silently() {
    let (probe, read) = float_read(spec());
    let mut sim = Simulator::new(probe.clone());
    let mut req = request(&read, probe.default_address, &[]);
    req[7] ^= 0x01;
    assert!(exchange(&mut sim, &req).is_empty());
    assert!(exchange(&mut sim, &[]).is_empty());
    assert!(exchange(&mut sim, &[0x01, 0x03]).is_empty());
    assert_eq!(sim.stats().ignored_bad_crc, 3);
    assert_eq!(sim.stats().replies, 0);
}

#[test]
fn broadcast_writes_are_applied_without_reply() {
    let (probe, (set, get)) = spec()
        .sensors
        .iter()
        .find_map(|s| Some((s.clone(), float_write_with_readback(s)?)))
        .expect("a sensor with a float write read back");
    let mut bus = Bus::new()
        .with(Simulator::new(probe.clone()).with_address(1))
        .with(Simulator::new(probe.clone()).with_address(2));
    let written: Vec<(String, Value)> =
        set.fields.iter().enumerate().map(|(i, fl)| (fl.name.clone().unwrap(), f(2.0 + i as f32))).collect();
    let values: Vec<(&str, Value)> = written.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
    assert!(exchange(&mut bus, &request(&set, 0, &values)).is_empty());
    for device in bus.devices() {
        assert!(same(&device.values(&get.name).unwrap(), &written));
        assert_eq!(device.stats().broadcasts, 1);
    }
    // A broadcast read is not a thing: ignored.
    let mut read = request(&get, 1, &[])[..6].to_vec();
    read[0] = 0;
    assert!(exchange(&mut bus, &with_crc(&read)).is_empty());
}

#[test]
fn bus_with_two_sensors_only_the_addressed_one_answers() {
    // A single-float read of one sensor, and another sensor with no register there.
    let spec = spec();
    let (one, get_one) = float_read(spec);
    let (two, get_two) = spec
        .sensors
        .iter()
        .filter(|s| !s.commands.iter().any(|c| c.is_read() && c.address == get_one.address))
        .find_map(|s| Some((s.clone(), s.commands.iter().find(|c| is_float_read(c))?.clone())))
        .expect("another sensor with a float read and no register at the first's");
    let (name_one, name_two) = (first_field(&get_one), get_two.fields.last().unwrap().name.clone().unwrap());
    let mut bus =
        Bus::new().with(Simulator::new(one.clone()).with_address(1)).with(Simulator::new(two.clone()).with_address(2));
    bus.device_mut(1).unwrap().set(&get_one.name, &name_one, f(6.5)).unwrap();
    bus.device_mut(2).unwrap().set(&get_two.name, &name_two, f(1.5)).unwrap();
    let reply = exchange(&mut bus, &request(&get_one, 1, &[]));
    assert_eq!(get_one.decode_response(1, &reply).unwrap()[0].1, f(6.5));
    let reply = exchange(&mut bus, &request(&get_two, 2, &[]));
    assert_eq!(get_two.decode_response(2, &reply).unwrap().last().unwrap().1, f(1.5));
    // The first read's registers at address 2 (the second has none there): silence,
    // or 02 from 2 only when it is asked to answer exceptions.
    assert!(exchange(&mut bus, &request(&get_one, 2, &[])).is_empty());
    assert_eq!(bus.device(2).unwrap().stats().ignored_unknown, 1);
    bus.device_mut(2).unwrap().set_unknown_request_policy(UnknownRequestPolicy::Exception);
    assert_eq!(exchange(&mut bus, &request(&get_one, 2, &[])), exception(2, 0x03, 0x02));
    assert!(exchange(&mut bus, &request(&get_one, 3, &[])).is_empty(), "nobody at 3");
    assert_eq!(bus.collisions(), 0);
    assert_eq!(bus.device(1).unwrap().stats().ignored_other_slave, 4, "three requests to 2, one to 3");
    // Two probes answering the 0xFF wildcard collide.
    let (probe, _) = addressable();
    let mut two = Bus::new()
        .with(Simulator::new(probe.clone()).with_address(3))
        .with(Simulator::new(probe.clone()).with_address(5));
    let get_id = with_role(&probe, Role::GetSlaveAddress);
    let reply = exchange(&mut two, &request(&get_id, 0xFF, &[]));
    assert_eq!(two.collisions(), 1);
    assert!(get_id.decode_response(0xFF, &reply).is_err(), "collided bytes do not decode: {reply:02X?}");
}

#[test]
fn three_point_calibration_status_of_the_calibration_point_role() {
    use yosemitech_sim::behaviour::STATUS_TOO_FEW_POINTS as TOO_FEW;
    use yosemitech_sim::behaviour::{STATUS_NOT_A_STANDARD as NOT_A_STANDARD, STATUS_SUCCESS as SUCCESS};
    let mut checked = 0;
    for (probe, point, standard, standards) in calibrating() {
        calibration_rule_of(&probe, &point, &standard, &standards, (SUCCESS, NOT_A_STANDARD, TOO_FEW));
        checked += 1;
    }
    // A calibration point the rule does not apply to is a plain write.
    let mut plain = 0;
    for probe in spec().sensors.iter().filter(|s| !yosemitech_sim::behaviour::simulates_calibration(s)) {
        let Some(point) = probe.command_with_role(Role::CalibrationPoint) else { continue };
        let slave = probe.default_address;
        let mut sim = Simulator::new(probe.clone());
        let values = yosemitech_tests::values::sample_values(point);
        let reply = exchange(&mut sim, &point.encode_request(slave, &values).unwrap());
        assert_eq!(reply, point.encode_response(slave, &BTreeMap::new()).unwrap(), "{}: the echo", probe.name);
        assert!(sim.calibration_points().is_empty(), "{}", probe.name);
        plain += 1;
    }
    yosemitech_tests::report!("calibration: the rule on {checked} sensors, {plain} calibration points as plain writes");
}

/// The rule on one sensor; `names` are the status variants it reports.
fn calibration_rule_of(
    probe: &Sensor,
    point: &CommandSpec,
    standard: &str,
    standards: &[f32],
    (success, not_a_standard, too_few): (&str, &str, &str),
) {
    assert!(!standards.is_empty(), "{standards:?}");
    let status = with_role(probe, Role::CalibrationStatus);
    let slave = probe.default_address;
    let mut sim = Simulator::new(probe.clone());
    let calibrate = |sim: &mut Simulator, v: f32| {
        let reply = exchange(sim, &request(point, slave, &[(standard, f(v))]));
        assert_eq!(reply[1], 0x10, "echo");
    };
    let read_status = |sim: &mut Simulator| -> String {
        let values = status.decode_response(slave, &exchange(sim, &request(&status, slave, &[]))).unwrap();
        match values.iter().find(|(_, v)| matches!(v, Value::Enum { .. })) {
            Some((_, Value::Enum { name: Some(name), .. })) => name.clone(),
            other => panic!("{other:?}"),
        }
    };
    // Before any point: what the manual's example shows, if it shows one.
    let initial = read_status(&mut sim);
    if let Some(example) = example_reading(&status).filter(|_| seeded_from_example(probe, &status)) {
        let shown = example.iter().find_map(|(_, v)| match v {
            Value::Enum { name: Some(name), .. } => Some(name.clone()),
            _ => None,
        });
        assert_eq!(Some(initial), shown, "{}: as the manual's example", probe.name);
    }
    let first = standards[0];
    let last = standards[standards.len() - 1];
    let all_but_last = &standards[..standards.len() - 1];
    if standards.len() >= 2 {
        calibrate(&mut sim, first);
        assert_eq!(read_status(&mut sim), too_few);
        for &v in &all_but_last[1..] {
            calibrate(&mut sim, v);
        }
        assert_eq!(sim.calibration_points(), all_but_last);
        assert_eq!(read_status(&mut sim), too_few);
    }
    calibrate(&mut sim, last);
    assert_eq!(read_status(&mut sim), success);
    // Not a standard: between the first standard and the next (or beside the
    // only one, inside the point's range).
    let range = point.field(standard).and_then(|fl| fl.range).map(|(lo, hi)| (lo as f32, hi as f32));
    let beside = [first + 1.0, first - 1.0, first + 0.1, first - 0.1]
        .into_iter()
        .find(|v| range.is_none_or(|(lo, hi)| (lo..=hi).contains(v)))
        .unwrap_or(first + 0.02);
    let next = standards.get(1).copied().unwrap_or(beside);
    calibrate(&mut sim, first);
    calibrate(&mut sim, (first + next) / 2.0);
    assert_eq!(read_status(&mut sim), not_a_standard);
    assert!(sim.calibration_points().is_empty());
    if standards.len() >= 2 {
        // Out of order: the second standard first is not the expected standard.
        calibrate(&mut sim, standards[1]);
        assert_eq!(read_status(&mut sim), not_a_standard);
        // Restart in the middle: the first standard again starts over.
        calibrate(&mut sim, first);
        calibrate(&mut sim, standards[1]);
        calibrate(&mut sim, first);
        assert_eq!(sim.calibration_points(), [first]);
        for &v in &standards[1..] {
            calibrate(&mut sim, v);
        }
        assert_eq!(read_status(&mut sim), success);
    }
}

#[test]
fn measurement_trigger_and_warm_up() {
    // A sensor whose procedure starts the measurement and waits for it, and
    // the procedure's first read that is a measurement (the reads the warm-up holds back).
    let (probe, read) = spec()
        .sensors
        .iter()
        .find_map(|s| {
            let start = s.command_with_role(Role::StartMeasurement)?;
            let p = s.procedure.as_ref().filter(|p| p.before.contains(&start.name) && p.warm_up_ms > 0)?;
            let read = p.read.iter().filter_map(|n| s.command(n)).find(|c| s.is_measurement(c))?;
            Some((s.clone(), read.clone()))
        })
        .expect("a sensor with a start command, a warm-up and a measurement read");
    let slave = probe.default_address;
    let start = with_role(&probe, Role::StartMeasurement);
    let procedure = probe.procedure.as_ref().unwrap();
    let warm_up = Duration::from_millis(u64::from(procedure.warm_up_ms));
    let part = warm_up / 2;
    let mut sim = Simulator::new(probe.clone()).with_manual_clock();
    assert_eq!(sim.measurement_state(), MeasurementState::Idle, "the procedure starts the measurement");
    // Plain policy: readings before the trigger are served as they are.
    assert_eq!(exchange(&mut sim, &request(&read, slave, &[]))[1], 0x03);
    sim.set_warm_up_policy(WarmUpPolicy::Busy);
    assert_eq!(exchange(&mut sim, &request(&read, slave, &[])), exception(slave, 0x03, 0x06));
    let echo = if start.is_read() {
        manual_form(&start, slave)
    } else {
        start.encode_response(slave, &Default::default()).unwrap()
    };
    assert_eq!(exchange(&mut sim, &request(&start, slave, &[])), echo);
    assert_eq!(sim.measurement_state(), MeasurementState::WarmingUp { remaining: warm_up });
    sim.advance(part);
    assert_eq!(exchange(&mut sim, &request(&read, slave, &[])), exception(slave, 0x03, 0x06));
    assert_eq!(sim.measurement_state(), MeasurementState::WarmingUp { remaining: warm_up - part });
    sim.advance(warm_up - part);
    assert_eq!(sim.measurement_state(), MeasurementState::Measuring);
    assert_eq!(exchange(&mut sim, &request(&read, slave, &[])).len(), read.layout().response_len());
    // A stop command (if any) stops it: busy again.
    if let Some(stop) = probe.command_with_role(Role::StopMeasurement) {
        let reply = exchange(&mut sim, &request(stop, slave, &[]));
        assert!(stop.decode_response(slave, &reply).is_ok(), "{reply:02X?}");
        assert_eq!(sim.measurement_state(), MeasurementState::Idle);
        assert_eq!(exchange(&mut sim, &request(&read, slave, &[])), exception(slave, 0x03, 0x06));
    }
    // A sensor with no start or stop command is free-running.
    for sensor in spec().sensors.iter().filter(|s| {
        s.command_with_role(Role::StartMeasurement).is_none() && s.command_with_role(Role::StopMeasurement).is_none()
    }) {
        assert_eq!(Simulator::new(sensor.clone()).measurement_state(), MeasurementState::Measuring, "{}", sensor.name);
    }
}

/// The reply a trigger read gets: the form its manual prints (the layout's, unless a complete 5-byte reply is printed).
fn manual_form(command: &CommandSpec, slave: u8) -> Vec<u8> {
    // A manual that prints the reply complete as slave, function, byte
    // count 0 and the CRC: that short form.
    if command.examples.iter().filter_map(|e| e.true_response()).any(|r| r.len() == 5) {
        return with_crc(&[slave, 0x03, 0]);
    }
    let mut out = vec![0u8; command.layout().response_len()];
    let n = command.layout().encode_response(slave, &[], &mut out).unwrap();
    out.truncate(n);
    out
}

#[test]
fn every_start_and_stop_command_is_answered_and_moves_the_measurement_state() {
    let mut checked = 0;
    for sensor in &spec().sensors {
        let start = sensor.command_with_role(Role::StartMeasurement);
        let stop = sensor.command_with_role(Role::StopMeasurement);
        if start.is_none() && stop.is_none() {
            continue;
        }
        let warm_up = Duration::from_millis(u64::from(sensor.procedure.as_ref().map_or(0, |p| p.warm_up_ms)));
        let slave = sensor.default_address;
        let mut sim = Simulator::new(sensor.clone()).with_manual_clock();
        sim.set_warm_up_policy(WarmUpPolicy::Busy);
        let send = |sim: &mut Simulator, command: &CommandSpec| {
            let reply = exchange(sim, &request(command, slave, &[]));
            if command.trigger && command.is_read() {
                assert_eq!(reply, manual_form(command, slave), "{}.{}: the manuals' form", sensor.name, command.name);
            }
            assert!(command.decode_response(slave, &reply).is_ok(), "{}.{}: {reply:02X?}", sensor.name, command.name);
        };
        if let Some(stop) = stop {
            send(&mut sim, stop);
            assert_eq!(sim.measurement_state(), MeasurementState::Idle, "{}", sensor.name);
        }
        if let Some(start) = start {
            send(&mut sim, start);
            let expected = if warm_up.is_zero() {
                MeasurementState::Measuring
            } else {
                MeasurementState::WarmingUp { remaining: warm_up }
            };
            assert_eq!(sim.measurement_state(), expected, "{}: the procedure's warm-up", sensor.name);
            sim.advance(warm_up);
            assert_eq!(sim.measurement_state(), MeasurementState::Measuring, "{}", sensor.name);
            // The procedure's reads are served once measuring.
            for name in sensor.procedure.iter().flat_map(|p| &p.read) {
                let read = command(sensor, name);
                let reply = exchange(&mut sim, &request(&read, slave, &[]));
                assert!(read.decode_response(slave, &reply).is_ok(), "{}.{name}: {reply:02X?}", sensor.name);
            }
        }
        assert_eq!(sim.stats().exceptions, 0, "{}", sensor.name);
        checked += 1;
    }
    assert!(checked > 0, "some sensor has a start or stop command");
}

#[test]
fn variation_is_deterministic_and_bounded() {
    // The simulator varies measurement reads only.
    let Some((probe, read)) = measurement_float_read(spec()) else {
        return yosemitech_tests::report!("variation: the spec has no single-float measurement read");
    };
    let (slave, name) = (probe.default_address, first_field(&read));
    // A base inside the measuring range; readings are clamped to it.
    let field = &read.fields[0];
    let base = yosemitech_tests::values::varied_float(field, 3);
    let (min, max) = field.range.map_or((f32::MIN, f32::MAX), |(lo, hi)| (lo as f32, hi as f32));
    let run = |seed: u64| -> Vec<f32> {
        let mut sim = Simulator::new(probe.clone());
        sim.set_variation(Some(Variation::noise(seed, 0.05, 0.01)));
        sim.set(&read.name, &name, f(base)).unwrap();
        (0..20)
            .map(|_| {
                let reply = exchange(&mut sim, &request(&read, slave, &[]));
                let Value::Float(v) = read.decode_response(slave, &reply).unwrap()[0].1 else { panic!() };
                assert_eq!(sim.get(&read.name, &name).unwrap(), f(v), "the registers hold what was sent");
                v
            })
            .collect()
    };
    let (a, b, c) = (run(1), run(1), run(2));
    assert_eq!(a, b, "same seed, same readings");
    assert_ne!(a, c, "{}.{}", probe.name, read.name);
    let slack = 1e-4 * base.abs().max(1.0);
    for (n, v) in a.iter().enumerate() {
        let centre = base + 0.01 * n as f32;
        let (lo, hi) = ((centre - 0.05).clamp(min, max), (centre + 0.05).clamp(min, max));
        assert!(*v >= lo - slack && *v <= hi + slack, "{}.{} reading {n}: {v}", probe.name, read.name);
    }
    yosemitech_tests::report!("variation: {} readings of {}.{name} around {base}", a.len(), probe.name);
}

#[test]
fn a_sensor_loaded_at_run_time_is_simulated_generically() {
    // A made-up sensor: no name of the spec, so only the generic rules apply.
    let dir = std::env::temp_dir().join(format!("yosemitech-sim-generic-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("made_up.yaml"),
        r#"
sensor:
  name: made_up
  title: Made-up probe
  doc: A test sensor.
  manual: {title: Test manual, revision: "1"}
  serial: {baud: 19200, data_bits: 8, parity: even, stop_bits: 1}
  addresses: {min: 1, max: 247}
  default_address: 9
commands:
  - name: get_reading
    title: Get reading
    doc: Reading.
    source: {section: "1"}
    function: read
    address: 0x1000
    count: 2
    fields:
      - {name: reading, type: f32, byte_order: abcd, unit: NTU, doc: Reading.}
  - name: set_threshold
    title: Set threshold
    doc: Alarm threshold.
    source: {section: "2"}
    function: write
    address: 0x2000
    count: 1
    fields:
      - {name: threshold, type: u16, byte_order: ab, range: {min: 0, max: 1000}, doc: Threshold.}
  - name: get_threshold
    title: Get threshold
    doc: Alarm threshold.
    source: {section: "3"}
    function: read
    address: 0x2000
    count: 1
    fields:
      - {name: threshold, type: u16, byte_order: ab, doc: Threshold.}
"#,
    )
    .unwrap();
    let spec = yosemitech_spec::load_paths(std::slice::from_ref(&dir));
    std::fs::remove_dir_all(&dir).ok();
    let spec = match spec {
        Ok(spec) => spec,
        Err(e) => panic!("the test spec must load: {e}"),
    };
    let sensor = spec.sensor("made_up").unwrap().clone();
    let mut sim = Simulator::new(sensor.clone());
    assert_eq!(sim.address(), 9);
    assert_eq!(sim.line_timing().bits_per_char(), 11);
    sim.set("get_reading", "reading", f(12.5)).unwrap();
    let get = command(&sensor, "get_reading");
    let reply = exchange(&mut sim, &request(&get, 9, &[]));
    assert_eq!(&reply[3..7], 12.5f32.to_be_bytes());
    let set = command(&sensor, "set_threshold");
    exchange(&mut sim, &request(&set, 9, &[("threshold", Value::Int(500))]));
    assert_eq!(sim.get("get_threshold", "threshold").unwrap(), Value::Int(500));
    let over = with_crc(&[9, 0x10, 0x20, 0x00, 0x00, 0x01, 0x02, 0x03, 0xE9]);
    assert_eq!(exchange(&mut sim, &over), exception(9, 0x10, 0x03), "1001 is outside the range");
    assert!(exchange(&mut sim, &with_crc(&[9, 0x03, 0x30, 0x00, 0x00, 0x01])).is_empty(), "no such register");
    assert!(exchange(&mut sim, &with_crc(&[0xFF, 0x03, 0x30, 0x00, 0x00, 0x01])).is_empty(), "no wildcard");
    assert_eq!((sim.stats().ignored_unknown, sim.stats().ignored_other_slave), (1, 1));
    assert_eq!(sim.measurement_state(), MeasurementState::Measuring);
    assert!(sim.calibration_points().is_empty());
}

#[test]
fn a_device_trait_object_serves_too() {
    let (probe, read) = float_read(spec());
    let req = request(&read, probe.default_address, &[]);
    let mut devices: Vec<Box<dyn FrameHandler>> = vec![Box::new(Simulator::new(probe)), Box::new(Bus::new())];
    assert_eq!(exchange(&mut devices[0], &req).len(), read.layout().response_len());
    assert!(exchange(&mut devices[1], &req).is_empty(), "an empty bus is silent");
}

/// Every measured quantity of every sensor over a simulated day of
/// natural water: inside its declared range at every reading, changing
/// over the day, and one water temperature for every probe.
#[test]
fn a_simulated_day_of_water_stays_in_range_and_moves() {
    let quarter = Duration::from_secs(15 * 60);
    let mut sims: Vec<(Sensor, Simulator)> = spec()
        .sensors
        .iter()
        .map(|sensor| {
            let mut sim = Simulator::new(sensor.clone()).with_manual_clock();
            sim.fill_with_water();
            sim.set_variation(Some(Variation::water(3, 0.05, Duration::from_secs(86_400))));
            if let Some(start) = sensor.command_with_role(Role::StartMeasurement) {
                exchange(&mut sim, &request(start, sensor.default_address, &[]));
            }
            (sensor.clone(), sim)
        })
        .collect();
    let mut seen: BTreeMap<(String, String, String), (f32, f32)> = BTreeMap::new();
    let (mut readings, mut shared) = (0, 0);
    for _ in 0..96 {
        let mut temperatures: Vec<(String, f32)> = Vec::new();
        for (sensor, sim) in &mut sims {
            sim.advance(quarter);
            let slave = sensor.default_address;
            for read in sensor.measurement_reads() {
                let reply = exchange(sim, &request(read, slave, &[]));
                let Ok(values) = read.decode_response(slave, &reply) else {
                    panic!("{}.{}: no reading in water: {reply:02X?}", sensor.name, read.name)
                };
                for (name, value) in values {
                    let (Some(field), Value::Float(v)) = (read.field(&name), value) else { continue };
                    readings += 1;
                    if let Some((min, max)) = field.range {
                        assert!(
                            (min..=max).contains(&f64::from(v)),
                            "{}.{name}: {v} outside {min}..={max}",
                            sensor.name
                        );
                    }
                    if field.unit.as_deref() == Some("degC")
                        && field.range.is_none_or(|(min, max)| min <= 10.0 && max >= 30.0)
                    {
                        temperatures.push((format!("{}.{name}", sensor.name), v));
                    }
                    let e = seen.entry((sensor.name.clone(), read.name.clone(), name)).or_insert((v, v));
                    *e = (e.0.min(v), e.1.max(v));
                }
            }
        }
        if let Some((first, t)) = temperatures.first() {
            for (other, u) in &temperatures {
                assert!((t - u).abs() < 1e-3, "one water: {first} reads {t} degC, {other} {u} degC");
                shared += 1;
            }
        }
    }
    for ((sensor, read, field), (min, max)) in &seen {
        assert!(max > min, "{sensor}.{read}.{field} stays at {min} all day");
    }
    yosemitech_tests::report!(
        "a simulated day: {readings} readings of {} quantities inside their ranges, {shared} temperatures shared",
        seen.len()
    );
}

/// A quantity that two measurement reads hold (pH in `get_ph` and in
/// `get_orp_and_ph`) reads the same through both at one moment, with noise
/// and a daily cycle on: the simulator holds one water, not one per register.
#[test]
fn registers_that_hold_one_quantity_agree() {
    let mut pairs = 0;
    for sensor in &spec().sensors {
        let mut sim = Simulator::new(sensor.clone()).with_manual_clock();
        sim.fill_with_water();
        sim.set_variation(Some(Variation { noise: 0.05, ..Variation::water(5, 0.05, Duration::from_secs(86_400)) }));
        if let Some(start) = sensor.command_with_role(Role::StartMeasurement) {
            exchange(&mut sim, &request(start, sensor.default_address, &[]));
        }
        let slave = sensor.default_address;
        for hour in 0..6 {
            sim.advance(Duration::from_secs(3600 + hour));
            // Every quantity as each read gives it, all at this moment.
            let mut read: BTreeMap<String, Vec<(String, f32)>> = BTreeMap::new();
            for command in sensor.measurement_reads() {
                let reply = exchange(&mut sim, &request(command, slave, &[]));
                let Ok(values) = command.decode_response(slave, &reply) else {
                    panic!("{}.{}: no reading: {reply:02X?}", sensor.name, command.name)
                };
                for (name, value) in values {
                    if let Value::Float(v) = value {
                        read.entry(name).or_default().push((command.name.clone(), v));
                    }
                }
            }
            for (name, readings) in read.iter().filter(|(_, r)| r.len() > 1) {
                let (first, v) = &readings[0];
                for (other, u) in &readings[1..] {
                    assert_eq!(v.to_bits(), u.to_bits(), "{}.{name}: {first} reads {v}, {other} {u}", sensor.name);
                    pairs += 1;
                }
            }
        }
    }
    yosemitech_tests::report!("one quantity, one value: {pairs} pairs of reads agreed");
}

#[test]
fn setting_a_reading_changes_no_other_read_but_the_same_registers() {
    // A value set on one read shows in another read only where that read's
    // field is the same bytes of the same registers; reads whose addresses
    // are parameter numbers (fields straddling each other) keep their own.
    let span = |c: &CommandSpec, name: &str| {
        c.field(name).map(|f| {
            let start = u32::from(c.address) * 2 + f.offset as u32;
            (start, start + f.size() as u32)
        })
    };
    let (mut set, mut looked_at) = (0, 0);
    for sensor in &spec().sensors {
        let reads: Vec<&CommandSpec> = sensor.commands.iter().filter(|c| c.is_read() && !c.trigger).collect();
        for read in &reads {
            for field in read.named_fields().filter(|f| is_f32(f)) {
                let name = field.display_name();
                let mut sim = Simulator::new(sensor.clone());
                sim.fill_with_water();
                let before: Vec<_> = reads.iter().map(|r| sim.values(&r.name).unwrap()).collect();
                let new = 12345.5;
                sim.set(&read.name, name, f(new)).unwrap();
                set += 1;
                for (other, old) in reads.iter().zip(&before) {
                    for (other_name, value) in sim.values(&other.name).unwrap() {
                        let shared = span(other, &other_name) == span(read, name);
                        let expected = if shared {
                            f(new)
                        } else {
                            old.iter().find(|(n, _)| *n == other_name).map(|(_, v)| v.clone()).unwrap()
                        };
                        assert!(
                            value.same_as(&expected),
                            "{}: after setting {}.{name}, {}.{other_name} is {value:?}, not {expected:?}",
                            sensor.name,
                            read.name,
                            other.name
                        );
                        looked_at += 1;
                    }
                }
            }
        }
    }
    assert!(set > 0 && looked_at > set, "{set} set, {looked_at} looked at");
}

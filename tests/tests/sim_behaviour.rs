//! The simulator's device behaviour: state, addressing, exceptions,
//! calibration, measurement trigger, the bus.

mod sim_common;

use std::time::Duration;

use sim_common::{
    client, command, exception, exchange, request, same, sensor, sim, sim_with_exceptions, spec, with_crc,
};
use yosemitech_rtu::{Error, Function, ResponderTransport};
use yosemitech_sim::{Bus, Device, MeasurementState, Simulator, UnknownRequestPolicy, Variation, WarmUpPolicy};
use yosemitech_spec::{Command, Role, Sensor, Value};

fn f(v: f32) -> Value {
    Value::Float(v)
}

#[test]
fn writes_are_read_back() {
    let cond = sensor("conductivity");
    let (set, get) = (command(&cond, "set_user_calibration"), command(&cond, "get_user_calibration"));
    let mut sim = Simulator::new(cond.clone());
    assert!(same(
        &sim.values("get_user_calibration").unwrap(),
        &[("k_slope".into(), f(1.0)), ("b_offset".into(), f(0.0))]
    ));
    let write = request(&set, 1, &[("k_slope", f(1.25)), ("b_offset", f(-0.5))]);
    assert_eq!(exchange(&mut sim, &write), set.encode_response(1, &Default::default()).unwrap(), "echo");
    let reply = exchange(&mut sim, &request(&get, 1, &[]));
    let values = get.decode_response(1, &reply).unwrap();
    assert!(same(&values, &[("k_slope".into(), f(1.25)), ("b_offset".into(), f(-0.5))]), "{values:?}");

    // pH: K1..K6 through 0x2900, both directions.
    let ph = sensor("ph_orp");
    let (set, get) = (command(&ph, "set_ph_electrode_coefficients"), command(&ph, "get_ph_electrode_coefficients"));
    let mut sim = Simulator::new(ph.clone());
    let ks: Vec<(&str, Value)> = ["k1", "k2", "k3", "k4", "k5", "k6"].iter().map(|k| (*k, f(0.5))).collect();
    exchange(&mut sim, &request(&set, 1, &ks));
    let values = get.decode_response(1, &exchange(&mut sim, &request(&get, 1, &[]))).unwrap();
    assert!(values.iter().all(|(_, v)| v.same_as(&f(0.5))), "{values:?}");
    assert_eq!(sim.stats().writes, 1);
    assert_eq!(sim.stats().reads, 1);
}

#[test]
fn readings_set_by_name_are_served() {
    let ph = sensor("ph_orp");
    let mut sim = Simulator::new(ph.clone());
    sim.set("get_ph", "ph", f(7.0)).unwrap();
    let get_ph = command(&ph, "get_ph");
    let reply = exchange(&mut sim, &request(&get_ph, 1, &[]));
    assert_eq!(reply, [0x01, 0x03, 0x04, 0x00, 0x00, 0xE0, 0x40, 0xB2, 0x03]);
    let with_ph = ph.commands.iter().filter(|c| c.is_read() && c.field("ph").is_some()).count();
    assert!(with_ph >= 2, "get_ph and get_orp_and_ph");
    assert_eq!(sim.set_everywhere("ph", f(8.5)).unwrap(), with_ph);
    assert_eq!(sim.get("get_orp_and_ph", "ph").unwrap(), f(8.5));
    assert!(sim.set("get_ph", "nope", f(1.0)).is_err());
    assert!(sim.set("nope", "ph", f(1.0)).is_err());
    assert!(sim.set("start_ph_calibration", "standard_ph", f(15.0)).is_err(), "outside the write field's range");
    // A read's range is the measuring range, which a probe may leave: a client test may set it.
    let (_, max) = get_ph_range(&ph);
    sim.set("get_ph", "ph", f(max as f32 + 5.0)).unwrap();
    assert_eq!(sim.get("get_ph", "ph").unwrap(), f(max as f32 + 5.0));
    assert!(sim.is_measurement("get_ph") && !sim.is_measurement("get_ph_calibration") && !sim.is_measurement("get_sn"));
}

fn get_ph_range(ph: &Sensor) -> (f64, f64) {
    command(ph, "get_ph").field("ph").and_then(|f| f.range).unwrap_or((0.0, 14.0))
}

#[test]
fn set_slave_id_takes_effect_after_the_reply() {
    let ph = sensor("ph_orp");
    let (set_id, get_ph) = (command(&ph, "set_slave_id"), command(&ph, "get_ph"));
    let mut sim = Simulator::new(ph.clone());
    let reply = exchange(&mut sim, &request(&set_id, 1, &[("slave_address", Value::Int(20))]));
    assert_eq!(reply, [0x01, 0x10, 0x30, 0x00, 0x00, 0x01, 0x0E, 0xC9], "Fig 17: from the old address");
    assert_eq!(sim.address(), 20);
    assert!(exchange(&mut sim, &request(&get_ph, 1, &[])).is_empty(), "the old address is silent");
    let reply = exchange(&mut sim, &request(&get_ph, 20, &[]));
    assert_eq!(reply[0], 20);
    assert_eq!(sim.stats().address_changes, 1);
    // Out of the field's range (1..=247): exception 03, address kept.
    let frame = with_crc(&[20, 0x10, 0x30, 0x00, 0x00, 0x01, 0x02, 248, 0x00]);
    assert_eq!(exchange(&mut sim, &frame), exception(20, 0x10, 0x03));
    assert_eq!(sim.address(), 20);
}

#[test]
fn get_slave_id_via_the_wildcard_reports_the_current_address() {
    let ph = sensor("ph_orp");
    let get_id = command(&ph, "get_slave_id");
    let mut sim = Simulator::new(ph.clone()).with_address(7);
    let reply = exchange(&mut sim, &request(&get_id, 0xFF, &[]));
    assert_eq!(reply[0], 0xFF, "E3: the reply comes from 0xFF");
    let values = get_id.decode_response(0xFF, &reply).unwrap();
    assert_eq!(values, [("slave_address".to_string(), Value::Int(7))]);
    // The same registers at the device's own address: answered from it.
    let mut own = request(&get_id, 0xFF, &[])[..6].to_vec();
    own[0] = 7;
    let reply = exchange(&mut sim, &with_crc(&own));
    assert_eq!(reply[..4], [7, 0x03, 0x02, 7]);
    // 0xFF with anything but the wildcard command is not for us.
    let other = with_crc(&[0xFF, 0x03, 0x28, 0x00, 0x00, 0x02]);
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
    let ph = sensor("ph_orp");
    // A conductivity command sent to a pH probe: the pH probe has no such register.
    let cond = sensor("conductivity");
    let foreign = cond
        .commands
        .iter()
        .find(|c| c.is_read() && !ph.commands.iter().any(|p| p.function == c.function && p.address == c.address))
        .expect("a conductivity read at an address the pH probe lacks");
    let mut client = client(ResponderTransport::new(Simulator::new(ph.clone())), Duration::from_millis(20));
    match client.call_raw(&request(foreign, 1, &[]), &foreign.layout()) {
        Err(Error::Timeout { received }) => assert!(received.is_empty(), "{received}"),
        other => panic!("expected a timeout, got {other:?}"),
    }
    let stats = *client.transport().responder().stats();
    assert!(stats.ignored_unknown >= 1 && stats.replies == 0, "{stats:?}");
    // With exceptions asked for: 02, at once.
    client.transport_mut().responder_mut().set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let err = client.call_raw(&request(foreign, 1, &[]), &foreign.layout()).unwrap_err();
    assert_eq!(err.exception(), Some(yosemitech_rtu::ExceptionCode::IllegalDataAddress), "{err}");
}

#[test]
fn exceptions_for_unknown_function_address_and_bad_counts_when_asked_for() {
    let mut sim = sim_with_exceptions("ph_orp");
    // Unknown function (0x04, read input registers): 01.
    assert_eq!(exchange(&mut sim, &with_crc(&[1, 0x04, 0x28, 0x00, 0x00, 0x02])), exception(1, 0x04, 0x01));
    // No command at 0x2700: 02.
    assert_eq!(exchange(&mut sim, &with_crc(&[1, 0x03, 0x27, 0x00, 0x00, 0x02])), exception(1, 0x03, 0x02));
    // get_ph's address, wrong count: 03.
    assert_eq!(exchange(&mut sim, &with_crc(&[1, 0x03, 0x28, 0x00, 0x00, 0x03])), exception(1, 0x03, 0x03));
    // A write to a read-only block: 02.
    let write = with_crc(&[1, 0x10, 0x28, 0x00, 0x00, 0x02, 0x04, 0, 0, 0, 0]);
    assert_eq!(exchange(&mut sim, &write), exception(1, 0x10, 0x02));
    // Byte count inconsistent with the register count: 03.
    let write = with_crc(&[1, 0x10, 0x23, 0x00, 0x00, 0x02, 0x02, 0, 0]);
    assert_eq!(exchange(&mut sim, &write), exception(1, 0x10, 0x03));
    // Byte count inconsistent with the frame's length: 03.
    let write = with_crc(&[1, 0x10, 0x23, 0x00, 0x00, 0x02, 0x04, 0, 0, 0x80]);
    assert_eq!(exchange(&mut sim, &write), exception(1, 0x10, 0x03));
    // A read frame of the wrong length: 03.
    assert_eq!(exchange(&mut sim, &with_crc(&[1, 0x03, 0x28, 0x00, 0x00, 0x02, 0x00])), exception(1, 0x03, 0x03));
    // standard_ph outside 0..14: 03, nothing stored.
    let cal = command(&sensor("ph_orp"), "start_ph_calibration");
    let mut bad = request(&cal, 1, &[("standard_ph", f(4.0))]);
    bad[7..11].copy_from_slice(&20.0f32.to_le_bytes());
    let bad = with_crc(&bad[..bad.len() - 2]);
    assert_eq!(exchange(&mut sim, &bad), exception(1, 0x10, 0x03));
    assert_eq!(sim.calibration_points(), [] as [f32; 0]);
    assert_eq!(sim.stats().exceptions, 8);
    assert_eq!(sim.stats().ignored_unknown, 0);
    // Exceptions to another slave or broadcast: nothing.
    assert!(exchange(&mut sim, &with_crc(&[2, 0x04, 0x28, 0x00, 0x00, 0x02])).is_empty());
    assert!(exchange(&mut sim, &with_crc(&[0, 0x04, 0x28, 0x00, 0x00, 0x02])).is_empty());
}

#[test]
fn bad_crc_and_noise_are_ignored_silently() {
    let ph = sensor("ph_orp");
    let mut sim = Simulator::new(ph.clone());
    let mut req = request(&command(&ph, "get_ph"), 1, &[]);
    req[7] ^= 0x01;
    assert!(exchange(&mut sim, &req).is_empty());
    assert!(exchange(&mut sim, &[]).is_empty());
    assert!(exchange(&mut sim, &[0x01, 0x03]).is_empty());
    assert_eq!(sim.stats().ignored_bad_crc, 3);
    assert_eq!(sim.stats().replies, 0);
}

#[test]
fn broadcast_writes_are_applied_without_reply() {
    let ph = sensor("ph_orp");
    let set = command(&ph, "set_orp_calibration");
    let mut bus =
        Bus::new().with(Simulator::new(ph.clone()).with_address(1)).with(Simulator::new(ph.clone()).with_address(2));
    let write = request(&set, 0, &[("k_slope", f(2.0)), ("b_offset", f(3.0))]);
    assert!(exchange(&mut bus, &write).is_empty());
    for device in bus.devices() {
        assert_eq!(device.get("get_orp_calibration", "k_slope").unwrap(), f(2.0));
        assert_eq!(device.stats().broadcasts, 1);
    }
    // A broadcast read is not a thing: ignored.
    assert!(exchange(&mut bus, &with_crc(&[0, 0x03, 0x28, 0x00, 0x00, 0x02])).is_empty());
}

#[test]
fn bus_with_two_sensors_only_the_addressed_one_answers() {
    let (ph, cond) = (sensor("ph_orp"), sensor("conductivity"));
    let mut bus =
        Bus::new().with(Simulator::new(ph.clone()).with_address(1)).with(Simulator::new(cond.clone()).with_address(2));
    bus.device_mut(1).unwrap().set("get_ph", "ph", f(6.5)).unwrap();
    bus.device_mut(2).unwrap().set("get_temperature_and_conductivity", "conductivity_ms_cm", f(1.5)).unwrap();
    let get_ph = command(&ph, "get_ph");
    let get_tc = command(&cond, "get_temperature_and_conductivity");
    let reply = exchange(&mut bus, &request(&get_ph, 1, &[]));
    assert_eq!(get_ph.decode_response(1, &reply).unwrap()[0].1, f(6.5));
    let reply = exchange(&mut bus, &request(&get_tc, 2, &[]));
    assert_eq!(get_tc.decode_response(2, &reply).unwrap()[1].1, f(1.5));
    // get_ph's registers at address 2 (conductivity has none there): silence,
    // or 02 from 2 only when it is asked to answer exceptions.
    assert!(exchange(&mut bus, &request(&get_ph, 2, &[])).is_empty());
    assert_eq!(bus.device(2).unwrap().stats().ignored_unknown, 1);
    bus.device_mut(2).unwrap().set_unknown_request_policy(UnknownRequestPolicy::Exception);
    assert_eq!(exchange(&mut bus, &request(&get_ph, 2, &[])), exception(2, 0x03, 0x02));
    assert!(exchange(&mut bus, &request(&get_ph, 3, &[])).is_empty(), "nobody at 3");
    assert_eq!(bus.collisions(), 0);
    assert_eq!(bus.device(1).unwrap().stats().ignored_other_slave, 4, "three requests to 2, one to 3");
    // Two pH probes answering the 0xFF wildcard collide.
    let mut two =
        Bus::new().with(Simulator::new(ph.clone()).with_address(3)).with(Simulator::new(ph.clone()).with_address(5));
    let get_id = command(&ph, "get_slave_id");
    let reply = exchange(&mut two, &request(&get_id, 0xFF, &[]));
    assert_eq!(two.collisions(), 1);
    assert!(get_id.decode_response(0xFF, &reply).is_err(), "collided bytes do not decode: {reply:02X?}");
}

#[test]
fn ph_three_point_calibration_status() {
    let ph = sensor("ph_orp");
    let point = ph.command_with_role(Role::CalibrationPoint).expect("a calibration point command").clone();
    let status = ph.command_with_role(Role::CalibrationStatus).expect("a calibration status command").clone();
    let standard = point.named_fields().next().and_then(|f| f.name.clone()).unwrap();
    let mut sim = Simulator::new(ph.clone());
    let calibrate = |sim: &mut Simulator, v: f32| {
        let reply = exchange(sim, &request(&point, 1, &[(standard.as_str(), f(v))]));
        assert_eq!(reply[1], 0x10, "echo");
    };
    let read_status = |sim: &mut Simulator| -> String {
        let values = status.decode_response(1, &exchange(sim, &request(&status, 1, &[]))).unwrap();
        match &values[0].1 {
            Value::Enum { name: Some(name), .. } => name.clone(),
            other => panic!("{other:?}"),
        }
    };
    assert_eq!(read_status(&mut sim), "success", "as the manual's example");
    calibrate(&mut sim, 4.0);
    assert_eq!(read_status(&mut sim), "fewer_than_three_points");
    calibrate(&mut sim, 6.86);
    assert_eq!(sim.calibration_points(), [4.0, 6.86]);
    assert_eq!(read_status(&mut sim), "fewer_than_three_points");
    calibrate(&mut sim, 9.18);
    assert_eq!(read_status(&mut sim), "success");
    // Not a standard.
    calibrate(&mut sim, 4.0);
    calibrate(&mut sim, 7.0);
    assert_eq!(read_status(&mut sim), "not_a_calibration_standard");
    assert!(sim.calibration_points().is_empty());
    // Out of order: 6.86 first is not the expected standard.
    calibrate(&mut sim, 6.86);
    assert_eq!(read_status(&mut sim), "not_a_calibration_standard");
    // Restart in the middle: 4.00 again starts over.
    calibrate(&mut sim, 4.0);
    calibrate(&mut sim, 6.86);
    calibrate(&mut sim, 4.0);
    assert_eq!(sim.calibration_points(), [4.0]);
    calibrate(&mut sim, 6.86);
    calibrate(&mut sim, 9.18);
    assert_eq!(read_status(&mut sim), "success");
}

#[test]
fn conductivity_measurement_trigger_and_warm_up() {
    let cond = sensor("conductivity");
    let start = cond.command_with_role(Role::StartMeasurement).expect("a start command").clone();
    let read = command(&cond, "get_temperature_and_conductivity");
    let warm_up = Duration::from_millis(u64::from(cond.procedure.as_ref().unwrap().warm_up_ms));
    assert!(warm_up > Duration::from_secs(4), "{warm_up:?}");
    let mut sim = Simulator::new(cond.clone()).with_manual_clock();
    assert_eq!(sim.measurement_state(), MeasurementState::Idle, "the procedure starts the measurement");
    // Plain policy: readings before the trigger are served as they are.
    assert_eq!(exchange(&mut sim, &request(&read, 1, &[]))[1], 0x03);
    sim.set_warm_up_policy(WarmUpPolicy::Busy);
    assert_eq!(exchange(&mut sim, &request(&read, 1, &[])), exception(1, 0x03, 0x06));
    assert_eq!(exchange(&mut sim, &request(&start, 1, &[])), [0x01, 0x10, 0x1C, 0x00, 0x00, 0x00, 0xC7, 0x99]);
    assert_eq!(sim.measurement_state(), MeasurementState::WarmingUp { remaining: warm_up });
    sim.advance(Duration::from_secs(4));
    assert_eq!(exchange(&mut sim, &request(&read, 1, &[])), exception(1, 0x03, 0x06));
    assert_eq!(sim.measurement_state(), MeasurementState::WarmingUp { remaining: warm_up - Duration::from_secs(4) });
    sim.advance(warm_up - Duration::from_secs(4));
    assert_eq!(sim.measurement_state(), MeasurementState::Measuring);
    assert_eq!(exchange(&mut sim, &request(&read, 1, &[])).len(), read.layout().response_len());
    // SW 1.8's Stop Measurement (a trigger read) stops it: busy again.
    if let Some(stop) = cond.command_with_role(Role::StopMeasurement) {
        let reply = exchange(&mut sim, &request(stop, 1, &[]));
        assert!(stop.decode_response(1, &reply).is_ok(), "{reply:02X?}");
        assert_eq!(sim.measurement_state(), MeasurementState::Idle);
        assert_eq!(exchange(&mut sim, &request(&read, 1, &[])), exception(1, 0x03, 0x06));
    }
    // A sensor with no start or stop command is free-running.
    for sensor in spec().sensors.iter().filter(|s| {
        s.command_with_role(Role::StartMeasurement).is_none() && s.command_with_role(Role::StopMeasurement).is_none()
    }) {
        assert_eq!(Simulator::new(sensor.clone()).measurement_state(), MeasurementState::Measuring, "{}", sensor.name);
    }
}

/// The reply a trigger read gets: the manuals' form from the layout.
fn manual_form(command: &Command, slave: u8) -> Vec<u8> {
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
        let send = |sim: &mut Simulator, command: &Command| {
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
    let ph = sensor("ph_orp");
    let get_ph = command(&ph, "get_ph");
    let run = |seed: u64| -> Vec<f32> {
        let mut sim = Simulator::new(ph.clone());
        sim.set_variation(Some(Variation { seed, noise: 0.05, drift_per_read: 0.01 }));
        sim.set("get_ph", "ph", f(7.0)).unwrap();
        (0..20)
            .map(|_| {
                let reply = exchange(&mut sim, &request(&get_ph, 1, &[]));
                let Value::Float(v) = get_ph.decode_response(1, &reply).unwrap()[0].1 else { panic!() };
                assert_eq!(sim.get("get_ph", "ph").unwrap(), f(v), "the registers hold what was sent");
                v
            })
            .collect()
    };
    let (a, b, c) = (run(1), run(1), run(2));
    assert_eq!(a, b, "same seed, same readings");
    assert_ne!(a, c);
    for (n, v) in a.iter().enumerate() {
        let centre = 7.0 + 0.01 * n as f32;
        assert!((v - centre).abs() <= 0.05 + 1e-4, "reading {n}: {v}");
    }
}

#[test]
fn a_sensor_loaded_at_run_time_is_simulated_generically() {
    // A made-up sensor: no Yosemitech names, so only the generic rules apply.
    let dir = std::env::temp_dir().join(format!("yosemitech-sim-generic-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("turbidity.yaml"),
        r#"
sensor:
  name: turbidity
  title: Turbidity probe
  doc: A test sensor.
  manual: {title: Test manual, revision: "1"}
  serial: {baud: 19200, data_bits: 8, parity: even, stop_bits: 1}
  addresses: {min: 1, max: 247}
  default_address: 9
commands:
  - name: get_turbidity
    title: Get turbidity
    doc: Turbidity.
    source: {section: "1"}
    function: read
    address: 0x1000
    count: 2
    fields:
      - {name: ntu, type: f32, byte_order: abcd, unit: NTU, doc: Turbidity.}
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
    let sensor = spec.sensor("turbidity").unwrap().clone();
    let mut sim = Simulator::new(sensor.clone());
    assert_eq!(sim.address(), 9);
    assert_eq!(sim.line_timing().bits_per_char(), 11);
    sim.set("get_turbidity", "ntu", f(12.5)).unwrap();
    let get = command(&sensor, "get_turbidity");
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
    let mut devices: Vec<Box<dyn Device>> = vec![Box::new(sim("ph_orp")), Box::new(Bus::new())];
    let req = with_crc(&[1, 0x03, 0x28, 0x00, 0x00, 0x02]);
    assert_eq!(exchange(&mut devices[0], &req).len(), 9);
    assert!(exchange(&mut devices[1], &req).is_empty(), "an empty bus is silent");
}

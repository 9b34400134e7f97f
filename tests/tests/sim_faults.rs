//! Fault injection seen from the rtu client: each kind as the right error
//! and retries that recover, through both drivers (blocking and tokio),
//! counters that match, and a soak that accepts no wrong value.

use yosemitech_tests::sim as sim_common;

use std::collections::BTreeMap;
use std::thread;
use std::time::{Duration, Instant};

use sim_common::{client, exchange, float_read, request, same, spec};
use yosemitech_rtu::{
    AsyncClient, Client, ClientConfig, Error, ExceptionCode, FrameError, ResponderTransport, RetryPolicy, Transport,
};
use yosemitech_sim::{Bus, FaultConfig, FaultKind, Rng, ServeConfig, Simulator, serve_memory};
use yosemitech_spec::{CommandSpec, Field, FieldKind, Role, Sensor, Value};

const TIMEOUT: Duration = Duration::from_millis(20);

/// The two drivers of the client core: each fault kind must look the same
/// through both.
#[derive(Debug, Clone, Copy)]
enum Driver {
    Blocking,
    Tokio,
}

const DRIVERS: [Driver; 2] = [Driver::Blocking, Driver::Tokio];

/// `request` through a client of `driver` on `transport`: the result, the
/// bytes the client received and the transport.
fn call_raw_on(
    driver: Driver,
    transport: ResponderTransport<Simulator>,
    config: ClientConfig,
    request: &[u8],
    layout: &yosemitech_rtu::Layout<'_>,
) -> (Result<Vec<u8>, Error>, Vec<u8>, ResponderTransport<Simulator>) {
    match driver {
        Driver::Blocking => {
            let mut client = Client::with_config(transport, config);
            let result = client.call_raw(request, layout).map(<[u8]>::to_vec);
            (result, client.last_reply().to_vec(), client.into_transport())
        }
        Driver::Tokio => {
            let runtime = tokio::runtime::Builder::new_current_thread().enable_time().build().unwrap();
            let mut client = AsyncClient::with_config(transport, config);
            let result = runtime.block_on(client.call_raw(request, layout)).map(<[u8]>::to_vec);
            (result, client.last_reply().to_vec(), client.into_link())
        }
    }
}

/// The spec's first single-float read, its sensor, and the reply a
/// fault-free simulator gives it at the sensor's factory address.
fn float_read_with_reply() -> (Sensor, CommandSpec, Vec<u8>) {
    let (probe, read) = float_read(spec());
    let reply = exchange(&mut Simulator::new(probe.clone()), &request(&read, probe.default_address, &[]));
    assert!(!reply.is_empty(), "{}: the simulator answers {}", probe.name, read.name);
    (probe, read, reply)
}

/// A float read through `driver` on a simulator that injects `fault` into
/// its first reply. Returns the result, the bytes the client received, the
/// simulator and the fault-free reply.
fn one_fault(fault: FaultKind, driver: Driver) -> (Result<Vec<u8>, Error>, Vec<u8>, Simulator, Vec<u8>) {
    let (probe, read, reply) = float_read_with_reply();
    let slave = probe.default_address;
    let sim = Simulator::new(probe).with_faults(FaultConfig::scripted([Some(fault)]));
    let config = ClientConfig { timeout: TIMEOUT, retry: RetryPolicy::NONE, ..ClientConfig::default() };
    let (result, received, transport) =
        call_raw_on(driver, ResponderTransport::new(sim), config, &request(&read, slave, &[]), &read.layout());
    (result, received, transport.into_responder(), reply)
}

#[test]
fn each_fault_kind_is_seen_by_the_client_as_the_right_error() {
    for (kind, driver) in FaultKind::ALL.into_iter().flat_map(|kind| DRIVERS.map(|driver| (kind, driver))) {
        let (result, bytes, sim, clean_reply) = one_fault(kind, driver);
        match (kind, &result) {
            (FaultKind::Drop | FaultKind::Delay, Err(Error::Timeout { received, .. })) => {
                assert_eq!(*received, 0, "{kind}: silence, got {bytes:02X?}");
            }
            (FaultKind::CorruptCrc, Err(Error::Frame { error: FrameError::Crc { .. }, .. })) => {}
            (FaultKind::Truncate, Err(Error::Timeout { received, .. })) => {
                assert!(*received > 0 && clean_reply.starts_with(&bytes), "{kind}: {bytes:02X?}");
            }
            // The rtu client skips noise before a frame: the reply is accepted.
            (FaultKind::Garbage, Ok(reply)) => assert_eq!(reply, &clean_reply),
            (FaultKind::WrongSlave, Err(Error::Frame { error: FrameError::WrongSlave { expected, actual }, .. }))
                if *expected == clean_reply[0] && actual != expected => {}
            (FaultKind::Busy, Err(e)) if e.exception() == Some(ExceptionCode::ServerDeviceBusy) => {}
            _ => panic!("{kind} ({driver:?}): unexpected {result:?}"),
        }
        assert_eq!(sim.faults().get(kind), 1, "{kind}");
        assert_eq!(sim.faults().total(), 1, "{kind}");
        assert_eq!(sim.faults().replies(), 1, "{kind}");
        println!("{kind:>11} ({driver:?}): {}", result.map_or_else(|e| e.to_string(), |_| "ok (noise skipped)".into()));
    }
}

#[test]
fn retries_recover_from_a_scripted_sequence() {
    let (probe, read, clean_reply) = float_read_with_reply();
    let slave = probe.default_address;
    let config = ClientConfig {
        timeout: TIMEOUT,
        retry: RetryPolicy { retries: 3, backoff: Duration::ZERO, ..RetryPolicy::default() },
        ..ClientConfig::default()
    };
    for driver in DRIVERS {
        let script = [Some(FaultKind::Drop), Some(FaultKind::CorruptCrc), Some(FaultKind::WrongSlave), None];
        let sim = Simulator::new(probe.clone()).with_faults(FaultConfig::scripted(script));
        let req = request(&read, slave, &[]);
        let (reply, _, mut transport) = call_raw_on(driver, ResponderTransport::new(sim), config, &req, &read.layout());
        assert_eq!(reply.unwrap(), clean_reply, "{driver:?}");
        let sim = transport.responder();
        assert_eq!(sim.faults().total(), 3, "{driver:?}");
        assert_eq!(sim.faults().replies(), 4, "{driver:?}");
        assert_eq!(sim.stats().reads, 4, "{driver:?}: the device served every attempt");
        // A busy exception is not retried.
        transport.responder_mut().set_faults(FaultConfig::scripted([Some(FaultKind::Busy)]));
        let (err, _, transport) = call_raw_on(driver, transport, config, &req, &read.layout());
        assert_eq!(err.unwrap_err().exception(), Some(ExceptionCode::ServerDeviceBusy), "{driver:?}");
        let busy = transport.responder().faults().get(FaultKind::Busy);
        assert_eq!(busy, 1, "{driver:?}: counts go on across configurations");
        assert_eq!(transport.responder().stats().requests, 5, "{driver:?}: busy is not retried");
    }
}

#[test]
fn a_delayed_reply_arrives_after_the_deadline_when_served_in_a_thread() {
    let (probe, read, clean_reply) = float_read_with_reply();
    let slave = probe.default_address;
    let delay = Duration::from_millis(200);
    let faults = FaultConfig { delay_by: delay, ..FaultConfig::scripted([Some(FaultKind::Delay)]) };
    let (transport, server) = serve_memory(Simulator::new(probe).with_faults(faults), ServeConfig::default()).unwrap();
    let mut client = client(transport, Duration::from_millis(50));
    let start = Instant::now();
    match client.call_raw(&request(&read, slave, &[]), &read.layout()) {
        Err(Error::Timeout { received, .. }) => assert_eq!(received, 0),
        other => panic!("expected a timeout, got {other:?}"),
    }
    assert!(start.elapsed() < delay, "the client gave up before the reply came");
    // The late reply lands as stale input; the client discards it before the next request.
    let waiting = Instant::now();
    while client.transport().available() < clean_reply.len() {
        assert!(waiting.elapsed() < Duration::from_secs(5), "the late reply never came");
        thread::sleep(Duration::from_millis(10));
    }
    assert!(start.elapsed() >= delay, "it came late");
    assert_eq!(client.call_raw(&request(&read, slave, &[]), &read.layout()).unwrap(), clean_reply);
    assert_eq!(server.device().faults().get(FaultKind::Delay), 1);
    server.stop().unwrap();
}

/// A random value of `field`'s type, within its range.
fn random_value(field: &Field, rng: &mut Rng) -> Value {
    let int = |rng: &mut Rng, (min, max): (f64, f64)| Value::Int(min as i64 + rng.below((max - min) as u64 + 1) as i64);
    let range = |default: (f64, f64)| field.range.unwrap_or(default);
    match &field.kind {
        FieldKind::F32 { .. } => {
            let (min, max) = range((-100.0, 100.0));
            Value::Float((min + rng.next_f64() * (max - min)) as f32)
        }
        FieldKind::I8 | FieldKind::I16 { .. } | FieldKind::I32 { .. } => int(rng, range((-100.0, 100.0))),
        FieldKind::U8 | FieldKind::U16 { .. } | FieldKind::U32 { .. } => int(rng, range((0.0, 100.0))),
        FieldKind::Bcd => int(rng, range((0.0, 99.0))),
        FieldKind::Enum { variants, .. } => {
            Value::Int(i64::from(variants[rng.below(variants.len() as u64) as usize].value))
        }
        FieldKind::Flags { flags, .. } => {
            Value::Int(flags.iter().filter(|_| rng.chance(0.5)).fold(0, |bits, f| bits | i64::from(f.mask)))
        }
        FieldKind::Ascii { len, .. } => {
            Value::Text((0..*len).map(|_| char::from(b'A' + rng.below(26) as u8)).collect())
        }
        FieldKind::Version => Value::Text(format!("{}.{}", rng.below(10), rng.below(10))),
        FieldKind::Reserved { .. } => Value::Int(0),
    }
}

/// Random values for a write command's fields, within their ranges.
fn random_values(command: &CommandSpec, rng: &mut Rng) -> BTreeMap<String, Value> {
    command.named_fields().map(|f| (f.name.clone().unwrap(), random_value(f, rng))).collect()
}

/// How one soak transaction ended.
#[derive(Debug, Default)]
struct Tally {
    clean: u64,
    recovered: u64,
    failed: BTreeMap<String, u64>,
}

fn failure_kind(e: &Error) -> String {
    match e {
        Error::Timeout { received: 0, .. } => "timeout (silent)".into(),
        Error::Timeout { .. } => "timeout (partial)".into(),
        Error::Frame { error: FrameError::Exception { code, .. }, .. } => format!("exception {code}"),
        Error::Frame { error: FrameError::Crc { .. }, .. } => "crc".into(),
        Error::Frame { error: FrameError::WrongSlave { .. }, .. } => "wrong slave".into(),
        Error::Frame { error, .. } => format!("frame: {error}"),
        other => format!("other: {other}"),
    }
}

#[test]
fn soak_10k_transactions_with_10_percent_faults_accepts_no_wrong_value() {
    const TRANSACTIONS: usize = 10_000;
    // Every sensor of the spec on one bus, at addresses 1, 2, ...
    let spec = spec();
    let sensors: Vec<(u8, &Sensor)> = spec.sensors.iter().enumerate().map(|(i, s)| (i as u8 + 1, s)).collect();
    let bus = sensors.iter().fold(Bus::new(), |bus, &(address, sensor)| {
        let faults = FaultConfig::uniform(11 * u64::from(address), 0.10);
        bus.with(Simulator::new(sensor.clone()).with_address(address).with_faults(faults))
    });
    let config = ClientConfig {
        timeout: Duration::from_millis(2),
        retry: RetryPolicy { retries: 3, backoff: Duration::ZERO, ..RetryPolicy::default() },
        ..ClientConfig::default()
    };
    let mut client = Client::with_config(ResponderTransport::new(bus), config);
    // Every command but the address-changing one and the 0xFF wildcard (two
    // devices would collide on it).
    let plan: Vec<(u8, &Sensor, &CommandSpec)> = sensors
        .iter()
        .copied()
        .flat_map(|(address, sensor)| sensor.commands.iter().map(move |c| (address, sensor, c)))
        .filter(|(_, _, c)| c.fixed_slave.is_none() && c.role != Some(Role::SetSlaveAddress))
        .collect();
    let mut rng = Rng::new(2024);
    let mut tally = Tally::default();
    let mut wrong = 0u64;
    let started = Instant::now();
    for _ in 0..TRANSACTIONS {
        let (address, _sensor, cmd) = plan[rng.below(plan.len() as u64) as usize];
        let bus = client.transport_mut().responder_mut();
        let device = bus.device_mut(address).unwrap();
        // Vary the truth: a fresh reading before each measurement read.
        if device.is_measurement(&cmd.name) {
            for field in cmd.named_fields().filter(|f| matches!(f.kind, FieldKind::F32 { .. })) {
                let v = Value::Float((rng.next_f64() * 20.0) as f32);
                device.set(&cmd.name, field.name.as_deref().unwrap(), v).unwrap();
            }
        }
        let faults_before = device.faults().total();
        let values = if cmd.is_read() { BTreeMap::new() } else { random_values(cmd, &mut rng) };
        let req = cmd.encode_request(address, &values).unwrap();
        let result = client.call_raw(&req, &cmd.layout()).map(<[u8]>::to_vec);
        let device = client.transport().responder().device(address).unwrap();
        let faulted = device.faults().total() > faults_before;
        match result {
            Ok(reply) => {
                let good = if cmd.is_read() {
                    let got = cmd.decode_response(address, &reply).unwrap();
                    same(&got, &device.values(&cmd.name).unwrap())
                } else {
                    // The write's echo was accepted: the device must hold the
                    // values, byte for byte as the request carried them.
                    let sent = cmd.layout().decode_request(&req).unwrap().1;
                    device.registers().read(cmd.address, cmd.count) == sent
                };
                if !good {
                    wrong += 1;
                    eprintln!("WRONG VALUE accepted: {} at {address}: {reply:02X?}", cmd.name);
                }
                if faulted {
                    tally.recovered += 1;
                } else {
                    tally.clean += 1;
                }
            }
            Err(e) => {
                assert!(faulted, "{} failed without an injected fault: {e}", cmd.name);
                *tally.failed.entry(failure_kind(&e)).or_default() += 1;
            }
        }
    }
    let bus = client.transport().responder();
    yosemitech_tests::report!("soak: {TRANSACTIONS} transactions in {:.2?}", started.elapsed());
    yosemitech_tests::report!("  ok first time: {}", tally.clean);
    yosemitech_tests::report!("  ok after faults (retried or noise skipped): {}", tally.recovered);
    for (kind, n) in &tally.failed {
        yosemitech_tests::report!("  failed, {kind}: {n}");
    }
    for device in bus.devices() {
        yosemitech_tests::report!("  device {} ({}): {}", device.address(), device.sensor().name, device.faults());
    }
    yosemitech_tests::report!("  wrong values accepted: {wrong}");
    assert_eq!(wrong, 0, "no wrong value may be accepted");
    assert_eq!(tally.clean + tally.recovered + tally.failed.values().sum::<u64>(), TRANSACTIONS as u64);
    let injected: u64 = bus.devices().iter().map(|d| d.faults().total()).sum();
    let replies: u64 = bus.devices().iter().map(|d| d.faults().replies()).sum();
    let rate = injected as f64 / replies as f64;
    assert!((0.08..0.12).contains(&rate), "fault rate {rate}");
    assert!(tally.recovered > 500, "retries recovered most faults: {tally:?}");
    // Busy is the only fault retries cannot cure (exceptions are final);
    // everything else needs four faults in a row.
    let busy = tally.failed.get("exception server device busy (0x06)").copied().unwrap_or(0);
    assert!(tally.failed.values().sum::<u64>() - busy < 5, "{tally:?}");
    let _ = client.transport_mut().discard_input();
}

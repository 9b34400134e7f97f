//! `yosemitech doctor` against simulated faults on pseudo-terminals: each
//! diagnosis is reproduced by a simulator fault, and each test checks the
//! report's JSON (the verdict's code, and the bytes its evidence holds),
//! never its wording.
#![cfg(unix)]

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read as _};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde_json::Value as Json;
use yosemitech_rtu::{CharFormat, Function, LineSettings, crc_ok};
use yosemitech_sim::{Bus, FaultConfig, FrameHandler, ServeConfig, Simulator, serve_pty};
use yosemitech_spec::{CommandSpec, Role, Sensor};
use yosemitech_tests::cli::{Binary, Run, Sim, interrupt, serve};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

fn unhex(text: &str) -> Vec<u8> {
    text.split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect()
}

/// A sensor of the spec with a serial-number read at its own address and
/// every one of `roles` (the start measurement as a trigger to its own address).
fn sensor_with(roles: &[Role]) -> Sensor {
    spec()
        .sensors
        .iter()
        .find(|s| {
            s.command_with_role(Role::SerialNumber).is_some_and(|c| c.fixed_slave.is_none())
                && roles.iter().all(|r| s.command_with_role(*r).is_some())
        })
        .unwrap_or_else(|| panic!("no sensor of the spec has {roles:?}"))
        .clone()
}

fn role(sensor: &Sensor, role: Role) -> &CommandSpec {
    sensor.command_with_role(role).unwrap()
}

/// The request `command` sends to `slave`.
fn request(command: &CommandSpec, slave: u8) -> Vec<u8> {
    command.encode_request(slave, &BTreeMap::new()).unwrap()
}

/// Runs the doctor on `port` for `sensor`, with `extra` arguments; its JSON
/// report. It exits 0 exactly when the verdict is `healthy`, 1 otherwise.
fn doctor(port: &str, sensor: &Sensor, extra: &[&str]) -> Json {
    let mut args = vec!["doctor", "-p", port, "--sensor", &sensor.name, "--json"];
    args.extend_from_slice(extra);
    let run = YOSEMITECH.run(&args);
    parse(&run)
}

fn parse(run: &Run) -> Json {
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    let json: Json = serde_json::from_str(&run.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}):\n{}\nstderr:\n{}", run.stdout, run.stderr));
    let healthy = json["verdict"]["code"] == "healthy";
    assert_eq!(run.code, if healthy { 0 } else { 1 }, "{json}\n{}", run.stderr);
    assert!(json["requests"].as_u64().unwrap() <= json["max_requests"].as_u64().unwrap(), "{json}");
    json
}

fn verdict(json: &Json) -> &str {
    json["verdict"]["code"].as_str().unwrap()
}

/// The findings of `kind`.
fn findings<'j>(json: &'j Json, kind: &str) -> Vec<&'j Json> {
    json["findings"].as_array().unwrap().iter().filter(|f| f["kind"] == kind).collect()
}

fn finding<'j>(json: &'j Json, kind: &str) -> &'j Json {
    findings(json, kind).first().copied().unwrap_or_else(|| panic!("no `{kind}` finding:\n{json:#}"))
}

fn received(f: &Json) -> Vec<u8> {
    unhex(f["received"].as_str().unwrap())
}

/// The register contents of a simulated probe, to compare before and after.
fn registers(device: &Simulator) -> Vec<(u16, [u8; 2])> {
    device.registers().iter().collect()
}

fn served<D: FrameHandler + Send + 'static>(device: D, config: ServeConfig) -> Sim<D> {
    let server = serve_pty(device, config).unwrap();
    let path = server.tty_path().unwrap().to_owned();
    Sim { server, path }
}

fn probe(sensor: &Sensor) -> Simulator {
    Simulator::new(Arc::new(sensor.clone())).with_address(sensor.default_address)
}

#[test]
fn a_healthy_probe_is_read_and_nothing_is_changed() {
    let sensor = sensor_with(&[Role::Version, Role::StartMeasurement]);
    let s = serve(probe(&sensor));
    let before = registers(&s.server.device());
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "healthy", "{json:#}");
    let reply = finding(&json, "reply");
    let sn = role(&sensor, Role::SerialNumber);
    assert_eq!(reply["sent"], hex(&request(sn, sensor.default_address)));
    assert!(sn.decode_response(sensor.default_address, &received(reply)).is_ok(), "{reply}");
    // Read-only: every register as it was; the one write-function frame is
    // the zero-register Start Measurement trigger, if the sensor's is one.
    let device = s.server.device();
    assert_eq!(registers(&device), before);
    let start = role(&sensor, Role::StartMeasurement);
    let trigger_writes = u64::from(start.function == Function::Write && start.count == 0);
    assert!(device.stats().writes <= trigger_writes, "{:?}", device.stats());
    assert!(start.function == Function::Read || start.count == 0, "the doctor sends no register write");
    assert_eq!(json["answering"]["address"], sensor.default_address);
}

#[test]
fn an_adapter_echo_is_our_own_request_read_back() {
    let sensor = sensor_with(&[]);
    let s = served(probe(&sensor), ServeConfig { echo: true, ..ServeConfig::default() });
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "echo", "{json:#}");
    let echo = finding(&json, "echo");
    let sent = request(role(&sensor, Role::SerialNumber), sensor.default_address);
    assert_eq!(echo["sent"], hex(&sent));
    let back = received(echo);
    assert_eq!(back[..sent.len()], sent[..], "the echo is the request");
    // The probe's reply follows the echo.
    let sn = role(&sensor, Role::SerialNumber);
    assert!(sn.decode_response(sensor.default_address, &back[sent.len()..]).is_ok(), "{echo}");
}

/// A bare pty pair: the far end is held open by `far`, which either reads
/// nothing or writes every byte back (a loop-back).
fn bare_pty(loop_back: bool) -> (String, std::thread::JoinHandle<()>, Arc<std::sync::atomic::AtomicBool>) {
    use serialport::SerialPort;
    use std::sync::atomic::{AtomicBool, Ordering};
    let (mut master, slave) = serialport::TTYPort::pair().unwrap();
    let path = slave.name().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::clone(&stop);
    master.set_timeout(Duration::from_millis(20)).unwrap();
    let far = std::thread::spawn(move || {
        let _slave = slave;
        let mut buf = [0u8; 256];
        while !done.load(Ordering::SeqCst) {
            match master.read(&mut buf) {
                Ok(n) if loop_back => {
                    let _ = std::io::Write::write_all(&mut master, &buf[..n]);
                }
                _ => {}
            }
        }
    });
    (path, far, stop)
}

#[test]
fn a_loop_back_is_an_echo_and_nothing_else() {
    // No sensor named: the doctor sends the frames most sensors share.
    let (path, far, stop) = bare_pty(true);
    let json = parse(&YOSEMITECH.run(&["doctor", "-p", &path, "--json"]));
    assert_eq!(verdict(&json), "echo", "{json:#}");
    let echo = finding(&json, "echo");
    let sent = unhex(echo["sent"].as_str().unwrap());
    assert_eq!(received(echo), sent, "only the request came back");
    assert_eq!(json["requests"], 1);
    // It is a serial-number read of some loaded sensor.
    let sensors = &spec().sensors;
    assert!(
        sensors.iter().filter_map(|s| s.command_with_role(Role::SerialNumber)).any(|c| request(c, sent[0]) == sent)
    );
    // As text: the verdict is an error (exit 1) with the next step as its hint.
    YOSEMITECH.run(&["doctor", "-p", &path]).fails_with_hint(1);
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    far.join().unwrap();
}

#[test]
fn a_line_with_nothing_on_it_is_silent_within_a_minute() {
    let sensor = sensor_with(&[]);
    let (path, far, stop) = bare_pty(false);
    let started = Instant::now();
    let json = doctor(&path, &sensor, &[]);
    let took = started.elapsed();
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    far.join().unwrap();
    assert_eq!(verdict(&json), "silent", "{json:#}");
    assert!(took < Duration::from_secs(60), "took {took:?}");
    let first = &json["findings"][0];
    assert_eq!(first["kind"], "silent");
    assert_eq!(first["sent"], hex(&request(role(&sensor, Role::SerialNumber), sensor.default_address)));
    assert_eq!(first["received"], "");
    // Every address was scanned once at the expected settings, and each
    // other setting asked: the whole bounded plan, no more.
    let requests = json["requests"].as_u64().unwrap();
    assert!(requests > 246, "{requests} requests");
    assert!(!json["skipped"].as_array().unwrap().is_empty());
    report!("a silent line: {requests} requests in {took:?}");
}

#[test]
fn ctrl_c_stops_with_the_findings_so_far() {
    let sensor = sensor_with(&[]);
    let mute = probe(&sensor).with_faults(FaultConfig { drop: 1.0, ..FaultConfig::seeded(1) });
    let s = serve(mute);
    let mut child = YOSEMITECH
        .command()
        .args(["doctor", "-p", &s.path, "--sensor", &sensor.name, "--json"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Progress names each phase on stderr; stop it once it scans.
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while !line.contains("scanning") {
        line.clear();
        assert!(err.read_line(&mut line).unwrap() > 0, "no scan phase on stderr");
    }
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let mut stdout = String::new();
    child.stdout.take().unwrap().read_to_string(&mut stdout).unwrap();
    let code = yosemitech_tests::cli::wait(&mut child, Duration::from_secs(10));
    let run = Run { code, stdout, stderr: String::new() };
    let json = parse(&run);
    assert_eq!(verdict(&json), "interrupted", "{json:#}");
    let silent = finding(&json, "silent");
    assert_eq!(silent["sent"], hex(&request(role(&sensor, Role::SerialNumber), sensor.default_address)));
    assert!(s.server.device().stats().requests >= 1);
}

#[test]
fn a_probe_at_other_serial_settings_answers_garbage_until_the_sweep_finds_them() {
    let sensor = sensor_with(&[]);
    let sn = role(&sensor, Role::SerialNumber);
    let mut cases = vec![LineSettings { baud: 19_200, format: CharFormat::EIGHT_N_1 }];
    if yosemitech_sim::pty_keeps_parity() {
        let even = CharFormat { parity: yosemitech_rtu::Parity::Even, ..CharFormat::EIGHT_N_1 };
        cases.push(LineSettings { baud: 9600, format: even });
    } else {
        report!("this system's ptys drop parity: the parity case is not run");
    }
    for settings in cases {
        let config = ServeConfig { settings: Some(settings), seed: 7, ..ServeConfig::default() };
        let s = served(probe(&sensor), config);
        let json = doctor(&s.path, &sensor, &[]);
        assert_eq!(verdict(&json), "serial_settings", "{json:#}");
        assert_eq!(json["answering"]["settings"], settings.to_string());
        let found = finding(&json, "settings");
        assert_eq!(found["settings"], settings.to_string());
        assert!(sn.decode_response(sensor.default_address, &received(found)).is_ok(), "{found}");
        // At the expected settings: bytes, and no frame among them.
        let garbage = finding(&json, "garbage");
        assert_eq!(garbage["settings"], LineSettings::default().to_string());
        let bytes = received(garbage);
        assert!(!bytes.is_empty() && sn.decode_response(sensor.default_address, &bytes).is_err(), "{garbage}");
    }
}

#[test]
fn replies_damaged_at_a_rate_are_noise() {
    let sensor = sensor_with(&[Role::Version]);
    let noisy = probe(&sensor).with_faults(FaultConfig { corrupt_crc: 0.4, ..FaultConfig::seeded(3) });
    let s = serve(noisy);
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "noise", "{json:#}");
    let noise = finding(&json, "noise");
    let bytes = received(noise);
    assert!(!bytes.is_empty() && !crc_ok(&bytes), "the evidence is a damaged reply: {noise}");
    assert_eq!(bytes[0], sensor.default_address);
    let injected = s.server.device().faults().total();
    assert!(injected > 0 && injected < s.server.device().stats().replies, "damaged between good ones");
}

#[test]
fn replies_damaged_every_time_but_differently_are_noise_not_a_collision() {
    let sensor = sensor_with(&[Role::Version]);
    let noisy = probe(&sensor).with_faults(FaultConfig { corrupt_crc: 1.0, ..FaultConfig::seeded(5) });
    let s = serve(noisy);
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "noise", "{json:#}");
    assert!(findings(&json, "collision").is_empty());
    assert!(!crc_ok(&received(finding(&json, "noise"))));
    assert!(findings(&json, "reply").is_empty(), "no reply came through intact");
}

/// `yosemitech simulate ARGS` in a child process, and the port it serves.
#[test]
fn two_probes_on_one_address_collide_the_same_way_every_time() {
    let sensor = sensor_with(&[Role::Version]);
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--collide"]);
    let json = doctor(&port, &sensor, &[]);
    interrupt(child);
    assert_eq!(verdict(&json), "collision", "{json:#}");
    let collision = finding(&json, "collision");
    let bytes = received(collision);
    let sn = role(&sensor, Role::SerialNumber);
    assert_eq!(collision["command"], sn.name);
    // A frame's head from the right address, a CRC that fails, and not the
    // reply one probe alone sends.
    assert_eq!(bytes[..2], [sensor.default_address, 0x03]);
    assert!(!crc_ok(&bytes));
    let mut alone = Vec::new();
    probe(&sensor).handle(&request(sn, sensor.default_address), &mut alone);
    assert_ne!(bytes, alone);
    // Every serial-number reply came back damaged alike, the version intact.
    let damaged = findings(&json, "damaged");
    assert!(damaged.iter().all(|d| received(d) == bytes), "{json:#}");
}

#[test]
fn a_probe_at_another_address_is_found_through_the_wildcard() {
    let sensor = sensor_with(&[Role::GetSlaveAddress]);
    let elsewhere = if sensor.default_address == 5 { 6 } else { 5 };
    let s = serve(probe(&sensor).with_address(elsewhere));
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "other_address", "{json:#}");
    assert_eq!(json["answering"]["address"], elsewhere);
    let wildcard = finding(&json, "wildcard");
    let get = role(&sensor, Role::GetSlaveAddress);
    assert_eq!(wildcard["sent"], hex(&request(get, 0xFF)));
    let values = get.decode_response(0xFF, &received(wildcard)).unwrap();
    assert!(values.iter().any(|(_, v)| *v == yosemitech_spec::Value::Int(i64::from(elsewhere))), "{values:?}");
}

#[test]
fn a_probe_outside_the_addresses_answers_only_at_the_wildcard() {
    let sensor = sensor_with(&[Role::GetSlaveAddress]);
    let s = serve(probe(&sensor).with_address(250));
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "only_wildcard", "{json:#}");
    assert_eq!(json["answering"]["address"], 250);
    let wildcard = finding(&json, "wildcard");
    assert_eq!(received(wildcard)[0], 0xFF);
    assert!(role(&sensor, Role::GetSlaveAddress).decode_response(0xFF, &received(wildcard)).is_ok());
}

#[test]
fn the_scan_finds_a_probe_when_the_wildcard_answer_is_garbled() {
    // Two probes answer the wildcard at once: only the scan finds them.
    let sensor = sensor_with(&[Role::GetSlaveAddress]);
    let (low, high) = (3, 9);
    let bus = Bus::new().with(probe(&sensor).with_address(low)).with(probe(&sensor).with_address(high));
    let s = serve(bus);
    let json = doctor(&s.path, &sensor, &["--address", "1"]);
    assert_eq!(verdict(&json), "other_address", "{json:#}");
    assert_eq!(json["answering"]["address"], low);
    let reply = findings(&json, "reply").into_iter().find(|f| f["address"] == low).unwrap();
    let sn = role(&sensor, Role::SerialNumber);
    assert_eq!(reply["sent"], hex(&request(sn, low)));
    assert!(sn.decode_response(low, &received(reply)).is_ok());
}

#[test]
fn a_late_answer_is_measured_against_the_timeout() {
    let sensor = sensor_with(&[]);
    let config = ServeConfig { turnaround: Duration::from_millis(1500), ..ServeConfig::default() };
    let s = served(probe(&sensor), config);
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "slow_turnaround", "{json:#}");
    let slow = finding(&json, "slow_turnaround");
    let ms = slow["turnaround_ms"].as_u64().unwrap();
    assert!((1500..3000).contains(&ms), "{ms} ms");
    // The evidence is the late reply itself, intact.
    let read = sensor.command(slow["command"].as_str().unwrap()).unwrap();
    assert!(read.decode_response(sensor.default_address, &received(slow)).is_ok(), "{slow}");
    assert!(json["verdict"]["next_step"].as_str().unwrap().contains("--timeout"));
}

#[test]
fn exception_replies_are_shown_with_their_code() {
    let sensor = sensor_with(&[]);
    let busy = probe(&sensor).with_faults(FaultConfig { busy: 1.0, ..FaultConfig::seeded(1) });
    let s = serve(busy);
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "exception", "{json:#}");
    let exception = finding(&json, "exception");
    let bytes = received(exception);
    assert_eq!(bytes.len(), 5);
    assert_eq!(bytes[..3], [sensor.default_address, 0x83, 0x06]);
    assert!(crc_ok(&bytes));
}

#[test]
fn a_refused_trigger_is_told_from_refused_reads() {
    let sensor = sensor_with(&[Role::StartMeasurement]);
    let mut device = probe(&sensor);
    device.set_refuses_start(true);
    let s = serve(device);
    let json = doctor(&s.path, &sensor, &[]);
    assert_eq!(verdict(&json), "trigger_refused", "{json:#}");
    let refused = finding(&json, "trigger_refused");
    let start = role(&sensor, Role::StartMeasurement);
    assert_eq!(refused["sent"], hex(&request(start, sensor.default_address)));
    let bytes = received(refused);
    assert_eq!(bytes[..2], [sensor.default_address, start.function.code() | 0x80]);
    assert!(crc_ok(&bytes));
    assert!(findings(&json, "exception").is_empty(), "reads are answered");
}

#[test]
fn doctor_and_simulate_misuse_is_a_usage_error() {
    let sensor = sensor_with(&[]);
    YOSEMITECH.run(&["doctor", "-p", "tcp://127.0.0.1:1"]).fails_with_hint(2);
    YOSEMITECH.run(&["doctor"]).fails_with_hint(2);
    YOSEMITECH.run(&["doctor", "-p", "/dev/null-no-such-port", "--address", "0"]).fails_with_hint(2);
    YOSEMITECH.run(&["simulate", &sensor.name, "--serial", "9600-9Z1"]).fails_with_hint(2);
}

#[test]
fn simulate_line_faults_from_the_command_line_reach_the_doctor() {
    let sensor = sensor_with(&[Role::StartMeasurement]);
    let sn = role(&sensor, Role::SerialNumber);
    // Each flag, and the verdict and evidence the doctor gives for it.
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--echo"]);
    let json = doctor(&port, &sensor, &[]);
    interrupt(child);
    assert_eq!(verdict(&json), "echo", "{json:#}");
    assert!(received(finding(&json, "echo")).starts_with(&request(sn, sensor.default_address)));

    // Stop bits alone do not garble (a receiver at 1 stop bit accepts 2):
    // a probe at 19200 8N2 answers the doctor's 19200 8N1.
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--serial", "19200-8N2"]);
    let json = doctor(&port, &sensor, &[]);
    interrupt(child);
    assert_eq!(verdict(&json), "serial_settings", "{json:#}");
    assert_eq!(json["answering"]["settings"], LineSettings { baud: 19_200, format: CharFormat::EIGHT_N_1 }.to_string());

    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--refuse-start"]);
    let json = doctor(&port, &sensor, &[]);
    interrupt(child);
    assert_eq!(verdict(&json), "trigger_refused", "{json:#}");
    let start = role(&sensor, Role::StartMeasurement);
    assert_eq!(finding(&json, "trigger_refused")["sent"], hex(&request(start, sensor.default_address)));
}

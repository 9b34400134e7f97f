//! The `yosemitech` binary against simulated probes on pseudo-terminals
//! (yosemitech-sim's `serve_pty`, or `yosemitech simulate` in a child
//! process), through the real serial code path. No hardware.
#![cfg(unix)]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use std::sync::Arc;

use yosemitech_tests::cli::{Binary, Run, Sim, fixture_spec_dir, interrupt, number_after, sim};
use yosemitech_tests::values::varied_float;
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));
use serde_json::Value as Json;
use yosemitech_sim::{Bus, FaultConfig, FaultKind, Simulator, UnknownRequestPolicy};
use yosemitech_spec::{CommandSpec, Field, FieldKind, Role, Sensor, Value};

/// Short timeouts for requests that are meant to fail.
const FAST: [&str; 4] = ["--timeout", "150ms", "--retries", "0"];

fn float(sim: &yosemitech_tests::cli::Sim<yosemitech_sim::Simulator>, command: &str, field: &str) -> f32 {
    match sim.server.device().get(command, field).unwrap() {
        Value::Float(v) => v,
        other => panic!("{command}.{field} is {other:?}"),
    }
}

/// The number `demo` or `measure` shows for `field` of `read` in `text`:
/// on the line labelled with the field's name, or `read.field` where two
/// reads share the name.
fn shown_number(text: &str, read: &str, field: &str) -> f64 {
    let qualified = format!("{read}.{field}");
    let label = if text.lines().any(|l| l.trim_start().starts_with(&format!("{qualified} "))) {
        qualified
    } else {
        format!("{field} ")
    };
    number_after(text, &label)
}

#[test]
fn demo_reads_every_sensor_and_runs_every_procedure() {
    let started = Instant::now();
    let run = YOSEMITECH.run(&["demo"]);
    let out = run.ok();
    assert!(started.elapsed() < Duration::from_secs(20), "the demo takes a few seconds");
    let (probes, rest) = out.split_once("waits shortened").unwrap_or_else(|| panic!("no procedures:\n{out}"));
    let procedures = rest.split("the whole family on one RS-485 bus").next().unwrap();
    let (mut reads, mut procedures_run, mut compared) = (0, 0, 0);
    for sensor in &spec().sensors {
        // Its own probe: identity, measurements and coefficients, each read's line with every field.
        let header = format!("{} ({}) on ", sensor.title, sensor.name);
        let section = probes.split(&header).nth(1).unwrap_or_else(|| panic!("`{header}` missing:\n{out}"));
        let section = section.split("\n\n").next().unwrap();
        let line = |read: &CommandSpec| {
            let line = section
                .lines()
                .find(|l| l.trim_start().starts_with(&format!("{} ", read.name)))
                .unwrap_or_else(|| panic!("{}: no `{}` line:\n{section}", sensor.name, read.name));
            for field in read.named_fields() {
                assert!(line.contains(&format!("{} ", field.display_name())), "{}: {line}", sensor.name);
            }
            line
        };
        if let Some(sn) = sensor.command_with_role(Role::SerialNumber) {
            let served = served_serial_number(sensor).expect("a simulated probe serves its serial number");
            assert!(line(sn).contains(&served), "{section}");
            reads += 1;
        }
        for read in sensor.measurement_reads().chain(sensor.coefficient_blocks().into_iter().map(|(_, r)| r)) {
            line(read);
            reads += 1;
        }
        // Each derived quantity whose reads the section shows, beside them.
        let shown = |command: &str| section.lines().any(|l| l.trim_start().starts_with(&format!("{command} ")));
        for d in &sensor.derived {
            let covered = d.inputs.iter().all(|i| match &i.source {
                yosemitech_spec::InputSource::Field { command, .. } => shown(command),
                yosemitech_spec::InputSource::Station(_) => true,
            });
            if covered {
                let derived_line = section.lines().find(|l| l.trim_start().starts_with(&format!("{} ", d.name)));
                assert!(
                    derived_line.is_some_and(|l| l.ends_with("(derived)") && !l.contains("not computable")),
                    "{}: no value of {} (derived):\n{section}",
                    sensor.name,
                    d.name
                );
                reads += 1;
            }
        }
        // Its manual's procedure: every field it reads, and the mean of what the simulator serves.
        let Some(procedure) = &sensor.procedure else { continue };
        let part = procedures
            .split(&format!("\n{}: ", sensor.name))
            .nth(1)
            .unwrap_or_else(|| panic!("{}: no procedure:\n{procedures}", sensor.name));
        let part = part.split("\n\n").next().unwrap();
        if procedure.readings > 1 {
            assert!(part.contains(&format!("mean of {} readings", procedure.readings)), "{part}");
        }
        // The demo's probes serve plausible water: each value near what the
        // simulator fills in, within its daily swing, and inside its range.
        let mut simulated = Simulator::new(Arc::new(sensor.clone()));
        simulated.fill_with_water();
        for read in procedure.read.iter().map(|r| sensor.command(r).unwrap()) {
            for field in read.named_fields() {
                let name = field.display_name();
                assert!(
                    part.lines()
                        .any(|l| l.trim_start().starts_with(name) || l.contains(&format!("{}.{name} ", read.name))),
                    "{}: field `{name}` missing:\n{part}",
                    sensor.name
                );
                if field.unit.is_none() {
                    continue;
                }
                let Ok(Value::Float(start)) = simulated.get(&read.name, name) else { continue };
                if !start.is_finite() || part.lines().any(|l| l.contains(name) && l.contains("absent")) {
                    continue;
                }
                let mean = shown_number(part, &read.name, name);
                let span = yosemitech_sim::daily_span(field, start);
                assert!(
                    (mean - f64::from(start)).abs() <= 0.05 * span + 0.01,
                    "{}: {name} {mean} is far from the water's {start}",
                    sensor.name
                );
                if let Some((min, max)) = field.range {
                    assert!(
                        (min - 1e-3..=max + 1e-3).contains(&mean),
                        "{}: {name} {mean} outside {min}..={max}",
                        sensor.name
                    );
                }
                compared += 1;
            }
        }
        procedures_run += 1;
    }
    report!("demo: {reads} reads shown, {procedures_run} procedures run, {compared} means compared");
}

/// The serial-number request `scan` sends to a probe of `sensor` (its
/// serial-number read at its own address), as function, address and count.
fn sn_request(sensor: &Sensor) -> Option<(u8, u16, u16)> {
    sensor
        .command_with_role(Role::SerialNumber)
        .filter(|c| c.fixed_slave.is_none())
        .map(|c| (c.function.code(), c.address, c.count))
}

/// The loaded sensors (the spec's, in spec order) `scan` names for a probe
/// of `sensor` that sends model code `code`: those that send the same
/// serial-number request and declare that code.
fn declaring(sensor: &Sensor, code: &str) -> Vec<Sensor> {
    let request = sn_request(sensor);
    spec()
        .sensors
        .iter()
        .filter(|s| request.is_some() && sn_request(s) == request && s.declares_model_code(code))
        .cloned()
        .collect()
}

/// A sensor as `scan` names it: `name (model, code 09)`.
fn sensor_text(sensor: &Sensor) -> String {
    let about: Vec<String> =
        sensor.model.iter().cloned().chain(sensor.model_code.iter().map(|c| format!("code {c}"))).collect();
    if about.is_empty() { sensor.name.clone() } else { format!("{} ({})", sensor.name, about.join(", ")) }
}

/// What `scan` says of a probe of `sensor` sending its own model code
/// `code` and serial number `sn`: the sensor alone, or, where other loaded
/// sensors send the same request and declare the same code, every one of
/// them and why (`None`: identified alone).
fn scan_says(sensor: &Sensor, code: &str, sn: &str) -> (String, Option<Vec<Sensor>>) {
    let twins = declaring(sensor, code);
    assert!(twins.iter().any(|t| t.name == sensor.name), "{} declares {code}", sensor.name);
    let refs: Vec<&Sensor> = twins.iter().collect();
    if twins.len() == 1 || yosemitech_cli::scan_tells_apart(&refs) {
        return (format!("SN {sn}  {}", sensor_text(sensor)), None);
    }
    let (_, address, _) = sn_request(sensor).unwrap();
    let names: Vec<String> = twins.iter().map(sensor_text).collect();
    let line = format!(
        "SN {sn}  not identified: one of {} ({} loaded sensors read their serial number at 0x{address:04X} and declare model code {code})",
        names.join(", "),
        twins.len()
    );
    (line, Some(twins))
}

/// Whether some read of `sensor` is another sensor's serial-number request
/// (the simulator answers a read by its function, address and count).
fn answers_a_serial_number_request(sensor: &Sensor) -> bool {
    let requests: Vec<(u8, u16, u16)> = spec().sensors.iter().filter_map(sn_request).collect();
    sensor.commands.iter().any(|c| c.is_read() && requests.contains(&(c.function.code(), c.address, c.count)))
}

/// The newest software revision of `sensor`'s manuals.
fn newest_software(sensor: &Sensor) -> Option<String> {
    sensor.manuals().filter_map(|m| m.software.clone()).max_by_key(|sw| {
        let (a, b) = sw.split_once('.').unwrap_or((sw, "0"));
        (a.parse::<u32>().unwrap(), b.parse::<u32>().unwrap())
    })
}

#[test]
fn demo_identifies_every_sensor_of_the_spec_on_one_bus() {
    let run = YOSEMITECH.run(&["demo"]);
    let out = run.ok();
    let section =
        out.split("the whole family on one RS-485 bus").nth(1).unwrap_or_else(|| panic!("no family section:\n{out}"));
    let sensors = spec().sensors.clone();
    let lines: Vec<&str> = section.lines().map(str::trim).filter(|l| l.starts_with("address ")).collect();
    let mut addresses: Vec<usize> = lines
        .iter()
        .map(|l| l.strip_prefix("address").and_then(|a| a.split_whitespace().next()).unwrap().parse().unwrap())
        .collect();
    addresses.sort_unstable();
    assert_eq!(addresses, (1..=sensors.len()).collect::<Vec<_>>(), "one address each:\n{section}");
    let (mut alone, mut among, mut unidentifiable) = (0, 0, 0);
    for (i, sensor) in sensors.iter().enumerate() {
        // The demo puts the sensors on the bus in spec order, at 1, 2, 3...
        let line = lines
            .iter()
            .find(|l| l.starts_with(&format!("address {:3}  ", i + 1)))
            .unwrap_or_else(|| panic!("no line for address {}:\n{section}", i + 1));
        let simulated = format!("[simulated: {}", sensor.name);
        match (sn_request(sensor), &sensor.model_code) {
            (Some(_), Some(code)) => {
                let sn = served_serial_number(sensor).unwrap();
                let (said, twins) = scan_says(sensor, code, &sn);
                assert!(line.contains(&said), "`{said}` missing from the family section:\n{section}");
                if twins.is_some() {
                    assert!(line.ends_with(&format!("{simulated}]")), "the demo says which it is: {line}");
                    among += 1;
                    continue;
                }
                assert!(!line.contains("not identified") && !line.contains("[simulated"), "{line}");
                // The firmware, and the manual that covers it.
                if sensor.command_with_role(Role::Version).is_some()
                    && let Some(sw) = newest_software(sensor)
                {
                    assert!(line.contains(&format!(" SW {sw}  manual SW {sw}")), "{line}");
                }
                alone += 1;
            }
            (Some(_), None) => {
                // Whatever scan makes of the serial number, the demo says what the spec lacks.
                assert!(line.contains(&simulated) && line.contains("no model code"), "{line}");
                unidentifiable += 1;
            }
            (None, _) => {
                assert!(line.contains(&simulated) && line.contains("no serial-number read"), "{line}");
                if !answers_a_serial_number_request(sensor) {
                    assert!(line.contains("not identified: no serial number read"), "{line}");
                }
                unidentifiable += 1;
            }
        }
    }
    let n = sensors.len();
    let count =
        if alone == n { format!("{n} probes identified in ") } else { format!("{alone} of {n} probes identified in ") };
    let requests = number_after(section, &count) as usize;
    assert!(requests <= n * (sn_layouts() + 1), "{requests} requests:\n{section}");
    report!(
        "demo's bus: {alone} probes identified alone, {among} among the sensors of their model code, {unidentifiable} \
         whose spec gives scan no way to tell, in {requests} requests"
    );
}

/// The example of `command` in the sensor's own manual, with values.
fn stated_example(command: &CommandSpec) -> Option<&yosemitech_spec::Example> {
    command.examples.iter().find(|e| e.manual.is_none() && e.erratum.is_none() && !e.values.is_empty())
}

/// `value unit` as `read` shows a field: the unit as the CLI shows it.
fn shown(value: &Value, unit: Option<&str>) -> String {
    let value = match value {
        Value::Float(f) => f.to_string(),
        Value::Int(i) => i.to_string(),
        Value::Text(t) => t.clone(),
        other => panic!("{other:?}"),
    };
    unit.map_or(value.clone(), |u| format!("{value} {}", yosemitech_cli::shown_unit(u)))
}

/// The shortest prefix of `name` no other sensor's name starts with, if
/// one is shorter than the name.
fn unique_prefix(name: &str) -> Option<&str> {
    let names: Vec<String> = spec().sensors.iter().map(|s| s.name.clone()).collect();
    (1..name.len()).map(|n| &name[..n]).find(|p| names.iter().filter(|n| n.starts_with(p)).count() == 1)
}

#[test]
fn read_shows_values_with_units() {
    let (mut checked, mut shortened, mut versions, mut addressed) = (0, 0, 0, 0);
    for sensor in spec().sensors.clone() {
        let name = sensor.name.as_str();
        let address = sensor.default_address;
        let s = sim(name, address);
        // Every measurement read with a stated f32 value: each field on a
        // line, `name  value unit`, as the manual's example states it.
        for command in sensor.commands.iter().filter(|c| c.is_read() && c.role.is_none()) {
            let Some(example) = stated_example(command) else { continue };
            let f32_with_unit: Vec<_> = command
                .named_fields()
                .filter(|f| matches!(f.kind, FieldKind::F32 { .. }) && f.unit.is_some())
                .collect();
            if f32_with_unit.is_empty() || command.named_fields().count() != f32_with_unit.len() {
                continue;
            }
            if f32_with_unit.iter().any(|f| {
                example
                    .values
                    .get(f.display_name())
                    .is_none_or(|v| !v.same_as(&s.server.device().get(&command.name, f.display_name()).unwrap()))
            }) {
                continue; // the simulator does not answer this example
            }
            let out = YOSEMITECH.run(&["read", name, &command.name, "--port", &s.path]).ok().to_owned();
            // Names may be shortened: a unique prefix of the sensor, the command without `get_`.
            if shortened == 0
                && let (Some(short), Some(prefix)) = (command.name.strip_prefix("get_"), unique_prefix(name))
            {
                assert_eq!(YOSEMITECH.run(&["read", prefix, short, "-p", &s.path]).ok(), out, "{prefix} {short}");
                shortened += 1;
            }
            let width = f32_with_unit.iter().map(|f| f.display_name().len()).max().unwrap();
            for field in &f32_with_unit {
                let value = &example.values[field.display_name()];
                let line = format!("{:width$}  {}", field.display_name(), shown(value, field.unit.as_deref()));
                assert!(out.lines().any(|l| l == line), "{name} {}: `{line}` in:\n{out}", command.name);
            }
            let measured = out.lines().filter(|l| !l.ends_with("(derived)") && !l.starts_with("note: "));
            assert_eq!(measured.count(), f32_with_unit.len(), "{out}");
            checked += 1;
        }
        // The version, as JSON.
        if let Some(version) = sensor.command_with_role(Role::Version) {
            let json = YOSEMITECH.run(&["read", name, &version.name, "-p", &s.path, "--json"]).json();
            for field in version.named_fields() {
                let want = s.server.device().get(&version.name, field.display_name()).unwrap();
                assert_eq!(json["values"][field.display_name()], serde_json::to_value(&want).unwrap(), "{json}");
            }
            assert!(json["timestamp"].as_str().unwrap().ends_with('Z'));
            versions += 1;
        }
        // A slave address read at a fixed address goes there whatever --address says.
        if let Some(get) = sensor.command_with_role(Role::GetSlaveAddress).filter(|c| c.fixed_slave.is_some()) {
            let field = get.named_fields().next().unwrap().display_name().to_owned();
            let elsewhere = elsewhere(address).to_string();
            let out = YOSEMITECH.run(&["read", name, &get.name, "-p", &s.path, "-a", &elsewhere]).ok().to_owned();
            assert_eq!(out.trim(), format!("{field}  {address}"));
            addressed += 1;
        }
    }
    report!(
        "read: {checked} stated f32 readings shown, {shortened} with shortened names, {versions} versions as JSON, \
         {addressed} slave-address reads at a fixed address"
    );
}

/// An address other than `address`: where no simulated probe is.
fn elsewhere(address: u8) -> u8 {
    if address == 9 { 10 } else { 9 }
}

#[test]
fn port_and_baud_come_from_the_environment() {
    let sensors = identifiable();
    for sensor in &sensors {
        let s = sim(&sensor.name, sensor.default_address);
        let (sn, _) = sn_field(sensor);
        let mut cmd = YOSEMITECH.command();
        cmd.args(["read", &sensor.name, &sn.name])
            .env("YOSEMITECH_PORT", &s.path)
            .env("YOSEMITECH_BAUD", sensor.serial.baud.to_string());
        let run = yosemitech_tests::cli::run_command(cmd, None);
        assert!(run.ok().contains(&served_serial_number(sensor).unwrap()), "{}: {}", sensor.name, run.stdout);
    }
    report!("{} serial numbers read with the port and baud from the environment", sensors.len());
}

/// A measurement read of `sensor`: a read with no role, at the probe's own address.
fn measurement_read(sensor: &Sensor) -> Option<&CommandSpec> {
    sensor.commands.iter().find(|c| c.is_read() && c.role.is_none() && c.fixed_slave.is_none())
}

/// A read of another sensor at registers `sensor` lacks, sent to its own
/// address: a command the probe does not have.
fn foreign_read(sensor: &Sensor, trigger: bool) -> Option<(Sensor, CommandSpec)> {
    spec().sensors.iter().flat_map(|o| o.commands.iter().map(move |c| (o, c))).find_map(|(o, c)| {
        (c.is_read()
            && (trigger || !c.trigger)
            && c.fixed_slave.is_none()
            && !sensor.commands.iter().any(|m| m.function == c.function && m.address == c.address))
        .then(|| (o.clone(), c.clone()))
    })
}

#[test]
fn a_silent_address_times_out_cleanly() {
    let sensors = spec().sensors.clone();
    let Some((sensor, read)) = sensors.iter().find_map(|s| measurement_read(s).map(|r| (s, r))) else {
        report!("no sensor of the spec has a measurement read at its own address: nothing to time out");
        return;
    };
    let address = sensor.default_address.to_string();
    let s = sim(&sensor.name, sensor.default_address);
    let silent = elsewhere(sensor.default_address).to_string();
    let mut args = vec!["read", sensor.name.as_str(), read.name.as_str(), "-p", &s.path, "-a", &silent];
    args.extend(["--timeout", "100ms", "--retries", "1"]);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(
        err.contains(&format!("no reply to {} from address {silent}", read.name)) && err.contains("within 100ms"),
        "{err}"
    );
    assert!(err.contains("yosemitech scan"), "{err}");
    // A command the probe does not have (another sensor's read at registers
    // this one lacks), at the probe's address: real probes stay silent, and
    // the hint says so.
    let Some((other, foreign)) = foreign_read(sensor, true) else {
        report!("no sensor of the spec reads registers {} lacks: no foreign read sent", sensor.name);
        return;
    };
    let mut args = vec!["read", other.name.as_str(), foreign.name.as_str(), "-p", &s.path, "-a", &address];
    args.extend(FAST);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(err.contains(&format!("no reply to {}", foreign.name)) && err.contains("lacks"), "{err}");
    // A device that answers exceptions instead: the exception (no register
    // there), explained.
    let mut device = Simulator::new(yosemitech_tests::sensor(&sensor.name));
    device.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let s = yosemitech_tests::cli::serve(device);
    let run = YOSEMITECH.run(&["read", &other.name, &foreign.name, "-p", &s.path, "-a", &address]);
    let want = format!("refused {} with Modbus exception illegal data address", foreign.name);
    assert!(run.fails_with_hint(1).contains(&want), "{}", run.stderr);
}

/// `name=value` arguments of `values`.
fn assignments(values: &std::collections::BTreeMap<String, Value>) -> Vec<String> {
    values
        .iter()
        .map(|(k, v)| match v {
            Value::Float(f) => format!("{k}={f}"),
            Value::Int(i) => format!("{k}={i}"),
            other => panic!("{k} = {other:?} is not a number"),
        })
        .collect()
}

/// True when some read of `sensor` covers the registers `write` writes.
fn read_covers(sensor: &Sensor, write: &CommandSpec) -> bool {
    let end = u32::from(write.address) + u32::from(write.count);
    sensor
        .commands
        .iter()
        .any(|r| r.is_read() && r.address <= write.address && u32::from(r.address) + u32::from(r.count) >= end)
}

/// Whether every value is a number (what [`assignments`] can write).
fn numeric(values: &std::collections::BTreeMap<String, Value>) -> bool {
    values.values().all(|v| matches!(v, Value::Float(_) | Value::Int(_)))
}

/// An address for a probe to move to, none of `taken`: inside the range of
/// the address write's field, near its middle.
fn new_address(set: &CommandSpec, taken: &[u8]) -> u8 {
    let (min, max) = set.named_fields().next().and_then(|f| f.range).unwrap_or((1.0, 247.0));
    let (min, max) = (min.max(1.0) as u8, max.min(247.0) as u8);
    let middle = min + (max - min) / 2;
    (middle..=max).chain(min..middle).find(|a| !taken.contains(a)).expect("a free address in the write's range")
}

#[test]
fn write_backs_up_coefficients_confirms_and_reads_back() {
    let Some(sensor) = yosemitech_tests::cli::sensors_with_coefficients().into_iter().next() else {
        report!("no sensor of the spec has a coefficient block: no coefficient written");
        return;
    };
    let name = sensor.name.as_str();
    let address = sensor.default_address;
    let blocks = sensor.coefficient_blocks();
    let (write, read) = blocks[0];
    let fields: Vec<&Field> = write.named_fields().collect();
    let s = sim(name, address);
    let old = coefficients(&s, &sensor);
    // New values inside each field's range, unlike the probe's.
    let new: std::collections::BTreeMap<String, Value> = fields
        .iter()
        .enumerate()
        .map(|(j, f)| {
            let was = float(&s, &read.name, f.display_name());
            (f.display_name().to_owned(), Value::Float(another_float(f, j + 1, was)))
        })
        .collect();
    let fields: Vec<String> = fields.iter().map(|f| f.display_name().to_owned()).collect();
    let dir = tempfile::tempdir().unwrap();
    let backup_dir = dir.path().to_str().unwrap();
    // Without a terminal and without --yes, nothing is sent.
    let positional: Vec<String> = fields.iter().map(|f| format!("{}", float_of(&new[f]))).collect();
    let mut args = vec!["write", name, write.name.as_str()];
    args.extend(positional.iter().map(String::as_str));
    args.extend(["-p", &s.path]);
    let run = YOSEMITECH.run(&args);
    assert!(run.fails_with_hint(2).contains("--yes") || run.stderr.contains("stdin is not a terminal"));
    for (c, f, v) in &old {
        assert_eq!(float(&s, c, f).to_bits(), v.to_bits(), "nothing sent");
    }

    let named = assignments(&new);
    let mut args = vec!["write", name, write.name.as_str()];
    args.extend(named.iter().map(String::as_str));
    args.extend(["-p", &s.path, "--yes", "--backup-dir", backup_dir]);
    let run = YOSEMITECH.run(&args);
    let out = run.ok();
    let frame = write.encode_request(address, &new).unwrap();
    let frame: Vec<String> = frame.iter().map(|b| format!("{b:02X}")).collect();
    assert!(out.contains(&format!("frame: {}", frame.join(" "))), "{out}");
    for f in &fields {
        let shown = format!("{f} = {}", float_of(&new[f]));
        let line = out.lines().map(str::trim).find(|l| l.starts_with(&format!("{shown} ")) && l.ends_with("(matches)"));
        assert!(line.is_some(), "`{shown} ... (matches)` in:\n{out}");
    }
    assert!(out.contains("verified"), "{out}");
    assert!(out.contains(&format!("restore with: yosemitech coefficients restore {name} --port")), "{out}");
    for f in &fields {
        assert_eq!(float(&s, &read.name, f).to_bits(), float_of(&new[f]).to_bits());
    }
    let files: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(files.len(), 1, "one backup file");
    let backup: Json =
        serde_json::from_str(&std::fs::read_to_string(files[0].as_ref().unwrap().path()).unwrap()).unwrap();
    // The backup holds the old values of every block.
    for (w, r) in &blocks {
        for (c, f, v) in old.iter().filter(|(c, _, _)| *c == r.name) {
            let saved = backup["coefficients"][&w.name][f].as_f64().unwrap_or_else(|| panic!("{c}.{f}: {backup}"));
            assert_eq!((saved as f32).to_bits(), v.to_bits(), "{c}.{f}: {backup}");
        }
    }

    // A write that is not a coefficient and that no read covers: no backup,
    // and no read-back. Any such write of the spec with an example's values.
    let uncovered = spec()
        .sensors
        .iter()
        .flat_map(|s| s.commands.iter().map(move |c| (s, c)))
        .filter(|(s, c)| !c.is_read() && c.count > 0 && !read_covers(s, c))
        .find_map(|(s, c)| {
            let e = c.examples.iter().find(|e| !e.values.is_empty() && e.erratum.is_none() && numeric(&e.values))?;
            Some((s.clone(), c.clone(), e.values.clone()))
        });
    match uncovered {
        Some((other, command, values)) => {
            let s2 = sim(&other.name, other.default_address);
            let values = assignments(&values);
            let mut args = vec!["write", other.name.as_str(), command.name.as_str()];
            args.extend(values.iter().map(String::as_str));
            args.extend(["-p", &s2.path, "--yes"]);
            let out = YOSEMITECH.run(&args).ok().to_owned();
            assert!(out.contains("nothing to read back") && !out.contains("saved every coefficient"), "{out}");
        }
        None => report!("no write of the spec that no read covers has an example: none written"),
    }
    // The address write: the probe moves, and a read of the same registers
    // (at a fixed address, where the spec has one) reads the new address back.
    let Some(set) = sensor.command_with_role(Role::SetSlaveAddress).filter(|c| c.fixed_slave.is_none()) else {
        report!("{name} has no slave-address write: its address stays");
        return;
    };
    let field = set.named_fields().next().unwrap().display_name().to_owned();
    let to = new_address(set, &[address]);
    let out = YOSEMITECH.run(&["write", name, &set.name, &to.to_string(), "-p", &s.path, "--yes"]).ok().to_owned();
    assert!(out.contains(&format!("now answers at address {to}")), "{out}");
    if read_covers(&sensor, set) {
        assert!(out.contains(&format!("{field} = {to} (matches)")), "{out}");
    } else {
        assert!(out.contains("nothing to read back"), "{out}");
    }
    assert_eq!(s.server.device().address(), to);
}

fn float_of(v: &Value) -> f32 {
    match v {
        Value::Float(f) => *f,
        other => panic!("{other:?}"),
    }
}

/// The columns `poll` shows for `sensor` by default: (read, field, column
/// name) of every measurement, taken from the read the station planner
/// picks for it (the fewest reads that cover every measurement).
fn poll_columns(sensor: &Sensor) -> Vec<(String, String, String)> {
    let chosen = yosemitech_station::plan::measurements(sensor);
    yosemitech_station::plan::plan(sensor, &chosen)
        .reads
        .iter()
        .flat_map(|r| r.fields.iter().map(|f| (r.command.name.clone(), (*f).to_owned(), (*f).to_owned())))
        .collect()
}

/// A simulated value as `poll` writes it in CSV: numbers plain, `None`
/// for anything else (enums by name).
fn plain(value: &Value) -> Option<String> {
    match value {
        Value::Float(f) => Some(f.to_string()),
        Value::Int(i) => Some(i.to_string()),
        _ => None,
    }
}

/// The inputs of a derived quantity as (command, field, station default).
type DerivedInputs = Vec<(String, String, Option<f32>)>;

/// The derived quantities whose field inputs all come from `reads`, each
/// with its inputs as (command, field, station default).
fn derived_of(sensor: &Sensor, reads: &[&str]) -> Vec<(yosemitech_spec::Derived, DerivedInputs)> {
    use yosemitech_spec::InputSource;
    sensor
        .derived
        .iter()
        .filter(|d| {
            d.inputs.iter().all(|i| match &i.source {
                InputSource::Field { command, .. } => reads.contains(&command.as_str()),
                InputSource::Station(_) => true,
            })
        })
        .map(|d| {
            let inputs = d
                .inputs
                .iter()
                .map(|i| match &i.source {
                    InputSource::Field { command, field } => (command.clone(), field.clone(), None),
                    InputSource::Station(_) => (String::new(), String::new(), i.default.map(|v| v as f32)),
                })
                .collect();
            (d.clone(), inputs)
        })
        .collect()
}

/// `read` shows each derived quantity its read gives beside the measured
/// values, marked derived, and in `--json`: the interpreter's value for
/// the simulator's reading, station inputs at their defaults.
#[test]
fn read_shows_derived_quantities_beside_measured_ones() {
    let mut shown = 0;
    for sensor in spec().sensors.clone() {
        let name = sensor.name.as_str();
        let s = sim(name, sensor.default_address);
        for command in sensor.commands.iter().filter(|c| c.is_read() && !c.fields.is_empty()) {
            let derived = derived_of(&sensor, &[command.name.as_str()]);
            if derived.is_empty() {
                continue;
            }
            let out = YOSEMITECH.run(&["read", name, &command.name, "-p", &s.path]).ok().to_owned();
            let json = YOSEMITECH.run(&["read", name, &command.name, "-p", &s.path, "--json"]).json();
            for (d, inputs) in &derived {
                let inputs: Vec<f32> =
                    inputs.iter().map(|(c, f, default)| default.unwrap_or_else(|| float(&s, c, f))).collect();
                let line =
                    out.lines().find(|l| l.starts_with(d.name.as_str())).unwrap_or_else(|| panic!("{}: {out}", d.name));
                assert!(line.ends_with("(derived)"), "{line}");
                match d.compute(&inputs) {
                    Ok(v) => {
                        assert!(line.contains(&v.to_string()), "{line}, want {v}");
                        let got = json["derived"][&d.name]["value"].as_f64().unwrap_or_else(|| panic!("{json}"));
                        assert_eq!((got as f32).to_bits(), v.to_bits(), "{json}");
                    }
                    Err(_) => assert!(line.contains("not computable"), "{line}"),
                }
                shown += 1;
            }
        }
    }
    report!("read: {shown} derived quantities shown beside the measured values");
}

#[test]
fn poll_csv_gives_one_row_per_poll() {
    let (mut polled, mut cells_checked) = (0, 0);
    for sensor in spec().sensors.clone() {
        let columns = poll_columns(&sensor);
        if columns.is_empty() {
            continue;
        }
        let name = sensor.name.as_str();
        // The probe at its factory address, where `poll` asks without --address.
        let s = sim(name, sensor.default_address);
        let run = YOSEMITECH.run(&["poll", name, "-p", &s.path, "--count", "3", "--interval", "0", "--format", "csv"]);
        let out = run.ok();
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), 4, "a header and 3 rows:\n{out}");
        let names: Vec<&str> = columns.iter().map(|(_, _, n)| n.as_str()).collect();
        // Then the derived quantities the polled reads give, marked so.
        let derived = derived_of(&sensor, &columns.iter().map(|(r, _, _)| r.as_str()).collect::<Vec<_>>());
        let head = format!("timestamp,{}", names.join(","));
        let middle = lines[0].strip_prefix(&head).and_then(|m| m.strip_suffix(",error"));
        let middle = middle.unwrap_or_else(|| panic!("`{head},...,error` in {}", lines[0]));
        let derived_heads: Vec<&str> = middle.split(',').filter(|h| !h.is_empty()).collect();
        assert_eq!(derived_heads.len(), derived.len(), "{}", lines[0]);
        for (h, (d, _)) in derived_heads.iter().zip(&derived) {
            assert!(h.starts_with(d.name.as_str()) && h.ends_with("(derived)"), "{h}");
        }
        for row in &lines[1..] {
            let cells: Vec<&str> = row.split(',').collect();
            assert_eq!(cells.len(), columns.len() + derived.len() + 2, "{row}");
            for ((d, inputs), cell) in derived.iter().zip(&cells[1 + columns.len()..]) {
                let inputs: Vec<f32> =
                    inputs.iter().map(|(c, f, default)| default.unwrap_or_else(|| float(&s, c, f))).collect();
                let want = d.compute(&inputs).map(|v| v.to_string()).unwrap_or_default();
                assert_eq!(*cell, want, "{name} {}: {row}", d.name);
                cells_checked += 1;
            }
            assert!(cells[0].len() == 24 && cells[0].ends_with('Z') && cells[0].as_bytes()[10] == b'T', "{row}");
            for ((read, field, _), cell) in columns.iter().zip(&cells[1..]) {
                let want = s.server.device().get(read, field).unwrap();
                match plain(&want) {
                    Some(want) => assert_eq!(*cell, want, "{name} {read}.{field}: {row}"),
                    None => assert!(!cell.is_empty(), "{name} {read}.{field}: {row}"),
                }
                cells_checked += 1;
            }
            assert_eq!(cells.last(), Some(&""), "no error: {row}");
        }
        polled += 1;
    }
    report!("poll csv: {polled} sensors polled, {cells_checked} cells checked");
}

#[test]
fn poll_reports_errors_per_row_and_goes_on() {
    let mut polled = 0;
    for sensor in spec().sensors.clone() {
        let columns = poll_columns(&sensor);
        let Some((first, _, _)) = columns.first().cloned() else { continue };
        let name = sensor.name.as_str();
        let s = sim(name, sensor.default_address);
        // The first reply is lost: that row carries the error, the next ones do not.
        s.server.device().set_faults(FaultConfig::scripted([Some(FaultKind::Drop)]));
        let mut args = vec!["poll", name, "-p", &s.path, "-n", "3", "-i", "0", "-f", "json"];
        args.extend(FAST);
        let run = YOSEMITECH.run(&args);
        let rows: Vec<Json> = run.ok().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        assert_eq!(rows.len(), 3);
        assert_eq!(rows[0]["error"], format!("{first}: no reply").as_str(), "{name}");
        assert_eq!(rows[1]["error"], Json::Null);
        for (read, field, column) in &columns {
            if *read == first {
                assert_eq!(rows[0]["values"][column], Json::Null, "{name} {column}");
            }
            if let Value::Float(v) = s.server.device().get(read, field).unwrap() {
                let got = rows[1]["values"][column].as_f64().unwrap_or_else(|| panic!("{name} {column}: {}", rows[1]));
                assert_eq!((got as f32).to_bits(), v.to_bits(), "{name} {column}");
            }
            assert_eq!(rows[2]["values"][column], rows[1]["values"][column], "{name} {column}");
        }

        // Every poll failing is exit 1, after every row was printed.
        let silent = elsewhere(sensor.default_address).to_string();
        let mut args = vec!["poll", name, "-p", &s.path, "-a", &silent, "-n", "2", "-i", "0", "-f", "table"];
        args.extend(FAST);
        let run = YOSEMITECH.run(&args);
        run.fails_with_hint(1);
        assert_eq!(run.stdout.lines().count(), 3, "{}", run.stdout);
        assert!(run.stdout.contains("no reply"), "{}", run.stdout);
        polled += 1;
    }
    report!("poll: {polled} sensors polled through a lost reply and a silent address");
}

#[test]
fn poll_stops_cleanly_on_ctrl_c() {
    let Some(sensor) = spec().sensors.iter().find(|&s| !poll_columns(s).is_empty()).cloned() else {
        report!("no sensor of the spec has a measurement to poll");
        return;
    };
    let s = sim(&sensor.name, sensor.default_address);
    let mut child = YOSEMITECH
        .command()
        .args(["poll", &sensor.name, "-p", &s.path, "--interval", "50ms", "--format", "csv"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    for _ in 0..3 {
        line.clear();
        stdout.read_line(&mut line).unwrap();
    }
    assert!(line.ends_with(",\n"), "a data row: {line}");
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let code = yosemitech_tests::cli::wait(&mut child, Duration::from_secs(10));
    assert_eq!(code, 0, "Ctrl-C ends polling with success");
}

#[test]
fn set_address_changes_and_verifies() {
    // A sensor `set-address --sensor` can move: an address write and a
    // serial-number read, both at the probe's own address.
    let own = |s: &Sensor, role| s.command_with_role(role).filter(|c| c.fixed_slave.is_none()).cloned();
    let Some((sensor, set)) = spec().sensors.iter().find_map(|s| {
        own(s, Role::SerialNumber)?;
        Some((s.clone(), own(s, Role::SetSlaveAddress)?))
    }) else {
        report!("no sensor of the spec has an address write and a serial-number read: no address changed");
        return;
    };
    let from = sensor.default_address;
    let to = new_address(&set, &[from]);
    let (from_arg, to_arg) = (from.to_string(), to.to_string());
    let s = sim(&sensor.name, from);
    let mut args = vec!["set-address", "-p", &s.path, "--from", &from_arg, "--to", &to_arg, "--yes"];
    args.extend(["--sensor", &sensor.name]);
    args.extend(FAST);
    let out = YOSEMITECH.run(&args).ok().to_owned();
    let sn = served_serial_number(&sensor).unwrap();
    assert!(out.contains(&format!("now answers at address {to}")) && out.contains(&sn), "{out}");
    assert_eq!(s.server.device().address(), to);
    // Nothing answers at the old address any more: refused, nothing written.
    let other = new_address(&set, &[from, to]).to_string();
    let mut args = vec!["set-address", "-p", &s.path, "--from", &from_arg, "--to", &other, "--yes"];
    args.extend(["--sensor", &sensor.name]);
    args.extend(FAST);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(err.contains(&format!("no probe answers at address {from}")), "{err}");
    assert_eq!(s.server.device().address(), to);
    // The new address taken by the probe itself.
    let elsewhere = elsewhere(to).to_string();
    let mut args = vec!["set-address", "-p", &s.path, "--from", &elsewhere, "--to", &to_arg, "--yes"];
    args.extend(["--sensor", &sensor.name]);
    args.extend(FAST);
    assert!(YOSEMITECH.run(&args).fails_with_hint(2).contains(&format!("already answers at address {to}")));
    report!("set-address: {} moved from {from} to {to}", sensor.name);
}

#[test]
fn set_address_refuses_0_and_248() {
    let s = sim(&spec().sensors[0].name, 1);
    for (from, to) in [("0", "5"), ("1", "0"), ("1", "248"), ("248", "1")] {
        let run = YOSEMITECH.run(&["set-address", "-p", &s.path, "--from", from, "--to", to, "--yes"]);
        assert!(run.fails_with_hint(2).contains("outside 1..=247"), "{}", run.stderr);
    }
    assert_eq!(s.server.device().stats().requests, 0, "nothing was sent");
}

#[test]
fn coefficients_backup_and_restore_round_trip() {
    let sensors = yosemitech_tests::cli::sensors_with_coefficients();
    for (i, sensor) in sensors.iter().enumerate() {
        let name = sensor.name.as_str();
        let address = 5u8.to_string();
        let s = sim(name, 5);
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join(format!("{name} backup.json"));
        let file = file.to_str().unwrap();
        let blocks = sensor.coefficient_blocks();
        // Values a restore may write (inside each field's range), the first
        // of every block one that only bit-exact float handling keeps.
        for (_, read) in &blocks {
            for (j, field) in read.named_fields().enumerate() {
                let field = coefficient_field(sensor, &read.name, field.display_name());
                let value = if j == 0 { awkward_float(field) } else { varied_float(field, j) };
                s.server.device().set(&read.name, field.display_name(), Value::Float(value)).unwrap();
            }
        }
        let before = coefficients(&s, sensor);
        let args = ["coefficients", "backup", name, "-p", &s.path, "-a", &address, "--file", file];
        let out = YOSEMITECH.run(&args).ok().to_owned();
        assert!(out.contains("restore with:") && out.contains("'"), "the path with a space is quoted:\n{out}");
        // Never overwritten.
        YOSEMITECH.run(&args).fails_with_hint(2);
        // The file: one block per write command, named by its fields.
        let json: Json = serde_json::from_str(&std::fs::read_to_string(file).unwrap()).unwrap();
        assert_eq!(json["sensor"], name);
        let saved = json["coefficients"].as_object().unwrap();
        assert_eq!(saved.len(), blocks.len(), "{name}: {json}");
        for (write, _) in &blocks {
            let mut names: Vec<String> = write.named_fields().map(|f| f.display_name().to_owned()).collect();
            names.sort();
            let keys: Vec<String> = saved[&write.name].as_object().unwrap().keys().cloned().collect();
            assert_eq!(keys, names, "{name}.{}", write.name);
        }

        // Change everything, then restore.
        let changed = overwrite(&s, sensor, &before, 3);
        // Restoring needs confirmation.
        let restore = ["coefficients", "restore", name, "-p", &s.path, "-a", &address, "--file", file];
        YOSEMITECH.run(&restore).fails_with_hint(2);
        for (c, f, v) in &changed {
            assert_eq!(float(&s, c, f).to_bits(), v.to_bits(), "nothing written without --yes");
        }
        let mut args = restore.to_vec();
        args.push("--yes");
        let out = YOSEMITECH.run(&args).ok().to_owned();
        assert!(out.contains("restored and verified"), "{out}");
        assert!(out.contains("saved the probe's current coefficients to"), "restore keeps what it overwrites:\n{out}");
        for (c, f, v) in &before {
            assert_eq!(float(&s, c, f).to_bits(), v.to_bits(), "{name}: {c}.{f} restored bit for bit");
        }
        // One sensor's backup is not another's.
        let other = &sensors[(i + 1) % sensors.len()].name;
        if other != name {
            let mut args = vec!["coefficients", "restore", other.as_str(), "-p", &s.path, "-a", &address];
            args.extend(["--file", file, "--yes"]);
            let err = YOSEMITECH.run(&args).fails_with_hint(2).to_owned();
            assert!(err.contains(&format!("`{name}` probe")), "{err}");
        }
    }
    report!("coefficients: {} sensors backed up and restored", sensors.len());
}

/// The field a restore writes for coefficient `field` of `read`: the
/// block's write's (whose range bounds the value), else the read's.
fn coefficient_field<'s>(sensor: &'s Sensor, read: &str, field: &str) -> &'s Field {
    let blocks = sensor.coefficient_blocks();
    let (write, read) = blocks.iter().find(|(_, r)| r.name == read).unwrap_or_else(|| panic!("no block read {read}"));
    write.field(field).or_else(|| read.field(field)).unwrap_or_else(|| panic!("{}: no field {field}", read.name))
}

/// A float inside `field`'s range that only bit-exact handling keeps: no
/// short decimal, and not the field's `absent` value.
fn awkward_float(field: &Field) -> f32 {
    let (min, max) = field.range.unwrap_or((0.0, 1.0));
    [0.987_654_3, 0.123_456_7]
        .into_iter()
        .map(|at| (min + (max - min) * at) as f32)
        .find(|v| field.absent != Some(f64::from(*v)))
        .unwrap()
}

/// A float inside `field`'s range unlike `old`: the first of the test kit's
/// varied values, from the `i`-th on, that differs.
fn another_float(field: &Field, i: usize, old: f32) -> f32 {
    (i..i + 8).map(|j| varied_float(field, j)).find(|v| v.to_bits() != old.to_bits()).unwrap()
}

/// Every coefficient the simulated probe holds, as (read, field, value)
/// over its sensor's coefficient blocks.
fn coefficients(s: &Sim<Simulator>, sensor: &Sensor) -> Vec<(String, String, f32)> {
    sensor
        .coefficient_blocks()
        .iter()
        .flat_map(|(_, r)| r.named_fields().map(|f| (r.name.clone(), f.display_name().to_owned())).collect::<Vec<_>>())
        .map(|(c, f)| {
            let v = float(s, &c, &f);
            (c, f, v)
        })
        .collect()
}

/// Sets each of `coefficients` on the probe to another value inside its
/// range (from the kit's `base`-th varied value on); returns what it set.
fn overwrite(
    s: &Sim<Simulator>,
    sensor: &Sensor,
    coefficients: &[(String, String, f32)],
    base: usize,
) -> Vec<(String, String, f32)> {
    coefficients
        .iter()
        .enumerate()
        .map(|(i, (c, f, old))| {
            let value = another_float(coefficient_field(sensor, c, f), base + i, *old);
            s.server.device().set(c, f, Value::Float(value)).unwrap();
            (c.clone(), f.clone(), value)
        })
        .collect()
}

/// The sensor `calibrate ph` drives, as the tool says.
fn calibrated_sensor() -> Sensor {
    yosemitech_tests::sensor(yosemitech_cli::calibrate_ph_sensor())
}

/// `calibrate ph` on a new simulated probe at its factory address, with
/// `input` on stdin and its backup in a new directory (returned with the
/// probe and the run).
fn calibrate_with(input: &str) -> (Sim<Simulator>, tempfile::TempDir, Run) {
    let sensor = calibrated_sensor();
    let s = sim(&sensor.name, sensor.default_address);
    let dir = tempfile::tempdir().unwrap();
    let backup_dir = dir.path().to_str().unwrap();
    let run = YOSEMITECH
        .run_with_input(&["calibrate", "ph", "-p", &s.path, "--yes", "--skip-wait", "--backup-dir", backup_dir], input);
    (s, dir, run)
}

#[test]
fn calibrate_ph_guides_three_points_and_reports_success() {
    let sensor = calibrated_sensor();
    // The buffers: the standards the spec states for the calibration point.
    let point = sensor.command_with_role(Role::CalibrationPoint).expect("the pH manual's calibration point");
    let field = point.named_fields().next().unwrap();
    let standards = yosemitech_sim::behaviour::calibration_standards(&sensor, field).expect("the pH standards");
    let buffers: Vec<String> = standards.values.iter().map(|v| format!("pH {v:.2} buffer")).collect();
    let (_s, dir, run) = calibrate_with(&"\n".repeat(buffers.len()));
    let out = run.ok();
    for needle in buffers.iter().map(String::as_str).chain(["calibration succeeded", "restore with:"]) {
        assert!(out.contains(needle), "`{needle}` missing:\n{out}");
    }
    assert!(out.find("saved every coefficient").unwrap() < out.find(&buffers[0]).unwrap(), "backup first");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "one backup file");
    // The coefficients after it: every block, read from the probe.
    let after = out.split("coefficients now:").nth(1).expect("the coefficients after the calibration");
    for (write, _) in sensor.coefficient_blocks() {
        assert!(after.contains(&format!("{}: ", write.name)), "{after}");
    }
}

#[test]
fn calibrate_ph_stops_on_q_and_prints_the_restore_command() {
    let sensor = calibrated_sensor();
    let name = sensor.name.clone();
    let (s, dir, run) = calibrate_with("\nq\n");
    let err = run.fails(1);
    assert!(err.contains("stopped by the user at point 2"), "{err}");
    assert!(err.contains(&format!("yosemitech coefficients restore {name}")), "{err}");
    assert_eq!(s.server.device().calibration_points().len(), 1, "one point written");
    // The calibration's backup restores like any other: every coefficient, bit for bit.
    let file = std::fs::read_dir(dir.path()).unwrap().next().expect("the backup file").unwrap().path();
    let before = coefficients(&s, &sensor);
    overwrite(&s, &sensor, &before, 2);
    let file = file.to_str().unwrap();
    let restore = ["coefficients", "restore", name.as_str(), "-p", &s.path, "--file", file, "--yes"];
    assert!(YOSEMITECH.run(&restore).ok().contains("restored and verified"));
    for (c, f, v) in &before {
        assert_eq!(float(&s, c, f).to_bits(), v.to_bits(), "{c}.{f}");
    }
    // Without --yes and without a terminal, nothing starts.
    let backup_dir = dir.path().to_str().unwrap();
    let run = YOSEMITECH.run(&["calibrate", "ph", "-p", &s.path, "--skip-wait", "--backup-dir", backup_dir]);
    run.fails_with_hint(2);
    // A backup that cannot be saved stops the calibration before any write.
    let before = s.server.device().stats().writes;
    let run = YOSEMITECH.run_with_input(
        &["calibrate", "ph", "-p", &s.path, "--yes", "--skip-wait", "--backup-dir", "/nonexistent/dir"],
        "\n\n\n",
    );
    assert!(run.fails_with_hint(1).contains("nothing was written"), "{}", run.stderr);
    assert_eq!(s.server.device().stats().writes, before);
}

/// The sensors of the spec that state a procedure.
fn sensors_with_a_procedure() -> Vec<Sensor> {
    spec().sensors.iter().filter(|&s| s.procedure.is_some()).cloned().collect()
}

#[test]
fn a_refused_start_does_not_stop_a_measurement() {
    // Some probes refuse Start Measurement and measure all the same (a real
    // Y533 does): every procedure that starts one reads on, and says so.
    let mut tried = 0;
    for sensor in sensors_with_a_procedure() {
        let procedure = sensor.procedure.clone().unwrap();
        let Some(start) = sensor.command_with_role(Role::StartMeasurement) else { continue };
        if !procedure.before.contains(&start.name) {
            continue;
        }
        let mut device = Simulator::new(Arc::new(sensor.clone())).with_address(sensor.default_address);
        device.set_refuses_start(true);
        let s = yosemitech_tests::cli::serve(device);
        let json =
            YOSEMITECH.run(&["measure", &sensor.name, "-p", &s.path, "--fast", "--readings", "2", "--json"]).json();
        assert_eq!(json["readings"], 2, "{}: {json}", sensor.name);
        let warnings = json["warnings"].as_array().unwrap();
        assert!(warnings.iter().any(|w| w.as_str().is_some_and(|w| w.contains(&start.name))), "{json}");
        tried += 1;
    }
    report!("a refused start: {tried} procedures read on");
}

#[test]
fn measure_runs_every_procedure_and_prints_each_field() {
    let sensors = sensors_with_a_procedure();
    for sensor in &sensors {
        let procedure = sensor.procedure.clone().unwrap();
        // At its factory address, where `measure` asks without --address.
        let s = sim(&sensor.name, sensor.default_address);
        let run = YOSEMITECH.run(&["measure", &sensor.name, "-p", &s.path, "--fast", "--readings", "3"]);
        let out = run.ok().to_owned();
        let reads: Vec<&CommandSpec> = procedure.read.iter().map(|r| sensor.command(r).unwrap()).collect();
        for read in &reads {
            for field in read.named_fields() {
                let name = field.display_name();
                assert!(
                    out.lines().any(|l| l.trim_start().starts_with(name) || l.contains(&format!(".{name} "))),
                    "{}: field `{name}` missing:\n{out}",
                    sensor.name
                );
            }
        }
        for name in procedure.before.iter().chain(&procedure.read) {
            assert!(out.contains(name.as_str()), "{}: the procedure line names `{name}`:\n{out}", sensor.name);
        }
        // Every request of the procedure reached the probe: before, 3 x the reads, after.
        let sent = procedure.before.len() + 3 * reads.len() + procedure.after.len();
        assert!(s.server.device().stats().requests >= sent as u64, "{}", sensor.name);

        // JSON: each averaged value is the simulated one (no noise: every reading alike).
        let json =
            YOSEMITECH.run(&["measure", &sensor.name, "-p", &s.path, "--fast", "--readings", "2", "--json"]).json();
        assert_eq!(json["readings"], 2, "{json}");
        assert_eq!(json["sensor"], sensor.name.as_str());
        let fields = json["fields"].as_array().unwrap();
        assert_eq!(fields.len(), reads.iter().map(|r| r.named_fields().count()).sum::<usize>());
        for f in fields {
            let (command, field) = (f["command"].as_str().unwrap(), f["field"].as_str().unwrap());
            let spec_field = sensor.command(command).unwrap().field(field).unwrap();
            let label = f["name"].as_str().unwrap();
            assert_eq!(json["values"][label], f["value"], "{json}");
            let Value::Float(want) = s.server.device().get(command, field).unwrap() else { continue };
            if spec_field.absent == Some(f64::from(want)) {
                assert_eq!(f["value"], Json::Null, "{} {field} reads absent: {json}", sensor.name);
                assert_eq!(f["absent"], 2);
                assert!(out.contains("absent"), "{out}");
            } else {
                assert_eq!(f["value"].as_f64().map(|v| v as f32), Some(want), "{} {field}: {json}", sensor.name);
                assert_eq!(f["readings"], 2);
            }
        }
    }
    report!("measure: {} procedures run", sensors.len());
}

#[test]
fn measure_averages_the_readings() {
    // A float field of a procedure read, set to a known value.
    let known = 1.413_f32;
    let chosen = sensors_with_a_procedure().into_iter().find_map(|sensor| {
        let procedure = sensor.procedure.clone()?;
        let (read, field) = procedure.read.iter().find_map(|r| {
            let read = sensor.command(r)?;
            let field = read
                .named_fields()
                .find(|f| matches!(f.kind, FieldKind::F32 { .. }) && f.absent != Some(f64::from(known)))?;
            Some((read.clone(), field.clone()))
        })?;
        Some((sensor, read, field))
    });
    let Some((sensor, read, field)) = chosen else {
        report!("no procedure of the spec reads a float field: nothing to average");
        return;
    };
    let s = sim(&sensor.name, 4);
    s.server.device().set(&read.name, field.display_name(), Value::Float(known)).unwrap();
    let run = YOSEMITECH.run(&[
        "measure",
        &sensor.name,
        "-p",
        &s.path,
        "-a",
        "4",
        "--warm-up",
        "10ms",
        "--interval",
        "5ms",
        "--readings",
        "4",
    ]);
    let out = run.ok();
    let label = field.display_name();
    assert_eq!(shown_number(out, &read.name, label) as f32, known, "{out}");
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with(label) || l.contains(&format!("{}.{label} ", read.name)))
        .unwrap();
    assert!(line.contains("mean of 4 readings"), "{line}");
    if let Some(unit) = &field.unit {
        assert!(line.contains(yosemitech_cli::shown_unit(unit)), "{line}");
    }
}

#[test]
fn measure_refuses_a_sensor_without_a_procedure() {
    // The fixture DO probe states no procedure.
    let dir = fixture_spec_dir();
    let spec_arg = dir.to_str().unwrap();
    let run = YOSEMITECH.run(&["--spec", spec_arg, "measure", "do_probe", "-p", "/dev/null"]);
    let err = run.fails_with_hint(2);
    assert!(err.contains("`do_probe` states no measuring procedure"), "{err}");
    let with = sensors_with_a_procedure();
    for sensor in &with {
        assert!(err.contains(&sensor.name), "`{}` not offered:\n{err}", sensor.name);
    }
    YOSEMITECH.run(&["measure", "no_such_sensor", "-p", "/dev/null"]).fails_with_hint(2);
    let Some(first) = with.first() else {
        report!("no sensor of the spec states a procedure: --readings 0 not tried");
        return;
    };
    assert!(
        YOSEMITECH
            .run(&["measure", &first.name, "-p", "/dev/null", "--readings", "0"])
            .fails_with_hint(2)
            .contains("--readings 0")
    );
    report!("measure offers the {} sensors with a procedure", with.len());
}

/// The serial number a simulated probe of `sensor` sends (`None`: its spec
/// has no serial-number read), as the simulator serves it before anything
/// is set.
fn served_serial_number(sensor: &Sensor) -> Option<String> {
    let command = sensor.command_with_role(Role::SerialNumber)?;
    let field = command.named_fields().find(|f| matches!(f.kind, FieldKind::Ascii { .. }))?;
    match Simulator::new(Arc::new(sensor.clone())).get(&command.name, field.display_name()) {
        Ok(Value::Text(text)) => Some(text),
        _ => None,
    }
}

/// The serial-number read of `sensor` and its text field.
fn sn_field(sensor: &Sensor) -> (&CommandSpec, &Field) {
    let command = sensor.command_with_role(Role::SerialNumber).unwrap();
    let field = command.named_fields().find(|f| matches!(f.kind, FieldKind::Ascii { .. })).unwrap();
    (command, field)
}

/// The sensors `scan` can identify: a serial-number read at the probe's
/// own address with a text field, and a model code.
fn identifiable() -> Vec<Sensor> {
    spec()
        .sensors
        .iter()
        .filter(|&s| {
            s.model_code.is_some()
                && sn_request(s).is_some()
                && s.command_with_role(Role::SerialNumber)
                    .is_some_and(|c| c.named_fields().any(|f| matches!(f.kind, FieldKind::Ascii { .. })))
        })
        .cloned()
        .collect()
}

/// The distinct serial-number requests of the spec: what `scan` may send
/// to an address before one is answered.
fn sn_layouts() -> usize {
    let mut requests: Vec<(u8, u16, u16)> = spec().sensors.iter().filter_map(sn_request).collect();
    requests.sort_unstable();
    requests.dedup();
    requests.len()
}

/// The newest manual of `sensor` whose software is at most `software`.
fn manual_for(sensor: &Sensor, software: &str) -> Option<String> {
    let key = |v: &str| -> (u32, u32) {
        let (a, b) = v.split_once('.').unwrap_or((v, "0"));
        (a.parse().unwrap(), b.parse().unwrap())
    };
    sensor.manuals().filter_map(|m| m.software.clone()).filter(|sw| key(sw) <= key(software)).max_by_key(|sw| key(sw))
}

/// A two-digit model code no sensor of the spec declares (and not `00`,
/// which the byte before a serial number carries when it names none).
fn undeclared_code() -> String {
    (10..=99)
        .map(|n: u8| n.to_string())
        .find(|code| spec().sensors.iter().all(|s| s.model_code.as_deref() != Some(code.as_str())))
        .expect("a two-digit code no sensor declares")
}

#[test]
fn scan_names_each_sensor_of_the_spec_alone() {
    // Every identifiable sensor on one bus: scan names each one alone,
    // except where another loaded sensor sends the same serial-number
    // request and declares the same model code: then it lists them all.
    let sensors = identifiable();
    let mut bus = Bus::new();
    for (i, sensor) in sensors.iter().enumerate() {
        bus.push(Simulator::new(Arc::new(sensor.clone())).with_address(i as u8 + 1));
    }
    let s = yosemitech_tests::cli::serve(bus);
    let last = sensors.len() + 1;
    let addresses = format!("1-{last}");
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s"]);
    if sensors.is_empty() {
        run.fails_with_hint(1);
        report!("no sensor of the spec has a serial-number read and a model code: nothing to scan for");
        return;
    }
    let out = run.ok().to_owned();
    let mut alone = 0;
    for (i, sensor) in sensors.iter().enumerate() {
        let code = sensor.model_code.as_deref().unwrap();
        let line = out
            .lines()
            .find(|l| l.starts_with(&format!("address {:3}  ", i + 1)))
            .unwrap_or_else(|| panic!("no line for address {}:\n{out}", i + 1));
        let (said, among) = scan_says(sensor, code, &served_serial_number(sensor).unwrap());
        assert!(line.contains(&said), "`{said}` not in: {line}");
        assert_eq!(line.contains("not identified"), among.is_some(), "{line}");
        alone += usize::from(among.is_none());
    }
    assert!(out.contains(&format!("found {} device(s)", sensors.len())), "{out}");
    // Few reads per address: the serial-number requests tried, and one for the revisions.
    let requests = s.server.device().devices()[0].stats().requests;
    assert!(requests <= (last * (sn_layouts() + 1)) as u64, "{requests} requests for {last} addresses");

    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices.len(), sensors.len(), "{json}");
    for (device, sensor) in devices.iter().zip(&sensors) {
        let code = sensor.model_code.as_deref().unwrap();
        let sn = served_serial_number(sensor).unwrap();
        assert_eq!(device["model_code"].as_str(), Some(code), "{device}");
        assert_eq!(device["serial_number"], sn.as_str());
        let bus = s.server.device();
        let sim = &bus.devices()[device["address"].as_u64().unwrap() as usize - 1];
        match scan_says(sensor, code, &sn).1 {
            None => {
                assert_eq!(device["sensor"], sensor.name.as_str(), "{device}");
                assert_eq!(device["sensors"], serde_json::json!([sensor.name]), "{device}");
                assert_eq!(device["model"].as_str(), sensor.model.as_deref(), "{device}");
                assert_eq!(device["reason"], Json::Null);
                // Every model that shares the sensor's code and commands, and why no read tells them apart.
                assert_eq!(device["models"], serde_json::json!(sensor.models_with_code(code)), "{device}");
                assert_eq!(device["models_reason"].is_null(), sensor.models_with_code(code).len() < 2, "{device}");
                // The revisions, and the manual that covers that firmware.
                match sensor.command_with_role(Role::Version) {
                    Some(version) => {
                        let software = version.named_fields().last().unwrap().display_name().to_owned();
                        let Value::Version(sw) = sim.get(&version.name, &software).unwrap() else { panic!() };
                        assert_eq!(device["software"], sw.to_string().as_str(), "{device}");
                        let manual = manual_for(sensor, &sw.to_string());
                        assert_eq!(device["manual"]["software"].as_str(), manual.as_deref(), "{device}");
                    }
                    None => assert_eq!(device["software"], Json::Null),
                }
            }
            Some(twins) => {
                let names: Vec<&str> = twins.iter().map(|t| t.name.as_str()).collect();
                assert_eq!(device["sensor"], Json::Null, "{device}");
                assert_eq!(device["sensors"], serde_json::json!(names), "{device}");
                assert_eq!(device["model"], Json::Null, "{device}");
                assert_eq!(device["manual"], Json::Null, "no manual for a probe not identified: {device}");
                let reason = device["reason"].as_str().unwrap_or_default();
                let why = format!("{} loaded sensors", twins.len());
                assert!(reason.contains(&why) && reason.contains(&format!("model code {code}")), "{device}");
            }
        }
    }
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &format!("{}", last + 1)]);
    assert!(run.fails_with_hint(1).contains("no device answered"), "{}", run.stderr);
    report!(
        "scan: {} probes, {alone} named alone, {} among the sensors of their model code, in {requests} requests",
        sensors.len(),
        sensors.len() - alone
    );
}

#[test]
fn scan_takes_the_model_code_from_the_byte_before_the_serial_number() {
    // Real probes send the code in the byte the manuals print as 0x00; the
    // text may carry another (the manuals print a sibling's serial number).
    let sensors: Vec<_> = identifiable()
        .into_iter()
        .filter(|s| {
            let (command, field) = sn_field(s);
            field.offset > 0
                && command.fields.iter().any(|f| f.is_reserved() && f.offset + f.size() == field.offset)
                && u8::from_str_radix(s.model_code.as_deref().unwrap(), 16).is_ok()
        })
        .collect();
    if sensors.is_empty() {
        report!("no sensor of the spec has a reserved byte before its serial number: no code read from it");
        return;
    }
    let other = undeclared_code();
    let text = format!("YL{other}14010022");
    let mut bus = Bus::new();
    for (i, sensor) in sensors.iter().enumerate() {
        let (command, field) = sn_field(sensor);
        let code = sensor.model_code.as_deref().unwrap();
        let byte = u8::from_str_radix(code, 16).unwrap();
        let mut device = Simulator::new(Arc::new(sensor.clone())).with_address(i as u8 + 1);
        device.set(&command.name, field.display_name(), Value::Text(text.clone())).unwrap();
        device.registers_mut().write_bytes(command.address, field.offset - 1, &[byte]);
        bus.push(device);
    }
    let s = yosemitech_tests::cli::serve(bus);
    let addresses = format!("1-{}", sensors.len());
    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices.len(), sensors.len());
    for (device, sensor) in devices.iter().zip(&sensors) {
        let code = sensor.model_code.as_deref().unwrap();
        assert_eq!(device["model_code"].as_str(), Some(code), "{device}");
        assert_eq!(device["serial_number"], text.as_str());
        let twins: Vec<String> = declaring(sensor, code).into_iter().map(|t| t.name).collect();
        let twin_sensors = declaring(sensor, code);
        let refs: Vec<&Sensor> = twin_sensors.iter().collect();
        if twins.len() == 1 || yosemitech_cli::scan_tells_apart(&refs) {
            assert_eq!(device["sensor"], sensor.name.as_str(), "{device}");
        } else {
            assert_eq!(device["sensors"], serde_json::json!(twins), "{device}");
            assert_eq!(device["sensor"], Json::Null, "{device}");
        }
    }
    report!("scan read the model code from the byte before the serial number of {} probes", sensors.len());
}

#[test]
fn scan_names_the_model_of_every_code_a_sensor_declares() {
    // A probe of a sensor sending any code the sensor declares (its own,
    // older ones, its aliases'): scan names the models of that code, the
    // aliases that share it beside the sensor's own model, with the reason.
    let mut bus = Bus::new();
    let mut expected: Vec<(Sensor, String)> = Vec::new();
    for sensor in identifiable() {
        let codes: Vec<String> = sensor
            .model_codes()
            .map(str::to_owned)
            .chain(sensor.aliases.iter().filter_map(|a| a.model_code.clone()))
            .filter(|c| u8::from_str_radix(c, 16).is_ok())
            .collect();
        for code in codes {
            // Where another sensor reads its serial number alike and declares the code, scan may list both.
            if declaring(&sensor, &code).len() > 1 {
                continue;
            }
            let (command, field) = sn_field(&sensor);
            let address = expected.len() as u8 + 1;
            let mut device = Simulator::new(Arc::new(sensor.clone())).with_address(address);
            device.set(&command.name, field.display_name(), Value::Text(format!("YL{code}14010022"))).unwrap();
            if command.fields.iter().any(|f| f.is_reserved() && f.offset + f.size() == field.offset) {
                let byte = u8::from_str_radix(&code, 16).unwrap();
                device.registers_mut().write_bytes(command.address, field.offset - 1, &[byte]);
            }
            bus.push(device);
            expected.push((sensor.clone(), code));
        }
    }
    if expected.is_empty() {
        report!("no sensor of the spec declares a model code scan can read");
        return;
    }
    let s = yosemitech_tests::cli::serve(bus);
    let addresses = format!("1-{}", expected.len());
    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices.len(), expected.len(), "{json}");
    let mut shared = 0;
    for (device, (sensor, code)) in devices.iter().zip(&expected) {
        assert_eq!(device["model_code"].as_str(), Some(code.as_str()), "{device}");
        assert_eq!(device["sensor"], sensor.name.as_str(), "{device}");
        let models = sensor.models_with_code(code);
        assert_eq!(device["models"], serde_json::json!(models), "{device}");
        if models.len() > 1 {
            let why = device["models_reason"].as_str().unwrap_or_default();
            assert!(models.iter().all(|m| why.contains(m)) && why.contains("no read"), "{device}");
            shared += 1;
        } else {
            assert_eq!(device["models_reason"], Json::Null, "{device}");
        }
    }
    report!("scan named the models of {} codes, {shared} shared by models no read tells apart", expected.len());
}

#[test]
fn scan_lists_the_candidates_where_it_cannot_decide() {
    let Some(sensor) = identifiable().into_iter().next() else {
        report!("no sensor of the spec has a serial-number read and a model code: no candidates to list");
        return;
    };
    let (command, field) = sn_field(&sensor);
    let address = sensor.default_address.to_string();
    // A model code no loaded sensor declares: every sensor that sends the
    // same serial-number request is a candidate.
    let other = undeclared_code();
    let mut device = Simulator::new(Arc::new(sensor.clone()));
    device.set(&command.name, field.display_name(), Value::Text(format!("YL{other}14010022"))).unwrap();
    if let Some(before) = field.offset.checked_sub(1) {
        device.registers_mut().write_bytes(command.address, before, &[u8::from_str_radix(&other, 16).unwrap()]);
    }
    let s = yosemitech_tests::cli::serve(device);
    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &address, "--timeout", "1s", "--json"]).json();
    let found = &json["devices"][0];
    assert_eq!(found["sensor"], Json::Null, "{found}");
    assert_eq!(found["model_code"], other.as_str());
    let same_request: Vec<String> =
        spec().sensors.iter().filter(|s| sn_request(s) == sn_request(&sensor)).map(|s| s.name.clone()).collect();
    assert_eq!(found["sensors"], serde_json::json!(same_request), "{found}");
    assert!(found["reason"].as_str().unwrap().contains(&format!("model code {other}")), "{found}");
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &address, "--timeout", "1s"]);
    let out = run.ok();
    let shown = format!("model code {other}");
    assert!(out.contains("not identified") && out.contains(&sensor.name) && out.contains(&shown), "{out}");

    // One more loaded sensor declaring its code: it joins the candidates.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(&sensor.file).unwrap();
    let twin = format!("{}_twin", sensor.name);
    let renamed = text.replacen(&format!("name: {}\n", sensor.name), &format!("name: {twin}\n"), 1);
    assert_ne!(renamed, text, "the sensor's name line");
    std::fs::write(dir.path().join("twin.yaml"), renamed).unwrap();
    let spec_arg = dir.path().to_str().unwrap();
    s.server
        .device()
        .set(&command.name, field.display_name(), Value::Text(served_serial_number(&sensor).unwrap()))
        .unwrap();
    if let Some(before) = field.offset.checked_sub(1) {
        // What the simulator sends there for its own code.
        let own = Simulator::new(Arc::new(sensor.clone())).registers().read(command.address, command.count);
        s.server.device().registers_mut().write_bytes(command.address, before, &own[before..=before]);
    }
    let json = YOSEMITECH
        .run(&["--spec", spec_arg, "scan", "-p", &s.path, "--addresses", &address, "--timeout", "1s", "--json"])
        .json();
    let found = &json["devices"][0];
    let code = sensor.model_code.as_deref().unwrap();
    let mut candidates: Vec<String> = declaring(&sensor, code).into_iter().map(|t| t.name).collect();
    candidates.push(twin);
    assert_eq!(found["sensor"], Json::Null, "{found}");
    assert_eq!(found["sensors"], serde_json::json!(candidates), "{found}");
    let why = format!("{} loaded sensors", candidates.len());
    assert!(found["reason"].as_str().unwrap().contains(&why), "{found}");
}

/// `yosemitech simulate` in a child process: the port it prints, and a clean
/// stop on Ctrl-C.
/// The sensor, the read, its true request and reply, and the line `read` shows.
type StatedRead = (Sensor, CommandSpec, Vec<u8>, Vec<u8>, String);

/// A measurement read whose example (in the sensor's own manual) the
/// simulator answers: the sensor, the read, the true request and reply,
/// and the line `read` shows for its one f32 field (`name  value unit`).
/// The example's frames go to the sensor's factory address, where the
/// simulator serves it.
fn stated_read() -> Option<StatedRead> {
    for sensor in spec().sensors.clone() {
        let device = Simulator::new(Arc::new(sensor.clone()));
        for command in sensor.commands.iter().filter(|c| c.is_read() && c.role.is_none() && c.fixed_slave.is_none()) {
            let mut named = command.named_fields();
            let (Some(field), None) = (named.next(), named.next()) else { continue };
            if !matches!(field.kind, FieldKind::F32 { .. }) || field.unit.is_none() {
                continue;
            }
            let Some(example) = stated_example(command) else { continue };
            let (Some((request, reply)), Some(value)) = (example.true_pair(), example.values.get(field.display_name()))
            else {
                continue;
            };
            if example.slave() != sensor.default_address
                || !device.get(&command.name, field.display_name()).is_ok_and(|v| v.same_as(value))
            {
                continue;
            }
            let line = format!("{}  {}", field.display_name(), shown(value, field.unit.as_deref()));
            return Some((sensor.clone(), command.clone(), request.to_vec(), reply.to_vec(), line));
        }
    }
    report!("no measurement read of the spec has a stated example the simulator answers");
    None
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

#[test]
fn simulate_serves_a_pty_until_interrupted() {
    let Some((sensor, command, _, _, line)) = stated_read() else { return };
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--address", "4"]);
    assert!(port.starts_with("/dev/"), "{port}");
    let out = YOSEMITECH.run(&["read", &sensor.name, &command.name, "-p", &port, "-a", "4"]);
    assert!(out.ok().contains(&line), "{}", out.stdout);
    let err = interrupt(child);
    let title = format!("simulating {} ({})", sensor.title, sensor.name);
    assert!(err.contains(&title) && err.contains("stopped: 1 requests"), "{err}");
}

#[test]
fn simulate_serves_rtu_over_tcp() {
    let Some((sensor, command, _, _, line)) = stated_read() else { return };
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--tcp", "127.0.0.1:0"]);
    assert!(port.starts_with("tcp://127.0.0.1:"), "{port}");
    let out = YOSEMITECH.run(&["read", &sensor.name, &command.name, "-p", &port]);
    assert_eq!(out.ok().trim(), line);
    interrupt(child);
}

#[test]
fn simulate_serves_modbus_tcp() {
    use std::io::{Read, Write};
    use yosemitech_rtu::mbap::{MAX_MBAP_ADU, adu_to_rtu, rtu_to_adu};

    let Some((sensor, command, request, reply, _)) = stated_read() else { return };
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--tcp", "127.0.0.1:0", "--protocol", "mbap"]);
    let addr = port.strip_prefix("mbap://").unwrap_or_else(|| panic!("{port}"));
    let mut stream = std::net::TcpStream::connect(addr).unwrap();
    stream.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut adu = [0u8; MAX_MBAP_ADU];
    let n = rtu_to_adu(&request, 0xBEEF, &mut adu).unwrap();
    stream.write_all(&adu[..n]).unwrap();
    let expected = rtu_to_adu(&reply, 0xBEEF, &mut adu).unwrap();
    let mut answer = vec![0u8; expected];
    stream.read_exact(&mut answer).unwrap();
    let mut rtu = [0u8; 256];
    let (header, n) = adu_to_rtu(&answer, &mut rtu).unwrap();
    assert_eq!(header.transaction, 0xBEEF);
    assert_eq!(rtu[..n], reply, "{}: the manual's reply, carried by Modbus TCP", command.name);
    drop(stream);
    let err = interrupt(child);
    assert!(err.contains("stopped: 1 requests"), "{err}");
}

#[test]
fn simulate_is_silent_for_registers_the_probe_lacks_unless_asked_for_exceptions() {
    // A read the first sensor of the spec lacks, from another sensor's
    // command, sent to the simulated probe's address (its factory one).
    let sensor = spec().sensors[0].clone();
    let Some((owner, foreign)) = foreign_read(&sensor, false) else {
        report!("no sensor of the spec reads registers {} lacks: nothing to ignore", sensor.name);
        return;
    };
    let address = sensor.default_address.to_string();
    for (flags, expected) in [(&[][..], "no reply"), (&["--exceptions"][..], "Modbus exception")] {
        let mut args = vec![sensor.name.as_str(), "--tcp", "127.0.0.1:0"];
        args.extend_from_slice(flags);
        let (child, port) = YOSEMITECH.simulate(&args);
        let mut read = vec!["read", owner.name.as_str(), foreign.name.as_str(), "-p", &port, "-a", &address];
        read.extend(["--timeout", "500ms", "--retries", "0"]);
        let run = YOSEMITECH.run(&read);
        assert_eq!(run.code, 1, "{flags:?}: {}", run.stderr);
        assert!(run.stderr.contains(expected), "{flags:?}: {}", run.stderr);
        let err = interrupt(child);
        if flags.is_empty() {
            assert!(err.contains("1 ignored (registers the probe lacks)"), "{err}");
        }
    }
}

#[test]
fn simulate_injects_faults_the_client_retries() {
    // The sensor with the most measurement reads: the most requests per poll.
    let sensor = spec()
        .sensors
        .iter()
        .cloned()
        .max_by_key(|s| {
            let mut reads: Vec<String> = poll_columns(s).into_iter().map(|(r, _, _)| r).collect();
            reads.dedup();
            reads.len()
        })
        .unwrap();
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--faults", "drop=0.3,corrupt_crc=0.2", "--seed", "5"]);
    let run = YOSEMITECH.run(&[
        "poll",
        &sensor.name,
        "-p",
        &port,
        "-n",
        "5",
        "-i",
        "0",
        "-f",
        "csv",
        "--timeout",
        "100ms",
        "--retries",
        "5",
    ]);
    assert_eq!(run.ok().lines().count(), 6);
    let err = interrupt(child);
    let injected: u64 = err
        .split("faults: ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no fault count in: {err}"));
    assert!(injected > 0, "faults were injected: {err}");
}

#[test]
fn spec_sensors_work_through_the_interpreter() {
    // The fixture DO probe (19200 8E1, address 10) exists only as a spec file.
    let dir = fixture_spec_dir();
    let spec = dir.to_str().unwrap();
    let (child, port) = YOSEMITECH.simulate(&["--spec", spec, "do_probe"]);
    let out = YOSEMITECH.run(&["read", "--spec", spec, "do_probe", "get_oxygen_sample", "-p", &port]);
    let text = out.ok();
    assert!(text.contains("do_mg_l") && text.contains("8.25 mg/L") && text.contains("-1250"), "{text}");
    let run = YOSEMITECH.run(&["--spec", spec, "poll", "do_probe", "-p", &port, "-n", "2", "-i", "0", "-f", "csv"]);
    assert_eq!(run.ok().lines().count(), 3, "{}", run.stdout);
    let run = YOSEMITECH.run(&[
        "--spec",
        spec,
        "write",
        "do_probe",
        "set_offsets",
        "pressure_offset_pa=-100",
        "salinity_ppt=12.5",
        "membrane_correction=3",
        "-p",
        &port,
        "--yes",
    ]);
    assert!(run.ok().contains("verified"), "{}", run.stdout);
    let run =
        YOSEMITECH.run(&["--spec", spec, "write", "do_probe", "set_offsets", "0", "50", "0", "-p", &port, "--yes"]);
    assert!(run.fails_with_hint(2).contains("outside the valid range 0..=40"), "{}", run.stderr);
    interrupt(child);
}

#[test]
fn verbose_shows_frame_dumps() {
    let Some((sensor, command, request, reply, _)) = stated_read() else { return };
    let s = sim(&sensor.name, sensor.default_address);
    let run = YOSEMITECH.run(&["read", &sensor.name, &command.name, "-p", &s.path, "-v"]);
    run.ok();
    assert!(run.stderr.contains("tx") && run.stderr.contains(&hex(&request)), "{}", run.stderr);
    assert!(run.stderr.contains("rx") && run.stderr.contains(&hex(&reply)), "{}", run.stderr);
    assert!(!run.stderr.contains('\u{1b}'), "no colour codes when stderr is not a terminal");
}

#[test]
fn a_spec_file_replacing_a_built_in_sensor_goes_through_the_interpreter() {
    // The calibrated sensor's manual (its spec file) loaded at run time
    // replaces the built-in sensor: coefficients go through the interpreter
    // (with the same read-back), and the typed procedures refuse.
    let sensor = calibrated_sensor();
    let name = sensor.name.clone();
    let dir = tempfile::tempdir().unwrap();
    let own = sensor.file.as_path();
    std::fs::copy(own, dir.path().join(own.file_name().unwrap())).unwrap();
    let spec_arg = dir.path().to_str().unwrap();
    let s = sim(&name, sensor.default_address);
    let file = dir.path().join("backup.json");
    let file = file.to_str().unwrap();
    let blocks = sensor.coefficient_blocks();
    let (_, first_read) = blocks[0];
    let first_field = first_read.named_fields().next().unwrap().display_name().to_owned();
    let first_value = float(&s, &first_read.name, &first_field);
    let out = YOSEMITECH
        .run(&["--spec", spec_arg, "coefficients", "backup", &name, "-p", &s.path, "-f", file])
        .ok()
        .to_owned();
    assert!(
        out.contains(&format!("{first_field}={first_value}")) && out.contains(&format!("--spec {spec_arg}")),
        "{out}"
    );
    let before = coefficients(&s, &sensor);
    overwrite(&s, &sensor, &before, 1);
    let out =
        YOSEMITECH.run(&["--spec", spec_arg, "coefficients", "restore", &name, "-p", &s.path, "-f", file, "--yes"]);
    assert!(out.ok().contains("restored and verified"));
    for (c, f, v) in &before {
        assert_eq!(float(&s, c, f).to_bits(), v.to_bits(), "{c}.{f}");
    }
    let run = YOSEMITECH
        .run_with_input(&["--spec", spec_arg, "calibrate", "ph", "-p", &s.path, "--yes", "--skip-wait"], "\n\n\n");
    assert!(run.fails_with_hint(2).contains(&format!("built-in {name}")), "{}", run.stderr);
}

/// Readings of a working electrode in the calibration buffers: the
/// potential falls `slopes` mV per pH unit below and above the neutral
/// buffer's `neutral_mv`.
fn electrode_readings(
    neutral_mv: f32,
    slopes: (f32, f32),
    t: f32,
) -> Vec<yosemitech::procedures::ph_electrode::BufferReading> {
    // The buffers: the standards the spec states for the calibration point,
    // as the simulator's calibration takes them.
    let sensor = calibrated_sensor();
    let point = sensor.command_with_role(Role::CalibrationPoint).expect("the pH manual's calibration point");
    let field = point.named_fields().next().unwrap();
    let standards: Vec<f32> = yosemitech_sim::behaviour::calibration_standards(&sensor, field)
        .expect("the calibration's standard buffers")
        .values
        .iter()
        .map(|v| *v as f32)
        .collect();
    let neutral = standards[1];
    standards
        .iter()
        .map(|&buffer_ph| {
            let slope = if buffer_ph < neutral { slopes.0 } else { slopes.1 };
            yosemitech::procedures::ph_electrode::BufferReading {
                buffer_ph,
                potential_mv: neutral_mv - slope * (buffer_ph - neutral),
                temperature_c: t,
            }
        })
        .collect()
}

fn readings_csv(dir: &std::path::Path, readings: &[yosemitech::procedures::ph_electrode::BufferReading]) -> String {
    let mut csv = String::from("buffer,mv,temperature_c\n");
    for r in readings {
        csv.push_str(&format!("{},{},{}\n", r.buffer_ph, r.potential_mv, r.temperature_c));
    }
    let path = dir.join("readings.csv");
    std::fs::write(&path, csv).unwrap();
    path.to_str().unwrap().to_owned()
}

fn json_coefficients(doc: &Json, key: &str) -> [f32; 6] {
    let mut k = [0.0f32; 6];
    for (i, v) in k.iter_mut().enumerate() {
        *v = doc[key][format!("k{}", i + 1)].as_f64().unwrap_or_else(|| panic!("{key}.k{}: {doc}", i + 1)) as f32;
    }
    k
}

#[test]
fn calibrate_ph_compute_from_a_readings_file_shows_and_writes_nothing_without_a_port() {
    let dir = tempfile::tempdir().unwrap();
    let readings = electrode_readings(12.5, (58.0, 56.5), 21.0);
    let csv = readings_csv(dir.path(), &readings);
    let expected = yosemitech::procedures::ph_electrode::compute(&readings).unwrap();
    let doc = YOSEMITECH.run(&["calibrate", "ph", "--compute", "--readings", &csv, "--json"]).json();
    assert_eq!(json_coefficients(&doc, "coefficients"), expected, "{doc}");
    assert_eq!(doc["written"], Json::Bool(false));
    assert!(doc["previous"].is_null(), "{doc}");
    let text = YOSEMITECH.run(&["calibrate", "ph", "--readings", &csv]).ok().to_owned();
    assert!(text.contains("nothing written"), "{text}");
    assert!((number_after(&text, "K3") - f64::from(expected[2])).abs() < 1e-3, "{text}");
    // Bad files: a file:line message, exit 2.
    for (content, says) in [
        ("buffer,mv\n4,1\n", "header"),
        ("buffer,mv,temperature_c\n4,abc,25\n6.86,1,25\n9.18,-100,25\n", "not a number"),
        ("buffer,mv,temperature_c\n6.86,1,25\n4,200,25\n9.18,-100,25\n", "in that order"),
        ("buffer,mv,temperature_c\n4,10,25\n6.86,10,25\n9.18,10,25\n", "mV per pH unit"),
    ] {
        let path = dir.path().join("bad.csv");
        std::fs::write(&path, content).unwrap();
        let err = YOSEMITECH.run(&["calibrate", "ph", "--readings", path.to_str().unwrap()]).fails(2).to_owned();
        assert!(err.contains(says), "{content:?}: {err}");
    }
    // Neither a port nor a file: a usage error naming both.
    let err = YOSEMITECH.run(&["calibrate", "ph", "--compute"]).fails_with_hint(2).to_owned();
    assert!(err.contains("--readings"), "{err}");
}

#[test]
fn calibrate_ph_compute_writes_through_a_port_after_a_backup_and_reads_back() {
    let sensor = calibrated_sensor();
    let s = sim(&sensor.name, sensor.default_address);
    let dir = tempfile::tempdir().unwrap();
    let readings = electrode_readings(-20.0, (55.0, 57.0), 24.0);
    let csv = readings_csv(dir.path(), &readings);
    let before = coefficients(&s, &sensor);
    let backup_dir = tempfile::tempdir().unwrap();
    let args = ["calibrate", "ph", "--compute", "--readings", &csv, "-p", &s.path, "--yes", "--json"];
    let doc = YOSEMITECH.run(&[&args[..], &["--backup-dir", backup_dir.path().to_str().unwrap()]].concat()).json();
    let k = json_coefficients(&doc, "coefficients");
    assert_eq!(doc["written"], Json::Bool(true), "{doc}");
    // The probe's previous coefficients were shown, and saved before the write.
    let previous = json_coefficients(&doc, "previous");
    assert!(before.windows(6).any(|w| w.iter().zip(previous).all(|((_, _, v), p)| v.to_bits() == p.to_bits())));
    assert_eq!(std::fs::read_dir(backup_dir.path()).unwrap().count(), 1, "one backup file");
    // Some coefficient block of the probe now holds exactly K1..K6.
    let after = coefficients(&s, &sensor);
    assert!(
        after.windows(6).any(|w| w.iter().zip(k).all(|((_, _, v), k)| v.to_bits() == k.to_bits())),
        "{k:?} not in {after:?}"
    );
}

#[test]
fn calibrate_ph_compute_measures_each_buffer_through_the_port() {
    // The probe is moved from buffer to buffer: the test sets the potential
    // it reads when the tool asks for the next buffer, then answers Enter.
    let sensor = calibrated_sensor();
    let s = sim(&sensor.name, sensor.default_address);
    let [(potential_read, potential_field), (temperature_read, temperature_field)] = yosemitech_cli::electrode_reads();
    let readings = electrode_readings(5.0, (57.5, 56.0), 19.5);
    let backup_dir = tempfile::tempdir().unwrap();
    let mut cmd = YOSEMITECH.command();
    cmd.args(["calibrate", "ph", "--compute", "-p", &s.path, "--yes", "--skip-wait", "--backup-dir"])
        .arg(backup_dir.path())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = cmd.spawn().unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut transcript = String::new();
    for r in &readings {
        // Up to the prompt for this buffer.
        let wanted = format!("pH {:.2} buffer", r.buffer_ph);
        loop {
            let line = lines.next().unwrap_or_else(|| panic!("no prompt for {wanted}:\n{transcript}")).unwrap();
            transcript.push_str(&line);
            transcript.push('\n');
            if line.contains(&wanted) {
                break;
            }
        }
        {
            let mut device = s.server.device();
            device.set(potential_read, potential_field, Value::Float(r.potential_mv)).unwrap();
            device.set(temperature_read, temperature_field, Value::Float(r.temperature_c)).unwrap();
        }
        std::io::Write::write_all(&mut stdin, b"\n").unwrap();
    }
    drop(stdin);
    for line in lines {
        transcript.push_str(&line.unwrap());
        transcript.push('\n');
    }
    assert_eq!(yosemitech_tests::cli::wait(&mut child, Duration::from_secs(60)), 0, "{transcript}");
    let expected = yosemitech::procedures::ph_electrode::compute(&readings).unwrap();
    assert!(transcript.contains("written and read back"), "{transcript}");
    for (i, k) in expected.iter().enumerate() {
        let shown = number_after(&transcript, &format!("K{}", i + 1));
        assert!((shown - f64::from(*k)).abs() < 1e-3, "K{}: {shown} vs {k}\n{transcript}", i + 1);
    }
    let after = coefficients(&s, &sensor);
    assert!(
        after.windows(6).any(|w| w.iter().zip(expected).all(|((_, _, v), k)| (v - k).abs() < 1e-4)),
        "{expected:?} not in {after:?}"
    );
}

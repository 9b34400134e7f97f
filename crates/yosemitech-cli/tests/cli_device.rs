//! The `yosemitech` binary against simulated probes on pseudo-terminals
//! (yosemitech-sim's `serve_pty`, or `yosemitech simulate` in a child
//! process), through the real serial code path. No hardware.
#![cfg(unix)]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use std::sync::Arc;

use yosemitech_tests::cli::{Binary, Run, Sim, fixture_spec_dir, number_after, sim};
use yosemitech_tests::spec;

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));
use serde_json::Value as Json;
use yosemitech_sim::{Bus, FaultConfig, FaultKind, Simulator, UnknownRequestPolicy};
use yosemitech_spec::{CommandSpec, Role, Value};

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
            assert!(line(sn).contains(&own_serial_number(sensor)), "{section}");
        }
        for read in sensor.measurement_reads().chain(sensor.coefficient_blocks().into_iter().map(|(_, r)| r)) {
            line(read);
        }
        // Its manual's procedure: the mean of what the simulator serves.
        let Some(procedure) = &sensor.procedure else { continue };
        let part = procedures
            .split(&format!("\n{}: ", sensor.name))
            .nth(1)
            .unwrap_or_else(|| panic!("{}: no procedure:\n{procedures}", sensor.name));
        let part = part.split("\n\n").next().unwrap();
        if procedure.readings > 1 {
            assert!(part.contains(&format!("mean of {} readings", procedure.readings)), "{part}");
        }
        let simulated = Simulator::new(Arc::new(sensor.clone()));
        let mut compared = 0;
        for read in procedure.read.iter().map(|r| sensor.command(r).unwrap()) {
            for field in read.named_fields().filter(|f| f.unit.is_some()) {
                let Ok(Value::Float(start)) = simulated.get(&read.name, field.display_name()) else { continue };
                if !start.is_finite() || part.lines().any(|l| l.contains(field.display_name()) && l.contains("absent"))
                {
                    continue;
                }
                let mean = shown_number(part, &read.name, field.display_name());
                assert!(
                    (mean - f64::from(start)).abs() < 0.01,
                    "{}: {} {mean} != {start}",
                    sensor.name,
                    field.display_name()
                );
                compared += 1;
            }
        }
        assert!(compared > 0, "{}: a measured float to compare:\n{part}", sensor.name);
    }
}

#[test]
fn demo_identifies_every_sensor_of_the_spec_on_one_bus() {
    let run = YOSEMITECH.run(&["demo"]);
    let out = run.ok();
    let section =
        out.split("the whole family on one RS-485 bus").nth(1).unwrap_or_else(|| panic!("no family section:\n{out}"));
    let sensors = spec().sensors.clone();
    let mut addresses = Vec::new();
    for sensor in &sensors {
        let code = sensor.model_code.as_deref().unwrap_or_else(|| panic!("{} declares no model code", sensor.name));
        let named = match &sensor.model {
            Some(model) => format!("{} ({model}, code {code})", sensor.name),
            None => format!("{} (code {code})", sensor.name),
        };
        let identified = format!("SN {}  {named}", own_serial_number(sensor));
        let line = section
            .lines()
            .find(|l| l.contains(&identified))
            .unwrap_or_else(|| panic!("`{identified}` missing from the family section:\n{section}"));
        let address: usize =
            line.trim().strip_prefix("address").and_then(|a| a.split_whitespace().next()).unwrap().parse().unwrap();
        addresses.push(address);
        // The firmware, and the manual that covers it.
        if sensor.command_with_role(Role::Version).is_some() {
            let newest = sensor.manuals().filter_map(|m| m.software.clone()).max_by_key(|sw| {
                let (a, b) = sw.split_once('.').unwrap_or((sw, "0"));
                (a.parse::<u32>().unwrap(), b.parse::<u32>().unwrap())
            });
            if let Some(sw) = newest {
                assert!(line.contains(&format!(" SW {sw}  manual SW {sw}")), "{line}");
            }
        }
    }
    addresses.sort_unstable();
    assert_eq!(addresses, (1..=sensors.len()).collect::<Vec<_>>(), "one address each:\n{section}");
    assert!(!section.contains("not identified"), "{section}");
    let count = format!("{} probes identified in ", sensors.len());
    let requests = number_after(section, &count) as usize;
    assert!(requests <= sensors.len() * (sn_layouts() + 1), "{requests} requests:\n{section}");
}

/// The example of `command` in the sensor's own manual, with values.
fn stated_example(command: &CommandSpec) -> Option<&yosemitech_spec::Example> {
    command.examples.iter().find(|e| e.manual.is_none() && e.erratum.is_none() && !e.values.is_empty())
}

/// `value unit` as `read` shows a field.
fn shown(value: &Value, unit: Option<&str>) -> String {
    let value = match value {
        Value::Float(f) => f.to_string(),
        Value::Int(i) => i.to_string(),
        Value::Text(t) => t.clone(),
        other => panic!("{other:?}"),
    };
    // The CLI shows `degC` as `°C`.
    unit.map_or(value.clone(), |u| format!("{value} {}", if u == "degC" { "°C" } else { u }))
}

#[test]
fn read_shows_values_with_units() {
    let (mut checked, mut addressed) = (0, 0);
    for sensor in spec().sensors.clone() {
        let name = sensor.name.as_str();
        let s = sim(name, 1);
        // Every measurement read with a stated f32 value: each field on a
        // line, `name  value unit`, as the manual's example states it.
        for command in sensor.commands.iter().filter(|c| c.is_read() && c.role.is_none()) {
            let Some(example) = stated_example(command) else { continue };
            let f32_with_unit: Vec<_> = command
                .named_fields()
                .filter(|f| matches!(f.kind, yosemitech_spec::FieldKind::F32 { .. }) && f.unit.is_some())
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
            if checked == 0
                && let Some(short) = command.name.strip_prefix("get_")
            {
                let names: Vec<String> = spec().sensors.iter().map(|s| s.name.clone()).collect();
                let prefix = (1..=name.len())
                    .map(|n| &name[..n])
                    .find(|p| names.iter().filter(|n| n.starts_with(p)).count() == 1)
                    .unwrap();
                assert_eq!(YOSEMITECH.run(&["read", prefix, short, "-p", &s.path]).ok(), out, "{prefix} {short}");
            }
            let width = f32_with_unit.iter().map(|f| f.display_name().len()).max().unwrap();
            for field in &f32_with_unit {
                let value = &example.values[field.display_name()];
                let line = format!("{:width$}  {}", field.display_name(), shown(value, field.unit.as_deref()));
                assert!(out.lines().any(|l| l == line), "{name} {}: `{line}` in:\n{out}", command.name);
            }
            assert_eq!(out.lines().count(), f32_with_unit.len(), "{out}");
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
        }
        // The slave address read goes to the wildcard address 0xFF whatever --address says.
        if let Some(get) = sensor.command_with_role(Role::GetSlaveAddress) {
            let field = get.named_fields().next().unwrap().display_name().to_owned();
            let out = YOSEMITECH.run(&["read", name, &get.name, "-p", &s.path, "-a", "9"]).ok().to_owned();
            assert_eq!(out.trim(), format!("{field}  1"));
            addressed += 1;
        }
    }
    assert!(checked > 0 && addressed > 0, "some read states an f32 value, some sensor reads its address");
    eprintln!("checked {checked} reads");
}

#[test]
fn port_and_baud_come_from_the_environment() {
    for sensor in identifiable() {
        let s = sim(&sensor.name, 1);
        let (sn, _) = sn_field(&sensor);
        let mut cmd = YOSEMITECH.command();
        cmd.args(["read", &sensor.name, &sn.name])
            .env("YOSEMITECH_PORT", &s.path)
            .env("YOSEMITECH_BAUD", sensor.serial.baud.to_string());
        let run = yosemitech_tests::cli::run_command(cmd, None);
        assert!(run.ok().contains(&own_serial_number(&sensor)), "{}: {}", sensor.name, run.stdout);
    }
}

/// A measurement read of `sensor`: a read with no role.
fn measurement_read(sensor: &yosemitech_spec::Sensor) -> &CommandSpec {
    sensor
        .commands
        .iter()
        .find(|c| c.is_read() && c.role.is_none() && c.fixed_slave.is_none())
        .expect("a measurement read")
}

#[test]
fn a_silent_address_times_out_cleanly() {
    let sensors = spec().sensors.clone();
    let sensor = &sensors[0];
    let read = measurement_read(sensor);
    let s = sim(&sensor.name, 1);
    let mut args = vec!["read", sensor.name.as_str(), read.name.as_str(), "-p", &s.path, "-a", "9"];
    args.extend(["--timeout", "100ms", "--retries", "1"]);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(
        err.contains(&format!("no reply to {} from address 9", read.name)) && err.contains("within 100ms"),
        "{err}"
    );
    assert!(err.contains("yosemitech scan"), "{err}");
    // A command the probe does not have (another sensor's read at registers
    // this one lacks): real probes stay silent, and the hint says so.
    let (other, foreign) = sensors
        .iter()
        .flat_map(|o| o.commands.iter().map(move |c| (o, c)))
        .find(|(_, c)| {
            c.is_read() && c.fixed_slave.is_none() && !sensor.commands.iter().any(|m| m.address == c.address)
        })
        .expect("a read another sensor has at registers the first lacks");
    let mut args = vec!["read", other.name.as_str(), foreign.name.as_str(), "-p", &s.path];
    args.extend(FAST);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(err.contains(&format!("no reply to {}", foreign.name)) && err.contains("lacks"), "{err}");
    // A device that answers exceptions instead: the exception (no register
    // there), explained.
    let mut device = Simulator::new(yosemitech_tests::sensor(&sensor.name));
    device.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let s = yosemitech_tests::cli::serve(device);
    let run = YOSEMITECH.run(&["read", &other.name, &foreign.name, "-p", &s.path]);
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
fn read_covers(sensor: &yosemitech_spec::Sensor, write: &CommandSpec) -> bool {
    let end = u32::from(write.address) + u32::from(write.count);
    sensor
        .commands
        .iter()
        .any(|r| r.is_read() && r.address <= write.address && u32::from(r.address) + u32::from(r.count) >= end)
}

#[test]
fn write_backs_up_coefficients_confirms_and_reads_back() {
    let sensor =
        yosemitech_tests::cli::sensors_with_coefficients().into_iter().next().expect("a sensor with coefficients");
    let name = sensor.name.as_str();
    let blocks = sensor.coefficient_blocks();
    let (write, read) = blocks[0];
    let fields: Vec<String> = write.named_fields().map(|f| f.display_name().to_owned()).collect();
    let s = sim(name, 1);
    let old: Vec<(String, String, f32)> = blocks
        .iter()
        .flat_map(|(_, r)| r.named_fields().map(|f| (r.name.clone(), f.display_name().to_owned())).collect::<Vec<_>>())
        .map(|(c, f)| {
            let v = float(&s, &c, &f);
            (c, f, v)
        })
        .collect();
    // New values, exact in f32 and unlike any default.
    let new: std::collections::BTreeMap<String, Value> =
        fields.iter().enumerate().map(|(j, f)| (f.clone(), Value::Float(1.25 * (j as f32 + 1.0) + 0.5))).collect();
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
    let frame = write.encode_request(1, &new).unwrap();
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
    let (other, command, values) = spec()
        .sensors
        .iter()
        .flat_map(|s| s.commands.iter().map(move |c| (s, c)))
        .filter(|(s, c)| !c.is_read() && c.count > 0 && !read_covers(s, c))
        .find_map(|(s, c)| {
            let e = c.examples.iter().find(|e| !e.values.is_empty() && e.erratum.is_none())?;
            Some((s.clone(), c.clone(), e.values.clone()))
        })
        .expect("a write no read covers, with an example");
    let s2 = sim(&other.name, 1);
    let values = assignments(&values);
    let mut args = vec!["write", other.name.as_str(), command.name.as_str()];
    args.extend(values.iter().map(String::as_str));
    args.extend(["-p", &s2.path, "--yes"]);
    let out = YOSEMITECH.run(&args).ok().to_owned();
    assert!(out.contains("nothing to read back") && !out.contains("saved every coefficient"), "{out}");
    // A write with a read of the same registers at another address (get_slave_id at 0xFF).
    let set = sensor.command_with_role(Role::SetSlaveAddress).expect("a set-address command");
    let field = set.named_fields().next().unwrap().display_name().to_owned();
    let out = YOSEMITECH.run(&["write", name, &set.name, "12", "-p", &s.path, "--yes"]).ok().to_owned();
    assert!(out.contains(&format!("{field} = 12 (matches)")), "{out}");
    assert_eq!(s.server.device().address(), 12);
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
fn poll_columns(sensor: &yosemitech_spec::Sensor) -> Vec<(String, String, String)> {
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

#[test]
fn poll_csv_gives_one_row_per_poll() {
    for sensor in spec().sensors.clone() {
        let columns = poll_columns(&sensor);
        if columns.is_empty() {
            continue;
        }
        let name = sensor.name.as_str();
        let s = sim(name, 1);
        let run = YOSEMITECH.run(&["poll", name, "-p", &s.path, "--count", "3", "--interval", "0", "--format", "csv"]);
        let out = run.ok();
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), 4, "a header and 3 rows:\n{out}");
        let names: Vec<&str> = columns.iter().map(|(_, _, n)| n.as_str()).collect();
        assert_eq!(lines[0], format!("timestamp,{},error", names.join(",")));
        for row in &lines[1..] {
            let cells: Vec<&str> = row.split(',').collect();
            assert_eq!(cells.len(), columns.len() + 2, "{row}");
            assert!(cells[0].len() == 24 && cells[0].ends_with('Z') && cells[0].as_bytes()[10] == b'T', "{row}");
            for ((read, field, _), cell) in columns.iter().zip(&cells[1..]) {
                let want = s.server.device().get(read, field).unwrap();
                match plain(&want) {
                    Some(want) => assert_eq!(*cell, want, "{name} {read}.{field}: {row}"),
                    None => assert!(!cell.is_empty(), "{name} {read}.{field}: {row}"),
                }
            }
            assert_eq!(cells.last(), Some(&""), "no error: {row}");
        }
    }
}

#[test]
fn poll_reports_errors_per_row_and_goes_on() {
    let mut polled = 0;
    for sensor in spec().sensors.clone() {
        let columns = poll_columns(&sensor);
        let Some((first, _, _)) = columns.first().cloned() else { continue };
        let name = sensor.name.as_str();
        let s = sim(name, 1);
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
        let mut args = vec!["poll", name, "-p", &s.path, "-a", "7", "-n", "2", "-i", "0", "-f", "table"];
        args.extend(FAST);
        let run = YOSEMITECH.run(&args);
        run.fails_with_hint(1);
        assert_eq!(run.stdout.lines().count(), 3, "{}", run.stdout);
        assert!(run.stdout.contains("no reply"), "{}", run.stdout);
        polled += 1;
    }
    assert!(polled > 0);
}

#[test]
fn poll_stops_cleanly_on_ctrl_c() {
    let sensor = spec().sensors.iter().find(|&s| !poll_columns(s).is_empty()).cloned().expect("a sensor to poll");
    let s = sim(&sensor.name, 1);
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
    let sensor = identifiable().into_iter().next().unwrap();
    let s = sim(&sensor.name, 1);
    let mut args = vec!["set-address", "-p", &s.path, "--from", "1", "--to", "42", "--yes", "--sensor", &sensor.name];
    args.extend(FAST);
    let out = YOSEMITECH.run(&args).ok().to_owned();
    assert!(out.contains("now answers at address 42") && out.contains(&own_serial_number(&sensor)), "{out}");
    assert_eq!(s.server.device().address(), 42);
    // Nothing answers at the old address any more: refused, nothing written.
    let mut args = vec!["set-address", "-p", &s.path, "--from", "1", "--to", "43", "--yes"];
    args.extend(FAST);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(err.contains("no probe answers at address 1"), "{err}");
    assert_eq!(s.server.device().address(), 42);
    // The new address taken by the probe itself.
    let mut args = vec!["set-address", "-p", &s.path, "--from", "7", "--to", "42", "--yes"];
    args.extend(FAST);
    assert!(YOSEMITECH.run(&args).fails_with_hint(2).contains("already answers at address 42"));
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
    assert!(!sensors.is_empty(), "the spec has coefficient blocks");
    for (i, sensor) in sensors.iter().enumerate() {
        let name = sensor.name.as_str();
        let address = 5u8.to_string();
        let s = sim(name, 5);
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join(format!("{name} backup.json"));
        let file = file.to_str().unwrap();
        let blocks = sensor.coefficient_blocks();
        // A value only bit-exact float handling keeps, in every block.
        let fields =
            |read: &CommandSpec| -> Vec<String> { read.named_fields().map(|f| f.display_name().to_owned()).collect() };
        for (_, read) in &blocks {
            let first = &fields(read)[0];
            s.server.device().set(&read.name, first, Value::Float(0.987_654_3)).unwrap();
        }
        let before: Vec<(String, String, f32)> = blocks
            .iter()
            .flat_map(|(_, read)| fields(read).into_iter().map(|f| (read.name.clone(), f)))
            .map(|(c, f)| {
                let v = float(&s, &c, &f);
                (c, f, v)
            })
            .collect();
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
        for (c, f, _) in &before {
            s.server.device().set(c, f, Value::Float(42.0)).unwrap();
        }
        // Restoring needs confirmation.
        let restore = ["coefficients", "restore", name, "-p", &s.path, "-a", &address, "--file", file];
        YOSEMITECH.run(&restore).fails_with_hint(2);
        for (c, f, _) in &before {
            assert_eq!(float(&s, c, f), 42.0, "nothing written without --yes");
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
}

/// Every coefficient the simulated probe holds, as (read, field, value)
/// over its sensor's coefficient blocks.
fn coefficients(s: &Sim<Simulator>, sensor: &yosemitech_spec::Sensor) -> Vec<(String, String, f32)> {
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

/// Sets each of `coefficients` on the probe to a value of its own (`base`, `base + 1`, ...).
fn overwrite(s: &Sim<Simulator>, coefficients: &[(String, String, f32)], base: f32) {
    for (i, (c, f, _)) in coefficients.iter().enumerate() {
        s.server.device().set(c, f, Value::Float(base + i as f32)).unwrap();
    }
}

/// The sensor `calibrate ph` drives: the one whose spec has a
/// `calibration_point` command (the pH manual's own procedure).
fn calibrated_sensor() -> String {
    let with: Vec<String> = spec()
        .sensors
        .iter()
        .filter(|&s| s.command_with_role(Role::CalibrationPoint).is_some())
        .cloned()
        .map(|s| s.name)
        .collect();
    assert_eq!(with.len(), 1, "one sensor has a calibration point: {with:?}");
    with[0].clone()
}

/// `calibrate ph` on a new simulated probe, with `input` on stdin and its
/// backup in a new directory (returned with the probe and the run).
fn calibrate_with(input: &str) -> (Sim<Simulator>, tempfile::TempDir, Run) {
    let s = sim(&calibrated_sensor(), 1);
    let dir = tempfile::tempdir().unwrap();
    let backup_dir = dir.path().to_str().unwrap();
    let run = YOSEMITECH
        .run_with_input(&["calibrate", "ph", "-p", &s.path, "--yes", "--skip-wait", "--backup-dir", backup_dir], input);
    (s, dir, run)
}

#[test]
fn calibrate_ph_guides_three_points_and_reports_success() {
    let (_s, dir, run) = calibrate_with("\n\n\n");
    let out = run.ok();
    for needle in ["pH 4.00 buffer", "pH 6.86 buffer", "pH 9.18 buffer", "calibration succeeded", "restore with:"] {
        assert!(out.contains(needle), "`{needle}` missing:\n{out}");
    }
    assert!(out.find("saved every coefficient").unwrap() < out.find("pH 4.00 buffer").unwrap(), "backup first");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "one backup file");
    // The coefficients after it: every block, read from the probe.
    let after = out.split("coefficients now:").nth(1).expect("the coefficients after the calibration");
    for (write, _) in yosemitech_tests::sensor(&calibrated_sensor()).coefficient_blocks() {
        assert!(after.contains(&format!("{}: ", write.name)), "{after}");
    }
}

#[test]
fn calibrate_ph_stops_on_q_and_prints_the_restore_command() {
    let name = calibrated_sensor();
    let (s, dir, run) = calibrate_with("\nq\n");
    let err = run.fails(1);
    assert!(err.contains("stopped by the user at point 2"), "{err}");
    assert!(err.contains(&format!("yosemitech coefficients restore {name}")), "{err}");
    assert_eq!(s.server.device().calibration_points().len(), 1, "one point written");
    // The calibration's backup restores like any other: every coefficient, bit for bit.
    let file = std::fs::read_dir(dir.path()).unwrap().next().expect("the backup file").unwrap().path();
    let before = coefficients(&s, &yosemitech_tests::sensor(&name));
    overwrite(&s, &before, 2.5);
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
fn sensors_with_a_procedure() -> Vec<yosemitech_spec::Sensor> {
    let with: Vec<_> = spec().sensors.iter().filter(|&s| s.procedure.is_some()).cloned().collect();
    assert!(!with.is_empty(), "some sensor of the spec states a procedure");
    with
}

#[test]
fn measure_runs_every_procedure_and_prints_each_field() {
    for sensor in sensors_with_a_procedure() {
        let procedure = sensor.procedure.clone().unwrap();
        let s = sim(&sensor.name, 1);
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
}

#[test]
fn measure_averages_the_readings() {
    // A float field of the first procedure read, set to a known value.
    let sensor = sensors_with_a_procedure().into_iter().next().unwrap();
    let procedure = sensor.procedure.clone().unwrap();
    let read = sensor.command(&procedure.read[0]).unwrap();
    let field = read
        .named_fields()
        .find(|f| matches!(f.kind, yosemitech_spec::FieldKind::F32 { .. }) && f.absent != Some(1.413))
        .expect("a float field");
    let s = sim(&sensor.name, 4);
    s.server.device().set(&read.name, field.display_name(), Value::Float(1.413)).unwrap();
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
    assert_eq!(number_after(out, label) as f32, 1.413, "{out}");
    let line = out.lines().find(|l| l.trim_start().starts_with(label)).unwrap();
    assert!(line.contains("mean of 4 readings"), "{line}");
    if let Some(unit) = &field.unit {
        let shown = if unit == "degC" { "°C" } else { unit.as_str() };
        assert!(line.contains(shown), "{line}");
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
    for sensor in sensors_with_a_procedure() {
        assert!(err.contains(&sensor.name), "`{}` not offered:\n{err}", sensor.name);
    }
    YOSEMITECH.run(&["measure", "no_such_sensor", "-p", "/dev/null"]).fails_with_hint(2);
    let first = &sensors_with_a_procedure()[0].name;
    assert!(
        YOSEMITECH
            .run(&["measure", first, "-p", "/dev/null", "--readings", "0"])
            .fails_with_hint(2)
            .contains("--readings 0")
    );
}

/// The serial number a probe of `sensor` carries: the manual's, with the
/// sensor's own model code in characters 3-4 (what real probes send, and
/// the simulator too).
fn own_serial_number(sensor: &yosemitech_spec::Sensor) -> String {
    let printed = sensor.example_serial_number().unwrap_or_else(|| "YL0014010022".into());
    match &sensor.model_code {
        Some(code) => format!("{}{code}{}", &printed[..2], &printed[4..]),
        None => printed,
    }
}

/// The serial-number read of `sensor` and its text field.
fn sn_field(sensor: &yosemitech_spec::Sensor) -> (&CommandSpec, &yosemitech_spec::Field) {
    let command = sensor.command_with_role(Role::SerialNumber).unwrap();
    let field = command.named_fields().find(|f| matches!(f.kind, yosemitech_spec::FieldKind::Ascii { .. })).unwrap();
    (command, field)
}

/// The sensors `scan` can identify: a serial-number read and a model code.
fn identifiable() -> Vec<yosemitech_spec::Sensor> {
    let all: Vec<_> = spec()
        .sensors
        .iter()
        .filter(|&s| s.model_code.is_some() && s.command_with_role(Role::SerialNumber).is_some())
        .cloned()
        .collect();
    assert!(all.len() >= 2, "the spec has sensors scan can tell apart");
    all
}

/// The distinct serial-number reads of the spec.
fn sn_layouts() -> usize {
    let mut layouts: Vec<(u16, u16)> = spec()
        .sensors
        .iter()
        .filter_map(|s| s.command_with_role(Role::SerialNumber).map(|c| (c.address, c.count)))
        .collect();
    layouts.sort_unstable();
    layouts.dedup();
    layouts.len()
}

/// The newest manual of `sensor` whose software is at most `software`.
fn manual_for(sensor: &yosemitech_spec::Sensor, software: &str) -> Option<String> {
    let key = |v: &str| -> (u32, u32) {
        let (a, b) = v.split_once('.').unwrap_or((v, "0"));
        (a.parse().unwrap(), b.parse().unwrap())
    };
    sensor.manuals().filter_map(|m| m.software.clone()).filter(|sw| key(sw) <= key(software)).max_by_key(|sw| key(sw))
}

#[test]
fn scan_names_each_sensor_of_the_spec_alone() {
    let sensors = identifiable();
    let mut bus = Bus::new();
    for (i, sensor) in sensors.iter().enumerate() {
        bus.push(Simulator::new(Arc::new(sensor.clone())).with_address(i as u8 + 1));
    }
    let s = yosemitech_tests::cli::serve(bus);
    let last = sensors.len() + 1;
    let addresses = format!("1-{last}");
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s"]);
    let out = run.ok().to_owned();
    for (i, sensor) in sensors.iter().enumerate() {
        let code = sensor.model_code.as_deref().unwrap();
        let line = out
            .lines()
            .find(|l| l.starts_with(&format!("address {:3}  ", i + 1)))
            .unwrap_or_else(|| panic!("no line for address {}:\n{out}", i + 1));
        let named = match &sensor.model {
            Some(model) => format!("{} ({model}, code {code})", sensor.name),
            None => format!("{} (code {code})", sensor.name),
        };
        assert!(line.contains(&format!("SN {}  {named}", own_serial_number(sensor))), "{line}");
        assert!(!line.contains("not identified"), "{line}");
    }
    assert!(out.contains(&format!("found {} device(s)", sensors.len())), "{out}");
    // Few reads per address: the serial-number reads tried, and one for the revisions.
    let requests = s.server.device().devices()[0].stats().requests;
    assert!(requests <= (last * (sn_layouts() + 1)) as u64, "{requests} requests for {last} addresses");

    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices.len(), sensors.len(), "{json}");
    for (device, sensor) in devices.iter().zip(&sensors) {
        assert_eq!(device["sensor"], sensor.name.as_str(), "{device}");
        assert_eq!(device["sensors"], serde_json::json!([sensor.name]), "{device}");
        assert_eq!(device["model"].as_str(), sensor.model.as_deref(), "{device}");
        assert_eq!(device["model_code"].as_str(), sensor.model_code.as_deref(), "{device}");
        assert_eq!(device["serial_number"], own_serial_number(sensor).as_str());
        assert_eq!(device["reason"], Json::Null);
        // The revisions, and the manual that covers that firmware.
        let bus = s.server.device();
        let sim = &bus.devices()[device["address"].as_u64().unwrap() as usize - 1];
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
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &format!("{}", last + 1)]);
    assert!(run.fails_with_hint(1).contains("no device answered"), "{}", run.stderr);
}

#[test]
fn scan_takes_the_model_code_from_the_byte_before_the_serial_number() {
    // Real probes send the code in the byte the manuals print as 0x00; the
    // text may carry another (the manuals print a sibling's serial number).
    let sensors: Vec<_> = identifiable()
        .into_iter()
        .filter(|s| {
            let (command, field) = sn_field(s);
            field.offset > 0 && command.fields.iter().any(|f| f.is_reserved() && f.offset + f.size() == field.offset)
        })
        .collect();
    let mut bus = Bus::new();
    for (i, sensor) in sensors.iter().enumerate() {
        let (command, field) = sn_field(sensor);
        let code = sensor.model_code.as_deref().unwrap();
        let byte = u8::from_str_radix(code, 16).unwrap();
        let mut device = Simulator::new(Arc::new(sensor.clone())).with_address(i as u8 + 1);
        device.set(&command.name, field.display_name(), Value::Text("YL9914010022".into())).unwrap();
        device.registers_mut().write_bytes(command.address, field.offset - 1, &[byte]);
        bus.push(device);
    }
    let s = yosemitech_tests::cli::serve(bus);
    let addresses = format!("1-{}", sensors.len());
    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices.len(), sensors.len());
    for (device, sensor) in devices.iter().zip(&sensors) {
        assert_eq!(device["sensor"], sensor.name.as_str(), "{device}");
        assert_eq!(device["model_code"].as_str(), sensor.model_code.as_deref());
        assert_eq!(device["serial_number"], "YL9914010022");
    }
}

#[test]
fn scan_lists_the_candidates_where_it_cannot_decide() {
    let sensor = identifiable().into_iter().next().unwrap();
    let (command, field) = sn_field(&sensor);
    // A model code no loaded sensor declares: every sensor that reads its
    // serial number the same way is a candidate.
    let mut device = Simulator::new(Arc::new(sensor.clone())).with_address(2);
    device.set(&command.name, field.display_name(), Value::Text("YL9914010022".into())).unwrap();
    if let Some(before) = field.offset.checked_sub(1) {
        device.registers_mut().write_bytes(command.address, before, &[0x99]);
    }
    let s = yosemitech_tests::cli::serve(device);
    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", "2", "--timeout", "1s", "--json"]).json();
    let found = &json["devices"][0];
    assert_eq!(found["sensor"], Json::Null, "{found}");
    assert_eq!(found["model_code"], "99");
    let same_read: Vec<String> = spec()
        .sensors
        .iter()
        .filter(|s| {
            s.command_with_role(Role::SerialNumber)
                .is_some_and(|c| (c.address, c.count) == (command.address, command.count))
        })
        .map(|s| s.name.clone())
        .collect();
    assert_eq!(found["sensors"], serde_json::json!(same_read), "{found}");
    assert!(found["reason"].as_str().unwrap().contains("model code 99"), "{found}");
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", "2", "--timeout", "1s"]);
    let out = run.ok();
    assert!(out.contains("not identified") && out.contains(&sensor.name) && out.contains("model code 99"), "{out}");

    // Two loaded sensors declaring one code: both are listed.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(&sensor.file).unwrap();
    let twin = format!("{}_twin", sensor.name);
    let renamed = text.replacen(&format!("name: {}\n", sensor.name), &format!("name: {twin}\n"), 1);
    assert_ne!(renamed, text, "the sensor's name line");
    std::fs::write(dir.path().join("twin.yaml"), renamed).unwrap();
    let spec_arg = dir.path().to_str().unwrap();
    s.server.device().set(&command.name, field.display_name(), Value::Text(own_serial_number(&sensor))).unwrap();
    let json = YOSEMITECH
        .run(&["--spec", spec_arg, "scan", "-p", &s.path, "--addresses", "2", "--timeout", "1s", "--json"])
        .json();
    let found = &json["devices"][0];
    assert_eq!(found["sensor"], Json::Null, "{found}");
    assert_eq!(found["sensors"], serde_json::json!([sensor.name, twin]), "{found}");
    assert!(found["reason"].as_str().unwrap().contains("2 loaded sensors"), "{found}");
}

/// `yosemitech simulate` in a child process: the port it prints, and a clean
/// stop on Ctrl-C.
fn spawn_simulate(args: &[&str]) -> (std::process::Child, String) {
    let mut child = YOSEMITECH
        .command()
        .arg("simulate")
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    (child, line.trim().to_owned())
}

fn interrupt(mut child: std::process::Child) -> String {
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    assert_eq!(yosemitech_tests::cli::wait(&mut child, Duration::from_secs(10)), 0, "simulate stops cleanly on Ctrl-C");
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    err
}

/// A measurement read whose example (in the sensor's own manual) the
/// simulator answers: the sensor, the read, the true request and reply,
/// and the line `read` shows for its one f32 field (`name  value unit`).
fn stated_read() -> (yosemitech_spec::Sensor, CommandSpec, Vec<u8>, Vec<u8>, String) {
    for sensor in spec().sensors.clone() {
        let device = Simulator::new(Arc::new(sensor.clone()));
        for command in sensor.commands.iter().filter(|c| c.is_read() && c.role.is_none() && c.fixed_slave.is_none()) {
            let mut named = command.named_fields();
            let (Some(field), None) = (named.next(), named.next()) else { continue };
            if !matches!(field.kind, yosemitech_spec::FieldKind::F32 { .. }) || field.unit.is_none() {
                continue;
            }
            let Some(example) = stated_example(command) else { continue };
            let (Some((request, reply)), Some(value)) = (example.true_pair(), example.values.get(field.display_name()))
            else {
                continue;
            };
            if example.slave() != 1 || !device.get(&command.name, field.display_name()).is_ok_and(|v| v.same_as(value))
            {
                continue;
            }
            let line = format!("{}  {}", field.display_name(), shown(value, field.unit.as_deref()));
            return (sensor.clone(), command.clone(), request.to_vec(), reply.to_vec(), line);
        }
    }
    panic!("no measurement read whose stated example the simulator answers")
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

#[test]
fn simulate_serves_a_pty_until_interrupted() {
    let (sensor, command, _, _, line) = stated_read();
    let (child, port) = spawn_simulate(&[&sensor.name, "--address", "4"]);
    assert!(port.starts_with("/dev/"), "{port}");
    let out = YOSEMITECH.run(&["read", &sensor.name, &command.name, "-p", &port, "-a", "4"]);
    assert!(out.ok().contains(&line), "{}", out.stdout);
    let err = interrupt(child);
    let title = format!("simulating {} ({})", sensor.title, sensor.name);
    assert!(err.contains(&title) && err.contains("stopped: 1 requests"), "{err}");
}

#[test]
fn simulate_serves_rtu_over_tcp() {
    let (sensor, command, _, _, line) = stated_read();
    let (child, port) = spawn_simulate(&[&sensor.name, "--tcp", "127.0.0.1:0"]);
    assert!(port.starts_with("tcp://127.0.0.1:"), "{port}");
    let out = YOSEMITECH.run(&["read", &sensor.name, &command.name, "-p", &port]);
    assert_eq!(out.ok().trim(), line);
    interrupt(child);
}

#[test]
fn simulate_serves_modbus_tcp() {
    use std::io::{Read, Write};
    use yosemitech_rtu::mbap::{MAX_MBAP_ADU, adu_to_rtu, rtu_to_adu};

    let (sensor, command, request, reply, _) = stated_read();
    let (child, port) = spawn_simulate(&[&sensor.name, "--tcp", "127.0.0.1:0", "--protocol", "mbap"]);
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
    // A read the first sensor of the spec lacks, from another sensor's command.
    let spec = spec();
    let sensor = &spec.sensors[0];
    let (owner, foreign) = spec
        .sensors
        .iter()
        .flat_map(|s| s.commands.iter().map(move |c| (s, c)))
        .find(|(_, c)| {
            c.is_read()
                && !c.trigger
                && c.fixed_slave.is_none()
                && !sensor.commands.iter().any(|m| m.function == c.function && m.address == c.address)
        })
        .expect("some sensor reads a register the first one lacks");
    for (flags, expected) in [(&[][..], "no reply"), (&["--exceptions"][..], "Modbus exception")] {
        let mut args = vec![sensor.name.as_str(), "--tcp", "127.0.0.1:0"];
        args.extend_from_slice(flags);
        let (child, port) = spawn_simulate(&args);
        let run =
            YOSEMITECH.run(&["read", &owner.name, &foreign.name, "-p", &port, "--timeout", "500ms", "--retries", "0"]);
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
    let (child, port) = spawn_simulate(&[&sensor.name, "--faults", "drop=0.3,corrupt_crc=0.2", "--seed", "5"]);
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
    let (child, port) = spawn_simulate(&["--spec", spec, "do_probe"]);
    let out = YOSEMITECH.run(&["read", "--spec", spec, "do_probe", "get_dissolved_oxygen", "-p", &port]);
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
    let (sensor, command, request, reply, _) = stated_read();
    let s = sim(&sensor.name, 1);
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
    let name = calibrated_sensor();
    let dir = tempfile::tempdir().unwrap();
    let own = std::fs::read_dir(yosemitech_tests::spec_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            p.extension().is_some_and(|e| e == "yaml")
                && std::fs::read_to_string(p).unwrap().contains(&format!("\n  name: {name}\n"))
        })
        .expect("the calibrated sensor's spec file");
    std::fs::copy(&own, dir.path().join(own.file_name().unwrap())).unwrap();
    let spec_arg = dir.path().to_str().unwrap();
    let s = sim(&name, 1);
    let file = dir.path().join("backup.json");
    let file = file.to_str().unwrap();
    let sensor = yosemitech_tests::sensor(&name);
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
    overwrite(&s, &before, 1.5);
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

//! The `yosemitech` binary against simulated probes on pseudo-terminals
//! (yosemitech-sim's `serve_pty`, or `yosemitech simulate` in a child
//! process), through the real serial code path. No hardware.
#![cfg(unix)]

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use std::sync::Arc;

use common::{fixture_spec_dir, number_after, sim, spec, yosemitech, yosemitech_with_input};
use serde_json::Value as Json;
use yosemitech_sim::{Bus, FaultConfig, FaultKind, Simulator, UnknownRequestPolicy};
use yosemitech_spec::{Command as SpecCommand, Role, Value};

/// Short timeouts for requests that are meant to fail.
const FAST: [&str; 4] = ["--timeout", "150ms", "--retries", "0"];

fn float(sim: &common::Sim<yosemitech_sim::Simulator>, command: &str, field: &str) -> f32 {
    match sim.server.device().get(command, field).unwrap() {
        Value::Float(v) => v,
        other => panic!("{command}.{field} is {other:?}"),
    }
}

#[test]
fn demo_runs_both_probes_and_prints_the_values() {
    let started = Instant::now();
    let run = yosemitech(&["demo"]);
    let out = run.ok();
    assert!(started.elapsed() < Duration::from_secs(20), "the demo takes a few seconds");
    for needle in [
        "/dev/pts/",
        "YL4314010022",
        "YL0914010022",
        "hardware        1.1",
        "software        1.0",
        " pH",
        " mV",
        "°C",
        "mS/cm",
        "range status    ok",
        "electrode K1-K6 6.86 -6.72 0.04 6.86 -6.56 -1.04",
        "mean of 10 readings",
        "ok (all 10 readings)",
    ] {
        assert!(out.contains(needle), "`{needle}` missing from the demo:\n{out}");
    }
    // The spec's procedure, waits shortened: the mean of the simulated 1.413 mS/cm.
    let measurement = out.split("waits shortened").nth(1).expect("the measurement section");
    let conductivity = number_after(measurement, "conductivity_ms_cm");
    assert!((conductivity - 1.413).abs() < 0.01, "{measurement}");
    assert!((number_after(out, "pH  ") - 7.02).abs() < 0.05, "{out}");
}

#[test]
fn demo_identifies_every_sensor_of_the_spec_on_one_bus() {
    let run = yosemitech(&["demo"]);
    let out = run.ok();
    let section =
        out.split("the whole family on one RS-485 bus").nth(1).unwrap_or_else(|| panic!("no family section:\n{out}"));
    let sensors = spec().sensors;
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

#[test]
fn read_shows_values_with_units() {
    let s = sim("ph_orp", 1);
    let out = yosemitech(&["read", "ph_orp", "get_ph", "--port", &s.path]).ok().to_owned();
    assert_eq!(out.trim(), "ph  7.6 pH");
    let out = yosemitech(&["read", "ph", "orp_and_ph", "-p", &s.path]).ok().to_owned();
    assert!(out.contains("orp_mv  -6.56 mV") && out.contains("ph      7 pH"), "{out}");
    let json = yosemitech(&["read", "ph_orp", "get_version", "-p", &s.path, "--json"]).json();
    assert_eq!(json["values"], serde_json::json!({ "hardware": "1.1", "software": "1.1" }));
    assert!(json["timestamp"].as_str().unwrap().ends_with('Z'));
    // get_slave_id goes to the wildcard address 0xFF whatever --address says.
    let out = yosemitech(&["read", "ph_orp", "get_slave_id", "-p", &s.path, "-a", "9"]).ok().to_owned();
    assert_eq!(out.trim(), "slave_address  1");
}

#[test]
fn port_and_baud_come_from_the_environment() {
    let s = sim("conductivity", 1);
    let mut cmd = common::command();
    cmd.args(["read", "conductivity", "get_sn"]).env("YOSEMITECH_PORT", &s.path).env("YOSEMITECH_BAUD", "9600");
    let run = common::run_command(cmd, None);
    assert!(run.ok().contains("YL0914010022"));
}

#[test]
fn a_silent_address_times_out_cleanly() {
    let s = sim("ph_orp", 1);
    let run =
        yosemitech(&["read", "ph_orp", "get_ph", "-p", &s.path, "-a", "9", "--timeout", "100ms", "--retries", "1"]);
    let err = run.fails_with_hint(1);
    assert!(err.contains("no reply to get_ph from address 9") && err.contains("within 100ms"), "{err}");
    assert!(err.contains("yosemitech scan"), "{err}");
    // A command the probe does not have: real probes stay silent, and the hint says so.
    let mut args = vec!["read", "conductivity", "get_temperature_and_conductivity", "-p", &s.path];
    args.extend(FAST);
    let err = yosemitech(&args).fails_with_hint(1).to_owned();
    assert!(err.contains("no reply to get_temperature_and_conductivity") && err.contains("lacks"), "{err}");
    // A device that answers exceptions instead: the exception, explained.
    let mut device = Simulator::new(common::sensor("ph_orp"));
    device.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let s = common::serve(device);
    let run = yosemitech(&["read", "conductivity", "get_temperature_and_conductivity", "-p", &s.path]);
    assert!(
        run.fails_with_hint(1)
            .contains("refused get_temperature_and_conductivity with Modbus exception illegal data value"),
        "{}",
        run.stderr
    );
}

#[test]
fn write_backs_up_coefficients_confirms_and_reads_back() {
    let s = sim("ph_orp", 1);
    let dir = tempfile::tempdir().unwrap();
    let backup_dir = dir.path().to_str().unwrap();
    // Without a terminal and without --yes, nothing is sent.
    let run = yosemitech(&["write", "ph_orp", "set_ph_calibration", "1.02", "-0.05", "-p", &s.path]);
    assert!(run.fails_with_hint(2).contains("--yes") || run.stderr.contains("stdin is not a terminal"));
    assert_eq!(float(&s, "get_ph_calibration", "k_slope"), 1.0);

    let run = yosemitech(&[
        "write",
        "ph_orp",
        "set_ph_calibration",
        "k_slope=1.02",
        "b_offset=-0.05",
        "-p",
        &s.path,
        "--yes",
        "--backup-dir",
        backup_dir,
    ]);
    let out = run.ok();
    assert!(out.contains("frame: 01 10 11 00 00 04 08 5C 8F 82 3F CD CC 4C BD F1 CF"), "{out}");
    assert!(out.contains("k_slope = 1.02 (matches)") && out.contains("verified"), "{out}");
    assert!(out.contains("restore with: yosemitech coefficients restore ph_orp --port"), "{out}");
    assert_eq!(float(&s, "get_ph_calibration", "k_slope"), 1.02);
    let files: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(files.len(), 1, "one backup file");
    let backup: Json =
        serde_json::from_str(&std::fs::read_to_string(files[0].as_ref().unwrap().path()).unwrap()).unwrap();
    assert_eq!(backup["coefficients"]["set_ph_calibration"]["k_slope"], 1.0, "the backup holds the old values");
    assert_eq!(backup["coefficients"]["set_ph_electrode_coefficients"]["k2"], -6.72);

    // A write that is not a coefficient: no backup, and no read-back command.
    let out = yosemitech(&["write", "ph_orp", "start_ph_calibration", "4", "-p", &s.path, "--yes"]).ok().to_owned();
    assert!(out.contains("nothing to read back") && !out.contains("saved every coefficient"), "{out}");
    // A write with a read of the same registers at another address (get_slave_id at 0xFF).
    let out = yosemitech(&["write", "ph_orp", "set_slave_id", "12", "-p", &s.path, "--yes"]).ok().to_owned();
    assert!(out.contains("slave_address = 12 (matches)"), "{out}");
    assert_eq!(s.server.device().address(), 12);
}

#[test]
fn poll_csv_gives_one_row_per_poll() {
    let s = sim("ph_orp", 1);
    let run = yosemitech(&["poll", "ph_orp", "-p", &s.path, "--count", "3", "--interval", "0", "--format", "csv"]);
    let out = run.ok();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 4, "a header and 3 rows:\n{out}");
    assert_eq!(
        lines[0],
        "timestamp,get_ph.ph,get_orp_and_ph.orp_mv,get_orp_and_ph.ph,get_orp.orp_mv,temperature_c,error"
    );
    for row in &lines[1..] {
        let cells: Vec<&str> = row.split(',').collect();
        assert_eq!(cells.len(), 7, "{row}");
        assert!(cells[0].len() == 24 && cells[0].ends_with('Z') && cells[0].as_bytes()[10] == b'T', "{row}");
        assert_eq!(&cells[1..], ["7.6", "-6.56", "7", "-10.28", "15.8", ""]);
    }
}

#[test]
fn poll_reports_errors_per_row_and_goes_on() {
    let s = sim("conductivity", 1);
    // The first reply is lost: that row carries the error, the next ones do not.
    s.server.device().set_faults(FaultConfig::scripted([Some(FaultKind::Drop)]));
    let mut args = vec!["poll", "conductivity", "-p", &s.path, "-n", "3", "-i", "0", "-f", "json"];
    args.extend(FAST);
    let run = yosemitech(&args);
    let rows: Vec<Json> = run.ok().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(rows.len(), 3);
    assert_eq!(rows[0]["error"], "get_temperature_and_conductivity: no reply");
    assert_eq!(rows[0]["values"]["conductivity_ms_cm"], Json::Null);
    assert_eq!(rows[1]["error"], Json::Null);
    assert_eq!(rows[1]["values"]["conductivity_ms_cm"], 17.625);
    assert_eq!(rows[2]["values"]["range_status"]["name"], "ok");

    // Every poll failing is exit 1, after every row was printed.
    let mut args = vec!["poll", "conductivity", "-p", &s.path, "-a", "7", "-n", "2", "-i", "0", "-f", "table"];
    args.extend(FAST);
    let run = yosemitech(&args);
    run.fails_with_hint(1);
    assert_eq!(run.stdout.lines().count(), 3, "{}", run.stdout);
    assert!(run.stdout.contains("no reply"), "{}", run.stdout);
}

#[test]
fn poll_stops_cleanly_on_ctrl_c() {
    let s = sim("ph_orp", 1);
    let mut child = common::command()
        .args(["poll", "ph_orp", "-p", &s.path, "--interval", "50ms", "--format", "csv"])
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
    let code = common::wait(&mut child, Duration::from_secs(10));
    assert_eq!(code, 0, "Ctrl-C ends polling with success");
}

#[test]
fn set_address_changes_and_verifies() {
    let s = sim("conductivity", 1);
    let mut args = vec!["set-address", "-p", &s.path, "--from", "1", "--to", "42", "--yes", "--sensor", "conductivity"];
    args.extend(FAST);
    let out = yosemitech(&args).ok().to_owned();
    assert!(out.contains("now answers at address 42") && out.contains("YL0914010022"), "{out}");
    assert_eq!(s.server.device().address(), 42);
    // Nothing answers at the old address any more: refused, nothing written.
    let mut args = vec!["set-address", "-p", &s.path, "--from", "1", "--to", "43", "--yes"];
    args.extend(FAST);
    let err = yosemitech(&args).fails_with_hint(1).to_owned();
    assert!(err.contains("no probe answers at address 1"), "{err}");
    assert_eq!(s.server.device().address(), 42);
    // The new address taken by the probe itself.
    let mut args = vec!["set-address", "-p", &s.path, "--from", "7", "--to", "42", "--yes"];
    args.extend(FAST);
    assert!(yosemitech(&args).fails_with_hint(2).contains("already answers at address 42"));
}

#[test]
fn set_address_refuses_0_and_248() {
    let s = sim("ph_orp", 1);
    for (from, to) in [("0", "5"), ("1", "0"), ("1", "248"), ("248", "1")] {
        let run = yosemitech(&["set-address", "-p", &s.path, "--from", from, "--to", to, "--yes"]);
        assert!(run.fails_with_hint(2).contains("outside 1..=247"), "{}", run.stderr);
    }
    assert_eq!(s.server.device().stats().requests, 0, "nothing was sent");
}

#[test]
fn coefficients_backup_and_restore_round_trip() {
    let s = sim("ph_orp", 1);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ph backup.json");
    let file = file.to_str().unwrap();
    s.server.device().set("get_orp_calibration", "k_slope", Value::Float(0.987_654_3)).unwrap();
    let out = yosemitech(&["coefficients", "backup", "ph_orp", "-p", &s.path, "--file", file]).ok().to_owned();
    assert!(out.contains("restore with:") && out.contains("'"), "the path with a space is quoted:\n{out}");
    // Never overwritten.
    yosemitech(&["coefficients", "backup", "ph_orp", "-p", &s.path, "--file", file]).fails_with_hint(2);

    // Change everything, then restore.
    for (command, field) in [("get_orp_calibration", "k_slope"), ("get_ph_calibration", "b_offset")] {
        s.server.device().set(command, field, Value::Float(42.0)).unwrap();
    }
    s.server.device().set("get_ph_electrode_coefficients", "k6", Value::Float(-3.5)).unwrap();
    // Restoring needs confirmation.
    yosemitech(&["coefficients", "restore", "ph_orp", "-p", &s.path, "--file", file]).fails_with_hint(2);
    assert_eq!(float(&s, "get_orp_calibration", "k_slope"), 42.0);
    let out =
        yosemitech(&["coefficients", "restore", "ph_orp", "-p", &s.path, "--file", file, "--yes"]).ok().to_owned();
    assert!(out.contains("restored and verified"), "{out}");
    assert!(out.contains("saved the probe's current coefficients to"), "restore keeps what it overwrites:\n{out}");
    assert_eq!(float(&s, "get_orp_calibration", "k_slope").to_bits(), 0.987_654_3f32.to_bits());
    assert_eq!(float(&s, "get_ph_calibration", "b_offset"), 0.0);
    assert_eq!(float(&s, "get_ph_electrode_coefficients", "k6"), -1.04);
    // A pH backup is not a conductivity backup.
    let err = yosemitech(&["coefficients", "restore", "conductivity", "-p", &s.path, "--file", file, "--yes"])
        .fails_with_hint(2)
        .to_owned();
    assert!(err.contains("`ph_orp` probe"), "{err}");
}

#[test]
fn conductivity_coefficients_round_trip() {
    let s = sim("conductivity", 5);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("c.json");
    let file = file.to_str().unwrap();
    yosemitech(&["coefficients", "backup", "conductivity", "-p", &s.path, "-a", "5", "-f", file]).ok();
    s.server.device().set("get_user_calibration", "k_slope", Value::Float(2.5)).unwrap();
    yosemitech(&["coefficients", "restore", "cond", "-p", &s.path, "-a", "5", "-f", file, "-y"]).ok();
    assert_eq!(float(&s, "get_user_calibration", "k_slope"), 1.0);
}

#[test]
fn calibrate_ph_guides_three_points_and_reports_success() {
    let s = sim("ph_orp", 1);
    let dir = tempfile::tempdir().unwrap();
    let backup_dir = dir.path().to_str().unwrap();
    let run = yosemitech_with_input(
        &["calibrate", "ph", "-p", &s.path, "--yes", "--skip-wait", "--backup-dir", backup_dir],
        "\n\n\n",
    );
    let out = run.ok();
    for needle in ["pH 4.00 buffer", "pH 6.86 buffer", "pH 9.18 buffer", "calibration succeeded", "restore with:"] {
        assert!(out.contains(needle), "`{needle}` missing:\n{out}");
    }
    assert!(out.find("saved every coefficient").unwrap() < out.find("pH 4.00 buffer").unwrap(), "backup first");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "one backup file");
}

#[test]
fn calibrate_ph_stops_on_q_and_prints_the_restore_command() {
    let s = sim("ph_orp", 1);
    let dir = tempfile::tempdir().unwrap();
    let backup_dir = dir.path().to_str().unwrap();
    let run = yosemitech_with_input(
        &["calibrate", "ph", "-p", &s.path, "--yes", "--skip-wait", "--backup-dir", backup_dir],
        "\nq\n",
    );
    let err = run.fails(1);
    assert!(err.contains("stopped by the user at point 2"), "{err}");
    assert!(err.contains("yosemitech coefficients restore ph_orp"), "{err}");
    assert_eq!(s.server.device().calibration_points().len(), 1, "one point written");
    // Without --yes and without a terminal, nothing starts.
    let run = yosemitech(&["calibrate", "ph", "-p", &s.path, "--skip-wait", "--backup-dir", backup_dir]);
    run.fails_with_hint(2);
    // A backup that cannot be saved stops the calibration before any write.
    let before = s.server.device().stats().writes;
    let run = yosemitech_with_input(
        &["calibrate", "ph", "-p", &s.path, "--yes", "--skip-wait", "--backup-dir", "/nonexistent/dir"],
        "\n\n\n",
    );
    assert!(run.fails_with_hint(1).contains("nothing was written"), "{}", run.stderr);
    assert_eq!(s.server.device().stats().writes, before);
}

/// The sensors of the spec that state a procedure.
fn sensors_with_a_procedure() -> Vec<yosemitech_spec::Sensor> {
    let with: Vec<_> = spec().sensors.into_iter().filter(|s| s.procedure.is_some()).collect();
    assert!(!with.is_empty(), "some sensor of the spec states a procedure");
    with
}

#[test]
fn measure_runs_every_procedure_and_prints_each_field() {
    for sensor in sensors_with_a_procedure() {
        let procedure = sensor.procedure.clone().unwrap();
        let s = sim(&sensor.name, 1);
        let run = yosemitech(&["measure", &sensor.name, "-p", &s.path, "--fast", "--readings", "3"]);
        let out = run.ok().to_owned();
        let reads: Vec<&SpecCommand> = procedure.read.iter().map(|r| sensor.command(r).unwrap()).collect();
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
        let json = yosemitech(&["measure", &sensor.name, "-p", &s.path, "--fast", "--readings", "2", "--json"]).json();
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
    let run = yosemitech(&[
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
    let run = yosemitech(&["--spec", spec_arg, "measure", "do_probe", "-p", "/dev/null"]);
    let err = run.fails_with_hint(2);
    assert!(err.contains("`do_probe` states no measuring procedure"), "{err}");
    for sensor in sensors_with_a_procedure() {
        assert!(err.contains(&sensor.name), "`{}` not offered:\n{err}", sensor.name);
    }
    yosemitech(&["measure", "no_such_sensor", "-p", "/dev/null"]).fails_with_hint(2);
    let first = &sensors_with_a_procedure()[0].name;
    assert!(
        yosemitech(&["measure", first, "-p", "/dev/null", "--readings", "0"])
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
fn sn_field(sensor: &yosemitech_spec::Sensor) -> (&SpecCommand, &yosemitech_spec::Field) {
    let command = sensor.command_with_role(Role::SerialNumber).unwrap();
    let field = command.named_fields().find(|f| matches!(f.kind, yosemitech_spec::FieldKind::Ascii { .. })).unwrap();
    (command, field)
}

/// The sensors `scan` can identify: a serial-number read and a model code.
fn identifiable() -> Vec<yosemitech_spec::Sensor> {
    let all: Vec<_> = spec()
        .sensors
        .into_iter()
        .filter(|s| s.model_code.is_some() && s.command_with_role(Role::SerialNumber).is_some())
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
    let s = common::serve(bus);
    let last = sensors.len() + 1;
    let addresses = format!("1-{last}");
    let run = yosemitech(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s"]);
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

    let json = yosemitech(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
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
    let run = yosemitech(&["scan", "-p", &s.path, "--addresses", &format!("{}", last + 1)]);
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
    let s = common::serve(bus);
    let addresses = format!("1-{}", sensors.len());
    let json = yosemitech(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
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
    let s = common::serve(device);
    let json = yosemitech(&["scan", "-p", &s.path, "--addresses", "2", "--timeout", "1s", "--json"]).json();
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
    let run = yosemitech(&["scan", "-p", &s.path, "--addresses", "2", "--timeout", "1s"]);
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
    let json =
        yosemitech(&["--spec", spec_arg, "scan", "-p", &s.path, "--addresses", "2", "--timeout", "1s", "--json"])
            .json();
    let found = &json["devices"][0];
    assert_eq!(found["sensor"], Json::Null, "{found}");
    assert_eq!(found["sensors"], serde_json::json!([sensor.name, twin]), "{found}");
    assert!(found["reason"].as_str().unwrap().contains("2 loaded sensors"), "{found}");
}

/// `yosemitech simulate` in a child process: the port it prints, and a clean
/// stop on Ctrl-C.
fn spawn_simulate(args: &[&str]) -> (std::process::Child, String) {
    let mut child = common::command()
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
    assert_eq!(common::wait(&mut child, Duration::from_secs(10)), 0, "simulate stops cleanly on Ctrl-C");
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    err
}

#[test]
fn simulate_serves_a_pty_until_interrupted() {
    let (child, port) = spawn_simulate(&["conductivity", "--address", "4"]);
    assert!(port.starts_with("/dev/"), "{port}");
    let out = yosemitech(&["read", "conductivity", "get_temperature_and_conductivity", "-p", &port, "-a", "4"]);
    assert!(out.ok().contains("conductivity_ms_cm  17.625 mS/cm"), "{}", out.stdout);
    let err = interrupt(child);
    assert!(err.contains("simulating Conductivity probe") && err.contains("stopped: 1 requests"), "{err}");
}

#[test]
fn simulate_serves_rtu_over_tcp() {
    let (child, port) = spawn_simulate(&["ph_orp", "--tcp", "127.0.0.1:0"]);
    assert!(port.starts_with("tcp://127.0.0.1:"), "{port}");
    let out = yosemitech(&["read", "ph_orp", "get_temperature", "-p", &port]);
    assert_eq!(out.ok().trim(), "temperature_c  15.8 °C");
    interrupt(child);
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
            yosemitech(&["read", &owner.name, &foreign.name, "-p", &port, "--timeout", "500ms", "--retries", "0"]);
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
    let (child, port) = spawn_simulate(&["ph_orp", "--faults", "drop=0.3,corrupt_crc=0.2", "--seed", "5"]);
    let run = yosemitech(&[
        "poll",
        "ph_orp",
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
    let out = yosemitech(&["read", "--spec", spec, "do_probe", "get_dissolved_oxygen", "-p", &port]);
    let text = out.ok();
    assert!(text.contains("do_mg_l") && text.contains("8.25 mg/L") && text.contains("-1250"), "{text}");
    let run = yosemitech(&["--spec", spec, "poll", "do_probe", "-p", &port, "-n", "2", "-i", "0", "-f", "csv"]);
    assert_eq!(run.ok().lines().count(), 3, "{}", run.stdout);
    let run = yosemitech(&[
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
    let run = yosemitech(&["--spec", spec, "write", "do_probe", "set_offsets", "0", "50", "0", "-p", &port, "--yes"]);
    assert!(run.fails_with_hint(2).contains("outside the valid range 0..=40"), "{}", run.stderr);
    interrupt(child);
}

#[test]
fn verbose_shows_frame_dumps() {
    let s = sim("ph_orp", 1);
    let run = yosemitech(&["read", "ph_orp", "get_ph", "-p", &s.path, "-v"]);
    run.ok();
    assert!(run.stderr.contains("tx") && run.stderr.contains("01 03 28 00 00 02 CD AB"), "{}", run.stderr);
    assert!(run.stderr.contains("rx") && run.stderr.contains("01 03 04 33 33 F3 40 40 78"), "{}", run.stderr);
    assert!(!run.stderr.contains('\u{1b}'), "no colour codes when stderr is not a terminal");
}

#[test]
fn a_spec_file_replacing_a_built_in_sensor_goes_through_the_interpreter() {
    // The pH manual's spec loaded at run time replaces the built-in sensor:
    // coefficients go through the interpreter (with the same read-back), and
    // the typed procedures refuse.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::spec_dir().join("ph-orp-optical.yaml")).unwrap();
    std::fs::write(dir.path().join("ph-orp-optical.yaml"), text).unwrap();
    let spec = dir.path().to_str().unwrap();
    let s = sim("ph_orp", 1);
    let file = dir.path().join("backup.json");
    let file = file.to_str().unwrap();
    let out =
        yosemitech(&["--spec", spec, "coefficients", "backup", "ph_orp", "-p", &s.path, "-f", file]).ok().to_owned();
    assert!(out.contains("k1=6.86") && out.contains(&format!("--spec {spec}")), "{out}");
    s.server.device().set("get_ph_electrode_coefficients", "k1", Value::Float(1.5)).unwrap();
    s.server.device().set("get_orp_calibration", "b_offset", Value::Float(-2.0)).unwrap();
    let out = yosemitech(&["--spec", spec, "coefficients", "restore", "ph_orp", "-p", &s.path, "-f", file, "--yes"]);
    assert!(out.ok().contains("restored and verified"));
    assert_eq!(float(&s, "get_ph_electrode_coefficients", "k1"), 6.86);
    assert_eq!(float(&s, "get_orp_calibration", "b_offset"), 0.0);
    let run =
        yosemitech_with_input(&["--spec", spec, "calibrate", "ph", "-p", &s.path, "--yes", "--skip-wait"], "\n\n\n");
    assert!(run.fails_with_hint(2).contains("built-in ph_orp"), "{}", run.stderr);
}

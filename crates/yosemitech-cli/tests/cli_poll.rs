//! `yosemitech poll` (and the derived quantities `read` shows): one CSV row
//! per poll, errors per row, a clean stop on Ctrl-C.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use std::process::Command;
use std::time::Duration;

use crate::device::{FAST, elsewhere, float, poll_columns, polling};
use serde_json::Value as Json;
use yosemitech_sim::{FaultConfig, FaultKind};
use yosemitech_spec::{Sensor, Value};
use yosemitech_tests::cli::{Binary, sim};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

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
    let Some((_sim, mut child, _stdout, line)) = polling(YOSEMITECH) else {
        report!("no sensor of the spec has a measurement to poll");
        return;
    };
    assert!(line.ends_with(",\n"), "a data row: {line}");
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let code = yosemitech_tests::cli::wait(&mut child, Duration::from_secs(10));
    assert_eq!(code, 0, "Ctrl-C ends polling with success");
}

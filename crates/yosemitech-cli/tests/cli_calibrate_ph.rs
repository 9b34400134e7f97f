//! `yosemitech calibrate ph`: the guided three-point calibration, a stop
//! that prints the restore command, and the coefficients computed from a
//! readings file or measured buffer by buffer through the port.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::time::Duration;

use crate::device::{calibrated_sensor, coefficients, float, overwrite};
use serde_json::Value as Json;
use yosemitech_sim::Simulator;
use yosemitech_spec::{Role, Value};
use yosemitech_tests::cli::{Binary, Run, Sim, number_after, sim};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

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

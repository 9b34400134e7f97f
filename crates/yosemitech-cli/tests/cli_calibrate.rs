//! `yosemitech calibrate SENSOR`: the K/B calibration of every probe with a
//! user calibration block, against simulated probes on pseudo-terminals
//! sitting in standards whose raw reading is a known line of the standard.
#![cfg(unix)]

use std::io::{BufRead, BufReader, Write};
use std::process::Stdio;
use std::time::Duration;

use yosemitech_sim::{FaultConfig, FaultKind, Simulator, Standard};
use yosemitech_spec::{CommandSpec, Role, Sensor, Value};
use yosemitech_tests::cli::{Binary, Sim, serve, wait};
use yosemitech_tests::spec;

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// The probe's own error in the tests: raw = (standard - B_TRUE) / K_TRUE.
const K_TRUE: f64 = 1.08;
const B_TRUE: f64 = -0.35;
/// Noise on the raw reading, half-width: small enough that the mean of
/// [`READINGS`] readings keeps K and B within 1e-3 of the truth.
const NOISE: f64 = 2e-4;
const READINGS: &str = "10";

/// Every sensor's user calibration blocks that state the field they calibrate.
fn stated_blocks() -> Vec<(Sensor, CommandSpec, String)> {
    let mut out = Vec::new();
    for sensor in &spec().sensors {
        for (write, _) in sensor.user_calibrations() {
            if let Some(c) = &write.calibrates {
                out.push((sensor.clone(), write.clone(), c.field.clone()));
            }
        }
    }
    out
}

/// K and B as the probe holds them.
fn held(s: &Sim<Simulator>, write: &CommandSpec) -> (f32, f32) {
    let device = s.server.device();
    let mut fields = write.named_fields().map(|f| match device.get(&write.name, f.display_name()) {
        Ok(Value::Float(v)) => v,
        other => panic!("{}.{}: {other:?}", write.name, f.display_name()),
    });
    (fields.next().unwrap(), fields.next().unwrap())
}

/// Sets K and B on the probe.
fn hold(s: &Sim<Simulator>, write: &CommandSpec, k: f32, b: f32) {
    let mut device = s.server.device();
    let mut names = write.named_fields().map(|f| f.display_name().to_owned());
    device.set(&write.name, &names.next().unwrap(), Value::Float(k)).unwrap();
    device.set(&write.name, &names.next().unwrap(), Value::Float(b)).unwrap();
}

/// What a run printed and how it ended.
struct Transcript {
    code: i32,
    stdout: String,
    stderr: String,
}

/// Runs `calibrate` with `args`, moving the probe into each standard when
/// the tool asks for it; `answer(i)` is the line typed at standard `i`'s
/// prompt (`None`: close stdin there).
fn drive(
    s: &Sim<Simulator>,
    field: &str,
    write: &CommandSpec,
    standards: &[f64],
    args: &[&str],
    answer: impl Fn(usize) -> Option<&'static str>,
) -> Transcript {
    let dir = tempfile::tempdir().unwrap();
    let mut cmd = YOSEMITECH.command();
    cmd.arg("calibrate")
        .args(args)
        .args(["-p", &s.path, "--yes", "--backup-dir"])
        .arg(dir.path())
        .args(["--readings", READINGS, "--interval", "0s", "--window", "3", "--cv-threshold", "5"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for standard in standards {
        cmd.arg(format!("--standard={standard}"));
    }
    if !args.iter().any(|a| *a == "--history" || *a == "--config") {
        cmd.arg("--history").arg(dir.path().join("history.sqlite"));
    }
    let mut child = cmd.spawn().unwrap();
    let mut stdin = child.stdin.take();
    let stderr = {
        let mut pipe = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            let mut text = String::new();
            let _ = std::io::Read::read_to_string(&mut pipe, &mut text);
            text
        })
    };
    let mut stdout = String::new();
    let mut next = 0;
    for line in BufReader::new(child.stdout.take().unwrap()).lines() {
        let Ok(line) = line else { break };
        stdout.push_str(&line);
        stdout.push('\n');
        if next < standards.len() && line.contains(&format!("standard {} of {}", next + 1, standards.len())) {
            let standard = Standard { value: standards[next], k_true: K_TRUE, b_true: B_TRUE, noise: NOISE, seed: 7 };
            s.server.device().immerse(Some((standard, field, &write.name))).unwrap();
            match (answer(next), stdin.as_mut()) {
                (Some(text), Some(pipe)) => {
                    // The tool may have stopped already: a closed pipe is its answer.
                    let _ = pipe.write_all(format!("{text}\n").as_bytes());
                    let _ = pipe.flush();
                }
                _ => stdin = None,
            }
            next += 1;
        }
    }
    drop(stdin);
    let code = wait(&mut child, Duration::from_secs(120));
    Transcript { code, stdout, stderr: stderr.join().unwrap() }
}

#[test]
fn two_and_three_standards_find_the_probes_line() {
    let blocks = stated_blocks();
    assert!(blocks.len() > 1, "no sensor states what its calibration block calibrates");
    for (sensor, write, field) in &blocks {
        let several = sensor.user_calibrations().len() > 1;
        for standards in [&[10.0, 100.0][..], &[10.0, 40.0, 100.0][..]] {
            let s = serve(Simulator::new(sensor.clone()));
            let mut args = vec![sensor.name.as_str()];
            if several {
                args.extend(["--quantity", field.as_str()]);
            }
            let run = drive(&s, field, write, standards, &args, |_| Some(""));
            let context = format!("{} {field} {standards:?}:\n{}\n{}", sensor.name, run.stdout, run.stderr);
            assert_eq!(run.code, 0, "{context}");
            let (k, b) = held(&s, write);
            assert!((f64::from(k) - K_TRUE).abs() < 1e-3, "K {k}: {context}");
            assert!((f64::from(b) - B_TRUE).abs() < 1e-3, "B {b}: {context}");
            // The steps the calibrator sheets prescribe, in order.
            let order = ["saved every coefficient", "wrote K = 1, B = 0", "stable: CV", "readings: mean", "R² = "];
            let at: Vec<Option<usize>> = order.iter().map(|n| run.stdout.find(n)).collect();
            assert!(at.iter().all(Option::is_some), "{context}");
            assert!(at.windows(2).all(|w| w[0] < w[1]), "{context}");
            assert_eq!(run.stdout.matches("residual").count(), standards.len(), "{context}");
            assert!(run.stdout.contains("written and read back"), "{context}");
            // Read once more through the new K and B: the last standard, within the noise.
            let error = yosemitech_tests::cli::number_after(&run.stdout, "the probe now reads");
            let last = standards.last().unwrap();
            assert!((error - last).abs() < 1e-2, "{context}");
        }
    }
}

#[test]
fn one_standard_is_an_offset() {
    let (sensor, write, field) = stated_blocks().into_iter().next().unwrap();
    let several = sensor.user_calibrations().len() > 1;
    let s = serve(Simulator::new(sensor.clone()));
    let mut args = vec![sensor.name.as_str()];
    if several {
        args.extend(["--quantity", field.as_str()]);
    }
    let run = drive(&s, &field, &write, &[50.0], &args, |_| Some(""));
    assert_eq!(run.code, 0, "{}\n{}", run.stdout, run.stderr);
    let (k, b) = held(&s, &write);
    assert_eq!(k, 1.0, "one standard keeps the slope");
    let want = 50.0 - (50.0 - B_TRUE) / K_TRUE;
    assert!((f64::from(b) - want).abs() < 1e-3, "B {b}, want {want}");
    assert!(!run.stdout.contains("R² = "), "no R² for one standard:\n{}", run.stdout);
}

/// The sensor with the most coefficient blocks among those that state
/// what a block calibrates: a restore there must leave every other block alone too.
fn richest() -> (Sensor, CommandSpec, String) {
    stated_blocks().into_iter().max_by_key(|(s, _, _)| s.coefficient_blocks().len()).unwrap()
}

/// Every coefficient the probe holds, bit for bit.
fn every_coefficient(s: &Sim<Simulator>, sensor: &Sensor) -> Vec<(String, Vec<u8>)> {
    let device = s.server.device();
    sensor
        .coefficient_blocks()
        .into_iter()
        .map(|(_, read)| (read.name.clone(), device.registers().read(read.address, read.count)))
        .collect()
}

fn args_for<'a>(sensor: &'a Sensor, field: &'a str) -> Vec<&'a str> {
    let mut args = vec![sensor.name.as_str(), "--quantity", field, "--timeout", "300ms", "--retries", "0"];
    args.push("--skip-wait");
    args
}

#[test]
fn a_fault_at_any_step_leaves_the_coefficients_as_they_were() {
    let (sensor, write, field) = richest();
    let standards = [10.0, 100.0];
    // The replies of a clean run: one fault is injected at each in turn.
    let clean = serve(Simulator::new(sensor.clone()));
    let run = drive(&clean, &field, &write, &standards, &args_for(&sensor, &field), |_| Some(""));
    assert_eq!(run.code, 0, "{}\n{}", run.stdout, run.stderr);
    let replies = clean.server.device().stats().replies;
    assert!(replies > 10, "{replies} replies");
    let identity_reads =
        [Role::SerialNumber, Role::Version].iter().filter(|&&role| sensor.command_with_role(role).is_some()).count()
            as u64;
    let mut failed = 0;
    for n in 0..replies {
        let mut script = vec![None; n as usize];
        script.push(Some(FaultKind::Drop));
        let s = serve(Simulator::new(sensor.clone()).with_faults(FaultConfig::scripted(script)));
        hold(&s, &write, 1.25, 0.375);
        let before = every_coefficient(&s, &sensor);
        let run = drive(&s, &field, &write, &standards, &args_for(&sensor, &field), |_| Some(""));
        let context = format!("fault at reply {n}:\n{}\n{}", run.stdout, run.stderr);
        if run.code == 0 {
            // Only a reply the calibration does without may be lost: the
            // identity reads (serial number, firmware) it starts with.
            assert!(n < identity_reads, "{context}");
            continue;
        }
        failed += 1;
        assert_eq!(run.code, 1, "{context}");
        assert_eq!(every_coefficient(&s, &sensor), before, "{context}");
        assert!(
            run.stderr.contains("nothing was written") || run.stderr.contains("read back bit for bit"),
            "{context}"
        );
    }
    assert_eq!(failed as u64 + identity_reads, replies, "every other fault stopped the calibration");
}

#[test]
fn stopping_at_any_standard_restores_the_coefficients() {
    let (sensor, write, field) = richest();
    let standards = [10.0, 40.0, 100.0];
    for stop in 0..standards.len() {
        for quit in [true, false] {
            let s = serve(Simulator::new(sensor.clone()));
            hold(&s, &write, 0.875, -1.5);
            let before = every_coefficient(&s, &sensor);
            let run = drive(&s, &field, &write, &standards, &args_for(&sensor, &field), |i| match i {
                _ if i < stop => Some(""),
                _ if quit => Some("q"),
                _ => None,
            });
            let context = format!("stop at {stop}, q {quit}:\n{}\n{}", run.stdout, run.stderr);
            assert_eq!(run.code, 1, "{context}");
            let why = if quit { "stopped by the user" } else { "stdin ended" };
            assert!(run.stderr.contains(why), "{context}");
            assert!(run.stderr.contains("read back bit for bit"), "{context}");
            assert_eq!(every_coefficient(&s, &sensor), before, "{context}");
            assert_eq!(held(&s, &write), (0.875, -1.5), "{context}");
        }
    }
}

#[test]
fn a_backup_that_cannot_be_saved_stops_before_any_write() {
    let (sensor, _, field) = richest();
    let s = serve(Simulator::new(sensor.clone()));
    let before = every_coefficient(&s, &sensor);
    let args = ["calibrate", &sensor.name, "--quantity", &field, "-p", &s.path, "--yes", "--standard", "5"];
    let run = YOSEMITECH.run_with_input(&[&args[..], &["--backup-dir", "/nonexistent/dir"]].concat(), "\n");
    assert!(run.fails(1).contains("nothing was written"), "{}", run.stderr);
    assert_eq!(s.server.device().stats().writes, 0);
    assert_eq!(every_coefficient(&s, &sensor), before);
}

#[test]
fn misuse_is_a_usage_error() {
    let (sensor, _, field) = richest();
    // No standard: the hint names how to give them.
    YOSEMITECH.run(&["calibrate", &sensor.name, "--quantity", &field, "-p", "/dev/null"]).fails_with_hint(2);
    // An unknown field.
    YOSEMITECH.run(&["calibrate", &sensor.name, "--quantity", "no_such_field", "--standard", "1"]).fails_with_hint(2);
    // No sensor at all.
    YOSEMITECH.run(&["calibrate", "--standard", "1"]).fails_with_hint(2);
    // Bad numbers.
    for bad in [["--readings", "0"], ["--window", "1"], ["--cv-threshold", "0"], ["--sd-threshold", "-1"]] {
        let args = ["calibrate", &sensor.name, "--quantity", &field, "--standard", "1", bad[0], bad[1]];
        YOSEMITECH.run(&args).fails(2);
    }
    // Where the manual recommends standards, the hint gives them.
    let mut recommended = 0;
    for (sensor, write, field) in stated_blocks() {
        let standards = &write.calibrates.as_ref().unwrap().standards;
        if standards.is_empty() {
            continue;
        }
        let run = YOSEMITECH.run(&["calibrate", &sensor.name, "--quantity", &field, "-p", "/dev/null", "--yes"]);
        let err = run.fails_with_hint(2);
        for standard in standards {
            assert!(err.contains(&format!("--standard {standard}")), "{err}");
        }
        recommended += 1;
    }
    assert!(recommended > 0, "no spec recommends standards");
    for s in &spec().sensors {
        let blocks = s.user_calibrations();
        let run = YOSEMITECH.run(&["calibrate", &s.name, "--standard", "1", "--yes"]);
        if blocks.is_empty() {
            // A sensor without a K/B block.
            assert!(run.fails_with_hint(2).contains("no user calibration block"), "{}", run.stderr);
        } else if blocks.len() > 1 || blocks[0].0.calibrates.is_none() {
            // Several blocks, or one the spec does not say the field of: --quantity, asked for.
            assert!(run.fails_with_hint(2).contains("--quantity"), "{}: {}", s.name, run.stderr);
        }
    }
}

/// A probe whose sensor has one user calibration block, stated, and measurements a station logs.
fn single_block() -> (Sensor, CommandSpec, String) {
    stated_blocks()
        .into_iter()
        .find(|(s, _, _)| s.user_calibrations().len() == 1 && !yosemitech_station::plan::measurements(s).is_empty())
        .expect("a sensor with one stated calibration block")
}

/// The bits of K and B.
fn bits((k, b): (f32, f32)) -> (u32, u32) {
    (k.to_bits(), b.to_bits())
}

#[test]
fn two_calibrations_are_listed_exported_and_the_first_restored() {
    let (sensor, write, field) = single_block();
    let dir = tempfile::tempdir().unwrap();
    let history = dir.path().join("calibrations.sqlite");
    let history = history.to_str().unwrap();
    let s = serve(Simulator::new(sensor.clone()));
    let standards = [10.0, 40.0, 100.0];
    let args = [sensor.name.as_str(), "--history", history, "--note", "first, after cleaning"];
    let first = drive(&s, &field, &write, &standards, &args, |_| Some(""));
    assert_eq!(first.code, 0, "{}\n{}", first.stdout, first.stderr);
    let after_first = held(&s, &write);
    // The second, with two of the standards; then the probe is given other coefficients.
    let args = [sensor.name.as_str(), "--history", history];
    let second = drive(&s, &field, &write, &standards[..2], &args, |_| Some(""));
    assert_eq!(second.code, 0, "{}\n{}", second.stdout, second.stderr);
    hold(&s, &write, 2.5, 7.0);
    let first_id = yosemitech_tests::cli::number_after(&first.stdout, "recorded as calibration");
    assert_eq!(first_id, 1.0, "{}", first.stdout);

    // Listed, oldest first, with the note.
    let run = YOSEMITECH.run(&["calibrate", "history", "--history", history]);
    let listed = run.ok();
    let ids: Vec<&str> =
        listed.lines().filter_map(|l| l.split_whitespace().next()).filter(|w| w.parse::<u32>().is_ok()).collect();
    assert_eq!(ids, ["1", "2"], "{listed}");
    assert!(listed.contains("note: first, after cleaning"), "{listed}");

    // Exported: everything kept, every reading taken.
    let json = YOSEMITECH.run(&["calibrate", "history", "--history", history, "--json"]).json();
    let all = json.as_array().unwrap();
    assert_eq!(all.len(), 2);
    let sn = all[0]["serial_number"].as_str().expect("the probe's serial number").to_owned();
    for (record, n) in all.iter().zip([3, 2]) {
        assert_eq!(record["sensor"], sensor.name.as_str());
        assert_eq!(record["kind"], "linear");
        assert_eq!(record["block"], write.name.as_str());
        assert_eq!(record["serial_number"], sn.as_str());
        let runs = record["readings"].as_array().unwrap();
        assert_eq!(runs.len(), n);
        for run in runs {
            assert_eq!(run["readings"].as_array().unwrap().len(), READINGS.parse::<usize>().unwrap());
            assert!(!run["settling"].as_array().unwrap().is_empty(), "the readings watched for stability are kept");
        }
        assert_eq!(record["fit"]["residuals"].as_array().unwrap().len(), n);
        assert_eq!(record["before"][&write.name].as_object().unwrap().len(), 2);
    }
    let k_name = write.named_fields().next().unwrap().display_name().to_owned();
    let first_k = all[0]["after"][&write.name][&k_name].as_f64().unwrap();
    assert_eq!(first_k as f32, after_first.0);
    let by_sn = YOSEMITECH.run(&["calibrate", "history", "--history", history, "--sn", &sn, "--json"]).json();
    assert_eq!(by_sn.as_array().unwrap().len(), 2);
    let none = YOSEMITECH.run(&["calibrate", "history", "--history", history, "--sn", "YL0000000000", "--json"]).json();
    assert_eq!(none.as_array().unwrap().len(), 0);

    // The first restored: backup, write, read back bit for bit, recorded.
    let backups = tempfile::tempdir().unwrap();
    let restore = ["calibrate", "restore", "1", "-p", &s.path, "--yes", "--history", history, "--backup-dir"];
    let run = YOSEMITECH.run(&[&restore[..], &[backups.path().to_str().unwrap()]].concat());
    let out = run.ok();
    assert!(out.contains("restored and verified"), "{out}");
    assert_eq!(bits(held(&s, &write)), bits(after_first));
    assert_eq!(std::fs::read_dir(backups.path()).unwrap().count(), 1, "a backup first");
    let json = YOSEMITECH.run(&["calibrate", "history", "--history", history, "--json"]).json();
    let last = json.as_array().unwrap().last().unwrap().clone();
    assert_eq!(last["kind"], "restore");
    assert_eq!(last["after"], all[0]["after"]);
    let before_k = last["before"][&write.name][&k_name].as_f64().unwrap();
    assert_eq!(before_k, 2.5, "what the probe held before the restore");

    // An unknown id, and another probe, are refused; nothing written.
    YOSEMITECH.run(&["calibrate", "restore", "99", "-p", &s.path, "--yes", "--history", history]).fails_with_hint(2);
    let other = serve(Simulator::new(sensor.clone()));
    {
        let mut device = other.server.device();
        let sn_read = sensor.command_with_role(Role::SerialNumber).unwrap();
        let sn_field = sn_read.named_fields().next().unwrap().display_name().to_owned();
        device.set(&sn_read.name, &sn_field, Value::Text("YL0000000001".into())).unwrap();
    }
    let writes = other.server.device().stats().writes;
    let run = YOSEMITECH.run(&["calibrate", "restore", "1", "-p", &other.path, "--yes", "--history", history]);
    assert!(run.fails_with_hint(2).contains("is of probe"), "{}", run.stderr);
    assert_eq!(other.server.device().stats().writes, writes);
}

/// Runs `yosemitech log --config` until it has announced `n` readings, then
/// stops it; the readings it announced.
fn log_readings(config: &str, n: usize) -> Vec<serde_json::Value> {
    let mut child = YOSEMITECH
        .command()
        .args(["log", "--config", config])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut announced = Vec::new();
    for _ in 0..n {
        let line = lines.next().expect("the logger announced a reading").unwrap();
        announced.push(serde_json::from_str(&line).unwrap());
    }
    let pid = child.id().to_string();
    assert!(std::process::Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
    assert_eq!(wait(&mut child, Duration::from_secs(30)), 0, "SIGTERM stops the logger cleanly");
    announced
}

#[test]
fn a_station_run_names_the_calibration_in_force() {
    let (sensor, write, field) = single_block();
    let s = serve(Simulator::new(sensor.clone()));
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("station.sqlite");
    let config = dir.path().join("station.toml");
    std::fs::write(
        &config,
        format!(
            "station = \"s\"\n[storage]\npath = \"{}\"\n[[bus]]\nname = \"a\"\nport = \"{}\"\n\
             [[bus.probe]]\nlabel = \"p\"\nsensor = \"{}\"\naddress = {}\ninterval = \"100ms\"\nprocedure = false\n",
            db.display(),
            s.path,
            sensor.name,
            sensor.default_address
        ),
    )
    .unwrap();
    let config = config.to_str().unwrap();
    let uncalibrated = log_readings(config, 3);
    assert!(uncalibrated.iter().all(|r| r.get("calibration_id").is_none()), "{uncalibrated:?}");
    // Calibrated with the station's file: the calibration goes into its store.
    let run = drive(&s, &field, &write, &[10.0, 100.0], &[sensor.name.as_str(), "--config", config], |_| Some(""));
    assert_eq!(run.code, 0, "{}\n{}", run.stdout, run.stderr);
    assert!(run.stdout.contains(&format!("recorded as calibration 1 in {}", db.display())), "{}", run.stdout);
    let calibrated = log_readings(config, 3);
    assert!(calibrated.iter().all(|r| r["calibration_id"] == 1), "the logger announces it too: {calibrated:?}");

    let store = yosemitech_station::Store::open(&db).unwrap();
    let recorded = store.calibrations(None).unwrap();
    assert_eq!(recorded.len(), 1);
    let calibration = &recorded[0];
    let readings = store.range(std::time::UNIX_EPOCH, std::time::SystemTime::now()).unwrap();
    assert!(readings.len() >= 6, "{} readings", readings.len());
    let (before, after): (Vec<_>, Vec<_>) =
        readings.iter().partition(|r| r.reading.timestamp < calibration.calibration.timestamp);
    assert!(before.len() >= 3 && after.len() >= 3, "{} before, {} after", before.len(), after.len());
    for r in &before {
        assert_eq!(r.calibration_id, None, "a reading before the calibration: {r:?}");
    }
    for r in &after {
        assert_eq!(r.reading.serial_number, calibration.calibration.serial_number);
        assert_eq!(r.calibration_id, Some(calibration.id), "a reading after the calibration: {r:?}");
    }
    // `export` carries it.
    let run = YOSEMITECH.run(&["export", "--db", db.to_str().unwrap(), "--format", "jsonl"]);
    let exported: Vec<serde_json::Value> = run.ok().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let named = exported.iter().filter(|r| r["calibration_id"] == calibration.id).count();
    assert_eq!(named, after.len());
}

#[test]
fn the_ph_calibrations_are_recorded_too() {
    let sensor = yosemitech_tests::sensor(yosemitech_cli::calibrate_ph_sensor());
    let s = serve(Simulator::new(sensor.clone()));
    let dir = tempfile::tempdir().unwrap();
    let history = dir.path().join("calibrations.sqlite");
    let (history, backups) = (history.to_str().unwrap(), dir.path().to_str().unwrap());
    let common = ["-p", s.path.as_str(), "--yes", "--backup-dir", backups, "--history", history];
    let three_point = [&["calibrate", "ph", "--skip-wait", "--note", "three buffers"][..], &common].concat();
    let out = YOSEMITECH.run_with_input(&three_point, "\n\n\n").ok().to_owned();
    assert!(out.contains("recorded as calibration 1"), "{out}");
    let csv = dir.path().join("buffers.csv");
    std::fs::write(&csv, "buffer,mv,temperature_c\n4.00,172.5,21.0\n6.86,8.25,21.5\n9.18,-125.0,22.0\n").unwrap();
    let compute = [&["calibrate", "ph", "--compute", "--readings", csv.to_str().unwrap()][..], &common].concat();
    let out = YOSEMITECH.run(&compute).ok().to_owned();
    assert!(out.contains("recorded as calibration 2"), "{out}");

    let json = YOSEMITECH.run(&["calibrate", "history", "--history", history, "--json"]).json();
    let all = json.as_array().unwrap();
    let kinds: Vec<&str> = all.iter().map(|c| c["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["ph_three_point", "ph_electrode"]);
    assert_eq!(all[0]["note"], "three buffers");
    // The three-point one keeps every block before and after; the computed one its readings.
    assert_eq!(all[0]["after"].as_object().unwrap().len(), sensor.coefficient_blocks().len());
    assert_eq!(all[1]["readings"].as_array().unwrap().len(), 3);
    assert_eq!(all[1]["readings"][1]["mv"], 8.25);
    let block = all[1]["block"].as_str().unwrap();
    let written: Vec<f32> = sensor
        .command(block)
        .unwrap()
        .named_fields()
        .map(|f| match s.server.device().get(block, f.display_name()).unwrap() {
            Value::Float(v) => v,
            other => panic!("{other:?}"),
        })
        .collect();
    let recorded: Vec<f32> = sensor
        .command(block)
        .unwrap()
        .named_fields()
        .map(|f| all[1]["after"][block][f.display_name()].as_f64().unwrap() as f32)
        .collect();
    assert_eq!(written, recorded, "the record holds what the probe holds");
}

#[test]
fn ctrl_c_at_a_prompt_restores_the_coefficients() {
    let (sensor, write, field) = richest();
    let s = serve(Simulator::new(sensor.clone()));
    hold(&s, &write, 1.5, 0.125);
    let before = every_coefficient(&s, &sensor);
    let dir = tempfile::tempdir().unwrap();
    let mut child = YOSEMITECH
        .command()
        .args(["calibrate", &sensor.name, "--quantity", &field, "-p", &s.path, "--yes", "--skip-wait"])
        .args(["--standard", "10", "--standard", "100", "--backup-dir"])
        .arg(dir.path())
        .arg("--history")
        .arg(dir.path().join("history.sqlite"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let _stdin = child.stdin.take();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut seen = String::new();
    while !seen.contains("standard 1 of 2") {
        let line = lines.next().unwrap_or_else(|| panic!("no prompt:\n{seen}")).unwrap();
        seen.push_str(&line);
        seen.push('\n');
    }
    assert_ne!(every_coefficient(&s, &sensor), before, "K = 1, B = 0 were written");
    let pid = child.id().to_string();
    assert!(std::process::Command::new("kill").args(["-INT", &pid]).status().unwrap().success());
    let code = wait(&mut child, Duration::from_secs(30));
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(code, 1, "{seen}\n{stderr}");
    assert!(stderr.contains("stopped by Ctrl-C") && stderr.contains("read back bit for bit"), "{stderr}");
    assert_eq!(every_coefficient(&s, &sensor), before);
}

#[test]
fn a_restore_that_fails_leaves_the_probe_as_it_was() {
    let (sensor, write, field) = single_block();
    let dir = tempfile::tempdir().unwrap();
    let history = dir.path().join("calibrations.sqlite");
    let history = history.to_str().unwrap();
    let s = serve(Simulator::new(sensor.clone()));
    let run = drive(&s, &field, &write, &[10.0, 100.0], &[sensor.name.as_str(), "--history", history], |_| Some(""));
    assert_eq!(run.code, 0, "{}\n{}", run.stdout, run.stderr);
    hold(&s, &write, 3.0, -2.0);
    let before = every_coefficient(&s, &sensor);
    // The restore reads the identity and every block, then writes: its write's reply is lost.
    let identity_reads =
        [Role::SerialNumber, Role::Version].iter().filter(|&&role| sensor.command_with_role(role).is_some()).count();
    let mut script = vec![None; identity_reads + sensor.coefficient_blocks().len()];
    script.push(Some(FaultKind::Drop));
    s.server.device().set_faults(FaultConfig::scripted(script));
    let args = ["calibrate", "restore", "1", "-p", &s.path, "--yes", "--history", history, "--timeout", "300ms"];
    let run = YOSEMITECH.run(&[&args[..], &["--retries", "0", "--backup-dir", dir.path().to_str().unwrap()]].concat());
    assert!(run.fails(1).contains("written back and read back"), "{}", run.stderr);
    assert_eq!(every_coefficient(&s, &sensor), before);
    let json = YOSEMITECH.run(&["calibrate", "history", "--history", history, "--json"]).json();
    assert_eq!(json.as_array().unwrap().len(), 1, "a failed restore is not recorded");
}

#[test]
fn a_standard_near_zero_is_judged_by_its_spread() {
    let (sensor, write, field) = single_block();
    let s = serve(Simulator::new(sensor.clone()));
    // Purified water: the readings scatter around zero, where a CV means nothing.
    let water = Standard { value: 0.0, k_true: 1.0, b_true: 0.0, noise: 1e-3, seed: 3 };
    s.server.device().immerse(Some((water, &field, &write.name))).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let history = dir.path().join("history.sqlite");
    let base = [
        "calibrate",
        sensor.name.as_str(),
        "-p",
        s.path.as_str(),
        "--yes",
        "--standard",
        "0",
        "--interval",
        "50ms",
        "--window",
        "3",
        "--backup-dir",
        dir.path().to_str().unwrap(),
        "--history",
        history.to_str().unwrap(),
    ];
    hold(&s, &write, 1.25, 0.5);
    // By CV alone it never settles: the wait runs out and the block is written back.
    let run = YOSEMITECH.run_with_input(&[&base[..], &["--max-wait", "1s"]].concat(), "\n");
    assert!(run.fails_with_hint(1).contains("not stable after"), "{}", run.stderr);
    assert_eq!(held(&s, &write), (1.25, 0.5));
    // A spread below --sd-threshold is stable.
    let run = YOSEMITECH.run_with_input(&[&base[..], &["--max-wait", "60s", "--sd-threshold", "0.01"]].concat(), "\n");
    assert!(run.ok().contains("stable:"), "{}", run.stdout);
    let (k, b) = held(&s, &write);
    assert_eq!(k, 1.0);
    assert!(b.abs() < 2e-3, "B {b}: the offset that brings the water to zero");
}

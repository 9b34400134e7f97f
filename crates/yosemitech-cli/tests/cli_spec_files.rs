//! Spec files given at run time: their sensors go through the interpreter,
//! replacing a built-in sensor; `--verbose` shows the frames.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use crate::device::{calibrated_sensor, coefficients, float, overwrite, stated_read};
use yosemitech_tests::cli::{Binary, fixture_spec_dir, interrupt, sim};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

#[test]
fn spec_sensors_work_through_the_interpreter() {
    // The fixture DO probe (19200 8E1, address 10) exists only as a spec file.
    let dir = fixture_spec_dir();
    let spec = dir.to_str().unwrap();
    // The manual's example values, which the assertions below name.
    let (child, port) = YOSEMITECH.simulate(&["--spec", spec, "do_probe", "--examples"]);
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
    assert!(run.fails_with_hint(2).contains("outside the valid range 0 to 40"), "{}", run.stderr);
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

//! `yosemitech measure`: every procedure of the spec run, its readings
//! averaged, a start the probe refuses, a sensor without a procedure.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use std::sync::Arc;

use crate::device::shown_number;
use serde_json::Value as Json;
use yosemitech_sim::Simulator;
use yosemitech_spec::{CommandSpec, FieldKind, Role, Sensor, Value};
use yosemitech_tests::cli::{Binary, fixture_spec_dir, sim};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

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

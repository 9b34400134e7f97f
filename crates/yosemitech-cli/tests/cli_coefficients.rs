//! `yosemitech coefficients`: a backup restored onto a probe whose
//! coefficients changed gives back every value.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use crate::device::{coefficient_field, coefficients, float, overwrite};
use serde_json::Value as Json;
use yosemitech_spec::{Field, Value};
use yosemitech_tests::cli::{Binary, sim};
use yosemitech_tests::report;
use yosemitech_tests::values::varied_float;

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

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

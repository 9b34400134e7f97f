//! `yosemitech write`: coefficients backed up before a write, the write
//! confirmed, and the values read back.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use crate::device::{another_float, coefficients, float, new_address};
use serde_json::Value as Json;
use yosemitech_spec::{CommandSpec, Field, Role, Sensor, Value};
use yosemitech_tests::cli::{Binary, sim};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

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

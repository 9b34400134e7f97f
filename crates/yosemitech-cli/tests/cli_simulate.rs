//! `yosemitech simulate`: a simulated probe served on a pty, RTU over TCP
//! and Modbus TCP (with `--examples`, the manual's replies byte for byte),
//! natural water by default, silence or exceptions for registers it lacks,
//! and injected faults the client retries.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use std::time::Duration;

use crate::device::{foreign_read, poll_columns, stated_read};
use yosemitech_tests::cli::{Binary, interrupt};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

#[test]
fn simulate_serves_a_pty_until_interrupted() {
    let Some((sensor, command, _, _, line)) = stated_read() else { return };
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--address", "4", "--examples"]);
    assert!(port.starts_with("/dev/"), "{port}");
    let out = YOSEMITECH.run(&["read", &sensor.name, &command.name, "-p", &port, "-a", "4"]);
    assert!(out.ok().contains(&line), "{}", out.stdout);
    let err = interrupt(child);
    let title = format!("simulating {} ({})", sensor.title, sensor.name);
    assert!(err.contains(&title) && err.contains("stopped: 1 requests"), "{err}");
}

#[test]
fn simulate_serves_natural_water_by_default_one_value_per_quantity() {
    // A quantity two measurement reads hold (pH in two reads of a pH probe).
    let spec = spec();
    let Some((sensor, reads, name)) = spec.sensors.iter().find_map(|s| {
        let reads: Vec<_> = s.measurement_reads().collect();
        reads.iter().flat_map(|r| r.fields.iter()).find_map(|f| {
            let name = f.name.as_deref()?;
            let holders: Vec<_> = reads.iter().filter(|r| r.field(name).is_some()).copied().collect();
            (holders.len() > 1 && f.unit.is_some()).then(|| (s, holders, name.to_owned()))
        })
    }) else {
        return report!("simulate: no sensor holds a quantity in two reads");
    };
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name]);
    let values: Vec<f64> = reads
        .iter()
        .map(|read| {
            let run = YOSEMITECH.run(&["read", &sensor.name, &read.name, "-p", &port, "--json"]);
            let json: serde_json::Value = serde_json::from_str(run.ok()).unwrap();
            json["values"][&name].as_f64().unwrap_or_else(|| panic!("{name} in {json}"))
        })
        .collect();
    interrupt(child);
    // One water: the reads agree but for the daily cycle's few seconds.
    for (read, v) in reads.iter().zip(&values) {
        let first = values[0];
        assert!((v - first).abs() <= 1e-3 * first.abs().max(1.0), "{}: {name} {v} vs {first}", read.name);
    }
    report!("simulate: {}.{name} agrees across {} reads: {values:?}", sensor.name, reads.len());
}

#[test]
fn simulate_serves_rtu_over_tcp() {
    let Some((sensor, command, _, _, line)) = stated_read() else { return };
    let (child, port) = YOSEMITECH.simulate(&[&sensor.name, "--tcp", "127.0.0.1:0", "--examples"]);
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
    let (child, port) =
        YOSEMITECH.simulate(&[&sensor.name, "--tcp", "127.0.0.1:0", "--protocol", "mbap", "--examples"]);
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
fn more_probes_on_the_line_and_a_tap_are_asked_for_clearly() {
    let sensor = &spec().sensors[0].name;
    for (args, says) in [
        (vec!["--also", "no_such_sensor@2"], "no_such_sensor"),
        (vec!["--also", &**sensor], "SENSOR@ADDRESS"),
        (vec!["--also", "x@two"], "not an address"),
        (vec!["--address", "3", "--also", &format!("{sensor}@3")], "two probes at address 3"),
        (vec!["--also", &format!("{sensor}@248")], "outside 1 to 247"),
        (vec!["--tap", "--tcp", "127.0.0.1:0"], "--tcp"),
    ] {
        let run = YOSEMITECH.run(&[&["simulate", sensor.as_str()], args.as_slice()].concat());
        assert!(run.stderr.contains(says), "{args:?}: {}", run.stderr);
        run.fails(2);
    }
}

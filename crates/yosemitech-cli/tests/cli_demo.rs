//! `yosemitech demo`: every sensor of the spec on its own simulated probe
//! (identity, measurements, coefficients, derived quantities), its manual's
//! procedure, and the whole family identified on one bus.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::device::{scan_says, served_serial_number, shown_number, sn_layouts, sn_request};
use yosemitech_sim::Simulator;
use yosemitech_spec::{CommandSpec, Role, Sensor, Value};
use yosemitech_tests::cli::{Binary, number_after};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

#[test]
fn demo_reads_every_sensor_and_runs_every_procedure() {
    let started = Instant::now();
    let run = YOSEMITECH.run(&["demo"]);
    let out = run.ok();
    // A generous bound, not a speed target: a demo that kept the manuals' waits
    // (a minute's settling per calibration point) would take several minutes.
    assert!(started.elapsed() < Duration::from_secs(180), "the demo shortens the procedures' waits");
    let (probes, rest) = out.split_once("waits shortened").unwrap_or_else(|| panic!("no procedures:\n{out}"));
    let procedures = rest.split("the whole family on one RS-485 bus").next().unwrap();
    let (mut reads, mut procedures_run, mut compared) = (0, 0, 0);
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
            let served = served_serial_number(sensor).expect("a simulated probe serves its serial number");
            assert!(line(sn).contains(&served), "{section}");
            reads += 1;
        }
        for read in sensor.measurement_reads().chain(sensor.coefficient_blocks().into_iter().map(|(_, r)| r)) {
            line(read);
            reads += 1;
        }
        // Each derived quantity whose reads the section shows, beside them.
        let shown = |command: &str| section.lines().any(|l| l.trim_start().starts_with(&format!("{command} ")));
        for d in &sensor.derived {
            let covered = d.inputs.iter().all(|i| match &i.source {
                yosemitech_spec::InputSource::Field { command, .. } => shown(command),
                yosemitech_spec::InputSource::Station(_) => true,
            });
            if covered {
                let derived_line = section.lines().find(|l| l.trim_start().starts_with(&format!("{} ", d.name)));
                assert!(
                    derived_line.is_some_and(|l| l.ends_with("(derived)") && !l.contains("not computable")),
                    "{}: no value of {} (derived):\n{section}",
                    sensor.name,
                    d.name
                );
                reads += 1;
            }
        }
        // Its manual's procedure: every field it reads, and the mean of what the simulator serves.
        let Some(procedure) = &sensor.procedure else { continue };
        let part = procedures
            .split(&format!("\n{}: ", sensor.name))
            .nth(1)
            .unwrap_or_else(|| panic!("{}: no procedure:\n{procedures}", sensor.name));
        let part = part.split("\n\n").next().unwrap();
        if procedure.readings > 1 {
            assert!(part.contains(&format!("mean of {} readings", procedure.readings)), "{part}");
        }
        // The demo's probes serve plausible water: each value near what the
        // simulator fills in, within its daily swing, and inside its range.
        let mut simulated = Simulator::new(Arc::new(sensor.clone()));
        simulated.fill_with_water();
        for read in procedure.read.iter().map(|r| sensor.command(r).unwrap()) {
            for field in read.named_fields() {
                let name = field.display_name();
                assert!(
                    part.lines()
                        .any(|l| l.trim_start().starts_with(name) || l.contains(&format!("{}.{name} ", read.name))),
                    "{}: field `{name}` missing:\n{part}",
                    sensor.name
                );
                if field.unit.is_none() {
                    continue;
                }
                let Ok(Value::Float(start)) = simulated.get(&read.name, name) else { continue };
                if !start.is_finite() || part.lines().any(|l| l.contains(name) && l.contains("absent")) {
                    continue;
                }
                let mean = shown_number(part, &read.name, name);
                let span = yosemitech_sim::daily_span(field, start);
                assert!(
                    (mean - f64::from(start)).abs() <= 0.05 * span + 0.01,
                    "{}: {name} {mean} is far from the water's {start}",
                    sensor.name
                );
                if let Some((min, max)) = field.range {
                    assert!(
                        (min - 1e-3..=max + 1e-3).contains(&mean),
                        "{}: {name} {mean} outside {min}..={max}",
                        sensor.name
                    );
                }
                compared += 1;
            }
        }
        procedures_run += 1;
    }
    report!("demo: {reads} reads shown, {procedures_run} procedures run, {compared} means compared");
}

/// Whether some read of `sensor` is another sensor's serial-number request
/// (the simulator answers a read by its function, address and count).
fn answers_a_serial_number_request(sensor: &Sensor) -> bool {
    let requests: Vec<(u8, u16, u16)> = spec().sensors.iter().filter_map(sn_request).collect();
    sensor.commands.iter().any(|c| c.is_read() && requests.contains(&(c.function.code(), c.address, c.count)))
}

/// The newest software revision of `sensor`'s manuals.
fn newest_software(sensor: &Sensor) -> Option<String> {
    sensor.manuals().filter_map(|m| m.software.clone()).max_by_key(|sw| {
        let (a, b) = sw.split_once('.').unwrap_or((sw, "0"));
        (a.parse::<u32>().unwrap(), b.parse::<u32>().unwrap())
    })
}

#[test]
fn demo_identifies_every_sensor_of_the_spec_on_one_bus() {
    let run = YOSEMITECH.run(&["demo"]);
    let out = run.ok();
    let section =
        out.split("the whole family on one RS-485 bus").nth(1).unwrap_or_else(|| panic!("no family section:\n{out}"));
    let sensors = spec().sensors.clone();
    let lines: Vec<&str> = section.lines().map(str::trim).filter(|l| l.starts_with("address ")).collect();
    let mut addresses: Vec<usize> = lines
        .iter()
        .map(|l| l.strip_prefix("address").and_then(|a| a.split_whitespace().next()).unwrap().parse().unwrap())
        .collect();
    addresses.sort_unstable();
    assert_eq!(addresses, (1..=sensors.len()).collect::<Vec<_>>(), "one address each:\n{section}");
    let (mut alone, mut among, mut unidentifiable) = (0, 0, 0);
    for (i, sensor) in sensors.iter().enumerate() {
        // The demo puts the sensors on the bus in spec order, at 1, 2, 3...
        let line = lines
            .iter()
            .find(|l| l.starts_with(&format!("address {:3}  ", i + 1)))
            .unwrap_or_else(|| panic!("no line for address {}:\n{section}", i + 1));
        let simulated = format!("[simulated: {}", sensor.name);
        match (sn_request(sensor), &sensor.model_code) {
            (Some(_), Some(code)) => {
                let sn = served_serial_number(sensor).unwrap();
                let (said, twins) = scan_says(sensor, code, &sn);
                assert!(line.contains(&said), "`{said}` missing from the family section:\n{section}");
                if twins.is_some() {
                    assert!(line.ends_with(&format!("{simulated}]")), "the demo says which it is: {line}");
                    among += 1;
                    continue;
                }
                assert!(!line.contains("not identified") && !line.contains("[simulated"), "{line}");
                // The firmware, and the manual that covers it.
                if sensor.command_with_role(Role::Version).is_some()
                    && let Some(sw) = newest_software(sensor)
                {
                    assert!(line.contains(&format!(" SW {sw}  manual SW {sw}")), "{line}");
                }
                alone += 1;
            }
            (Some(_), None) => {
                // Whatever scan makes of the serial number, the demo says what the spec lacks.
                assert!(line.contains(&simulated) && line.contains("no model code"), "{line}");
                unidentifiable += 1;
            }
            (None, _) => {
                assert!(line.contains(&simulated) && line.contains("no serial-number read"), "{line}");
                if !answers_a_serial_number_request(sensor) {
                    assert!(line.contains("not identified: no serial number read"), "{line}");
                }
                unidentifiable += 1;
            }
        }
    }
    let n = sensors.len();
    let count =
        if alone == n { format!("{n} probes identified in ") } else { format!("{alone} of {n} probes identified in ") };
    let requests = number_after(section, &count) as usize;
    assert!(requests <= n * (sn_layouts() + 1), "{requests} requests:\n{section}");
    report!(
        "demo's bus: {alone} probes identified alone, {among} among the sensors of their model code, {unidentifiable} \
         whose spec gives scan no way to tell, in {requests} requests"
    );
}

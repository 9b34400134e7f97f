//! `yosemitech read`: values with their units, the port and baud rate from
//! the environment, and a silent address timing out cleanly.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use crate::device::{
    FAST, elsewhere, foreign_read, identifiable, served_serial_number, shown, sn_field, stated_example,
};
use yosemitech_sim::{Simulator, UnknownRequestPolicy};
use yosemitech_spec::{CommandSpec, FieldKind, Role, Sensor};
use yosemitech_tests::cli::{Binary, sim};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// The shortest prefix of `name` no other sensor's name starts with, if
/// one is shorter than the name.
fn unique_prefix(name: &str) -> Option<&str> {
    let names: Vec<String> = spec().sensors.iter().map(|s| s.name.clone()).collect();
    (1..name.len()).map(|n| &name[..n]).find(|p| names.iter().filter(|n| n.starts_with(p)).count() == 1)
}

#[test]
fn read_shows_values_with_units() {
    let (mut checked, mut shortened, mut versions, mut addressed) = (0, 0, 0, 0);
    for sensor in spec().sensors.clone() {
        let name = sensor.name.as_str();
        let address = sensor.default_address;
        let s = sim(name, address);
        // Every measurement read with a stated f32 value: each field on a
        // line, `name  value unit`, as the manual's example states it.
        for command in sensor.commands.iter().filter(|c| c.is_read() && c.role.is_none()) {
            let Some(example) = stated_example(command) else { continue };
            let f32_with_unit: Vec<_> = command
                .named_fields()
                .filter(|f| matches!(f.kind, FieldKind::F32 { .. }) && f.unit.is_some())
                .collect();
            if f32_with_unit.is_empty() || command.named_fields().count() != f32_with_unit.len() {
                continue;
            }
            if f32_with_unit.iter().any(|f| {
                example
                    .values
                    .get(f.display_name())
                    .is_none_or(|v| !v.same_as(&s.server.device().get(&command.name, f.display_name()).unwrap()))
            }) {
                continue; // the simulator does not answer this example
            }
            let out = YOSEMITECH.run(&["read", name, &command.name, "--port", &s.path]).ok().to_owned();
            // Names may be shortened: a unique prefix of the sensor, the command without `get_`.
            if shortened == 0
                && let (Some(short), Some(prefix)) = (command.name.strip_prefix("get_"), unique_prefix(name))
            {
                assert_eq!(YOSEMITECH.run(&["read", prefix, short, "-p", &s.path]).ok(), out, "{prefix} {short}");
                shortened += 1;
            }
            let width = f32_with_unit.iter().map(|f| f.display_name().len()).max().unwrap();
            for field in &f32_with_unit {
                let value = &example.values[field.display_name()];
                let line = format!("{:width$}  {}", field.display_name(), shown(value, field.unit.as_deref()));
                assert!(out.lines().any(|l| l == line), "{name} {}: `{line}` in:\n{out}", command.name);
            }
            let measured = out.lines().filter(|l| !l.ends_with("(derived)") && !l.starts_with("note: "));
            assert_eq!(measured.count(), f32_with_unit.len(), "{out}");
            checked += 1;
        }
        // The version, as JSON.
        if let Some(version) = sensor.command_with_role(Role::Version) {
            let json = YOSEMITECH.run(&["read", name, &version.name, "-p", &s.path, "--json"]).json();
            for field in version.named_fields() {
                let want = s.server.device().get(&version.name, field.display_name()).unwrap();
                assert_eq!(json["values"][field.display_name()], serde_json::to_value(&want).unwrap(), "{json}");
            }
            assert!(json["timestamp"].as_str().unwrap().ends_with('Z'));
            versions += 1;
        }
        // A slave address read at a fixed address goes there whatever --address says.
        if let Some(get) = sensor.command_with_role(Role::GetSlaveAddress).filter(|c| c.fixed_slave.is_some()) {
            let field = get.named_fields().next().unwrap().display_name().to_owned();
            let elsewhere = elsewhere(address).to_string();
            let out = YOSEMITECH.run(&["read", name, &get.name, "-p", &s.path, "-a", &elsewhere]).ok().to_owned();
            assert_eq!(out.trim(), format!("{field}  {address}"));
            addressed += 1;
        }
    }
    report!(
        "read: {checked} stated f32 readings shown, {shortened} with shortened names, {versions} versions as JSON, \
         {addressed} slave-address reads at a fixed address"
    );
}

#[test]
fn port_and_baud_come_from_the_environment() {
    let sensors = identifiable();
    for sensor in &sensors {
        let s = sim(&sensor.name, sensor.default_address);
        let (sn, _) = sn_field(sensor);
        let mut cmd = YOSEMITECH.command();
        cmd.args(["read", &sensor.name, &sn.name])
            .env("YOSEMITECH_PORT", &s.path)
            .env("YOSEMITECH_BAUD", sensor.serial.baud.to_string());
        let run = yosemitech_tests::cli::run_command(cmd, None);
        assert!(run.ok().contains(&served_serial_number(sensor).unwrap()), "{}: {}", sensor.name, run.stdout);
    }
    report!("{} serial numbers read with the port and baud from the environment", sensors.len());
}

/// A measurement read of `sensor`: a read with no role, at the probe's own address.
fn measurement_read(sensor: &Sensor) -> Option<&CommandSpec> {
    sensor.commands.iter().find(|c| c.is_read() && c.role.is_none() && c.fixed_slave.is_none())
}

#[test]
fn a_silent_address_times_out_cleanly() {
    let sensors = spec().sensors.clone();
    let Some((sensor, read)) = sensors.iter().find_map(|s| measurement_read(s).map(|r| (s, r))) else {
        report!("no sensor of the spec has a measurement read at its own address: nothing to time out");
        return;
    };
    let address = sensor.default_address.to_string();
    let s = sim(&sensor.name, sensor.default_address);
    let silent = elsewhere(sensor.default_address).to_string();
    let mut args = vec!["read", sensor.name.as_str(), read.name.as_str(), "-p", &s.path, "-a", &silent];
    args.extend(["--timeout", "100ms", "--retries", "1"]);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(
        err.contains(&format!("no reply to {} from address {silent}", read.name)) && err.contains("within 100ms"),
        "{err}"
    );
    assert!(err.contains("yosemitech scan"), "{err}");
    // A command the probe does not have (another sensor's read at registers
    // this one lacks), at the probe's address: real probes stay silent, and
    // the hint says so.
    let Some((other, foreign)) = foreign_read(sensor, true) else {
        report!("no sensor of the spec reads registers {} lacks: no foreign read sent", sensor.name);
        return;
    };
    let mut args = vec!["read", other.name.as_str(), foreign.name.as_str(), "-p", &s.path, "-a", &address];
    args.extend(FAST);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(err.contains(&format!("no reply to {}", foreign.name)) && err.contains("lacks"), "{err}");
    // A device that answers exceptions instead: the exception (no register
    // there), explained.
    let mut device = Simulator::new(yosemitech_tests::sensor(&sensor.name));
    device.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let s = yosemitech_tests::cli::serve(device);
    let run = YOSEMITECH.run(&["read", &other.name, &foreign.name, "-p", &s.path, "-a", &address]);
    let want = format!("refused {} with Modbus exception illegal data address", foreign.name);
    assert!(run.fails_with_hint(1).contains(&want), "{}", run.stderr);
}

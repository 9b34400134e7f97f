//! `yosemitech set-address`: the new address verified, the broadcast and
//! reserved addresses refused.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use crate::device::{FAST, elsewhere, new_address, served_serial_number};
use yosemitech_spec::{Role, Sensor};
use yosemitech_tests::cli::{Binary, sim};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

#[test]
fn set_address_changes_and_verifies() {
    // A sensor `set-address --sensor` can move: an address write and a
    // serial-number read, both at the probe's own address.
    let own = |s: &Sensor, role| s.command_with_role(role).filter(|c| c.fixed_slave.is_none()).cloned();
    let Some((sensor, set)) = spec().sensors.iter().find_map(|s| {
        own(s, Role::SerialNumber)?;
        Some((s.clone(), own(s, Role::SetSlaveAddress)?))
    }) else {
        report!("no sensor of the spec has an address write and a serial-number read: no address changed");
        return;
    };
    let from = sensor.default_address;
    let to = new_address(&set, &[from]);
    let (from_arg, to_arg) = (from.to_string(), to.to_string());
    let s = sim(&sensor.name, from);
    let mut args = vec!["set-address", "-p", &s.path, "--from", &from_arg, "--to", &to_arg, "--yes"];
    args.extend(["--sensor", &sensor.name]);
    args.extend(FAST);
    let out = YOSEMITECH.run(&args).ok().to_owned();
    let sn = served_serial_number(&sensor).unwrap();
    assert!(out.contains(&format!("now answers at address {to}")) && out.contains(&sn), "{out}");
    assert_eq!(s.server.device().address(), to);
    // Nothing answers at the old address any more: refused, nothing written.
    let other = new_address(&set, &[from, to]).to_string();
    let mut args = vec!["set-address", "-p", &s.path, "--from", &from_arg, "--to", &other, "--yes"];
    args.extend(["--sensor", &sensor.name]);
    args.extend(FAST);
    let err = YOSEMITECH.run(&args).fails_with_hint(1).to_owned();
    assert!(err.contains(&format!("no probe answers at address {from}")), "{err}");
    assert_eq!(s.server.device().address(), to);
    // The new address taken by the probe itself.
    let elsewhere = elsewhere(to).to_string();
    let mut args = vec!["set-address", "-p", &s.path, "--from", &elsewhere, "--to", &to_arg, "--yes"];
    args.extend(["--sensor", &sensor.name]);
    args.extend(FAST);
    assert!(YOSEMITECH.run(&args).fails_with_hint(2).contains(&format!("already answers at address {to}")));
    report!("set-address: {} moved from {from} to {to}", sensor.name);
}

#[test]
fn set_address_refuses_0_and_248() {
    let s = sim(&spec().sensors[0].name, 1);
    for (from, to) in [("0", "5"), ("1", "0"), ("1", "248"), ("248", "1")] {
        let run = YOSEMITECH.run(&["set-address", "-p", &s.path, "--from", from, "--to", to, "--yes"]);
        assert!(run.fails_with_hint(2).contains("outside 1 to 247"), "{}", run.stderr);
    }
    assert_eq!(s.server.device().stats().requests, 0, "nothing was sent");
}

//! `yosemitech set-address --plan` against simulated probes that all start
//! at one address on one pty, connected one at a time as the tool asks.
#![cfg(unix)]

use std::io::{Read, Write};
use std::process::Stdio;
use std::sync::Arc;
use std::sync::mpsc;
use std::time::Duration;

use yosemitech_sim::{Bus, Simulator};
use yosemitech_spec::{FieldKind, Role, Sensor, Value};
use yosemitech_tests::cli::{Binary, serve, wait};
use yosemitech_tests::{report, spec};

const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// Where every new probe arrives (the family's factory address).
const FACTORY: u8 = 1;

/// The sensors whose probes `--plan` can address: an address write and a
/// text serial-number read, both at the probe's own address.
fn addressable() -> Vec<Sensor> {
    fn own(s: &Sensor, role: Role) -> Option<&yosemitech_spec::CommandSpec> {
        s.command_with_role(role).filter(|c| c.fixed_slave.is_none())
    }
    spec()
        .sensors
        .iter()
        .filter(|s| {
            own(s, Role::SetSlaveAddress).is_some()
                && own(s, Role::SerialNumber)
                    .is_some_and(|c| c.named_fields().any(|f| matches!(f.kind, FieldKind::Ascii { .. })))
        })
        .cloned()
        .collect()
}

/// A probe of `sensor` at the factory address whose serial number ends in
/// `number` (so several of one model differ), and that serial number.
fn new_probe(sensor: &Sensor, number: usize) -> (Simulator, String) {
    let mut probe = Simulator::new(Arc::new(sensor.clone())).with_address(FACTORY);
    let command = sensor.command_with_role(Role::SerialNumber).unwrap();
    let field = command.named_fields().find(|f| matches!(f.kind, FieldKind::Ascii { .. })).unwrap();
    let Ok(Value::Text(served)) = probe.get(&command.name, field.display_name()) else {
        panic!("{}: no serial number served", sensor.name)
    };
    let suffix = format!("{:02}", number % 100);
    let keep = served.trim_end().chars().count().saturating_sub(suffix.len());
    let sn: String = served.trim_end().chars().take(keep).chain(suffix.chars()).collect();
    probe.set(&command.name, field.display_name(), Value::Text(sn.clone())).unwrap();
    let Ok(Value::Text(now)) = probe.get(&command.name, field.display_name()) else { unreachable!() };
    (probe, now.trim_end().to_owned())
}

#[test]
fn plan_addresses_three_probes_connected_one_at_a_time() {
    let sensors = addressable();
    if sensors.is_empty() {
        report!("no sensor of the spec changes its address with a serial-number read: nothing planned");
        return;
    }
    // A device already on the bus at the plan's first address (3): the plan skips it.
    let (squatter, _) = new_probe(&sensors[0], 99);
    let bus = serve(Bus::new().with(squatter.with_address(3)));
    let dir = tempfile::tempdir().unwrap();
    let draft = dir.path().join("station.toml");
    let mut cmd = YOSEMITECH.command();
    cmd.args(["set-address", "--plan", "--count", "3", "--yes", "-p", &bus.path, "--timeout", "300ms"])
        .arg("--station-toml")
        .arg(&draft)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = cmd.spawn().unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let out = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stdout.read_to_string(&mut text);
        text
    });
    // The prompts go to stderr without a newline: count them as they come.
    let (prompts, prompted) = mpsc::channel();
    let err = std::thread::spawn(move || {
        let (mut text, mut seen, mut chunk) = (String::new(), 0, [0u8; 512]);
        while let Ok(n @ 1..) = stderr.read(&mut chunk) {
            text.push_str(&String::from_utf8_lossy(&chunk[..n]));
            let now = text.matches("then press Enter").count();
            for _ in seen..now {
                let _ = prompts.send(());
            }
            seen = now;
        }
        text
    });
    let mut connected = Vec::new();
    for number in 0..3 {
        if prompted.recv_timeout(Duration::from_secs(60)).is_err() {
            let code = wait(&mut child, Duration::from_secs(60));
            panic!("no prompt for probe {}; exit {code}\n{}\n{}", number + 1, out.join().unwrap(), err.join().unwrap());
        }
        let sensor = &sensors[number % sensors.len()];
        let (probe, sn) = new_probe(sensor, number + 1);
        bus.server.device().push(probe);
        connected.push((sensor.name.clone(), sn));
        stdin.write_all(b"\n").unwrap();
    }
    drop(stdin);
    let code = wait(&mut child, Duration::from_secs(120));
    let (out, err) = (out.join().unwrap(), err.join().unwrap());
    assert_eq!(code, 0, "stdout:\n{out}\nstderr:\n{err}");
    assert!(out.contains("address 3 (0x03) is taken"), "{out}");

    // Each probe left the factory address for the next free address of the
    // plan (5, 7, 9: spaced by 2, 3 taken), in the order connected.
    let devices = bus.server.device().devices().to_vec();
    let moved: Vec<u8> = devices[1..].iter().map(Simulator::address).collect();
    assert_eq!(moved, [5, 7, 9], "{out}");
    // The bus table: one row per probe with its address in decimal and hex and its serial number.
    let table = out.split("bus table").nth(1).unwrap_or_else(|| panic!("no bus table:\n{out}"));
    for ((sensor, sn), address) in connected.iter().zip(&moved) {
        let row = table
            .lines()
            .find(|l| l.split_whitespace().next() == Some(&address.to_string()))
            .unwrap_or_else(|| panic!("no row for address {address}:\n{table}"));
        assert!(row.contains(&format!("0x{address:02X}")) && row.contains(sn.as_str()), "{row}");
        let verified = format!("SN {sn} now answers at address {address} (0x{address:02X}), verified");
        assert!(out.contains(&verified), "{sensor}: `{verified}` missing:\n{out}");
    }

    // The draft station file names each identified probe at its new address and passes --check.
    let text = std::fs::read_to_string(&draft).unwrap();
    for address in &moved {
        assert!(text.contains(&format!("address = {address}")), "{text}");
    }
    let check = YOSEMITECH.run(&["log", "--config", draft.to_str().unwrap(), "--check"]);
    check.ok();
    report!("set-address --plan: {} probe(s) moved to {moved:?}, draft checked", connected.len());
}

#[test]
fn plan_refuses_the_factory_address_and_a_short_plan_before_opening_the_port() {
    for (args, says) in [
        (&["--addresses", "1,3,5"][..], "where every new probe arrives"),
        (&["--addresses", "3,5", "--count", "3"][..], "only 2 addresses"),
        (&["--step", "0"][..], "--step 0"),
        (&["--count", "0"][..], "--count 0"),
    ] {
        let mut all = vec!["set-address", "--plan", "--yes", "-p", "/nonexistent/port"];
        all.extend(args);
        let run = YOSEMITECH.run(&all);
        assert!(run.fails(2).contains(says), "{args:?}: {}", run.stderr);
    }
    // --to makes no sense with a plan.
    let run = YOSEMITECH.run(&["set-address", "--plan", "--to", "5", "-p", "/nonexistent/port"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
}

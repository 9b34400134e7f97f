//! `yosemitech scan`: each sensor of the spec identified alone by its
//! serial number and model code, and the candidates listed where the spec
//! cannot tell them apart.
//!
//! Against simulated probes on pseudo-terminals (yosemitech-sim's
//! `serve_pty`, or `yosemitech simulate` in a child process), through the
//! real serial code path. No hardware.
#![cfg(unix)]

use std::sync::Arc;

use crate::device::{declaring, identifiable, scan_says, served_serial_number, sn_field, sn_layouts, sn_request};
use serde_json::Value as Json;
use yosemitech_sim::{Bus, Simulator};
use yosemitech_spec::{Role, Sensor, Value};
use yosemitech_tests::cli::Binary;
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// The newest manual of `sensor` whose software is at most `software`.
fn manual_for(sensor: &Sensor, software: &str) -> Option<String> {
    let key = |v: &str| -> (u32, u32) {
        let (a, b) = v.split_once('.').unwrap_or((v, "0"));
        (a.parse().unwrap(), b.parse().unwrap())
    };
    sensor.manuals().filter_map(|m| m.software.clone()).filter(|sw| key(sw) <= key(software)).max_by_key(|sw| key(sw))
}

/// A two-digit model code no sensor of the spec declares (and not `00`,
/// which the byte before a serial number carries when it names none).
fn undeclared_code() -> String {
    (10..=99)
        .map(|n: u8| n.to_string())
        .find(|code| spec().sensors.iter().all(|s| s.model_code.as_deref() != Some(code.as_str())))
        .expect("a two-digit code no sensor declares")
}

#[test]
fn scan_names_each_sensor_of_the_spec_alone() {
    // Every identifiable sensor on one bus: scan names each one alone,
    // except where another loaded sensor sends the same serial-number
    // request and declares the same model code: then it lists them all.
    let sensors = identifiable();
    let mut bus = Bus::new();
    for (i, sensor) in sensors.iter().enumerate() {
        bus.push(Simulator::new(Arc::new(sensor.clone())).with_address(i as u8 + 1));
    }
    let s = yosemitech_tests::cli::serve(bus);
    let last = sensors.len() + 1;
    let addresses = format!("1-{last}");
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s"]);
    if sensors.is_empty() {
        run.fails_with_hint(1);
        report!("no sensor of the spec has a serial-number read and a model code: nothing to scan for");
        return;
    }
    let out = run.ok().to_owned();
    let mut alone = 0;
    for (i, sensor) in sensors.iter().enumerate() {
        let code = sensor.model_code.as_deref().unwrap();
        let line = out
            .lines()
            .find(|l| l.starts_with(&format!("address {:3}  ", i + 1)))
            .unwrap_or_else(|| panic!("no line for address {}:\n{out}", i + 1));
        let (said, among) = scan_says(sensor, code, &served_serial_number(sensor).unwrap());
        assert!(line.contains(&said), "`{said}` not in: {line}");
        assert_eq!(line.contains("not identified"), among.is_some(), "{line}");
        alone += usize::from(among.is_none());
    }
    assert!(out.contains(&format!("found {} device(s)", sensors.len())), "{out}");
    // Few reads per address: the serial-number requests tried, and one for the revisions.
    let requests = s.server.device().devices()[0].stats().requests;
    assert!(requests <= (last * (sn_layouts() + 1)) as u64, "{requests} requests for {last} addresses");

    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices.len(), sensors.len(), "{json}");
    for (device, sensor) in devices.iter().zip(&sensors) {
        let code = sensor.model_code.as_deref().unwrap();
        let sn = served_serial_number(sensor).unwrap();
        assert_eq!(device["model_code"].as_str(), Some(code), "{device}");
        assert_eq!(device["serial_number"], sn.as_str());
        let bus = s.server.device();
        let sim = &bus.devices()[device["address"].as_u64().unwrap() as usize - 1];
        match scan_says(sensor, code, &sn).1 {
            None => {
                assert_eq!(device["sensor"], sensor.name.as_str(), "{device}");
                assert_eq!(device["sensors"], serde_json::json!([sensor.name]), "{device}");
                assert_eq!(device["model"].as_str(), sensor.model.as_deref(), "{device}");
                assert_eq!(device["reason"], Json::Null);
                // Every model that shares the sensor's code and commands, and why no read tells them apart.
                assert_eq!(device["models"], serde_json::json!(sensor.models_with_code(code)), "{device}");
                assert_eq!(device["models_reason"].is_null(), sensor.models_with_code(code).len() < 2, "{device}");
                // The revisions, and the manual that covers that firmware.
                match sensor.command_with_role(Role::Version) {
                    Some(version) => {
                        let software = version.named_fields().last().unwrap().display_name().to_owned();
                        let Value::Version(sw) = sim.get(&version.name, &software).unwrap() else { panic!() };
                        assert_eq!(device["software"], sw.to_string().as_str(), "{device}");
                        let manual = manual_for(sensor, &sw.to_string());
                        assert_eq!(device["manual"]["software"].as_str(), manual.as_deref(), "{device}");
                    }
                    None => assert_eq!(device["software"], Json::Null),
                }
            }
            Some(twins) => {
                let names: Vec<&str> = twins.iter().map(|t| t.name.as_str()).collect();
                assert_eq!(device["sensor"], Json::Null, "{device}");
                assert_eq!(device["sensors"], serde_json::json!(names), "{device}");
                assert_eq!(device["model"], Json::Null, "{device}");
                assert_eq!(device["manual"], Json::Null, "no manual for a probe not identified: {device}");
                let reason = device["reason"].as_str().unwrap_or_default();
                let why = format!("{} loaded sensors", twins.len());
                assert!(reason.contains(&why) && reason.contains(&format!("model code {code}")), "{device}");
            }
        }
    }
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &format!("{}", last + 1)]);
    assert!(run.fails_with_hint(1).contains("no device answered"), "{}", run.stderr);
    report!(
        "scan: {} probes, {alone} named alone, {} among the sensors of their model code, in {requests} requests",
        sensors.len(),
        sensors.len() - alone
    );
}

#[test]
fn scan_takes_the_model_code_from_the_byte_before_the_serial_number() {
    // Real probes send the code in the byte the manuals print as 0x00; the
    // text may carry another (the manuals print a sibling's serial number).
    let sensors: Vec<_> = identifiable()
        .into_iter()
        .filter(|s| {
            let (command, field) = sn_field(s);
            field.offset > 0
                && command.fields.iter().any(|f| f.is_reserved() && f.offset + f.size() == field.offset)
                && u8::from_str_radix(s.model_code.as_deref().unwrap(), 16).is_ok()
        })
        .collect();
    if sensors.is_empty() {
        report!("no sensor of the spec has a reserved byte before its serial number: no code read from it");
        return;
    }
    let other = undeclared_code();
    let text = format!("YL{other}14010022");
    let mut bus = Bus::new();
    for (i, sensor) in sensors.iter().enumerate() {
        let (command, field) = sn_field(sensor);
        let code = sensor.model_code.as_deref().unwrap();
        let byte = u8::from_str_radix(code, 16).unwrap();
        let mut device = Simulator::new(Arc::new(sensor.clone())).with_address(i as u8 + 1);
        device.set(&command.name, field.display_name(), Value::Text(text.clone())).unwrap();
        device.registers_mut().write_bytes(command.address, field.offset - 1, &[byte]);
        bus.push(device);
    }
    let s = yosemitech_tests::cli::serve(bus);
    let addresses = format!("1-{}", sensors.len());
    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices.len(), sensors.len());
    for (device, sensor) in devices.iter().zip(&sensors) {
        let code = sensor.model_code.as_deref().unwrap();
        assert_eq!(device["model_code"].as_str(), Some(code), "{device}");
        assert_eq!(device["serial_number"], text.as_str());
        let twins: Vec<String> = declaring(sensor, code).into_iter().map(|t| t.name).collect();
        let twin_sensors = declaring(sensor, code);
        let refs: Vec<&Sensor> = twin_sensors.iter().collect();
        if twins.len() == 1 || yosemitech_cli::scan_tells_apart(&refs) {
            assert_eq!(device["sensor"], sensor.name.as_str(), "{device}");
        } else {
            assert_eq!(device["sensors"], serde_json::json!(twins), "{device}");
            assert_eq!(device["sensor"], Json::Null, "{device}");
        }
    }
    report!("scan read the model code from the byte before the serial number of {} probes", sensors.len());
}

#[test]
fn scan_names_the_model_of_every_code_a_sensor_declares() {
    // A probe of a sensor sending any code the sensor declares (its own,
    // older ones, its aliases'): scan names the models of that code, the
    // aliases that share it beside the sensor's own model, with the reason.
    let mut bus = Bus::new();
    let mut expected: Vec<(Sensor, String)> = Vec::new();
    for sensor in identifiable() {
        let codes: Vec<String> = sensor
            .model_codes()
            .map(str::to_owned)
            .chain(sensor.aliases.iter().filter_map(|a| a.model_code.clone()))
            .filter(|c| u8::from_str_radix(c, 16).is_ok())
            .collect();
        for code in codes {
            // Where another sensor reads its serial number alike and declares the code, scan may list both.
            if declaring(&sensor, &code).len() > 1 {
                continue;
            }
            let (command, field) = sn_field(&sensor);
            let address = expected.len() as u8 + 1;
            let mut device = Simulator::new(Arc::new(sensor.clone())).with_address(address);
            device.set(&command.name, field.display_name(), Value::Text(format!("YL{code}14010022"))).unwrap();
            if command.fields.iter().any(|f| f.is_reserved() && f.offset + f.size() == field.offset) {
                let byte = u8::from_str_radix(&code, 16).unwrap();
                device.registers_mut().write_bytes(command.address, field.offset - 1, &[byte]);
            }
            bus.push(device);
            expected.push((sensor.clone(), code));
        }
    }
    if expected.is_empty() {
        report!("no sensor of the spec declares a model code scan can read");
        return;
    }
    let s = yosemitech_tests::cli::serve(bus);
    let addresses = format!("1-{}", expected.len());
    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &addresses, "--timeout", "1s", "--json"]).json();
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices.len(), expected.len(), "{json}");
    let mut shared = 0;
    for (device, (sensor, code)) in devices.iter().zip(&expected) {
        assert_eq!(device["model_code"].as_str(), Some(code.as_str()), "{device}");
        assert_eq!(device["sensor"], sensor.name.as_str(), "{device}");
        let models = sensor.models_with_code(code);
        assert_eq!(device["models"], serde_json::json!(models), "{device}");
        if models.len() > 1 {
            let why = device["models_reason"].as_str().unwrap_or_default();
            assert!(models.iter().all(|m| why.contains(m)) && why.contains("no read"), "{device}");
            shared += 1;
        } else {
            assert_eq!(device["models_reason"], Json::Null, "{device}");
        }
    }
    report!("scan named the models of {} codes, {shared} shared by models no read tells apart", expected.len());
}

#[test]
fn scan_lists_the_candidates_where_it_cannot_decide() {
    let Some(sensor) = identifiable().into_iter().next() else {
        report!("no sensor of the spec has a serial-number read and a model code: no candidates to list");
        return;
    };
    let (command, field) = sn_field(&sensor);
    let address = sensor.default_address.to_string();
    // A model code no loaded sensor declares: every sensor that sends the
    // same serial-number request is a candidate.
    let other = undeclared_code();
    let mut device = Simulator::new(Arc::new(sensor.clone()));
    device.set(&command.name, field.display_name(), Value::Text(format!("YL{other}14010022"))).unwrap();
    if let Some(before) = field.offset.checked_sub(1) {
        device.registers_mut().write_bytes(command.address, before, &[u8::from_str_radix(&other, 16).unwrap()]);
    }
    let s = yosemitech_tests::cli::serve(device);
    let json = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &address, "--timeout", "1s", "--json"]).json();
    let found = &json["devices"][0];
    assert_eq!(found["sensor"], Json::Null, "{found}");
    assert_eq!(found["model_code"], other.as_str());
    let same_request: Vec<String> =
        spec().sensors.iter().filter(|s| sn_request(s) == sn_request(&sensor)).map(|s| s.name.clone()).collect();
    assert_eq!(found["sensors"], serde_json::json!(same_request), "{found}");
    assert!(found["reason"].as_str().unwrap().contains(&format!("model code {other}")), "{found}");
    let run = YOSEMITECH.run(&["scan", "-p", &s.path, "--addresses", &address, "--timeout", "1s"]);
    let out = run.ok();
    let shown = format!("model code {other}");
    assert!(out.contains("not identified") && out.contains(&sensor.name) && out.contains(&shown), "{out}");

    // One more loaded sensor declaring its code: it joins the candidates.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(&sensor.file).unwrap();
    let twin = format!("{}_twin", sensor.name);
    let renamed = text.replacen(&format!("name: {}\n", sensor.name), &format!("name: {twin}\n"), 1);
    assert_ne!(renamed, text, "the sensor's name line");
    std::fs::write(dir.path().join("twin.yaml"), renamed).unwrap();
    let spec_arg = dir.path().to_str().unwrap();
    s.server
        .device()
        .set(&command.name, field.display_name(), Value::Text(served_serial_number(&sensor).unwrap()))
        .unwrap();
    if let Some(before) = field.offset.checked_sub(1) {
        // What the simulator sends there for its own code.
        let own = Simulator::new(Arc::new(sensor.clone())).registers().read(command.address, command.count);
        s.server.device().registers_mut().write_bytes(command.address, before, &own[before..=before]);
    }
    let json = YOSEMITECH
        .run(&["--spec", spec_arg, "scan", "-p", &s.path, "--addresses", &address, "--timeout", "1s", "--json"])
        .json();
    let found = &json["devices"][0];
    let code = sensor.model_code.as_deref().unwrap();
    let mut candidates: Vec<String> = declaring(&sensor, code).into_iter().map(|t| t.name).collect();
    candidates.push(twin);
    assert_eq!(found["sensor"], Json::Null, "{found}");
    assert_eq!(found["sensors"], serde_json::json!(candidates), "{found}");
    let why = format!("{} loaded sensors", candidates.len());
    assert!(found["reason"].as_str().unwrap().contains(&why), "{found}");
}

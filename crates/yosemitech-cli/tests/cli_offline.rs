//! The `yosemitech` binary without a device: help, list, decode, encode, and
//! bad input. Every frame the manuals print goes through `decode --json` and
//! `encode` and must give the manuals' stated values and bytes.

mod common;

use common::{spec, yosemitech};
use serde_json::Value as Json;
use yosemitech_spec::{Command, Example, Sensor, Value};

const SUBCOMMANDS: [&str; 13] = [
    "demo",
    "list",
    "read",
    "write",
    "poll",
    "measure",
    "calibrate",
    "coefficients",
    "scan",
    "set-address",
    "decode",
    "encode",
    "simulate",
];

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

/// Whether a decoded JSON value is the value the manual states.
fn same(expected: &Value, got: &Json) -> bool {
    match expected {
        Value::Float(f) => got.as_f64().is_some_and(|g| (g as f32).to_bits() == f.to_bits()),
        Value::Int(i) => got.as_i64() == Some(*i),
        Value::Text(t) => got.as_str() == Some(t.as_str()),
        Value::Version(v) => got.as_str() == Some(v.to_string().as_str()),
        Value::Bcd(v) => got.as_u64() == v.value().map(u64::from),
        Value::Enum { raw, name } => {
            got["raw"].as_u64() == Some(u64::from(*raw)) && got["name"].as_str() == name.as_deref()
        }
    }
}

/// A stated value as the command line takes it.
fn arg(value: &Value) -> String {
    match value {
        Value::Float(f) => f.to_string(),
        Value::Int(i) => i.to_string(),
        Value::Text(t) => t.clone(),
        Value::Version(v) => v.to_string(),
        Value::Bcd(v) => v.value().map_or_else(|| format!("0x{:02X}", v.0), |n| n.to_string()),
        Value::Enum { raw, name } => name.clone().unwrap_or_else(|| raw.to_string()),
    }
}

/// Every example of every command, with its sensor and command.
fn examples() -> Vec<(Sensor, Command, Example)> {
    let spec = spec();
    let mut out = Vec::new();
    for sensor in &spec.sensors {
        for command in &sensor.commands {
            for example in &command.examples {
                out.push((sensor.clone(), command.clone(), example.clone()));
            }
        }
    }
    assert!(out.len() >= 20, "the manuals print at least 20 example pairs");
    out
}

fn decode_json(frame: &[u8], sensor: &str, command: &str) -> Json {
    let frame = hex(frame);
    let run = yosemitech(&["decode", &frame, "--sensor", sensor, "--command", command, "--json"]);
    run.json()
}

#[test]
fn help_works_for_every_subcommand() {
    let top = yosemitech(&["--help"]);
    let text = top.ok();
    for sub in SUBCOMMANDS {
        assert!(text.contains(sub), "`{sub}` missing from --help");
        let run = yosemitech(&[sub, "--help"]);
        assert!(run.ok().contains("Usage:"), "{sub} --help:\n{}", run.stdout);
    }
    for nested in [["calibrate", "ph"], ["coefficients", "backup"], ["coefficients", "restore"]] {
        assert!(yosemitech(&[nested[0], nested[1], "--help"]).ok().contains("Usage:"));
    }
    // `measure SENSOR --help` for every sensor (the help of `measure`).
    for sensor in spec().sensors {
        assert!(yosemitech(&["measure", &sensor.name, "--help"]).ok().contains("Usage:"), "{}", sensor.name);
    }
    assert!(yosemitech(&["--version"]).ok().starts_with("yosemitech "));
}

#[test]
fn usage_errors_exit_2() {
    // No subcommand: the usage, on stderr.
    let run = yosemitech(&[]);
    assert_eq!(run.code, 2);
    assert!(run.stderr.contains("Usage:"), "{}", run.stderr);
    yosemitech(&["frobnicate"]).fails(2);
    yosemitech(&["decode"]).fails(2);
    yosemitech(&["poll", "ph_orp", "--interval", "fast"]).fails(2);
}

/// `9600 8N1`, as `list` shows serial settings.
fn serial_text(serial: &yosemitech_spec::Serial) -> String {
    let parity = match serial.parity {
        yosemitech_spec::Parity::None => 'N',
        yosemitech_spec::Parity::Even => 'E',
        yosemitech_spec::Parity::Odd => 'O',
    };
    format!("{} {}{parity}{}", serial.baud, serial.data_bits, serial.stop_bits)
}

#[test]
fn list_json_has_every_command_with_its_layout() {
    let json = yosemitech(&["list", "--json"]).json();
    let sensors = json["sensors"].as_array().expect("sensors");
    let spec = spec();
    let names: Vec<&str> = sensors.iter().filter_map(|s| s["name"].as_str()).collect();
    let want: Vec<&str> = spec.sensors.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, want);
    for s in sensors {
        let sensor = spec.sensor(s["name"].as_str().unwrap()).unwrap();
        assert_eq!(s["model"].as_str(), sensor.model.as_deref());
        assert_eq!(s["model_code"].as_str(), sensor.model_code.as_deref());
        // Every manual, with the serial settings of its firmware.
        let manuals = s["manuals"].as_array().expect("manuals");
        assert_eq!(manuals.len(), 1 + sensor.revisions.len(), "{}", sensor.name);
        for manual in sensor.manuals() {
            let m = manuals
                .iter()
                .find(|m| m["title"] == manual.title.as_str() && m["software"].as_str() == manual.software.as_deref());
            let m = m.unwrap_or_else(|| panic!("{}: manual {:?} missing", sensor.name, manual.software));
            let serial = manual.software.as_deref().map_or(sensor.serial, |sw| sensor.serial_for(sw));
            assert_eq!(m["serial"]["stop_bits"].as_u64(), Some(u64::from(serial.stop_bits)));
            assert_eq!(m["serial"]["baud"].as_u64(), Some(u64::from(serial.baud)));
        }
        assert_eq!(s["procedure"].is_null(), sensor.procedure.is_none(), "{}", sensor.name);
        let commands = s["commands"].as_array().expect("commands");
        assert_eq!(commands.len(), sensor.commands.len());
        for c in commands {
            for key in ["name", "function", "address", "count", "fields"] {
                assert!(!c[key].is_null(), "{key} missing in {c}");
            }
            let command = sensor.command(c["name"].as_str().unwrap()).unwrap();
            assert_eq!(c["address"].as_u64(), Some(u64::from(command.address)));
            assert_eq!(c["count"].as_u64(), Some(u64::from(command.count)));
            assert_eq!(c["function"].as_str(), Some(if command.is_read() { "read" } else { "write" }));
            assert_eq!(c["since"].as_str(), command.since.as_deref(), "{}", command.name);
            assert_eq!(c["role"].as_str(), command.role.map(|r| r.name()), "{}", command.name);
            let fields = c["fields"].as_array().unwrap();
            assert_eq!(fields.len(), command.fields.len());
            let size: u64 = fields.iter().map(|f| f["size"].as_u64().unwrap()).sum();
            if !command.trigger {
                assert_eq!(size, 2 * u64::from(command.count), "fields fill the registers of {}", command.name);
            }
            for (f, field) in fields.iter().zip(&command.fields) {
                for key in ["name", "type", "unit", "offset", "size", "byte_order"] {
                    assert!(f.get(key).is_some(), "{key} missing in {f}");
                }
                assert_eq!(f["name"].as_str(), field.name.as_deref());
                assert_eq!(f["type"], field.kind.type_name());
                assert_eq!(f["unit"].as_str(), field.unit.as_deref());
                assert_eq!(f["offset"].as_u64(), Some(field.offset as u64));
                assert_eq!(f["size"].as_u64(), Some(field.size() as u64));
            }
        }
    }
    for sensor in &spec.sensors {
        let one = yosemitech(&["list", &sensor.name, "--json"]).json();
        assert_eq!(one["sensors"].as_array().unwrap().len(), 1);
        assert_eq!(one["sensors"][0]["name"], sensor.name.as_str());
    }
}

#[test]
fn list_shows_sensors_commands_and_fields() {
    let all = yosemitech(&["list"]);
    let text = all.ok();
    for sensor in spec().sensors {
        assert!(text.contains(&format!("{} — {}", sensor.name, sensor.title)), "{}", sensor.name);
        let one = yosemitech(&["list", &sensor.name]).ok().to_owned();
        if let Some(model) = &sensor.model {
            assert!(one.contains(&format!("model {model}")), "{one}");
        }
        if let Some(code) = &sensor.model_code {
            assert!(one.contains(&format!("model code {code}")), "{one}");
        }
        for manual in sensor.manuals() {
            let serial = manual.software.as_deref().map_or(sensor.serial, |sw| sensor.serial_for(sw));
            let line = one
                .lines()
                .find(|l| {
                    l.contains(&manual.title)
                        && manual.software.as_ref().is_none_or(|sw| l.contains(&format!("SW {sw}:")))
                })
                .unwrap_or_else(|| panic!("no line for the manual {:?}:\n{one}", manual.software));
            assert!(line.contains(&serial_text(&serial)), "{line}");
            if serial.stop_bits == 2 {
                assert!(line.contains("2 stop bits"), "{line}");
            }
        }
        if sensor.procedure.is_some() {
            assert!(one.contains(&format!("`yosemitech measure {}`", sensor.name)), "{one}");
        }
        for command in &sensor.commands {
            let line = one
                .lines()
                .find(|l| l.trim_start().starts_with(&format!("{} ", command.name)))
                .unwrap_or_else(|| panic!("no line for {}:\n{one}", command.name));
            assert!(line.contains(&format!("0x{:04X}", command.address)), "{line}");
            if let Some(role) = command.role {
                assert!(line.contains(&format!("[{}]", role.name())), "{line}");
            }
            if let Some(since) = &command.since {
                assert!(line.contains(&format!("since SW {since}")), "{line}");
            }
            for field in command.named_fields() {
                let shown = format!("{}: {}", field.display_name(), field.kind.type_name());
                assert!(one.contains(&shown), "`{shown}` missing:\n{one}");
            }
        }
    }
    let one = yosemitech(&["list", "ph"]);
    assert!(one.ok().contains("ph: f32 dcba [pH]"), "{}", one.stdout);
}

#[test]
fn decode_json_of_every_manual_reply_gives_the_stated_values() {
    for (sensor, command, example) in examples() {
        let Some(reply) = example.true_response() else { continue };
        let mut frames = vec![reply.to_vec()];
        if example.erratum.as_ref().is_some_and(|e| e.printed_decodes && e.corrected_response.is_some())
            && let Some(printed) = example.response.as_ref().and_then(|f| f.complete.clone())
        {
            frames.push(printed);
        }
        for frame in frames {
            let json = decode_json(&frame, &sensor.name, &command.name);
            assert_eq!(json["crc"]["ok"], true, "{} {}: {json}", sensor.name, command.name);
            assert_eq!(json["command"]["name"], command.name.as_str());
            if command.is_read() {
                assert_eq!(json["kind"], "read_reply");
                let values = &json["values"];
                assert_eq!(values.as_object().unwrap().len(), example.values.len(), "{}: {json}", command.name);
                for (name, want) in &example.values {
                    assert!(
                        same(want, &values[name]),
                        "{} {name}: manual {want:?}, decoded {}",
                        command.name,
                        values[name]
                    );
                }
            } else {
                assert_eq!(json["kind"], "write_reply");
                assert_eq!(json["address"].as_u64(), Some(u64::from(command.address)));
            }
        }
    }
}

#[test]
fn decode_json_of_every_manual_request_gives_the_stated_values() {
    for (sensor, command, example) in examples() {
        let Some(request) = example.true_request() else { continue };
        let json = decode_json(request, &sensor.name, &command.name);
        assert_eq!(json["crc"]["ok"], true);
        assert_eq!(json["slave"].as_u64(), Some(u64::from(example.slave())));
        if command.is_read() {
            assert_eq!(json["kind"], "read_request");
        } else {
            assert_eq!(json["kind"], "write_request");
            for (name, want) in &example.values {
                assert!(same(want, &json["values"][name]), "{} {name}: {json}", command.name);
            }
        }
    }
}

#[test]
fn encode_reproduces_every_manual_frame() {
    for (sensor, command, example) in examples() {
        let Some((true_request, true_response)) = example.true_pair() else { continue };
        let values: Vec<String> = example.values.iter().map(|(k, v)| format!("{k}={}", arg(v))).collect();
        let address = example.slave().to_string();
        let mut base = vec!["encode".to_owned(), sensor.name.clone(), command.name.clone()];
        if command.fixed_slave.is_none() {
            base.extend(["--address".to_owned(), address]);
        }
        let (request_values, response_values) =
            if command.is_read() { (Vec::new(), values) } else { (values, Vec::new()) };
        let args: Vec<String> = base.iter().cloned().chain(request_values).collect();
        let run = yosemitech(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert_eq!(run.ok().trim(), hex(true_request), "{} request", command.name);
        let args: Vec<String> = base.iter().cloned().chain(["--response".to_owned()]).chain(response_values).collect();
        let run = yosemitech(&args.iter().map(String::as_str).collect::<Vec<_>>());
        if command.trigger {
            // The simulator's (the manuals') form; the example may show another accepted one.
            continue;
        }
        assert_eq!(run.ok().trim(), hex(true_response), "{} reply", command.name);
    }
}

#[test]
fn decode_identifies_unambiguous_frames_on_its_own() {
    // Every complete example reply that exactly one (sensor, command) of the
    // spec accepts is named without --sensor/--command; a reply several
    // commands accept is named with all of them.
    let spec = spec();
    let mut named_alone = 0;
    let mut ambiguous = 0;
    for (sensor, command, example) in examples() {
        let Some(reply) = example.true_response() else { continue };
        if !command.is_read() || command.trigger {
            continue;
        }
        let accepting: Vec<String> = spec
            .sensors
            .iter()
            .flat_map(|s| s.commands.iter().map(move |c| (s, c)))
            .filter(|(_, c)| c.is_read() && !c.trigger && c.decode_response(example.slave(), reply).is_ok())
            .map(|(s, c)| format!("{} {}", s.name, c.name))
            .collect();
        let run = yosemitech(&["decode", &hex(reply)]);
        let text = run.stdout.clone();
        if accepting.len() == 1 {
            assert!(text.contains(&format!("{} {}", sensor.name, command.name)), "{text}");
            assert!(text.contains("(ok)"), "{text}");
            named_alone += 1;
        } else {
            assert!(accepting.contains(&format!("{} {}", sensor.name, command.name)));
            ambiguous += 1;
        }
    }
    assert!(named_alone > 0, "some reply is unambiguous");
    println!("{named_alone} replies named alone, {ambiguous} fit several commands");
    // A printed frame the spec accepts as a documented firmware quirk decodes with a note.
    for (_, command, example) in examples() {
        let Some(err) = &example.erratum else { continue };
        let Some(printed) = example.response.as_ref().and_then(|f| f.complete.as_ref()) else { continue };
        if !err.printed_decodes || err.corrected_response.is_none() {
            continue;
        }
        let run = yosemitech(&["decode", &hex(printed), "--json"]);
        let json = run.json();
        assert_eq!(json["command"]["name"], command.name.as_str(), "{json}");
        assert!(json["notes"][0].as_str().is_some_and(|n| n.contains("quirk")), "{json}");
    }
}

#[test]
fn decode_asks_which_command_when_a_reply_is_ambiguous() {
    let run = yosemitech(&["decode", "01 03 04 33 33 F3 40 40 78"]);
    let err = run.fails_with_hint(2);
    for candidate in ["get_ph", "get_orp", "get_temperature", "get_version"] {
        assert!(err.contains(candidate), "{candidate} not listed:\n{err}");
    }
    assert!(err.contains("ph = 7.6 pH"), "{err}");
    assert!(err.contains("--sensor") && err.contains("--command"), "{err}");
    // Narrowing by command alone is enough.
    let run = yosemitech(&["decode", "01 03 04 33 33 F3 40 40 78", "--command", "get_ph"]);
    assert!(run.ok().contains("7.6 pH"));
}

#[test]
fn decode_reports_a_wrong_crc_with_the_expected_one() {
    let run = yosemitech(&["decode", "01 03 04 33 33 F3 40 40 79", "--sensor", "ph_orp", "--command", "get_ph"]);
    let err = run.fails_with_hint(1);
    assert!(run.stdout.contains("40 79 (wrong: the bytes give 40 78)"), "{}", run.stdout);
    assert!(run.stdout.contains("7.6 pH"), "fields still shown:\n{}", run.stdout);
    assert!(err.contains("40 78"));
    let run = yosemitech(&["decode", "01 03 04 33 33 F3 40 40 79", "--command", "get_ph", "--json"]);
    assert_eq!(run.code, 1);
    let json: Json = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(json["crc"], serde_json::json!({ "ok": false, "received": "40 79", "expected": "40 78" }));
}

#[test]
fn decode_explains_exceptions() {
    let run = yosemitech(&["decode", "01 83 02 C0 F1"]);
    let text = run.ok();
    assert!(text.contains("exception reply from address 1 to function 0x03"), "{text}");
    assert!(text.contains("illegal data address"), "{text}");
    let json = yosemitech(&["decode", "01 83 02 C0 F1", "--json"]).json();
    assert_eq!(json["exception"]["code"], 2);
}

#[test]
fn decode_rejects_a_frame_that_does_not_fit_the_command() {
    let err =
        yosemitech(&["decode", "01 03 04 33 33 F3 40 40 78", "--command", "get_sn"]).fails_with_hint(2).to_owned();
    assert!(err.contains("does not fit `get_sn`"), "{err}");
    let err =
        yosemitech(&["decode", "01 03 04 33 33 F3 40 40 78", "--command", "get_phh"]).fails_with_hint(2).to_owned();
    assert!(err.contains("did you mean `get_ph`"), "{err}");
}

#[test]
fn bad_input_gets_one_error_and_a_hint() {
    let cases: &[(&[&str], i32, &str)] = &[
        (&["decode", "01 03 0"], 2, "odd number"),
        (&["decode", "01 03 zz"], 2, "not a hex digit"),
        (&["decode", "0103"], 2, "too short"),
        (&["decode", "01 2B 0E 01 00 70 77"], 1, "function 0x2B"),
        (&["read", "ph_ors", "get_ph", "--port", "/dev/null"], 2, "did you mean `ph_orp`"),
        (&["read", "ph_orp", "get_pj", "--port", "/dev/null"], 2, "did you mean `get_ph`"),
        (&["read", "ph_orp", "get_ph"], 2, "no port given"),
        (&["read", "ph_orp", "get_ph", "--port", "/dev/yosemitech-no-such-port"], 1, "not found"),
        (&["read", "ph_orp", "get_ph", "--port", "/dev/null", "--address", "0"], 2, "outside 1..=247"),
        (&["read", "ph_orp", "get_ph", "--port", "/dev/null", "--address", "248"], 2, "outside 1..=247"),
        (&["read", "ph_orp", "set_ph_calibration", "--port", "/dev/null"], 2, "write command"),
        (&["write", "ph_orp", "get_ph", "--port", "/dev/null"], 2, "read command"),
        (
            &["write", "ph_orp", "start_ph_calibration", "15", "--port", "/dev/null", "--yes"],
            2,
            "outside the valid range",
        ),
        (&["write", "ph_orp", "set_ph_calibration", "k_slope=1", "--port", "/dev/null"], 2, "no value for `b_offset`"),
        (&["write", "ph_orp", "set_ph_calibration", "1", "x", "--port", "/dev/null"], 2, "not a number"),
        (&["write", "ph_orp", "set_ph_calibration", "1", "0", "--port", "/dev/null"], 2, "stdin is not a terminal"),
        (&["encode", "ph_orp", "set_slave_id", "0"], 2, "outside the valid range 1..=247"),
        (&["encode", "ph_orp", "set_slave_id", "248"], 2, "outside the valid range 1..=247"),
        (&["encode", "ph_orp", "set_slave_id", "slave_adress=3"], 2, "did you mean `slave_address`"),
        (&["encode", "ph_orp", "get_ph", "7.6"], 2, "carries no values"),
        (&["encode", "ph_orp", "get_slave_id", "--address", "3"], 2, "0xFF"),
        (&["set-address", "--port", "/dev/null", "--from", "0", "--to", "5"], 2, "--from 0 is outside 1..=247"),
        (&["set-address", "--port", "/dev/null", "--from", "1", "--to", "248"], 2, "--to 248 is outside 1..=247"),
        (&["scan", "--port", "/dev/null", "--addresses", "0-3"], 2, "outside 1..=247"),
        (&["scan", "--port", "/dev/null", "--addresses", "a-b"], 2, "not an address"),
        (&["simulate", "ph_orp", "--faults", "dorp=0.1"], 2, "did you mean `drop`"),
        (&["list", "nonexistent_sensor"], 2, "unknown sensor"),
        (&["list", "--spec", "/nonexistent/spec/dir"], 2, "no such file"),
        (
            &["coefficients", "restore", "ph_orp", "--port", "/dev/null", "--file", "/nonexistent.json"],
            2,
            "cannot read",
        ),
    ];
    for (args, code, needle) in cases {
        let run = yosemitech(args);
        let err = run.fails_with_hint(*code);
        assert!(err.starts_with("error: "), "{args:?}: stderr starts with the error:\n{err}");
        assert!(err.contains(needle), "{args:?}: `{needle}` not in:\n{err}");
        assert_eq!(err.lines().filter(|l| l.starts_with("error:")).count(), 1, "{args:?}: one error line:\n{err}");
    }
}

#[test]
fn a_spec_error_is_reported_with_its_position() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("broken.yaml"), "sensor:\n  name: Broken Name\n").unwrap();
    let run = yosemitech(&["list", "--spec", dir.path().to_str().unwrap()]);
    let err = run.fails_with_hint(2);
    assert!(err.contains("broken.yaml:"), "{err}");
}

#[test]
fn spec_files_load_at_run_time_with_the_shared_commands_built_in() {
    // A new sensor in a directory of its own: its include of
    // yosemitech-common.yaml falls back to the built-in copy.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("test-probe.yaml"),
        r#"sensor:
  name: test_probe
  title: Turbidity probe (test)
  doc: A made-up probe for the CLI's --spec test.
  manual: {title: Test manual, revision: "1.0"}
  serial: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1}
  addresses: {min: 1, max: 247}
  default_address: 1
include:
  - yosemitech-common.yaml
commands:
  - use: get_sn
  - name: get_turbidity
    title: Get Turbidity
    doc: Turbidity.
    function: read
    address: 0x2600
    count: 2
    fields:
      - {name: turbidity_ntu, type: f32, byte_order: dcba, unit: NTU, doc: Turbidity.}
    examples:
      - figures: []
        request: "01 03 26 00 00 02 CF 43"
        response: "01 03 04 00 00 20 41 23 C3"
        values: {turbidity_ntu: 10.0}
"#,
    )
    .unwrap();
    let spec = dir.path().to_str().unwrap();
    let json = yosemitech(&["--spec", spec, "list", "--json"]).json();
    let names: Vec<&str> = json["sensors"].as_array().unwrap().iter().filter_map(|s| s["name"].as_str()).collect();
    let built_in = common::spec();
    let want: Vec<&str> = built_in.sensors.iter().map(|s| s.name.as_str()).chain(["test_probe"]).collect();
    assert_eq!(names, want, "the built-in sensors, then the --spec one");
    let turbidity = yosemitech(&["list", "test_probe", "--json", "--spec", spec]).json();
    let commands: Vec<&str> =
        turbidity["sensors"][0]["commands"].as_array().unwrap().iter().filter_map(|c| c["name"].as_str()).collect();
    assert!(commands.contains(&"get_sn") && commands.contains(&"get_turbidity"), "{commands:?}");
    let run = yosemitech(&[
        "decode",
        "01 03 04 00 00 20 41 23 C3",
        "--spec",
        spec,
        "--sensor",
        "test_probe",
        "--command",
        "get_turbidity",
    ]);
    assert!(run.ok().contains("10 NTU"), "{}", run.stdout);
    let run = yosemitech(&["encode", "test_probe", "get_turbidity", "--spec", spec]);
    assert_eq!(run.ok().trim(), "01 03 26 00 00 02 CF 43");
}

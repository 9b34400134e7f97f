//! The `yosemitech` binary without a device: help, list, decode, encode, and
//! bad input. Every frame the manuals print goes through `decode --json` and
//! `encode` and must give the manuals' stated values and bytes.

use yosemitech_tests::cli::Binary;
use yosemitech_tests::spec;

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));
use serde_json::Value as Json;
use yosemitech_spec::{CommandSpec, Example, Sensor, Value};

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
fn examples() -> Vec<(Sensor, CommandSpec, Example)> {
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
    let run = YOSEMITECH.run(&["decode", &frame, "--sensor", sensor, "--command", command, "--json"]);
    run.json()
}

#[test]
fn help_works_for_every_subcommand() {
    let top = YOSEMITECH.run(&["--help"]);
    let text = top.ok();
    for sub in SUBCOMMANDS {
        assert!(text.contains(sub), "`{sub}` missing from --help");
        let run = YOSEMITECH.run(&[sub, "--help"]);
        assert!(run.ok().contains("Usage:"), "{sub} --help:\n{}", run.stdout);
    }
    for nested in [["calibrate", "ph"], ["coefficients", "backup"], ["coefficients", "restore"]] {
        assert!(YOSEMITECH.run(&[nested[0], nested[1], "--help"]).ok().contains("Usage:"));
    }
    // `measure SENSOR --help` for every sensor (the help of `measure`).
    for sensor in spec().sensors.clone() {
        assert!(YOSEMITECH.run(&["measure", &sensor.name, "--help"]).ok().contains("Usage:"), "{}", sensor.name);
    }
    assert!(YOSEMITECH.run(&["--version"]).ok().starts_with("yosemitech "));
}

/// The words of a shell command line of plain words and double-quoted ones.
fn words(line: &str) -> Vec<String> {
    line.split('"')
        .enumerate()
        .flat_map(
            |(i, part)| {
                if i % 2 == 1 { vec![part.to_owned()] } else { part.split_whitespace().map(str::to_owned).collect() }
            },
        )
        .collect()
}

#[test]
fn the_help_examples_come_from_the_spec_and_work() {
    // No placeholder is left, in any help.
    for args in [&["--help"][..], &["read", "--help"], &["decode", "--help"], &["help", "decode"]] {
        let run = YOSEMITECH.run(args);
        assert!(!run.ok().contains('{'), "{args:?}:\n{}", run.stdout);
    }
    let top = YOSEMITECH.run(&["--help"]).ok().to_owned();
    assert!(spec().sensors.iter().all(|s| top.contains(&s.title)), "every sensor's title:\n{top}");
    // Every decode example that needs no file decodes, and names a read of the spec.
    let decode = YOSEMITECH.run(&["decode", "--help"]).ok().to_owned();
    let mut tried = 0;
    for line in decode.lines().chain(top.lines()).map(str::trim) {
        let Some(args) = line.strip_prefix("yosemitech decode ") else { continue };
        if args.contains("--capture") {
            continue;
        }
        let args = words(args.split("  ").next().unwrap());
        let args: Vec<&str> = ["decode"].into_iter().chain(args.iter().map(String::as_str)).collect();
        let out = YOSEMITECH.run(&args).ok().to_owned();
        let named = spec().sensors.iter().any(|s| s.measurement_reads().any(|r| out.contains(&r.name)));
        assert!(named, "{line}:\n{out}");
        tried += 1;
    }
    assert!(tried >= 3, "the examples hold decode lines:\n{decode}\n{top}");
}

#[test]
fn usage_errors_exit_2() {
    // No subcommand: the usage, on stderr.
    let run = YOSEMITECH.run(&[]);
    assert_eq!(run.code, 2);
    assert!(run.stderr.contains("Usage:"), "{}", run.stderr);
    YOSEMITECH.run(&["frobnicate"]).fails(2);
    YOSEMITECH.run(&["decode"]).fails(2);
    YOSEMITECH.run(&["poll", &spec().sensors[0].name, "--interval", "fast"]).fails(2);
}

#[test]
fn list_json_has_every_command_with_its_layout() {
    let json = YOSEMITECH.run(&["list", "--json"]).json();
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
            assert_eq!(m["serial"]["stop_bits"].as_u64(), Some(u64::from(serial.format.stop_bits.bits())));
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
        let one = YOSEMITECH.run(&["list", &sensor.name, "--json"]).json();
        assert_eq!(one["sensors"].as_array().unwrap().len(), 1);
        assert_eq!(one["sensors"][0]["name"], sensor.name.as_str());
    }
}

#[test]
fn list_shows_sensors_commands_and_fields() {
    let all = YOSEMITECH.run(&["list"]);
    let text = all.ok();
    let mut f32_units = 0;
    for sensor in spec().sensors.clone() {
        assert!(text.contains(&format!("{} — {}", sensor.name, sensor.title)), "{}", sensor.name);
        let one = YOSEMITECH.run(&["list", &sensor.name]).ok().to_owned();
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
            assert!(line.contains(&serial.to_string()), "{line}");
            if serial.format.stop_bits == yosemitech_rtu::StopBits::Two {
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
                // An f32 field: its byte order and unit too.
                if let (yosemitech_spec::FieldKind::F32 { order }, Some(unit)) = (&field.kind, &field.unit) {
                    let unit = if unit == "degC" { "°C" } else { unit }; // as the CLI shows it
                    let full = format!("{shown} {} [{unit}]", format!("{order:?}").to_lowercase());
                    assert!(one.contains(&full), "`{full}` missing:\n{one}");
                    f32_units += 1;
                }
            }
        }
    }
    assert!(f32_units > 0, "some f32 field states a unit");
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
        let run = YOSEMITECH.run(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert_eq!(run.ok().trim(), hex(true_request), "{} request", command.name);
        let args: Vec<String> = base.iter().cloned().chain(["--response".to_owned()]).chain(response_values).collect();
        let run = YOSEMITECH.run(&args.iter().map(String::as_str).collect::<Vec<_>>());
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
        let run = YOSEMITECH.run(&["decode", &hex(reply)]);
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
        let run = YOSEMITECH.run(&["decode", &hex(printed), "--json"]);
        let json = run.json();
        assert_eq!(json["command"]["name"], command.name.as_str(), "{json}");
        assert!(json["notes"][0].as_str().is_some_and(|n| n.contains("quirk")), "{json}");
    }
}

/// A reply the manuals print that several reads of the spec fit: a
/// measurement read (no role) of one f32 field with a unit, its example's
/// true reply, and the field. The first in spec order.
fn ambiguous_reply() -> (CommandSpec, Vec<u8>, String, String) {
    let spec = spec();
    let reads: Vec<&CommandSpec> = spec.sensors.iter().flat_map(|s| &s.commands).filter(|c| c.is_read()).collect();
    reads
        .iter()
        .filter(|c| c.role.is_none() && c.fixed_slave.is_none() && c.named_fields().count() == 1)
        .find_map(|c| {
            let field = c.named_fields().next()?;
            let unit = field.unit.clone()?;
            if !matches!(field.kind, yosemitech_spec::FieldKind::F32 { .. }) {
                return None;
            }
            let others = reads.iter().filter(|o| o.name != c.name && o.count == c.count).count();
            let example = c.examples.iter().find(|e| e.manual.is_none() && e.erratum.is_none())?;
            let reply = example.true_response()?.to_vec();
            let value = match example.values.get(field.display_name())? {
                Value::Float(v) => v.to_string(),
                _ => return None,
            };
            (others > 0).then(|| ((*c).clone(), reply, field.display_name().to_owned(), format!("{value} {unit}")))
        })
        .expect("a reply several reads fit")
}

#[test]
fn decode_asks_which_command_when_a_reply_is_ambiguous() {
    let (command, reply, field, shown) = ambiguous_reply();
    let frame = hex(&reply);
    let run = YOSEMITECH.run(&["decode", &frame]);
    let err = run.fails_with_hint(2);
    // Every read of the same size is a candidate.
    let spec = spec();
    let same_size: Vec<&CommandSpec> = spec
        .sensors
        .iter()
        .flat_map(|s| &s.commands)
        .filter(|c| c.is_read() && c.fixed_slave.is_none() && c.count == command.count)
        .collect();
    assert!(same_size.len() > 1);
    for candidate in same_size {
        assert!(err.contains(&candidate.name), "{} not listed:\n{err}", candidate.name);
    }
    assert!(err.contains(&format!("{field} = {shown}")), "{err}");
    assert!(err.contains("--sensor") && err.contains("--command"), "{err}");
    // Narrowing by command alone is enough.
    let run = YOSEMITECH.run(&["decode", &frame, "--command", &command.name]);
    assert!(run.ok().contains(&shown));
}

#[test]
fn decode_reports_a_wrong_crc_with_the_expected_one() {
    let (command, reply, _, shown) = ambiguous_reply();
    let sensor = spec().sensors.iter().find(|&s| s.command(&command.name).is_some()).cloned().unwrap();
    let n = reply.len();
    let right = hex(&reply[n - 2..]);
    let mut bad = reply.clone();
    bad[n - 1] = bad[n - 1].wrapping_add(1);
    let wrong = hex(&bad[n - 2..]);
    let frame = hex(&bad);
    let run = YOSEMITECH.run(&["decode", &frame, "--sensor", &sensor.name, "--command", &command.name]);
    let err = run.fails_with_hint(1);
    assert!(run.stdout.contains(&format!("{wrong} (wrong: the bytes give {right})")), "{}", run.stdout);
    assert!(run.stdout.contains(&shown), "fields still shown:\n{}", run.stdout);
    assert!(err.contains(&right));
    let run = YOSEMITECH.run(&["decode", &frame, "--command", &command.name, "--json"]);
    assert_eq!(run.code, 1);
    let json: Json = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(json["crc"], serde_json::json!({ "ok": false, "received": wrong, "expected": right }));
}

#[test]
fn decode_explains_exceptions() {
    let run = YOSEMITECH.run(&["decode", "01 83 02 C0 F1"]);
    let text = run.ok();
    assert!(text.contains("exception reply from address 1 to function 0x03"), "{text}");
    assert!(text.contains("illegal data address"), "{text}");
    let json = YOSEMITECH.run(&["decode", "01 83 02 C0 F1", "--json"]).json();
    assert_eq!(json["exception"]["code"], 2);
}

#[test]
fn decode_rejects_a_frame_that_does_not_fit_the_command() {
    let (command, reply, _, _) = ambiguous_reply();
    let frame = hex(&reply);
    // The serial-number read of the same sensor: another size.
    let sensor = spec().sensors.iter().find(|&s| s.command(&command.name).is_some()).cloned().unwrap();
    let sn = sensor.command_with_role(yosemitech_spec::Role::SerialNumber).expect("a serial-number read");
    assert_ne!(sn.count, command.count);
    let err = YOSEMITECH.run(&["decode", &frame, "--command", &sn.name]).fails_with_hint(2).to_owned();
    assert!(err.contains(&format!("does not fit `{}`", sn.name)), "{err}");
    let typo = format!("{}{}", command.name, command.name.chars().last().unwrap());
    let err = YOSEMITECH.run(&["decode", &frame, "--command", &typo]).fails_with_hint(2).to_owned();
    assert!(err.contains(&format!("did you mean `{}`", command.name)), "{err}");
}

/// `name` with its last character changed: a typo `did you mean` catches.
fn typo(name: &str) -> String {
    let last = if name.ends_with('q') { 'z' } else { 'q' };
    format!("{}{last}", &name[..name.len() - 1])
}

#[test]
fn bad_input_gets_one_error_and_a_hint() {
    // A sensor with a coefficient block of two or more fields, a
    // measurement read and the slave-address commands, from the spec.
    let spec = spec();
    let sensor = spec
        .sensors
        .iter()
        .find(|s| {
            s.command_with_role(yosemitech_spec::Role::SetSlaveAddress).is_some()
                && s.command_with_role(yosemitech_spec::Role::GetSlaveAddress).is_some_and(|c| c.fixed_slave.is_some())
                && s.commands.iter().any(|c| c.is_read() && c.role.is_none())
                && s.commands.iter().any(|w| {
                    !w.is_read()
                        && w.named_fields().count() >= 2
                        && w.named_fields().all(|f| matches!(f.kind, yosemitech_spec::FieldKind::F32 { .. }))
                })
        })
        .expect("a sensor with coefficients, a measurement and the address commands");
    let name = sensor.name.as_str();
    let read = sensor.commands.iter().find(|c| c.is_read() && c.role.is_none()).unwrap().name.as_str();
    let write = sensor
        .commands
        .iter()
        .find(|w| {
            !w.is_read()
                && w.named_fields().count() >= 2
                && w.named_fields().all(|f| matches!(f.kind, yosemitech_spec::FieldKind::F32 { .. }))
        })
        .unwrap();
    let fields: Vec<&str> = write.named_fields().map(|f| f.display_name()).collect();
    let set_id = sensor.command_with_role(yosemitech_spec::Role::SetSlaveAddress).unwrap();
    let address_field = set_id.named_fields().next().unwrap().display_name();
    let get_id = sensor.command_with_role(yosemitech_spec::Role::GetSlaveAddress).unwrap();
    let fixed = format!("0x{:02X}", get_id.fixed_slave.unwrap());
    // A write of the spec with a range, given a value beyond it.
    let (ranged_sensor, ranged, beyond) = spec
        .sensors
        .iter()
        .flat_map(|s| s.commands.iter().map(move |c| (s, c)))
        .find_map(|(s, c)| {
            let mut named = c.named_fields();
            let (only, none) = (named.next()?, named.next());
            let (_, max) = only.range?;
            (!c.is_read() && none.is_none()).then(|| (s.name.as_str(), c.name.as_str(), (max + 1.0).to_string()))
        })
        .expect("a write with a stated range");
    let first = format!("{}=1", fields[0]);
    let dropped = {
        let mid = address_field.len() / 2;
        format!("{}{}=3", &address_field[..mid], &address_field[mid + 1..])
    };
    let owned: Vec<(Vec<String>, i32, String)> = vec![
        (
            vec!["read".into(), typo(name), read.into(), "--port".into(), "/dev/null".into()],
            2,
            format!("did you mean `{name}`"),
        ),
        (
            vec!["read".into(), name.into(), typo(read), "--port".into(), "/dev/null".into()],
            2,
            format!("did you mean `{read}`"),
        ),
        (vec!["read".into(), name.into(), read.into()], 2, "no port given".into()),
        (
            vec!["read".into(), name.into(), read.into(), "--port".into(), "/dev/yosemitech-no-such-port".into()],
            1,
            "not found".into(),
        ),
        (
            vec![
                "read".into(),
                name.into(),
                read.into(),
                "--port".into(),
                "/dev/null".into(),
                "--address".into(),
                "0".into(),
            ],
            2,
            "outside 1..=247".into(),
        ),
        (
            vec![
                "read".into(),
                name.into(),
                read.into(),
                "--port".into(),
                "/dev/null".into(),
                "--address".into(),
                "248".into(),
            ],
            2,
            "outside 1..=247".into(),
        ),
        (
            vec!["read".into(), name.into(), write.name.clone(), "--port".into(), "/dev/null".into()],
            2,
            "write command".into(),
        ),
        (vec!["write".into(), name.into(), read.into(), "--port".into(), "/dev/null".into()], 2, "read command".into()),
        (
            vec![
                "write".into(),
                ranged_sensor.into(),
                ranged.into(),
                beyond,
                "--port".into(),
                "/dev/null".into(),
                "--yes".into(),
            ],
            2,
            "outside the valid range".into(),
        ),
        (
            vec!["write".into(), name.into(), write.name.clone(), first, "--port".into(), "/dev/null".into()],
            2,
            format!("no value for `{}`", fields[1]),
        ),
        (
            vec![
                "write".into(),
                name.into(),
                write.name.clone(),
                "1".into(),
                "x".into(),
                "--port".into(),
                "/dev/null".into(),
            ],
            2,
            "not a number".into(),
        ),
        (
            vec![
                "write".into(),
                name.into(),
                write.name.clone(),
                "1".into(),
                "0".into(),
                "--port".into(),
                "/dev/null".into(),
            ],
            2,
            "stdin is not a terminal".into(),
        ),
        (
            vec!["encode".into(), name.into(), set_id.name.clone(), "0".into()],
            2,
            "outside the valid range 1..=247".into(),
        ),
        (
            vec!["encode".into(), name.into(), set_id.name.clone(), "248".into()],
            2,
            "outside the valid range 1..=247".into(),
        ),
        (
            vec!["encode".into(), name.into(), set_id.name.clone(), dropped],
            2,
            format!("did you mean `{address_field}`"),
        ),
        (vec!["encode".into(), name.into(), read.into(), "7.6".into()], 2, "carries no values".into()),
        (vec!["encode".into(), name.into(), get_id.name.clone(), "--address".into(), "3".into()], 2, fixed),
        (vec!["simulate".into(), name.into(), "--faults".into(), "dorp=0.1".into()], 2, "did you mean `drop`".into()),
        (
            vec![
                "coefficients".into(),
                "restore".into(),
                name.into(),
                "--port".into(),
                "/dev/null".into(),
                "--file".into(),
                "/nonexistent.json".into(),
            ],
            2,
            "cannot read".into(),
        ),
    ];
    let fixed_cases: &[(&[&str], i32, &str)] = &[
        (&["decode", "01 03 0"], 2, "odd number"),
        (&["decode", "01 03 zz"], 2, "not a hex digit"),
        (&["decode", "0103"], 2, "too short"),
        (&["decode", "01 2B 0E 01 00 70 77"], 1, "function 0x2B"),
        (&["set-address", "--port", "/dev/null", "--from", "0", "--to", "5"], 2, "--from 0 is outside 1..=247"),
        (&["set-address", "--port", "/dev/null", "--from", "1", "--to", "248"], 2, "--to 248 is outside 1..=247"),
        (&["scan", "--port", "/dev/null", "--addresses", "0-3"], 2, "outside 1..=247"),
        (&["scan", "--port", "/dev/null", "--addresses", "a-b"], 2, "not an address"),
        (&["list", "nonexistent_sensor"], 2, "unknown sensor"),
        (&["list", "--spec", "/nonexistent/spec/dir"], 2, "no such file"),
    ];
    let owned: Vec<(Vec<&str>, i32, &str)> =
        owned.iter().map(|(a, c, n)| (a.iter().map(String::as_str).collect(), *c, n.as_str())).collect();
    let cases = fixed_cases.iter().map(|(a, c, n)| (a.to_vec(), *c, *n)).chain(owned);
    for (args, code, needle) in cases {
        let run = YOSEMITECH.run(&args);
        let err = run.fails_with_hint(code);
        assert!(err.starts_with("error: "), "{args:?}: stderr starts with the error:\n{err}");
        assert!(err.contains(needle), "{args:?}: `{needle}` not in:\n{err}");
        assert_eq!(err.lines().filter(|l| l.starts_with("error:")).count(), 1, "{args:?}: one error line:\n{err}");
    }
}

#[test]
fn a_spec_error_is_reported_with_its_position() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("broken.yaml"), "sensor:\n  name: Broken Name\n").unwrap();
    let run = YOSEMITECH.run(&["list", "--spec", dir.path().to_str().unwrap()]);
    let err = run.fails_with_hint(2);
    assert!(err.contains("broken.yaml:"), "{err}");
}

#[test]
fn spec_files_load_at_run_time_with_the_shared_commands_built_in() {
    // A new sensor in a directory of its own: its include of
    // yosemitech-common.yaml falls back to the built-in copy.
    // The shared fragment's serial-number read, picked by role.
    let built_in = yosemitech_tests::spec();
    let serial = built_in
        .fragments
        .iter()
        .flat_map(|f| &f.commands)
        .find(|c| c.role == Some(yosemitech_spec::Role::SerialNumber))
        .expect("a shared serial-number read");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("test-probe.yaml"),
        r#"sensor:
  name: test_probe
  title: Level probe (test)
  doc: A made-up probe for the CLI's --spec test.
  manual: {title: Test manual, revision: "1.0"}
  serial: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1}
  addresses: {min: 1, max: 247}
  default_address: 1
include:
  - yosemitech-common.yaml
commands:
  - use: SERIAL
  - name: read_level
    title: Read Level
    doc: Level.
    function: read
    address: 0x2600
    count: 2
    fields:
      - {name: level_ntu, type: f32, byte_order: dcba, unit: NTU, doc: Level.}
    examples:
      - figures: []
        request: "01 03 26 00 00 02 CF 43"
        response: "01 03 04 00 00 20 41 23 C3"
        values: {level_ntu: 10.0}
"#
        .replace("SERIAL", &serial.name),
    )
    .unwrap();
    let spec = dir.path().to_str().unwrap();
    let json = YOSEMITECH.run(&["--spec", spec, "list", "--json"]).json();
    let names: Vec<&str> = json["sensors"].as_array().unwrap().iter().filter_map(|s| s["name"].as_str()).collect();
    let want: Vec<&str> = built_in.sensors.iter().map(|s| s.name.as_str()).chain(["test_probe"]).collect();
    assert_eq!(names, want, "the built-in sensors, then the --spec one");
    let listed = YOSEMITECH.run(&["list", "test_probe", "--json", "--spec", spec]).json();
    let commands: Vec<&str> =
        listed["sensors"][0]["commands"].as_array().unwrap().iter().filter_map(|c| c["name"].as_str()).collect();
    assert!(commands.contains(&serial.name.as_str()) && commands.contains(&"read_level"), "{commands:?}");
    let run = YOSEMITECH.run(&[
        "decode",
        "01 03 04 00 00 20 41 23 C3",
        "--spec",
        spec,
        "--sensor",
        "test_probe",
        "--command",
        "read_level",
    ]);
    assert!(run.ok().contains("10 NTU"), "{}", run.stdout);
    let run = YOSEMITECH.run(&["encode", "test_probe", "read_level", "--spec", spec]);
    assert_eq!(run.ok().trim(), "01 03 26 00 00 02 CF 43");
}

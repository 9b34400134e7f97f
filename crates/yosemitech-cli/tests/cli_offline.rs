//! The `yosemitech` binary without a device: help, list, decode, encode, and
//! bad input. Every frame the manuals print goes through `decode --json` and
//! `encode` and must give the manuals' stated values and bytes.

use yosemitech_tests::cli::Binary;
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));
use serde_json::Value as Json;
use yosemitech_spec::{CommandSpec, Example, FieldKind, Role, Sensor, Value};

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
        assert_eq!(manuals.len(), sensor.manuals().count(), "{}", sensor.name);
        assert_eq!(s["manual"].is_null(), sensor.manual.is_none(), "{}", sensor.name);
        // Where the facts come from without a manual, and the models that share the commands.
        let sources: Vec<&str> = s["provenance"]["sources"]
            .as_array()
            .map_or_else(Vec::new, |a| a.iter().filter_map(|v| v.as_str()).collect());
        let want: Vec<&str> = sensor.provenance.iter().flat_map(|p| p.sources.iter().map(String::as_str)).collect();
        assert_eq!(sources, want, "{}", sensor.name);
        let aliases: Vec<&str> =
            s["aliases"].as_array().expect("aliases").iter().filter_map(|a| a["model"].as_str()).collect();
        let want: Vec<&str> = sensor.aliases.iter().map(|a| a.model.as_str()).collect();
        assert_eq!(aliases, want, "{}", sensor.name);
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
        // A model name, in any case, names the sensor where no other sensor answers to it.
        let models = sensor.model.iter().chain(sensor.aliases.iter().map(|a| &a.model));
        for model in models {
            let sharing: Vec<&str> =
                spec.sensors.iter().filter(|s| s.answers_to(model)).map(|s| s.name.as_str()).collect();
            let lower = model.to_lowercase();
            let run = YOSEMITECH.run(&["list", &lower, "--json"]);
            if sharing.len() == 1 {
                assert_eq!(run.json()["sensors"][0]["name"], sensor.name.as_str(), "list {lower}");
            } else {
                let err = run.fails_with_hint(2);
                for name in &sharing {
                    assert!(err.contains(name), "list {lower} names every sensor of the model: {err}");
                }
            }
        }
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
                if let (FieldKind::F32 { order }, Some(unit)) = (&field.kind, &field.unit) {
                    let unit = yosemitech_cli::shown_unit(unit);
                    let full = format!("{shown} {} [{unit}]", format!("{order:?}").to_lowercase());
                    assert!(one.contains(&full), "`{full}` missing:\n{one}");
                    f32_units += 1;
                }
            }
        }
    }
    report!("list: {} sensors, {f32_units} f32 fields with their byte order and unit", spec().sensors.len());
}

#[test]
fn decode_json_of_every_manual_reply_gives_the_stated_values() {
    if !yosemitech_tests::slow::enabled("decode --json of every manual reply, a process each (20-30 s)") {
        return;
    }
    let mut decoded = 0;
    for (sensor, command, example) in examples() {
        let Some(reply) = example.true_response() else { continue };
        let mut frames = vec![reply.to_vec()];
        if example.erratum.as_ref().is_some_and(|e| e.printed_decodes && e.corrected_response.is_some())
            && let Some(printed) = example.response.as_ref().and_then(|f| f.complete.clone())
        {
            frames.push(printed);
        }
        for frame in frames {
            decoded += 1;
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
    report!("decode --json: {decoded} manual replies gave the stated values");
}

#[test]
fn decode_json_of_every_manual_request_gives_the_stated_values() {
    if !yosemitech_tests::slow::enabled("decode --json of every manual request, a process each (about 20 s)") {
        return;
    }
    let mut decoded = 0;
    for (sensor, command, example) in examples() {
        let Some(request) = example.true_request() else { continue };
        decoded += 1;
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
    report!("decode --json: {decoded} manual requests gave the stated values");
}

#[test]
fn encode_reproduces_every_manual_frame() {
    if !yosemitech_tests::slow::enabled("encode of every manual frame, a process each (about 2 minutes)") {
        return;
    }
    let (mut requests, mut replies) = (0, 0);
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
        requests += 1;
        let args: Vec<String> = base.iter().cloned().chain(["--response".to_owned()]).chain(response_values).collect();
        let run = YOSEMITECH.run(&args.iter().map(String::as_str).collect::<Vec<_>>());
        if command.trigger {
            // The simulator's (the manuals') form; the example may show another accepted one.
            continue;
        }
        assert_eq!(run.ok().trim(), hex(true_response), "{} reply", command.name);
        replies += 1;
    }
    report!("encode: {requests} manual requests and {replies} replies reproduced");
}

/// A read's candidates as `decode` offers them for a reply on its own: the
/// sensors that have the command, and the command.
type Candidate = (Vec<String>, CommandSpec);

/// The commands `decode` takes a read reply for without --sensor and
/// --command: every read of the spec to and from the reply's slave (a
/// fixed slave address only, else 1..=247) whose reply is that long (a
/// trigger's short reply too), a command that a fragment shares between
/// sensors counted once, with all of them.
fn read_reply_candidates(reply: &[u8]) -> Vec<Candidate> {
    let slave = reply[0];
    let fits_slave = |c: &CommandSpec| c.fixed_slave.map_or((1..=247).contains(&slave), |f| f == slave);
    let mut out: Vec<Candidate> = Vec::new();
    for sensor in &spec().sensors {
        for c in sensor.commands.iter().filter(|c| c.is_read() && fits_slave(c)) {
            let layout = c.layout();
            if layout.response_len() != reply.len() && layout.short_response_len() != Some(reply.len()) {
                continue;
            }
            let shared = out.iter_mut().find(|(_, k)| {
                k.name == c.name && k.shared_from.is_some() && k.shared_from == c.shared_from && k.layout() == layout
            });
            match shared {
                Some((sensors, _)) => sensors.push(sensor.name.clone()),
                None => out.push((vec![sensor.name.clone()], c.clone())),
            }
        }
    }
    out
}

/// How `decode` labels a candidate: `sensor/sensor command`.
fn label((sensors, command): &Candidate) -> String {
    format!("{} {}", sensors.join("/"), command.name)
}

/// Checks what `decode FRAME` says of a read reply: the one command it
/// fits, named; or the question which, with every candidate. True when it
/// was named alone.
#[track_caller]
fn check_alone_or_asked(reply: &[u8]) -> bool {
    let candidates = read_reply_candidates(reply);
    let run = YOSEMITECH.run(&["decode", &hex(reply)]);
    if let [one] = candidates.as_slice() {
        let text = run.ok();
        assert!(text.contains(&format!("command     {}:", label(one))), "{}:\n{text}", hex(reply));
        assert!(text.contains("(ok)"), "{text}");
        return true;
    }
    let err = run.fails_with_hint(2);
    let asked = format!("fits {} commands", candidates.len());
    assert!(err.contains(&asked), "{}: `{asked}` not in\n{err}", hex(reply));
    assert!(err.contains("decode REQUEST REPLY"), "the hint names what tells them apart:\n{err}");
    for c in &candidates {
        let listed = format!("{} (0x{:04X}, ", label(c), c.1.address);
        assert!(err.contains(&listed), "{}: `{listed}` not listed:\n{err}", hex(reply));
    }
    // The same reply damaged on the line: the CRC is what is wrong, not the
    // choice of command.
    let mut damaged = reply.to_vec();
    if let Some(last) = damaged.last_mut() {
        *last ^= 0x01;
    }
    let run = YOSEMITECH.run(&["decode", &hex(&damaged)]);
    let err = run.fails_with_hint(1);
    let first = err.lines().next().unwrap_or_default();
    assert!(first.starts_with("error: the CRC is wrong"), "{}: {err}", hex(&damaged));
    false
}

#[test]
fn decode_identifies_unambiguous_frames_on_its_own() {
    // Every complete example reply of a read: where one command of the
    // spec fits it, decode names that command without --sensor/--command;
    // where several do, it asks which, naming them all.
    let (mut frames, mut alone, mut asked) = (0, 0, 0);
    for (sensor, command, example) in examples() {
        let Some(reply) = example.true_response() else { continue };
        if !command.is_read() {
            continue;
        }
        let candidates = read_reply_candidates(reply);
        assert!(
            candidates.iter().any(|(s, c)| c.name == command.name && s.contains(&sensor.name)),
            "{} {}: its own reply fits it",
            sensor.name,
            command.name
        );
        frames += 1;
        if check_alone_or_asked(reply) {
            alone += 1;
        } else {
            asked += 1;
        }
    }
    assert_eq!(alone + asked, frames, "every frame was checked");
    // A printed frame the spec accepts as a documented firmware quirk
    // decodes with a note, once the command is known.
    let mut quirks = 0;
    for (sensor, command, example) in examples() {
        let Some(err) = &example.erratum else { continue };
        let Some(printed) = example.response.as_ref().and_then(|f| f.complete.as_ref()) else { continue };
        if !err.printed_decodes || err.corrected_response.is_none() {
            continue;
        }
        let alone = read_reply_candidates(printed).len() == 1;
        let mut args = vec!["decode".to_owned(), hex(printed), "--json".to_owned()];
        if !alone {
            args.extend(["--sensor".to_owned(), sensor.name.clone(), "--command".to_owned(), command.name.clone()]);
        }
        let json = YOSEMITECH.run(&args.iter().map(String::as_str).collect::<Vec<_>>()).json();
        assert_eq!(json["command"]["name"], command.name.as_str(), "{json}");
        assert!(json["notes"][0].as_str().is_some_and(|n| n.contains("quirk")), "{json}");
        quirks += 1;
    }
    report!("decode: {frames} replies, {alone} named alone, {asked} fit several commands; {quirks} printed quirks");
}

/// A reply the manuals print that several reads of the spec fit: a
/// measurement read (no role) of one f32 field with a unit, its example's
/// true reply, the field, and the field's value as the CLI shows it.
fn ambiguous_reply() -> Option<(Sensor, CommandSpec, Vec<u8>, String, String)> {
    let found = spec().sensors.iter().find_map(|sensor| {
        sensor.commands.iter().filter(|c| c.role.is_none() && c.fixed_slave.is_none() && c.is_read()).find_map(|c| {
            let mut named = c.named_fields();
            let (Some(field), None) = (named.next(), named.next()) else { return None };
            let unit = field.unit.clone()?;
            if !matches!(field.kind, FieldKind::F32 { .. }) {
                return None;
            }
            let example = c.examples.iter().find(|e| e.manual.is_none() && e.erratum.is_none())?;
            let reply = example.true_response()?.to_vec();
            let Value::Float(value) = example.values.get(field.display_name())? else { return None };
            let shown = format!("{value} {}", yosemitech_cli::shown_unit(&unit));
            (read_reply_candidates(&reply).len() > 1)
                .then(|| (sensor.clone(), c.clone(), reply, field.display_name().to_owned(), shown))
        })
    });
    if found.is_none() {
        report!("no reply of a one-field measurement read fits several reads of the spec: no ambiguity to resolve");
    }
    found
}

/// The arguments that pick `command` of `sensor` for a reply: `--command`
/// alone where no other candidate has its name, else with `--sensor`.
fn narrowing(sensor: &Sensor, command: &CommandSpec, reply: &[u8]) -> Vec<String> {
    let named = read_reply_candidates(reply).into_iter().filter(|(_, c)| c.name == command.name).count();
    let mut args = vec!["--command".to_owned(), command.name.clone()];
    if named > 1 {
        args.extend(["--sensor".to_owned(), sensor.name.clone()]);
    }
    args
}

#[test]
fn decode_asks_which_command_when_a_reply_is_ambiguous() {
    let Some((sensor, command, reply, field, shown)) = ambiguous_reply() else { return };
    let frame = hex(&reply);
    assert!(!check_alone_or_asked(&reply), "several commands fit {frame}");
    let err = YOSEMITECH.run(&["decode", &frame]).fails_with_hint(2).to_owned();
    assert!(err.contains(&format!("{field} = {shown}")), "{err}");
    assert!(err.contains("--sensor") && err.contains("--command"), "{err}");
    // Naming the command is enough, with the sensor where others have a command of that name.
    let mut args = vec!["decode".to_owned(), frame];
    args.extend(narrowing(&sensor, &command, &reply));
    let run = YOSEMITECH.run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(run.ok().contains(&shown), "{}", run.stdout);
}

#[test]
fn decode_reports_a_wrong_crc_with_the_expected_one() {
    let Some((sensor, command, reply, _, shown)) = ambiguous_reply() else { return };
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
    let mut args = vec!["decode".to_owned(), frame, "--json".to_owned()];
    args.extend(narrowing(&sensor, &command, &reply));
    let run = YOSEMITECH.run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(run.code, 1, "{}", run.stderr);
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
    // A reply the manuals print of a read at the probe's own address.
    let found = examples().into_iter().find_map(|(_, c, e)| {
        (c.is_read() && !c.trigger && c.fixed_slave.is_none())
            .then(|| e.true_response().map(|r| (c.clone(), r.to_vec())))?
    });
    let Some((command, reply)) = found else {
        report!("no read of the spec has an example reply: nothing to refuse");
        return;
    };
    let frame = hex(&reply);
    // A read whose every command of that name has replies of another length.
    let lengths = |c: &CommandSpec| [Some(c.layout().response_len()), c.layout().short_response_len()];
    let other = spec().sensors.iter().flat_map(|s| &s.commands).filter(|c| c.is_read()).find(|c| {
        spec()
            .sensors
            .iter()
            .flat_map(|s| &s.commands)
            .filter(|o| o.name == c.name)
            .all(|o| !lengths(o).contains(&Some(reply.len())))
    });
    match other {
        Some(other) => {
            let err = YOSEMITECH.run(&["decode", &frame, "--command", &other.name]).fails_with_hint(2).to_owned();
            assert!(err.contains(&format!("does not fit `{}`", other.name)), "{err}");
        }
        None => report!("every read of the spec has replies of {} bytes: none refuses {frame}", reply.len()),
    }
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
    // Each kind of mistake with commands of the spec picked by shape and
    // role: any sensor that has one. A kind the spec has no command for is
    // reported, not tried.
    let spec = spec();
    let commands = || spec.sensors.iter().flat_map(|s| s.commands.iter().map(move |c| (s, c)));
    let words = |a: &[&str]| a.iter().map(|w| (*w).to_owned()).collect::<Vec<String>>();
    let mut owned: Vec<(Vec<String>, i32, String)> = Vec::new();
    let mut untried: Vec<&str> = Vec::new();

    // A read at the probe's own address: names, port and address mistakes.
    match commands().find(|(_, c)| c.is_read() && c.fixed_slave.is_none()) {
        Some((sensor, read)) => {
            let (name, read) = (sensor.name.as_str(), read.name.as_str());
            let null = ["--port", "/dev/null"];
            owned.extend(
                [
                    ([&["read", &typo(name), read][..], &null].concat(), 2, format!("did you mean `{name}`")),
                    ([&["read", name, &typo(read)][..], &null].concat(), 2, format!("did you mean `{read}`")),
                    (vec!["read", name, read], 2, "no port given".into()),
                    ([&["read", name][..], &null].concat(), 2, format!("say which read of `{name}`: ")),
                    (vec!["read", name, read, "--port", "/dev/yosemitech-no-such-port"], 1, "not found".into()),
                    ([&["read", name, read][..], &null, &["--address", "0"]].concat(), 2, "outside 1 to 247".into()),
                    ([&["read", name, read][..], &null, &["--address", "248"]].concat(), 2, "outside 1 to 247".into()),
                    ([&["write", name, read][..], &null].concat(), 2, "read command".into()),
                    (vec!["encode", name, read, "7.6"], 2, "carries no values".into()),
                    (vec!["simulate", name, "--faults", "dorp=0.1"], 2, "did you mean `drop`".into()),
                ]
                .map(|(a, c, n)| (words(&a), c, n)),
            );
        }
        None => untried.push("a read"),
    }
    // A write of values: a read of it, a value missing, a value that is no
    // number, and all its values without a terminal to confirm on.
    let numeric = |k: &FieldKind| match k {
        FieldKind::F32 { .. } => Some("not a number"),
        FieldKind::U8 | FieldKind::I8 | FieldKind::U16 { .. } | FieldKind::I16 { .. } => Some("not a whole number"),
        FieldKind::U32 { .. } | FieldKind::I32 { .. } => Some("not a whole number"),
        _ => None,
    };
    // The write of most fields (the first of them), for a value left out.
    let write = commands()
        .filter(|(_, c)| {
            !c.is_read()
                && c.fixed_slave.is_none()
                && c.named_fields().next().is_some_and(|f| numeric(&f.kind).is_some())
        })
        .min_by_key(|(_, c)| std::cmp::Reverse(c.named_fields().count()));
    match write {
        Some((sensor, write)) => {
            let (name, command) = (sensor.name.as_str(), write.name.as_str());
            let fields: Vec<&yosemitech_spec::Field> = write.named_fields().collect();
            let values = yosemitech_tests::values::sample_values(write);
            let given: Vec<String> = fields.iter().map(|f| arg(&values[f.display_name()])).collect();
            let null = ["--port", "/dev/null"].map(String::from);
            owned.push((words(&["read", name, command, "--port", "/dev/null"]), 2, "write command".into()));
            let not_a_number = numeric(&fields[0].kind).unwrap();
            owned.push(([words(&["write", name, command, "x"]), null.to_vec()].concat(), 2, not_a_number.into()));
            let all = [words(&["write", name, command]), given.clone(), null.to_vec()].concat();
            owned.push((all, 2, "stdin is not a terminal".into()));
            if let [first, second, ..] = fields.as_slice() {
                let one = format!("{}={}", first.display_name(), given[0]);
                let args = [words(&["write", name, command]), vec![one], null.to_vec()].concat();
                owned.push((args, 2, format!("no value for `{}`", second.display_name())));
            } else {
                untried.push("a write of two fields or more");
            }
        }
        None => untried.push("a write of a number"),
    }
    // The address write: a new address outside its field's range, a field name misspelt.
    let set = spec.sensors.iter().find_map(|s| s.command_with_role(Role::SetSlaveAddress).map(|c| (s, c)));
    match set.and_then(|(s, c)| c.named_fields().next().map(|f| (s, c, f))) {
        Some((sensor, set, field)) => {
            let (name, command, field_name) = (sensor.name.as_str(), set.name.as_str(), field.display_name());
            if let Some((min, max)) = field.range {
                let range = format!("outside the valid range {min} to {max}");
                for beyond in [min - 1.0, max + 1.0].into_iter().filter(|v| *v >= 0.0) {
                    owned.push((words(&["encode", name, command, &beyond.to_string()]), 2, range.clone()));
                }
            }
            let mid = field_name.len() / 2;
            let dropped = format!("{}{}=3", &field_name[..mid], &field_name[mid + 1..]);
            owned.push((words(&["encode", name, command, &dropped]), 2, format!("did you mean `{field_name}`")));
        }
        None => untried.push("an address write"),
    }
    // A read at a fixed address, given another.
    match commands().find(|(_, c)| c.is_read() && c.fixed_slave.is_some()) {
        Some((sensor, get)) => {
            let fixed = get.fixed_slave.unwrap();
            let other = if fixed == 3 { "4" } else { "3" };
            let args = words(&["encode", &sensor.name, &get.name, "--address", other]);
            owned.push((args, 2, format!("0x{fixed:02X}")));
        }
        None => untried.push("a read at a fixed address"),
    }
    // A write of one field with a range, given a value beyond it.
    let ranged = commands().find_map(|(s, c)| {
        let mut named = c.named_fields();
        let (only, none) = (named.next()?, named.next());
        let (_, max) = only.range?;
        (!c.is_read() && none.is_none()).then(|| (s.name.as_str(), c.name.as_str(), (max + 1.0).to_string()))
    });
    match ranged {
        Some((sensor, command, beyond)) => {
            let args = words(&["write", sensor, command, &beyond, "--port", "/dev/null", "--yes"]);
            owned.push((args, 2, "outside the valid range".into()));
        }
        None => untried.push("a write of one field with a range"),
    }
    // A restore from a file that is not there.
    match yosemitech_tests::cli::sensors_with_coefficients().first() {
        Some(sensor) => {
            let args = ["coefficients", "restore", &sensor.name, "--port", "/dev/null", "--file", "/nonexistent.json"];
            owned.push((words(&args), 2, "cannot read".into()));
        }
        None => untried.push("a sensor with coefficients"),
    }
    let fixed_cases: &[(&[&str], i32, &str)] = &[
        (&["decode", "01 03 0"], 2, "odd number"),
        (&["decode", "01 03 zz"], 2, "not a hex digit"),
        (&["decode", "0103"], 2, "too short"),
        (&["decode", "-"], 2, "use `--capture -`"),
        (&["export", "--db", "/nonexistent/station.sqlite"], 2, "no station store at /nonexistent/station.sqlite"),
        (&["plot", "--db", "/nonexistent/station.sqlite", "--out", "/nonexistent/day.png"], 2, "no station store at"),
        (&["decode", "01 2B 0E 01 00 70 77"], 1, "function 0x2B"),
        (&["set-address", "--port", "/dev/null", "--from", "0", "--to", "5"], 2, "--from 0 is outside 1 to 247"),
        (&["set-address", "--port", "/dev/null", "--from", "1", "--to", "248"], 2, "--to 248 is outside 1 to 247"),
        (&["scan", "--port", "/dev/null", "--addresses", "0-3"], 2, "outside 1 to 247"),
        (&["scan", "--port", "/dev/null", "--addresses", "a-b"], 2, "not an address"),
        (&["list", "nonexistent_sensor"], 2, "unknown sensor"),
        (&["list", "--spec", "/nonexistent/spec/dir"], 2, "no such file"),
    ];
    let owned: Vec<(Vec<&str>, i32, &str)> =
        owned.iter().map(|(a, c, n)| (a.iter().map(String::as_str).collect(), *c, n.as_str())).collect();
    let cases: Vec<_> = fixed_cases.iter().map(|(a, c, n)| (a.to_vec(), *c, *n)).chain(owned).collect();
    for (args, code, needle) in &cases {
        let run = YOSEMITECH.run(args);
        let err = run.fails_with_hint(*code);
        assert!(err.starts_with("error: "), "{args:?}: stderr starts with the error:\n{err}");
        assert!(err.contains(needle), "{args:?}: `{needle}` not in:\n{err}");
        assert_eq!(err.lines().filter(|l| l.starts_with("error:")).count(), 1, "{args:?}: one error line:\n{err}");
    }
    let untried = if untried.is_empty() { "none".to_owned() } else { untried.join(", ") };
    report!("bad input: {} cases tried; not tried, for want of such a command in the spec: {untried}", cases.len());
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

#[test]
fn the_readmes_offline_decode_examples_succeed() {
    // What a technician copies from the README first: every `decode` of
    // frames given on the line (no file, no port) must decode and exit 0.
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../README.md")).expect("README.md");
    let mut ran = 0;
    for line in readme.lines().filter(|l| l.starts_with("yosemitech decode ")) {
        // The command, without its `# comment`.
        let words = words(line.split(" #").next().unwrap_or(line));
        if words.iter().any(|w| w.starts_with("--capture")) {
            continue;
        }
        let args: Vec<&str> = words.iter().skip(1).map(String::as_str).collect();
        let text = YOSEMITECH.run(&args).ok().to_owned();
        assert!(text.contains("command "), "`{line}` names no command:\n{text}");
        ran += 1;
    }
    assert!(ran > 0, "the README shows no offline decode");
}

#[test]
fn only_the_subcommands_that_open_a_port_take_its_timeout_and_retries() {
    // Every subcommand `--help` lists.
    let top = YOSEMITECH.run(&["--help"]).ok().to_owned();
    let subcommands: Vec<&str> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|s| *s != "help")
        .collect();
    let (mut checked, mut with_client) = (0, 0);
    for sub in subcommands {
        let help = YOSEMITECH.run(&[sub, "--help"]).ok().to_owned();
        // The client's options come together, and only with a port (a
        // listener, `sniff`, opens one without sending: it takes neither).
        let opens_a_port = help.contains("--port");
        let (timeout, retries) = (help.contains("--timeout "), help.contains("--retries "));
        assert_eq!(timeout, retries, "`{sub} --help`: --timeout and --retries go together:\n{help}");
        assert!(!timeout || opens_a_port, "`{sub} --help` takes the client's options without a port:\n{help}");
        with_client += usize::from(timeout);
        checked += 1;
    }
    assert!(checked > 0, "no subcommand in:\n{top}");
    assert!(with_client > 0, "no subcommand takes the client's options");
}

#[test]
fn a_bad_baud_rate_from_the_environment_names_the_variable() {
    let Some(sensor) = spec().sensors.first().cloned() else { return };
    let Some(read) = sensor.measurement_reads().next() else { return };
    let out = std::process::Command::new(YOSEMITECH.0)
        .args(["read", &sensor.name, &read.name, "--port", "/dev/null"])
        .env("YOSEMITECH_BAUD", "fast")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: YOSEMITECH_BAUD=\"fast\""), "{err}");
    // Given on the command line, the option is what is wrong.
    let out = std::process::Command::new(YOSEMITECH.0)
        .args(["read", &sensor.name, &read.name, "--port", "/dev/null", "--baud", "fast"])
        .env("YOSEMITECH_BAUD", "9600")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("'--baud <BAUD>'") && !err.contains("YOSEMITECH_BAUD"), "{err}");
}

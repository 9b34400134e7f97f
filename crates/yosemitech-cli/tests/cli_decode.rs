//! `yosemitech decode` on several frames: a request with its reply, hex
//! streams and capture files. Every frame comes from the spec's own examples
//! (or is built from the spec's commands), so the tests follow the spec as
//! sensors are added: nothing here names a frame or counts examples.

use std::collections::BTreeMap;
use std::path::Path;

use yosemitech_tests::cli::{Binary, Run};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));
use serde_json::Value as Json;
use yosemitech_rtu::crc_ok;
use yosemitech_spec::{CommandSpec, Example, Spec};

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

/// A frame's bytes as the model serialises them: an array of bytes, or a
/// printed frame whose `complete` is one. `None` when absent or when not
/// every byte is known. (Read through serde so that the test does not
/// depend on how the model spells a partial frame.)
fn bytes_of(v: &Json) -> Option<Vec<u8>> {
    match v {
        Json::Array(items) => items.iter().map(|b| b.as_u64().and_then(|b| u8::try_from(b).ok())).collect(),
        Json::Object(o) => o.get("complete").and_then(bytes_of),
        _ => None,
    }
}

/// A copy of `frame` with its CRC recomputed.
fn with_crc(frame: Vec<u8>) -> Vec<u8> {
    yosemitech_tests::with_crc(&frame[..frame.len().saturating_sub(2)])
}

/// A request and its reply as a bus carries them.
#[derive(Debug, Clone)]
struct Pair {
    sensor: String,
    command: String,
    request: Vec<u8>,
    reply: Vec<u8>,
    /// The values the manual states, as JSON.
    values: BTreeMap<String, Json>,
}

impl Pair {
    fn is_exception(&self) -> bool {
        self.reply.get(1).is_some_and(|f| f & 0x80 != 0)
    }

    fn what(&self) -> String {
        format!("{} {} ({} / {})", self.sensor, self.command, hex(&self.request), hex(&self.reply))
    }
}

/// The example's true request and reply, when both are complete frames whose
/// CRC checks and the request is the command's: examples with a frame absent,
/// partial or open-ended are skipped.
fn true_pair(sensor: &str, command: &CommandSpec, example: &Example) -> Option<Pair> {
    let v = serde_json::to_value(example).ok()?;
    let pick = |corrected: &str, printed: &str| bytes_of(&v["erratum"][corrected]).or_else(|| bytes_of(&v[printed]));
    let request = pick("corrected_request", "request")?;
    let reply = pick("corrected_response", "response")?;
    let complete = |f: &[u8]| f.len() >= 5 && crc_ok(f);
    if !(complete(&request) && complete(&reply) && request.len() == command.layout().request_len()) {
        return None;
    }
    let values = match &v["values"] {
        Json::Object(values) => values.iter().map(|(k, v)| (k.clone(), v.clone())).collect(),
        _ => BTreeMap::new(),
    };
    Some(Pair { sensor: sensor.to_owned(), command: command.name.clone(), request, reply, values })
}

/// Every example of every sensor that is a complete pair.
fn pairs(spec: &Spec) -> Vec<Pair> {
    let mut out = Vec::new();
    for sensor in &spec.sensors {
        for command in &sensor.commands {
            out.extend(command.examples.iter().filter_map(|e| true_pair(&sensor.name, command, e)));
        }
    }
    out
}

/// [`pairs`], or `None` (said) when the spec's examples hold no complete pair.
fn some_pairs(spec: &Spec) -> Option<Vec<Pair>> {
    let pairs = pairs(spec);
    if pairs.is_empty() {
        report!("no example of the spec is a complete request and reply: nothing to decode");
        return None;
    }
    Some(pairs)
}

/// Whether a decoded JSON value is the value the manual states (floats bit for bit as f32).
fn same(want: &Json, got: &Json) -> bool {
    match (want, got) {
        (Json::Number(a), Json::Number(b)) => match (a.as_i64(), b.as_i64()) {
            (Some(a), Some(b)) => a == b,
            _ => a.as_f64().map(|a| (a as f32).to_bits()) == b.as_f64().map(|b| (b as f32).to_bits()),
        },
        (Json::Object(a), Json::Object(b)) => a.iter().all(|(k, v)| b.get(k).is_some_and(|g| same(v, g))),
        (Json::Array(a), Json::Array(b)) => a.len() == b.len() && a.iter().zip(b).all(|(x, y)| same(x, y)),
        (a, b) => a == b,
    }
}

/// Whether a decoding (or transaction) names `sensor`'s `command`.
fn names(decoding: &Json, sensor: &str, command: &str) -> bool {
    decoding["commands"]
        .as_array()
        .is_some_and(|cs| cs.iter().any(|c| c["sensor"] == sensor && c["command"] == command))
}

/// The decoding of a transaction that names the pair's command, checked
/// against the manual's values.
#[track_caller]
fn check_decoding<'j>(doc: &'j Json, pair: &Pair) -> &'j Json {
    let decodings = doc["decodings"].as_array().unwrap_or_else(|| panic!("no decodings for {}: {doc}", pair.what()));
    let decoding = decodings
        .iter()
        .find(|d| names(d, &pair.sensor, &pair.command))
        .unwrap_or_else(|| panic!("{} is not among the decodings:\n{doc:#}", pair.what()));
    if !pair.is_exception() {
        for (name, want) in &pair.values {
            let got = &decoding["values"][name];
            assert!(same(want, got), "{} {name}: the manual says {want}, decoded {got}\n{doc:#}", pair.what());
        }
    }
    decoding
}

/// Stdout as one JSON document.
#[track_caller]
fn document(run: &Run) -> Json {
    serde_json::from_str(&run.stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON document ({e}):\n{}\nstderr:\n{}", run.stdout, run.stderr))
}

/// Stdout as JSON lines.
#[track_caller]
fn json_lines(run: &Run) -> Vec<Json> {
    run.stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not a JSON line ({e}): {l}\n{}", run.stderr)))
        .collect()
}

/// The commands of every sensor whose request header is `request`'s.
fn commands_with_request<'s>(spec: &'s Spec, request: &[u8]) -> Vec<(&'s str, &'s CommandSpec)> {
    let word = |at: usize| u16::from_be_bytes([request[at], request[at + 1]]);
    spec.sensors
        .iter()
        .flat_map(|s| s.commands.iter().map(move |c| (s.name.as_str(), c)))
        .filter(|(_, c)| c.function.code() == request[1] && c.address == word(2) && c.count == word(4))
        .filter(|(_, c)| c.fixed_slave.is_none_or(|f| f == request[0]))
        .collect()
}

#[test]
fn every_example_pair_decodes_as_its_command() {
    if !yosemitech_tests::slow::enabled("decode of every example pair, a process each (about 25 s)") {
        return;
    }
    let spec = spec();
    // The two-argument form and the text output are checked once per sensor
    // and per command shared by several sensors (each run loads the spec).
    let mut shown = std::collections::BTreeSet::new();
    let (mut decoded, mut ambiguous) = (0, 0);
    for pair in pairs(spec) {
        let (request, reply) = (hex(&pair.request), hex(&pair.reply));
        // Back to back in one argument.
        let joined = YOSEMITECH.run(&["decode", &format!("{request} {reply}"), "--json"]);
        let doc = document(&joined);
        assert_eq!(doc["type"], "transaction", "{}: {doc:#}", pair.what());
        assert_eq!(doc["request"]["frame"], request.as_str());
        assert_eq!(doc["reply"]["frame"], reply.as_str());
        assert_eq!(doc["slave"].as_u64(), Some(u64::from(pair.request[0])));
        check_decoding(&doc, &pair);
        let sharing = commands_with_request(spec, &pair.request);
        let mut text_label = None;
        match joined.code {
            0 => {
                decoded += 1;
                joined.ok();
                let status = if pair.is_exception() { "exception" } else { "decoded" };
                assert_eq!(doc["status"], status, "{}: {doc:#}", pair.what());
                assert_eq!(doc["decodings"].as_array().map(Vec::len), Some(1));
                assert!(names(&doc, &pair.sensor, &pair.command), "{}: {doc:#}", pair.what());
                assert!(doc["error"].is_null());
                // Sensors that share the request and read the reply alike are reported together.
                let listed: Vec<(&str, &str)> = doc["commands"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|c| (c["sensor"].as_str().unwrap(), c["command"].as_str().unwrap()))
                    .collect();
                for (sensor, command) in &listed {
                    assert!(
                        sharing.iter().any(|(s, c)| s == sensor && c.name == *command),
                        "{}: {sensor} {command} listed, but its request differs",
                        pair.what()
                    );
                }
                if !pair.is_exception() && doc["command"] == pair.command.as_str() {
                    let sensors: Vec<&str> = listed.iter().map(|(s, _)| *s).collect();
                    text_label = Some((listed.len() > 1, format!("{} of {}", pair.command, sensors.join(", "))));
                }
            }
            2 => {
                // Several commands share the request and read the reply differently.
                ambiguous += 1;
                joined.fails_with_hint(2);
                assert_eq!(doc["status"], "ambiguous", "{}: {doc:#}", pair.what());
                assert!(doc["decodings"].as_array().is_some_and(|d| d.len() >= 2), "{doc:#}");
                assert_eq!(doc["error"]["exit_code"], 2);
                assert!(doc["error"]["hint"].as_str().is_some_and(|h| h.contains("--sensor")), "{doc:#}");
                assert!(sharing.len() >= 2, "{}: ambiguous, yet the spec has {sharing:?}", pair.what());
                // Naming the sensor and command decides.
                let run = YOSEMITECH.run(&[
                    "decode",
                    &request,
                    &reply,
                    "--sensor",
                    &pair.sensor,
                    "--command",
                    &pair.command,
                    "--json",
                ]);
                let doc = document(&run);
                run.ok();
                assert_eq!(doc["command"], pair.command.as_str(), "{doc:#}");
                assert_eq!(doc["sensors"], serde_json::json!([pair.sensor]));
                check_decoding(&doc, &pair);
            }
            code => panic!("{}: exit {code}\n{}\n{}", pair.what(), joined.stdout, joined.stderr),
        }
        let shared = text_label.as_ref().is_some_and(|(shared, _)| *shared);
        let first = shown.insert(pair.sensor.clone());
        if first || (shared && shown.insert(format!("shared {}", pair.command))) {
            // Two arguments are the same stream as one.
            let split = YOSEMITECH.run(&["decode", &request, &reply, "--json"]);
            assert_eq!(joined.stdout, split.stdout, "{}", pair.what());
            // The text output names the command (with every sensor that reads it alike).
            let text = YOSEMITECH.run(&["decode", &request, &reply]);
            let want = text_label.map_or_else(|| pair.command.clone(), |(_, label)| label);
            assert!(text.stdout.contains(&want), "{}: `{want}` not in\n{}", pair.what(), text.stdout);
        }
    }
    report!(
        "decode: {decoded} example pairs decoded as their command, {ambiguous} asked which (several commands read them)"
    );
}

/// Lines of a capture: a timestamp and direction label before each frame.
fn capture_lines(pairs: &[Pair]) -> Vec<String> {
    let mut lines = vec!["# a capture built from the spec's examples".to_owned()];
    for (i, p) in pairs.iter().enumerate() {
        lines.push(format!("12:00:{:02}.{:03} TX: {}", i / 10, i % 1000, hex(&p.request)));
        lines.push(format!("12:00:{:02}.{:03} RX: {}", i / 10, i % 1000 + 20, hex(&p.reply)));
    }
    lines
}

/// Checks the transactions of a capture's JSON lines against the pairs, in order.
#[track_caller]
fn check_transactions(entries: &[Json], pairs: &[Pair]) {
    let transactions: Vec<&Json> = entries.iter().filter(|e| e["type"] == "transaction").collect();
    assert_eq!(transactions.len(), pairs.len(), "{entries:#?}");
    for (t, pair) in transactions.iter().zip(pairs) {
        assert_eq!(t["request"]["frame"], hex(&pair.request).as_str(), "{}", pair.what());
        assert_eq!(t["reply"]["frame"], hex(&pair.reply).as_str(), "{}", pair.what());
        check_decoding(t, pair);
        let ok = t["status"] == "decoded" || t["status"] == "exception";
        assert!(ok || t["status"] == "ambiguous", "{}: {t:#}", pair.what());
        assert_eq!(t["ok"], ok);
    }
}

#[test]
fn a_capture_of_several_sensors_with_noise_decodes_every_pair() {
    let spec = spec();
    let Some(pairs) = some_pairs(spec) else { return };
    let sensors: std::collections::BTreeSet<&str> = pairs.iter().map(|p| p.sensor.as_str()).collect();
    report!("capture: {} pairs of {} sensors", pairs.len(), sensors.len());
    let mut lines = capture_lines(&pairs);
    // Noise after the first pair: too short to be any frame.
    lines.insert(3, "12:00:00.500 RX: 00 00 00".to_owned());
    let noise_line = 4;
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bus.log");
    std::fs::write(&file, lines.join("\n") + "\n").unwrap();
    let file = file.to_str().unwrap();

    let run = YOSEMITECH.run(&["decode", "--capture", file, "--json"]);
    run.fails_with_hint(1);
    let entries = json_lines(&run);
    check_transactions(&entries, &pairs);
    let noise: Vec<&Json> = entries.iter().filter(|e| e["type"] == "noise").collect();
    assert_eq!(noise.len(), 1, "{entries:#?}");
    assert_eq!(noise[0]["bytes"], "00 00 00");
    assert_eq!(noise[0]["line"], noise_line);
    // Entries are in capture order: the noise comes after the first pair.
    assert_eq!(entries[1]["type"], "noise", "{entries:#?}");
    let summary = entries.last().unwrap();
    assert_eq!(summary["type"], "summary");
    assert_eq!(summary["mode"], "lines");
    assert_eq!(summary["transactions"].as_u64(), Some(pairs.len() as u64));
    let failed = entries.iter().filter(|e| e["type"] != "summary" && e["ok"] == false).count() as u64;
    assert_eq!(summary["failed"].as_u64(), Some(failed));
    assert!(failed >= 1);
    // Request and reply lines are those of the file.
    assert_eq!(entries[0]["request"]["line"], 2);
    assert_eq!(entries[0]["reply"]["line"], 3);

    // The same capture on stdin, as text: one line per entry and a summary.
    let text = YOSEMITECH.run_with_input(&["decode", "--capture", "-"], &(lines.join("\n") + "\n"));
    let err = text.fails_with_hint(1);
    assert!(err.contains("could not be decoded"), "{err}");
    assert!(text.stdout.contains(&format!("line {noise_line}")) && text.stdout.contains("noise"), "{}", text.stdout);
    assert!(text.stdout.contains("lines 2-3"), "{}", text.stdout);
    assert_eq!(text.stdout.lines().count(), entries.len(), "{}", text.stdout);
    for pair in &pairs {
        assert!(text.stdout.contains(&pair.command), "{} missing:\n{}", pair.command, text.stdout);
    }
}

#[test]
fn a_capture_of_one_sensor_decodes_every_pair_and_exits_0() {
    let spec = spec();
    let all = pairs(spec);
    let mut captured = 0;
    for sensor in &spec.sensors {
        let pairs: Vec<Pair> = all.iter().filter(|p| p.sensor == sensor.name).cloned().collect();
        if pairs.is_empty() {
            continue;
        }
        captured += 1;
        let capture = capture_lines(&pairs).join("\n");
        let run =
            YOSEMITECH.run_with_input(&["decode", "--capture", "-", "--sensor", &sensor.name, "--json"], &capture);
        run.ok();
        let entries = json_lines(&run);
        check_transactions(&entries, &pairs);
        assert!(entries.iter().all(|e| e["ok"] == true), "{entries:#?}");
        for (t, pair) in entries.iter().zip(&pairs) {
            assert_eq!(t["command"], pair.command.as_str(), "{t:#}");
        }
    }
    report!("{captured} captures of one sensor each decoded");
}

#[test]
fn a_hex_stream_splits_into_the_same_pairs() {
    let spec = spec();
    let Some(pairs) = some_pairs(spec) else { return };
    // Everything back to back, with two bytes of noise (no frame starts with
    // address 0 and function 0) between pairs.
    let mut stream = Vec::new();
    for pair in &pairs {
        stream.extend_from_slice(&pair.request);
        stream.extend_from_slice(&pair.reply);
        stream.extend_from_slice(&[0, 0]);
    }
    let compact: String = stream.iter().map(|b| format!("{b:02x}")).collect();
    let run = YOSEMITECH.run(&["decode", &compact, "--json"]);
    let entries = json_lines(&run);
    check_transactions(&entries, &pairs);
    let noise = entries.iter().filter(|e| e["type"] == "noise").count();
    assert_eq!(noise, pairs.len(), "{entries:#?}");
    assert!(entries.iter().filter(|e| e["type"] == "noise").all(|e| e["bytes"] == "00 00"));
    assert_eq!(entries.last().unwrap()["mode"], "stream");

    // A dump wrapped at 16 bytes a line (frames span lines) is read as a stream.
    let mut stream = Vec::new();
    for pair in &pairs {
        stream.extend_from_slice(&pair.request);
        stream.extend_from_slice(&pair.reply);
    }
    let wrapped: Vec<String> = stream.chunks(16).map(hex).collect();
    let run = YOSEMITECH.run_with_input(&["decode", "--capture", "-", "--json"], &wrapped.join("\n"));
    let entries = json_lines(&run);
    check_transactions(&entries, &pairs);
    let summary = entries.last().unwrap();
    assert_eq!(summary["mode"], "stream", "{summary}");
    assert_eq!(summary["entries"].as_u64(), Some(pairs.len() as u64), "{entries:#?}");
    // Exit 0 exactly when no pair is ambiguous.
    let expected = if entries.iter().all(|e| e["ok"] == true) { 0 } else { 1 };
    assert_eq!(run.code, expected, "{}", run.stderr);
}

#[test]
fn a_reply_from_0xff_fits_only_commands_with_that_fixed_slave() {
    let spec = spec();
    let fixed_slaves: Vec<u8> =
        spec.sensors.iter().flat_map(|s| s.commands.iter().filter_map(|c| c.fixed_slave)).collect();
    let is_fixed = |sensor: &str, command: &str, slave: u8| {
        spec.sensor(sensor).and_then(|s| s.command(command)).is_some_and(|c| c.fixed_slave == Some(slave))
    };
    // Alone, a reply from a fixed address is read only as such a command.
    let mut seen = 0;
    for pair in pairs(spec).iter().filter(|p| fixed_slaves.contains(&p.reply[0])) {
        seen += 1;
        let run = YOSEMITECH.run(&["decode", &hex(&pair.reply), "--json"]);
        let doc = document(&run);
        let slave = pair.reply[0];
        match run.code {
            0 => assert!(is_fixed(doc["command"]["sensor"].as_str().unwrap(), &pair.command, slave), "{doc:#}"),
            2 => {
                for c in doc["candidates"].as_array().unwrap() {
                    let command = c["command"].as_str().unwrap();
                    assert!(c["sensors"].as_array().unwrap().iter().all(|s| is_fixed(
                        s.as_str().unwrap(),
                        command,
                        slave
                    )));
                }
            }
            code => panic!("exit {code}: {}", run.stderr),
        }
    }
    report!("{seen} example replies from a fixed address decoded alone");

    // A read of an ordinary command answered from 0xFF: the reply is not the
    // request's (a reply comes from the request's slave) and, unpaired, fits
    // no command but one with fixed slave 0xFF.
    let ordinary = pairs(spec).into_iter().find(|p| {
        let c = spec.sensor(&p.sensor).and_then(|s| s.command(&p.command)).unwrap();
        c.is_read() && c.fixed_slave.is_none() && !p.is_exception()
    });
    let Some(ordinary) = ordinary else {
        report!("no example of the spec is an ordinary read's pair: none answered from 0xFF");
        return;
    };
    let mut from_ff = ordinary.reply.clone();
    from_ff[0] = 0xFF;
    let from_ff = with_crc(from_ff);
    let run = YOSEMITECH.run(&["decode", &hex(&ordinary.request), &hex(&from_ff), "--json"]);
    run.fails_with_hint(1);
    let entries = json_lines(&run);
    assert_eq!(entries[0]["status"], "no_reply", "{entries:#?}");
    if !fixed_slaves.contains(&0xFF) {
        // Without such a command, a frame from 0xFF is no reply at all.
        assert_eq!(entries[1]["type"], "noise", "{entries:#?}");
        return;
    }
    assert_eq!(entries[1]["type"], "reply");
    assert_eq!(entries[1]["status"], "unpaired");
    for d in entries[1]["decodings"].as_array().unwrap() {
        for c in d["commands"].as_array().unwrap() {
            let (sensor, command) = (c["sensor"].as_str().unwrap(), c["command"].as_str().unwrap());
            assert!(is_fixed(sensor, command, 0xFF), "{sensor} {command} taken for a reply from 0xFF");
        }
    }
}

/// A spec directory with a made-up sensor whose reads have the same requests
/// as two of the spec's reads (as 16-bit words): one ordinary, and one whose
/// example reply carries a byte count only the original accepts.
struct Twin {
    dir: tempfile::TempDir,
    /// The pair whose reply both commands decode (differently).
    ambiguous: Pair,
    /// A pair whose reply only the original decodes, if the spec has one.
    quirk: Option<Pair>,
}

fn twin() -> Option<Twin> {
    let spec = spec();
    let command = |p: &Pair| spec.sensor(&p.sensor).and_then(|s| s.command(&p.command)).unwrap().clone();
    let ordinary = |c: &CommandSpec| c.is_read() && c.fixed_slave.is_none() && !c.trigger && c.count <= 16;
    let all = pairs(spec);
    let Some(ambiguous) = all.iter().find(|p| ordinary(&command(p)) && !p.is_exception()).cloned() else {
        report!("no example of the spec is a read's pair: no twin made");
        return None;
    };
    // A printed reply whose byte count is a documented quirk.
    let quirk = spec.sensors.iter().find_map(|s| {
        s.commands.iter().filter(|c| ordinary(c) && !c.extra_byte_counts.is_empty()).find_map(|c| {
            c.examples.iter().find_map(|e| {
                let v = serde_json::to_value(e).ok()?;
                let printed = bytes_of(&v["response"])?;
                let pair = true_pair(&s.name, c, e)?;
                (crc_ok(&printed) && c.extra_byte_counts.contains(&printed[2])).then(|| Pair {
                    reply: printed,
                    values: BTreeMap::new(),
                    ..pair
                })
            })
        })
    });
    let read = |name: &str, c: &CommandSpec| {
        let fields: Vec<String> = (0..c.count)
            .map(|i| format!("      - {{name: w{i}, type: u16, byte_order: ab, doc: Word {i}.}}"))
            .collect();
        format!(
            "  - name: {name}\n    title: Twin of {}\n    doc: The same registers as words.\n    function: read\n    address: 0x{:04X}\n    count: {}\n    fields:\n{}\n",
            c.name,
            c.address,
            c.count,
            fields.join("\n")
        )
    };
    let mut yaml = String::from(
        "sensor:\n  name: twin_probe\n  title: Twin probe (test)\n  doc: A made-up probe that shares requests with others.\n  manual: {title: Test manual, revision: \"1.0\"}\n  serial: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1}\n  addresses: {min: 1, max: 247}\n  default_address: 1\ncommands:\n",
    );
    yaml.push_str(&read("get_twin_words", &command(&ambiguous)));
    if let Some(q) = &quirk {
        yaml.push_str(&read("get_twin_quirk", &command(q)));
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("twin.yaml"), yaml).unwrap();
    Some(Twin { dir, ambiguous, quirk })
}

#[test]
fn an_ambiguous_pair_is_a_usage_error_listing_every_decoding_and_json_under_json() {
    let Some(twin) = twin() else { return };
    let spec_dir = twin.dir.path().to_str().unwrap();
    let pair = &twin.ambiguous;
    let (request, reply) = (hex(&pair.request), hex(&pair.reply));

    let run = YOSEMITECH.run(&["decode", &request, &reply, "--spec", spec_dir, "--json"]);
    let err = run.fails_with_hint(2).to_owned();
    assert!(err.contains("get_twin_words of twin_probe") && err.contains(&pair.command), "{err}");
    let doc = document(&run);
    assert_eq!(doc["status"], "ambiguous");
    assert_eq!(doc["ok"], false);
    assert!(doc["command"].is_null(), "{doc:#}");
    let decodings = doc["decodings"].as_array().unwrap();
    assert!(decodings.len() >= 2);
    check_decoding(&doc, pair);
    let words = decodings.iter().find(|d| names(d, "twin_probe", "get_twin_words")).expect("the twin's decoding");
    assert_eq!(words["values"].as_object().map(|v| v.len()), Some(pair.request[5] as usize), "{words:#}");
    let error = &doc["error"];
    assert_eq!(error["exit_code"], 2);
    assert!(error["message"].as_str().unwrap().contains("say which one"), "{error}");
    assert!(error["hint"].as_str().unwrap().contains("--sensor"), "{error}");
    assert_eq!(error["details"].as_array().map(Vec::len), Some(decodings.len()));

    // Text: every decoding on stdout, the error on stderr.
    let run = YOSEMITECH.run(&["decode", &request, &reply, "--spec", spec_dir]);
    run.fails_with_hint(2);
    assert!(run.stdout.contains("decoding 1") && run.stdout.contains("decoding 2"), "{}", run.stdout);

    // --sensor decides.
    let run = YOSEMITECH.run(&["decode", &request, &reply, "--spec", spec_dir, "--sensor", "twin_probe", "--json"]);
    run.ok();
    let doc = document(&run);
    assert_eq!(doc["command"], "get_twin_words");
    let run = YOSEMITECH.run(&["decode", &request, &reply, "--spec", spec_dir, "--sensor", &pair.sensor, "--json"]);
    run.ok();

    // In a capture an ambiguity is one entry that failed, not the end.
    let capture = format!("{request}\n{reply}\n");
    let run = YOSEMITECH.run_with_input(&["decode", "--capture", "-", "--spec", spec_dir, "--json"], &capture);
    run.fails(1);
    let entries = json_lines(&run);
    assert_eq!(entries[0]["status"], "ambiguous");
    assert_eq!(entries.last().unwrap()["failed"], 1);
}

#[test]
fn a_candidate_whose_decode_fails_is_dropped() {
    let Some(twin) = twin() else { return };
    let Some(pair) = &twin.quirk else {
        report!("no read in the spec documents a byte-count quirk with an example: nothing to drop");
        return;
    };
    let spec_dir = twin.dir.path().to_str().unwrap();
    let run = YOSEMITECH.run(&["decode", &hex(&pair.request), &hex(&pair.reply), "--spec", spec_dir, "--json"]);
    run.ok();
    let doc = document(&run);
    assert_eq!(doc["status"], "decoded", "{doc:#}");
    assert!(names(&doc, &pair.sensor, &pair.command), "{doc:#}");
    assert!(!names(&doc, "twin_probe", "get_twin_quirk"), "{doc:#}");
    let notes = doc["notes"].to_string();
    assert!(notes.contains("not get_twin_quirk of twin_probe") && notes.contains("quirk"), "{notes}");
}

#[test]
fn requests_without_replies_and_broadcasts() {
    let spec = spec();
    let Some(pairs) = some_pairs(spec) else { return };
    // Two requests back to back: neither is answered.
    let (a, b) = (&pairs[0], &pairs[pairs.len() - 1]);
    let run = YOSEMITECH.run(&["decode", &hex(&a.request), &hex(&b.request), "--json"]);
    run.fails_with_hint(1);
    let entries = json_lines(&run);
    assert_eq!(entries.len(), 3, "{entries:#?}");
    for (entry, pair) in entries.iter().zip([a, b]) {
        assert_eq!(entry["status"], "no_reply");
        assert!(entry["reply"].is_null());
        assert!(entry["decodings"].as_array().unwrap().iter().any(|d| names(d, &pair.sensor, &pair.command)));
    }

    // A broadcast write is never answered, and that is fine.
    let write = pairs.iter().find(|p| {
        let c = spec.sensor(&p.sensor).and_then(|s| s.command(&p.command)).unwrap();
        !c.is_read() && c.fixed_slave.is_none()
    });
    if let Some(write) = write {
        let mut broadcast = write.request.clone();
        broadcast[0] = 0;
        let broadcast = with_crc(broadcast);
        let run = YOSEMITECH.run(&["decode", &hex(&broadcast), &hex(&write.request), &hex(&write.reply), "--json"]);
        let entries = json_lines(&run);
        assert_eq!(entries[0]["status"], "broadcast", "{entries:#?}");
        assert_eq!(entries[0]["ok"], true);
        assert_eq!(entries[1]["request"]["frame"], hex(&write.request).as_str());
        let expected = if entries[1]["ok"] == true { 0 } else { 1 };
        assert_eq!(run.code, expected, "{}", run.stderr);
    }
}

#[test]
fn a_damaged_reply_is_paired_and_reported() {
    let spec = spec();
    let Some(pair) = pairs(spec).into_iter().find(|p| !p.is_exception()) else {
        report!("no example of the spec is a pair with a normal reply: none damaged");
        return;
    };
    let mut bad = pair.reply.clone();
    let last = bad.len() - 1;
    bad[last] ^= 0xFF;
    let run = YOSEMITECH.run(&["decode", &hex(&pair.request), &hex(&bad), "--json"]);
    run.fails_with_hint(1);
    let doc = document(&run);
    assert_eq!(doc["status"], "undecodable");
    assert_eq!(doc["reply"]["crc_ok"], false);
    assert!(doc["problems"][0].as_str().unwrap().contains("CRC"), "{doc:#}");
    assert!(doc["error"]["message"].as_str().is_some());

    let cut = &pair.reply[..pair.reply.len() - 3];
    let run = YOSEMITECH.run(&["decode", &hex(&pair.request), &hex(cut), "--json"]);
    run.fails_with_hint(1);
    let doc = document(&run);
    assert!(doc["problems"][0].as_str().unwrap().contains("cut short"), "{doc:#}");
}

#[test]
fn malformed_input_is_a_usage_error_with_a_hint() {
    let dir = tempfile::tempdir().unwrap();
    let text_only = dir.path().join("text.log");
    std::fs::write(&text_only, "no hex here\nnor here\n").unwrap();
    let binary = dir.path().join("capture.bin");
    std::fs::write(&binary, [0x01u8, 0x03, 0xFF, 0xFE, 0x80]).unwrap();
    let missing = dir.path().join("missing.log");
    let path = |p: &Path| p.to_str().unwrap().to_owned();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["01 03 2Z".into()], "not a hex digit"),
        (vec!["01 03 28 0".into()], "odd number"),
        (vec!["01 03 28 00 00 02 CD AB".into(), "01 03 0".into()], "odd number"),
        (vec!["--capture".into(), path(&missing)], "cannot read the capture"),
        (vec!["--capture".into(), path(&text_only)], "no hex"),
        (vec!["--capture".into(), path(&binary)], "not text"),
    ];
    for (args, needle) in cases {
        let mut all = vec!["decode".to_owned()];
        all.extend(args.iter().cloned());
        let argv: Vec<&str> = all.iter().map(String::as_str).collect();
        let run = YOSEMITECH.run(&argv);
        let err = run.fails_with_hint(2);
        assert!(err.starts_with("error: ") && err.contains(needle), "{args:?}: `{needle}` not in:\n{err}");
        assert!(run.stdout.is_empty(), "{args:?}: {}", run.stdout);
        // Under --json the error is also a JSON document on stdout.
        let mut json_args = argv.clone();
        json_args.push("--json");
        let run = YOSEMITECH.run(&json_args);
        run.fails_with_hint(2);
        let doc = document(&run);
        assert!(doc["error"]["message"].as_str().unwrap().contains(needle), "{doc:#}");
        assert_eq!(doc["error"]["exit_code"], 2);
        assert!(doc["error"]["hint"].is_string());
    }
    // A capture and frames at once, or neither: clap's usage error.
    YOSEMITECH.run(&["decode", "--capture", "-", "01 03"]).fails(2);
    YOSEMITECH.run(&["decode", "--json"]).fails(2);
}

#[test]
fn every_prefix_of_a_stream_decodes_or_fails_cleanly() {
    let spec = spec();
    let Some(pairs) = some_pairs(spec) else { return };
    // A pair, then the start of the next request: every cut of it.
    let (first, next) = (&pairs[0], &pairs[pairs.len() - 1]);
    let mut stream = [first.request.as_slice(), &first.reply, &next.request].concat();
    stream.truncate(first.request.len() + first.reply.len() + 4);
    for end in 1..=stream.len() {
        let text = hex(&stream[..end]);
        let run = YOSEMITECH.run(&["decode", &text, "--json"]);
        assert!([0, 1, 2].contains(&run.code), "{text}: exit {}\n{}", run.code, run.stderr);
        if run.code != 0 {
            run.fails(run.code);
        }
        // One document, or JSON lines: JSON either way.
        let parsed = serde_json::from_str::<Json>(&run.stdout).is_ok()
            || run.stdout.lines().all(|l| serde_json::from_str::<Json>(l).is_ok());
        assert!(parsed, "{text}: stdout is not JSON:\n{}", run.stdout);
    }
}

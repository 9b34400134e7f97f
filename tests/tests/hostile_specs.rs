//! Hostile specs: text that tries to escape the doc comments and literals it
//! becomes, names that would inject code or shadow what generated code
//! relies on, absurd sizes and counts, deep and cyclic includes, huge files
//! and YAML bombs.
//!
//! Each one is either rejected by the loader with a clear diagnostic that
//! points into the file (names that only collide once generated too: what
//! the loader accepts, the generator generates), or accepted and escaped: the accepted ones are in
//! tests/fixtures/hostile-valid, which build.rs generates into typed code
//! that this package compiles (`yosemitech_tests::hostile`), and more are
//! generated here in memory and checked for text outside literals.
//!
//! (The malformed-spec corpus, tests/specs/malformed with spec_corpus.rs,
//! snapshots ordinary mistakes; this file is about attacks and limits.)

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use yosemitech::{Client, Command, FieldValue, ResponderTransport};
use yosemitech_sim::Simulator;
use yosemitech_spec::sources::{MAX_FILE_BYTES, MemSources};
use yosemitech_spec::{Diagnostics, MAX_INCLUDE_DEPTH, Spec, Value, load_paths, load_with};
use yosemitech_tests::hostile::{self, BoxKind, GetMaxRead, GetMaxReadIterator, SetMaxWrite};

/// Longest a case may take to load (debug build, busy machine).
const TIME_LIMIT: Duration = Duration::from_secs(10);

/// A valid sensor file with one read command; cases replace parts of it.
const BASE: &str = r#"sensor:
  name: probe
  title: Probe
  doc: A probe.
  manual: {title: Manual, revision: Rev 1}
  serial: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1}
  addresses: {min: 1, max: 247}
  default_address: 1
commands:
  - name: get_value
    title: Get Value
    doc: The value.
    function: read
    address: 0x0100
    count: 2
    fields:
      - {name: value, type: f32, byte_order: dcba, unit: mg/L, doc: The value.}
"#;

/// A fragment that may `include` another and defines one command, reading register `address`.
fn fragment(name: &str, address: u16, include: Option<&str>) -> String {
    let include = include.map(|i| format!("include: [{i}]\n")).unwrap_or_default();
    format!(
        "{include}fragment:\n  name: {name}\n  doc: Shared.\ncommands:\n  - name: get_{name}\n    title: T\n    doc: D.\n    function: read\n    address: 0x{address:04X}\n    count: 1\n    fields:\n      - {{name: v, type: u16, byte_order: ab}}\n"
    )
}

/// `BASE` with `from` replaced by `to` (which must occur).
fn base_with(from: &str, to: &str) -> String {
    assert!(BASE.contains(from), "`{from}` is not in BASE");
    BASE.replacen(from, to, 1)
}

/// `BASE` with the command renamed.
fn command_named(name: &str) -> String {
    base_with("name: get_value", &format!("name: {name}"))
}

/// `BASE` with a second command appended.
fn with_command(name: &str, function: &str, address: u16, count: u16, fields: &str) -> String {
    format!(
        "{BASE}  - name: {name}\n    title: T\n    doc: D.\n    function: {function}\n    address: 0x{address:04X}\n    count: {count}\n{fields}"
    )
}

/// One hostile spec: files in memory, the root(s) to load, and a fragment
/// of the diagnostic expected.
struct Case {
    name: String,
    files: Vec<(String, String)>,
    expect: String,
}

fn case(name: impl Into<String>, text: impl Into<String>, expect: impl Into<String>) -> Case {
    Case { name: name.into(), files: vec![("spec/probe.yaml".into(), text.into())], expect: expect.into() }
}

fn multi(name: &str, files: Vec<(String, String)>, expect: &str) -> Case {
    Case { name: name.into(), files, expect: expect.into() }
}

/// Loads `spec/` from `files`, turning a panic or a slow load into a failure naming the case.
fn load(name: &str, files: &[(String, String)]) -> Result<Spec, Diagnostics> {
    let sources = files.iter().fold(MemSources::default(), |s, (p, t)| s.with(p.as_str(), t.as_str()));
    let start = Instant::now();
    let result = catch_unwind(AssertUnwindSafe(|| load_with(&sources, &[PathBuf::from("spec")])));
    let elapsed = start.elapsed();
    assert!(elapsed < TIME_LIMIT, "{name}: loading took {elapsed:?}");
    result.unwrap_or_else(|_| panic!("{name}: the loader panicked"))
}

/// Cases the loader must reject.
fn loader_cases() -> Vec<Case> {
    let mut cases = Vec::new();

    // Names that would inject code or are not identifiers.
    for (label, name) in [
        ("inject-brackets", r#"'x"]; fn evil() {'"#),
        ("inject-braces", "'read_level() {} fn x'"),
        ("inject-comment", "'read_level/*'"),
        ("inject-newline", "\"get_ph\\nfn evil() {}\""),
        ("inject-raw-identifier", "'r#type'"),
        ("inject-attribute", "'#[cfg(any())]'"),
        ("unicode-homoglyph", "get_\u{440}h"),
        ("unicode-letters", "gr\u{f6}\u{df}e"),
        ("unicode-bidi", "'get\u{202E}_ph'"),
        ("zero-width-space", "'get\u{200B}_ph'"),
        ("camel-case", "GetPh"),
        ("kebab-case", "get-ph"),
        ("empty", "''"),
        ("number", "123"),
        ("too-long", &"a".repeat(65)),
        ("trailing-underscore", "get_"),
    ] {
        cases.push(case(format!("command-name-{label}"), command_named(name), "invalid name"));
    }
    // Keywords, and names whose types the generated code reserves or takes
    // from the Rust prelude (a unit struct `Some` or `Ok` breaks every match).
    for name in [
        "fn", "type", "self", "crate", "super", "async", "gen", "union", "raw", "command", "response", "request",
        "device", "unknown", "error", "result", "option", "some", "none", "ok", "err", "from", "iterator", "into",
        "try_from", "string", "vec", "default", "clone", "send", "sized", "drop", "fn_once",
    ] {
        cases.push(case(format!("command-name-{name}"), command_named(name), "invalid name"));
    }
    // Sensor modules that would shadow crates that generated code and the
    // including crate use (`std::time` in the yosemitech crate, `::yosemitech_rtu as rtu`).
    for name in ["core", "std", "alloc", "rtu", "yosemitech_rtu", "mod", "self"] {
        cases.push(case(
            format!("sensor-name-{name}"),
            base_with("name: probe", &format!("name: {name}")),
            "invalid name",
        ));
    }
    // Field and variant names are checked the same way.
    cases.push(case("field-name-injection", base_with("name: value,", "name: 'value: f32 }',"), "invalid name"));
    cases.push(case("field-name-keyword", base_with("name: value,", "name: match,"), "invalid name"));

    // Text that is not printable: NUL, escape sequences, bidi overrides.
    for (label, text) in [
        ("nul", "\"a\\0b\""),
        ("escape-sequence", "\"red \\e[31m text\""),
        ("bell", "\"ding \\a\""),
        ("bidi-override", "\"safe \u{202E}evil\""),
        ("bidi-isolate", "\"safe \u{2066}evil\""),
    ] {
        cases.push(case(format!("doc-{label}"), base_with("doc: A probe.", &format!("doc: {text}")), "text"));
    }
    cases.push(case("title-too-long", base_with("title: Probe", &format!("title: {}", "x".repeat(5000))), "at most"));

    // Absurd sizes and counts.
    cases.push(case("count-65535", base_with("count: 2", "count: 65535"), "count"));
    cases.push(case("count-read-126", base_with("count: 2", "count: 126"), "count"));
    cases.push(case(
        "count-write-124",
        with_command("set_many", "write", 0x0300, 124, "    fields:\n      - {type: reserved, size: 248}\n"),
        "count",
    ));
    cases.push(case("count-negative", base_with("count: 2", "count: -1"), "count"));
    cases.push(case("count-float", base_with("count: 2", "count: 2.5"), "count"));
    cases.push(case("count-huge", base_with("count: 2", "count: 18446744073709551616"), "count"));
    cases.push(case("address-17-bit", base_with("address: 0x0100", "address: 0x10000"), "16 bits"));
    cases.push(case(
        "ascii-size-million",
        base_with("type: f32, byte_order: dcba,", "type: ascii, size: 1000000,"),
        "size 1000000",
    ));
    cases.push(case(
        "enum-code-too-big",
        with_command(
            "get_mode",
            "read",
            0x0300,
            1,
            "    fields:\n      - name: mode\n        type: enum\n        size: 2\n        byte_order: ab\n        variants:\n          - {name: big, value: 0x10000}\n",
        ),
        "does not fit",
    ));
    cases.push(case(
        "constant-u32-overflow",
        format!("{BASE}constants:\n  - {{name: big, type: u32, value: 4294967296, doc: Big.}}\n"),
        "not a valid `u32`",
    ));
    cases.push(case(
        "constant-f32-overflow",
        format!("{BASE}constants:\n  - {{name: big, type: f32, value: 1e39, doc: Big.}}\n"),
        "f32",
    ));
    cases.push(case(
        "constant-nan",
        format!("{BASE}constants:\n  - {{name: nan, type: f32, value: .nan, doc: Not a number.}}\n"),
        "NaN",
    ));
    cases.push(case(
        "constant-infinity",
        format!("{BASE}constants:\n  - {{name: inf, type: f32, value: .inf, doc: Infinite.}}\n"),
        "inf",
    ));

    // Includes: too deep, cyclic, escaping the directory, absolute, not YAML.
    let depth = MAX_INCLUDE_DEPTH + 1;
    let mut files = vec![("spec/probe.yaml".to_string(), format!("include: [f1.yaml]\n{BASE}"))];
    for i in 1..=depth {
        let next = (i < depth).then(|| format!("f{}.yaml", i + 1));
        files.push((format!("spec/f{i}.yaml"), fragment(&format!("f{i}"), 0x0200 + i as u16, next.as_deref())));
    }
    cases.push(multi("include-depth-9", files, "deeper"));
    cases.push(multi(
        "include-cycle",
        vec![
            ("spec/probe.yaml".into(), format!("include: [a.yaml]\n{BASE}")),
            ("spec/a.yaml".into(), fragment("a", 0x0200, Some("b.yaml"))),
            ("spec/b.yaml".into(), fragment("b", 0x0201, Some("a.yaml"))),
        ],
        "cycle",
    ));
    cases.push(multi(
        "include-self",
        vec![
            ("spec/probe.yaml".into(), format!("include: [a.yaml]\n{BASE}")),
            ("spec/a.yaml".into(), fragment("a", 0x0200, Some("a.yaml"))),
        ],
        "cycle",
    ));
    cases.push(case("include-absolute", format!("include: [/etc/passwd]\n{BASE}"), "absolute"));
    cases.push(case("include-parent", format!("include: [../../../etc/passwd.yaml]\n{BASE}"), "no such file"));
    cases.push(case("include-not-yaml", format!("include: [notes.txt]\n{BASE}"), "not a `.yaml` file"));
    cases.push(case("include-missing", format!("include: [nowhere.yaml]\n{BASE}"), "no such file"));

    // Huge files and YAML bombs.
    let line = format!("# {}\n", "x".repeat(77));
    let huge = format!("{BASE}{}", line.repeat(MAX_FILE_BYTES as usize / line.len() + 1));
    cases.push(case("file-over-1-mib", huge, "1 MiB"));
    // A billion laughs where the loader must take the value: an example's stated value.
    let mut bomb = String::from("[&a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]");
    for i in 1..10 {
        let p = i - 1;
        bomb.push_str(&format!(", &a{i} [*a{p}, *a{p}, *a{p}, *a{p}, *a{p}, *a{p}, *a{p}, *a{p}, *a{p}]"));
    }
    bomb.push(']');
    let example = |value: &str| {
        format!(
            "{BASE}    examples:\n      - request: \"01 03 01 00 00 02 C5 F7\"\n        response: \"01 03 04 00 00 00 00 FA 33\"\n        values: {{value: {value}}}\n"
        )
    };
    cases.push(case("alias-bomb", example(&bomb), "aliases expand"));
    cases.push(case(
        "nesting-10000",
        example(&format!("{}{}", "[".repeat(10_000), "]".repeat(10_000))),
        "nests more than",
    ));
    cases.push(case(
        "flow-nesting-10000",
        example(&format!("{}1{}", "{a: ".repeat(10_000), "}".repeat(10_000))),
        "nests more than",
    ));
    cases.push(case(
        "aliases-duplicate-a-command",
        format!(
            "{BASE}  - &c {{name: get_dup, title: T, doc: D., function: read, address: 0x0300, count: 1, fields: [{{name: v, type: u16, byte_order: ab}}]}}\n  - *c\n"
        ),
        "two commands",
    ));
    cases.push(case("many-documents", format!("{BASE}---\n{BASE}---\n{BASE}"), "second YAML document"));
    cases
}

/// Names that only collide once turned into Rust items: the loader refuses
/// them (what it accepts, the generator generates).
fn generated_name_cases() -> Vec<Case> {
    let u16_field = "    fields:\n      - {name: v, type: u16, byte_order: ab}\n";
    let mut cases = vec![
        case("type-command-id", with_command("command_id", "read", 0x0300, 1, u16_field), "CommandId"),
        case("type-async-device", with_command("async_device", "read", 0x0300, 1, u16_field), "AsyncDevice"),
        case("type-x-response", with_command("get_value_response", "read", 0x0300, 1, u16_field), "GetValueResponse"),
        case("device-method-call", with_command("call", "write", 0x0300, 1, u16_field), "Device::call"),
        case("device-method-new", with_command("new", "write", 0x0300, 1, u16_field), "Device::new"),
        case(
            "device-method-set-address",
            with_command("set_address", "write", 0x0300, 1, u16_field),
            "Device::set_address",
        ),
        case(
            "constant-sensor",
            format!("{BASE}constants:\n  - {{name: sensor, type: u32, value: 1, doc: Clashes.}}\n"),
            "SENSOR",
        ),
        case(
            "constant-module",
            format!("{BASE}constants:\n  - {{name: module, type: u32, value: 1, doc: Clashes.}}\n"),
            "MODULE",
        ),
        case(
            "constant-commands",
            format!("{BASE}constants:\n  - {{name: commands, type: u32, value: 1, doc: Clashes.}}\n"),
            "COMMANDS",
        ),
        case(
            "constant-derived",
            format!("{BASE}constants:\n  - {{name: derived, type: u32, value: 1, doc: Clashes.}}\n"),
            "DERIVED",
        ),
    ];
    // A derived quantity's function must not be one of the module's own.
    for function in yosemitech_spec::names::MODULE_FUNCTIONS {
        cases.push(case(
            format!("derived-{function}"),
            format!(
                "{BASE}derived:\n  - {{name: {function}, title: T, doc: D, inputs: [{{name: x, field: get_value.value}}], expr: \"x * 2\"}}\n"
            ),
            format!("the function `{function}`"),
        ));
    }
    cases
}

/// Texts that must survive into generated code as text and nothing else.
const HOSTILE_TEXTS: &[&str] = &[
    "*/ fn evil() {} /*",
    "\"#] fn evil() {} #[doc = \"",
    "\"## fn evil() {} r##\"",
    "\\\" fn evil() \\\\ \\",
    "``` fn evil() {} ```",
    "{} {{}} {0} {:?} {evil}",
    "'q' \"qq\" `b`",
    "#![allow(unsafe_code)] fn evil() {}",
    "} fn evil() { panic!() } mod m {",
    "<script>evil()</script> &amp; &lt;",
    "温度 🧪 Ω ‰ ±0.1 °C µS/cm evil",
    "\u{feff}BOM evil",
    "line one\nline two */ evil\n\n/* three",
];

/// Wraps `text` as a double-quoted YAML scalar.
fn yaml_quoted(text: &str) -> String {
    let mut out = String::from("\"");
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\u{feff}' => out.push_str("\\uFEFF"),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A spec with `text` in every free-text slot: titles, docs, units, the
/// manual, constants, errata and an example's doc.
fn text_everywhere(text: &str) -> String {
    let q = yaml_quoted(text);
    format!(
        r#"sensor:
  name: probe
  title: {q}
  doc: {q}
  manual: {{title: {q}, revision: {q}}}
  serial: {{baud: 9600, data_bits: 8, parity: none, stop_bits: 1}}
  addresses: {{min: 1, max: 247}}
  default_address: 1
commands:
  - name: get_ph
    title: {q}
    doc: {q}
    source: {{section: {q}, figures: [23, 24]}}
    function: read
    address: 0x2800
    count: 2
    fields:
      - {{name: ph, type: f32, byte_order: dcba, unit: {q}, doc: {q}}}
    examples:
      - figures: [23, 24]
        doc: {q}
        request: "01 03 28 00 00 02 CD AB"
        response: "01 03 04 33 33 F3 40 40 78"
        values: {{ph: 7.6}}
  - name: get_mode
    title: T
    doc: D.
    function: read
    address: 0x2900
    count: 1
    fields:
      - name: mode
        type: enum
        size: 2
        byte_order: ab
        doc: {q}
        variants:
          - {{name: first, value: 1, doc: {q}}}
constants:
  - {{name: settle_ms, type: u32, value: 60000, unit: {q}, doc: {q}}}
errata:
  - id: H1
    note: {q}
"#
    )
}

/// Whether `line` of generated code holds `marker` only inside a comment
/// or a string literal.
fn only_in_text(line: &str, marker: &str) -> bool {
    let Some(at) = line.find(marker) else { return true };
    let t = line.trim_start();
    t.starts_with("///") || t.starts_with("//!") || t.starts_with("//") || line[..at].contains('"')
}

#[test]
fn hostile_specs_are_rejected_or_escaped() {
    // Rejected by the loader, with a positioned diagnostic.
    let mut loader = loader_cases();
    loader.extend(generated_name_cases());
    for c in &loader {
        let diags = match load(&c.name, &c.files) {
            Ok(spec) => panic!("{}: expected a rejection, but it loaded {:?}", c.name, spec.summary()),
            Err(d) => d,
        };
        assert!(!diags.is_empty(), "{}: a rejection without diagnostics", c.name);
        let text = diags.to_string();
        println!("{:<34} {}", c.name, text.lines().next().unwrap_or_default());
        assert!(text.contains(&c.expect), "{}: expected `{}` in\n{text}", c.name, c.expect);
        assert!(diags.0.iter().all(|d| d.pos.line > 0 && !d.message.is_empty()), "{}: unpositioned\n{text}", c.name);
        assert!(text.contains("-->"), "{}: no location in\n{text}", c.name);
        // The diagnostic never echoes control or bidi characters raw.
        assert!(
            !text.chars().any(|ch| (ch.is_control() && ch != '\n') || ('\u{202A}'..='\u{202E}').contains(&ch)),
            "{}: raw control characters in\n{text:?}",
            c.name
        );
    }

    // Accepted and escaped: every hostile text in every text slot.
    for (i, text) in HOSTILE_TEXTS.iter().enumerate() {
        let name = format!("text-{i}");
        let files = vec![("spec/probe.yaml".to_string(), text_everywhere(text))];
        let spec = load(&name, &files).unwrap_or_else(|d| panic!("{name}: {text:?} is rejected:\n{d}"));
        let sensor = spec.sensor("probe").expect("the sensor");
        let trimmed = text.trim();
        assert_eq!(sensor.title.trim(), trimmed, "{name}: the title is kept verbatim");
        let generated = yosemitech_codegen::Config::new()
            .generate_spec(&spec)
            .unwrap_or_else(|e| panic!("{name}: the generator refuses {text:?}: {e}"));
        for file in generated.files() {
            for line in file.1.lines() {
                assert!(only_in_text(line, "evil"), "{name}: spec text escaped into code in {}:\n{line}", file.0);
            }
        }
    }

    yosemitech_tests::report!(
        "hostile specs: {} rejected by the loader, {} texts escaped in every text slot, \
         1 hostile fixture generated and compiled",
        loader.len(),
        HOSTILE_TEXTS.len()
    );
}

fn fixture_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/hostile-valid/spec")
}

fn fixture_spec() -> Spec {
    load_paths(&[fixture_dir()]).unwrap_or_else(|d| panic!("the hostile fixture does not load:\n{d}"))
}

/// Typed field values equal the interpreter's.
fn same_values<'a>(typed: impl Iterator<Item = (&'a str, FieldValue<'a>)>, values: &[(String, Value)]) {
    let typed: Vec<_> = typed.collect();
    assert_eq!(typed.len(), values.len());
    for ((name, t), (other, v)) in typed.iter().zip(values) {
        assert_eq!(name, other);
        let same = v.matches(t);
        assert!(same, "{name}: typed {t:?}, interpreted {v:?}");
    }
}

#[test]
fn hostile_fixture_keeps_its_text_verbatim() {
    let spec = fixture_spec();
    let sensor = spec.sensor("hostile").expect("the fixture sensor");
    assert_eq!(hostile::SENSOR.title, sensor.title);
    assert_eq!(hostile::SENSOR.title, r##"Hostile */ probe "#] \ `x` {} 'q' ""##);
    assert_eq!(hostile::SENSOR.manual, Some(r##"MODBUS RTU */ for "#] hostile {} probes \"##));
    assert_eq!(hostile::SENSOR.revision, Some(r##"Rev "1" */ `2` \"##));
    for id in hostile::CommandId::ALL {
        let c = sensor.command(id.name()).expect("every generated command is in the spec");
        assert_eq!(id.title(), c.title, "{id}");
        let units: Vec<Option<&str>> = id.response_fields().iter().chain(id.request_fields()).map(|f| f.unit).collect();
        let spec_units: Vec<Option<&str>> = c.named_fields().map(|f| f.unit.as_deref()).collect();
        assert_eq!(units, spec_units, "{id}");
    }
    let units: Vec<_> =
        <hostile::GetMaxReadResponse as yosemitech::Message>::FIELDS.iter().map(|f| (f.name, f.unit)).collect();
    assert_eq!(
        units[1..8],
        [
            ("option", Some("*/")),
            ("string", Some("\"#]")),
            ("vec", Some("\\")),
            ("core", Some("`")),
            ("std", Some("{}")),
            ("rtu", Some("'")),
            ("value", Some("µS/cm \"")),
        ]
    );
    assert_eq!(hostile::SETTLE_MS, u32::MAX);
    assert_eq!(hostile::LEVELS, [-1.5, 0.0, 3.25]);
    // The enum of a field named `iterator` does not take the prelude's name.
    assert_eq!(GetMaxReadIterator::KNOWN.len(), 4);
    assert_eq!(GetMaxReadIterator::from_raw(0x0102), GetMaxReadIterator::None);
    assert_eq!(GetMaxReadIterator::from_raw(0x0103), GetMaxReadIterator::Unknown(0x0103));
    assert_eq!(GetMaxReadIterator::Err.to_string(), "err (65535)");
}

#[test]
fn hostile_fixture_decodes_and_encodes_its_examples() {
    let spec = fixture_spec();
    let sensor = spec.sensor("hostile").expect("the fixture sensor");
    let mut frames = 0;
    for c in &sensor.commands {
        let id = hostile::CommandId::from_name(&c.name).expect("a generated command");
        for ex in &c.examples {
            let (ex_request, ex_response) = ex.true_pair().expect("the fixture's examples are complete");
            let (slave, request) = id.decode_request(ex_request).expect("the example request decodes");
            assert_eq!(hostile::identify_request(ex_request), Some(id));
            let (_, values) = c.decode_request(ex_request).expect("the interpreter decodes it");
            same_values(request.fields().map(|(i, v)| (i.name, v)), &values);
            let mut out = [0u8; 256];
            let n = request.encode(slave, &mut out).expect("it encodes");
            assert_eq!(out[..n], ex_request[..], "{}", c.name);

            let response = hostile::decode_response(id, slave, ex_response).expect("the example reply decodes");
            let values = c.decode_response(slave, ex_response).expect("the interpreter decodes it");
            same_values(response.fields().map(|(i, v)| (i.name, v)), &values);
            let n = response.encode(slave, &mut out).expect("it encodes");
            assert_eq!(out[..n], ex_response[..], "{}", c.name);
            frames += 2;
        }
    }
    assert_eq!(frames, 6);

    // The largest frames Modbus allows, typed.
    let read = sensor.command("get_max_read").expect("get_max_read");
    let reply = read.examples[0].true_response().expect("a complete reply");
    assert_eq!(reply.len(), 255);
    let r = GetMaxRead::decode_response(7, reply).expect("the 255-byte reply decodes");
    assert_eq!(r.label.as_str(), Some(r##"Probe */ "#] \ `x` {}"##));
    assert_eq!((r.option, r.string, r.vec, r.core), (1, 255, 0x1234, -2));
    assert_eq!((r.std, r.rtu, r.value), (4_000_000_000, -123_456, 1.5));
    assert_eq!(r.firmware, yosemitech::Version::new(2, 7));
    assert_eq!(r.iterator, GetMaxReadIterator::None);
    let write = sensor.command("set_max_write").expect("set_max_write");
    let request = write.examples[0].true_request().expect("a complete request");
    let (_, w) = SetMaxWrite::decode_request(request).expect("the 255-byte request decodes");
    assert_eq!(request.len(), 255);
    assert_eq!(w.option, -1000);
    assert_eq!(w.string.as_bytes(), b"a\\b\"c*/\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0");
    assert_eq!(w.box_kind, BoxKind::Large);
    assert_eq!(
        SetMaxWrite { option: 1001, ..w }.request_frame(7).err(),
        Some(yosemitech::EncodeError::OutOfRange { field: "option" })
    );
    yosemitech_tests::report!("hostile fixture: {frames} frames decode and re-encode, 255-byte frames included");
}

#[test]
fn hostile_fixture_talks_to_its_simulator() {
    let spec = fixture_spec();
    let sensor = spec.sensor("hostile").expect("the fixture sensor").clone();
    let sim = Simulator::new(sensor);
    let mut client = Client::new(ResponderTransport::new(sim));
    let mut device = hostile::Device::new(&mut client, 7);
    let r = device.max_read().expect("a 255-byte reply through the client");
    assert_eq!(r.value, 1.5);
    assert_eq!(r.iterator, GetMaxReadIterator::None);
    let write = SetMaxWrite {
        option: 7,
        vec: 2.5,
        string: yosemitech::Ascii::from_text("*/ \"#]", 0).expect("ascii"),
        box_kind: BoxKind::Small,
    };
    device.set_max_write(write).expect("a 255-byte request through the client");
    // `response` and `command` are not usable method names: these keep the `get_`.
    assert_eq!(device.get_response().expect("get_response").response_code, 0xBEEF);
    device.get_command().expect("get_command");
    device.get_address().expect("get_address keeps its full name: Device::address is taken");
    device.trigger().expect("a write of no registers");
    assert_eq!(device.address(), 7);
}

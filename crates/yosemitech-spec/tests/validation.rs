//! Validation rules, on small specs held in memory.

use std::path::PathBuf;

use yosemitech_spec::sources::MemSources;
use yosemitech_spec::{Diagnostics, Spec, load_with};

const HEAD: &str = "sensor:
  name: probe
  title: Probe
  doc: A probe.
  manual: {title: Manual, revision: Rev 1}
  serial: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1}
  addresses: {min: 1, max: 247}
  default_address: 1
";

const READ_VALUE: &str = "
  - name: read_value
    function: read
    address: 0x2800
    count: 2
    fields:
      - {name: level, type: f32, byte_order: dcba}
";

fn load(files: &[(&str, &str)]) -> Result<Spec, Diagnostics> {
    let mut sources = MemSources::default();
    for (path, text) in files {
        sources = sources.with(*path, *text);
    }
    load_with(&sources, &[PathBuf::from("spec")])
}

/// Loads one sensor file made of the common head and `rest`; returns the errors.
fn errors(rest: &str) -> Diagnostics {
    let text = format!("{HEAD}{rest}");
    match load(&[("spec/probe.yaml", &text)]) {
        Ok(_) => panic!("expected errors in\n{text}"),
        Err(d) => d,
    }
}

fn assert_error(d: &Diagnostics, line: u32, key: &str, message: &str) {
    assert!(
        d.0.iter().any(|x| x.pos.line == line && x.key == key && x.message.contains(message)),
        "no error at line {line}, key `{key}`, containing `{message}` in\n{d}"
    );
}

#[test]
fn a_minimal_sensor_loads() {
    let spec = load(&[("spec/probe.yaml", &format!("{HEAD}commands:{READ_VALUE}"))]).expect("loads");
    assert_eq!(spec.sensors[0].commands[0].name, "read_value");
}

#[test]
fn register_counts_are_in_modbus_range() {
    let d = errors("commands:\n  - {name: get_x, function: read, address: 1, count: 126, fields: []}\n");
    assert_error(&d, 10, "commands[0] (get_x).count", "register count 126 is out of range for a read");
    let d = errors("commands:\n  - {name: set_x, function: write, address: 1, count: 124, fields: []}\n");
    assert_error(&d, 10, "commands[0] (set_x).count", "out of range for a write");
    let d = errors("commands:\n  - {name: set_x, function: write, address: 1, count: 0}\n");
    assert_error(&d, 10, "commands[0] (set_x).count", "only valid for a trigger");
    assert_eq!(d.len(), 1, "count 0 alone, not a cascade:\n{d}");
}

#[test]
fn a_trigger_is_a_write_of_nothing_or_a_read_whose_reply_is_ignored() {
    let ok = "commands:\n  - {name: start, function: write, address: 0x1C00, count: 0, trigger: true}\n";
    load(&[("spec/probe.yaml", &format!("{HEAD}{ok}"))]).expect("a write trigger loads");
    let ok = "commands:\n  - {name: start, function: read, address: 0x2500, count: 1, trigger: true}\n";
    load(&[("spec/probe.yaml", &format!("{HEAD}{ok}"))]).expect("a read trigger loads");
    let d = errors("commands:\n  - {name: start, function: read, address: 0x1C00, count: 0, trigger: true}\n");
    assert_error(&d, 10, "commands[0] (start).count", "a trigger read asks for 1..=125 registers, not 0");
    let d = errors(
        "commands:\n  - {name: start, function: read, address: 0x2500, count: 1, trigger: true, fields: [{name: x, type: u16, byte_order: ab}]}\n",
    );
    assert_error(&d, 10, "commands[0] (start).fields", "a trigger carries no fields");
}

#[test]
fn partial_frames_state_what_they_can() {
    // "meaningless" data after byte count 0, CRC cells empty: the header is checked.
    let trigger = "commands:\n  - name: stop\n    function: read\n    address: 0x2E00\n    count: 1\n    trigger: true\n    examples:\n      - figures: [33, 34]\n        request: \"01 03 2E 00 00 01 8D 22\"\n        response: \"01 03 00 ...\"\n        response_crc: missing\n        values: {}\n";
    load(&[("spec/probe.yaml", &format!("{HEAD}{trigger}"))]).expect("a partial trigger reply loads");
    // A header byte that contradicts the command is an error.
    let d = errors(&trigger.replace("01 03 00 ...", "01 04 00 ..."));
    assert_error(&d, 18, "commands[0] (stop).examples[0].response", "byte 1 (function) is 0x04");
    // Placeholders need `*_crc: missing`.
    let d = errors(&trigger.replace("        response_crc: missing\n", ""));
    assert_error(&d, 18, "commands[0] (stop).examples[0].response", "placeholders cannot carry a known CRC");
    // A frame printed without its CRC is completed and replayed in full.
    let no_crc = READ_VALUE_EXAMPLE_NO_CRC;
    load(&[("spec/probe.yaml", &format!("{HEAD}commands:{READ_VALUE}{no_crc}"))]).expect("a computed CRC replays");
    let d = errors(&format!("commands:{READ_VALUE}{}", no_crc.replace("F3 40\"", "F3 41\"")));
    assert_error(&d, 21, "commands[0] (read_value).examples[0].values.level", "the frame gives level =");
}

const READ_VALUE_EXAMPLE_NO_CRC: &str = "    examples:\n      - figures: [1]\n        request: \"01 03 28 00 00 02 CD AB\"\n        response: \"01 03 04 33 33 F3 40\"\n        response_crc: missing\n        values: {level: 7.6}\n";

#[test]
fn fields_fill_the_registers_exactly() {
    let d = errors(&format!("commands:{}", READ_VALUE.replace("count: 2", "count: 3")));
    assert_error(&d, 13, "commands[0] (read_value).fields", "cover 4 bytes but 3 registers hold 6");
    let d = errors(&format!("commands:{}", READ_VALUE.replace("count: 2", "count: 1")));
    assert_error(&d, 13, "commands[0] (read_value).fields", "need 4 bytes but 1 registers hold only 2");
    let overlap =
        READ_VALUE.replace("count: 2", "count: 3") + "      - {name: flags, type: u16, byte_order: ab, offset: 2}\n";
    let d = errors(&format!("commands:{overlap}"));
    assert_error(&d, 16, "commands[0] (read_value).fields[1] (flags).offset", "overlap");
}

#[test]
fn names_are_unique_and_rust_safe() {
    let d = errors(&format!("commands:{READ_VALUE}{}", READ_VALUE.replace("0x2800", "0x1200")));
    assert_error(&d, 17, "commands[1] (read_value).name", "two commands are called `read_value`");
    let d = errors(&format!("commands:{}", READ_VALUE.replace("name: level,", "name: type,")));
    assert_error(&d, 15, "commands[0] (read_value).fields[0].name", "`type` is a Rust keyword");
    let d = errors(&format!("commands:{}", READ_VALUE.replace("name: read_value", "name: 'x\"]; fn evil() {'")));
    assert_error(&d, 10, "commands[0].name", "is not a snake_case identifier");
}

#[test]
fn example_crcs_verify_unless_an_erratum_says_otherwise() {
    let example = |response: &str, erratum: &str| {
        format!(
            "commands:{READ_VALUE}    examples:\n      - figures: [1]\n        request: \"01 03 28 00 00 02 CD AB\"\n        response: \"{response}\"\n        values: {{level: 7.6}}\n{erratum}"
        )
    };
    let d = errors(&example("01 03 04 33 33 F3 40 40 79", ""));
    assert_error(&d, 19, "commands[0] (read_value).examples[0].response", "the printed CRC of the response is wrong");
    // With an erratum giving the true frame, the printed one may be wrong.
    let erratum = "        erratum:\n          id: E9\n          figure: 1\n          printed: Wrong CRC.\n          corrected_response: \"01 03 04 33 33 F3 40 40 78\"\n          printed_decodes: false\n";
    let text = format!("{HEAD}{}", example("01 03 04 33 33 F3 40 40 79", erratum));
    let spec = load(&[("spec/probe.yaml", &text)]).unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(spec.summary().printed_frames, 2);
    assert_eq!(spec.summary().frames, 3);
}

#[test]
fn an_erratum_may_complete_a_partial_frame_but_not_change_a_printed_byte() {
    // The manual prints a placeholder and no CRC; the erratum gives the true frame.
    let example = |corrected: &str| {
        format!(
            "commands:{READ_VALUE}    examples:\n      - figures: [1]\n        request: \"01 03 28 00 00 02 CD AB\"\n        response: \"01 03 04 ?? 33 F3 40\"\n        response_crc: missing\n        values: {{level: 7.6}}\n        erratum:\n          id: E9\n          figure: 1\n          printed: A word where byte 3 should be.\n          corrected_response: \"{corrected}\"\n          printed_decodes: false\n"
        )
    };
    let text = format!("{HEAD}{}", example("01 03 04 33 33 F3 40 40 78"));
    let spec = load(&[("spec/probe.yaml", &text)]).unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(spec.summary().frames, 3, "the request, the printed reply and its correction");

    // A correction that changes a printed byte stands for another frame.
    let d = errors(&example("01 03 04 33 34 F3 40 F1 B9"));
    assert_error(&d, 26, "commands[0] (read_value).examples[0].erratum.corrected_response", "byte 4 is printed as 33");
    // Nor may it be longer than the printed frame plus its missing CRC.
    let d = errors(&example("01 03 04 33 33 F3 40 00 79 F0"));
    assert_error(
        &d,
        26,
        "commands[0] (read_value).examples[0].erratum.corrected_response",
        "10 bytes where the printed frame has 9",
    );
}

#[test]
fn stated_values_must_match_the_frame() {
    let text = format!(
        "commands:{READ_VALUE}    examples:\n      - figures: [1]\n        request: \"01 03 28 00 00 02 CD AB\"\n        response: \"01 03 04 33 33 F3 40 40 78\"\n        values: {{level: 7.5}}\n"
    );
    let d = errors(&text);
    assert_error(&d, 20, "commands[0] (read_value).examples[0].values.level", "the frame gives level = 7.6");
}

#[test]
fn includes_must_exist_be_fragments_and_not_cycle() {
    let d = match load(&[("spec/probe.yaml", &format!("{HEAD}include: [missing.yaml]\n"))]) {
        Err(d) => d,
        Ok(_) => panic!("loaded"),
    };
    assert_error(&d, 9, "include[0]", "cannot read included file `missing.yaml`");

    let fragment = |name: &str, include: &str| {
        format!("fragment: {{name: {name}, doc: A fragment.}}\ninclude: [{include}]\ncommands: []\n")
    };
    let (a, b) = (fragment("frag_a", "b.yaml"), fragment("frag_b", "a.yaml"));
    let sensor = format!("{HEAD}include: [a.yaml]\n");
    let d = load(&[("spec/probe.yaml", &sensor), ("spec/a.yaml", &a), ("spec/b.yaml", &b)]).expect_err("a cycle");
    assert_eq!(d.len(), 1, "one cycle, reported once:\n{d}");
    assert!(d.0[0].message.starts_with("include cycle: "), "{d}");
}

#[test]
fn every_error_of_a_file_is_reported_at_once() {
    let text = format!(
        "commands:{}{}",
        READ_VALUE.replace("count: 2", "count: 200"),
        READ_VALUE.replace("name: read_value", "name: self").replace("0x2800", "0x1200")
    );
    let d = errors(&text);
    assert_eq!(d.len(), 2, "{d}");
    assert!(d.to_string().ends_with("could not load the spec due to 2 previous errors"));
}

#[test]
fn yaml_errors_carry_positions_and_keys() {
    let d = errors(&format!("commands:{}", READ_VALUE.replace("address", "adress")));
    assert_error(&d, 12, "commands[0] (read_value).adress", "unknown key `adress`");
    assert!(d.0[0].help.as_deref().is_some_and(|h| h.contains("did you mean `address`?")));
    let d = errors(&format!("commands:{}", READ_VALUE.replace("count: 2", "count: 2\n    count: 3")));
    assert_error(&d, 14, "commands[0] (read_value).count", "duplicate key `count`");
}

#[test]
fn limits_refuse_hostile_input_quickly() {
    // Billion laughs in a stated value (an untagged value serde buffers whole).
    let mut values =
        String::from("        values:\n          level:\n            - &a0 [x, x, x, x, x, x, x, x, x, x]\n");
    for i in 1..10 {
        let refs = vec![format!("*a{}", i - 1); 10].join(", ");
        values.push_str(&format!("            - &a{i} [{refs}]\n"));
    }
    let text = format!(
        "commands:{READ_VALUE}    examples:\n      - figures: [1]\n        request: \"01 03 28 00 00 02 CD AB\"\n        response: \"01 03 04 33 33 F3 40 40 78\"\n{values}"
    );
    let start = std::time::Instant::now();
    let d = errors(&text);
    assert!(start.elapsed() < std::time::Duration::from_secs(5), "took {:?}", start.elapsed());
    assert!(d.0[0].message.contains("aliases expand to more than"), "{d}");
    let big = "#".repeat(yosemitech_spec::sources::MAX_FILE_BYTES as usize + 1);
    let d = load(&[("spec/big.yaml", &big)]).expect_err("too big");
    assert!(d.0[0].message.contains("limited to 1048576 bytes"), "{d}");
}

/// A sensor of two manuals (SW 1.0 by default, SW 2.0 a revision) with one
/// example whose `also_in` is `cite`.
fn two_manuals(cite: &str) -> String {
    format!(
        "sensor:
  name: probe
  title: Probe
  doc: A probe.
  manual:
    title: Manual
    revision: SW Rev1.0
    software: \"1.0\"
    serial_claims:
      - serial: {{baud: 9600, data_bits: 8, parity: none, stop_bits: 2}}
        doc: One build states two stop bits.
  revisions:
    - manual: {{title: Manual, revision: SW Rev2.0, software: \"2.0\"}}
  serial: {{baud: 9600, data_bits: 8, parity: none, stop_bits: 1}}
  addresses: {{min: 1, max: 247}}
  default_address: 1
commands:
  - name: read_value
    function: read
    address: 0x2800
    count: 2
    fields:
      - {{name: level, type: f32, byte_order: dcba}}
    examples:
      - figures: [6]
        request: \"01 03 28 00 00 02 CD AB\"
        also_in: {cite}
"
    )
}

#[test]
fn citations_name_another_manual_and_claims_are_kept_apart_from_serial() {
    let text = two_manuals("[{manual: \"2.0\", figures: [9]}]");
    let spec = load(&[("spec/probe.yaml", &text)]).expect("loads");
    let s = &spec.sensors[0];
    let cited = &s.commands[0].examples[0].also_in;
    assert_eq!((cited[0].manual.as_str(), cited[0].figures[0].to_string()), ("2.0", "9".to_string()));
    assert_eq!(s.manual.as_ref().expect("a manual").serial_claims[0].serial.to_string(), "9600 baud, 8N2");
    assert_eq!(s.serial_for("1.0").to_string(), "9600 baud, 8N1", "a claim is not what clients use");

    for (cite, message) in [
        ("[{manual: \"3.0\", figures: [9]}]", "no manual of this sensor documents software `3.0`"),
        ("[{manual: \"1.0\", figures: [9]}]", "`also_in` cites other manuals"),
        (
            "[{manual: \"2.0\", figures: [9]}, {manual: \"2.0\", figures: [10]}]",
            "already cites the manual of software `2.0`",
        ),
    ] {
        let text = two_manuals(cite);
        let d = load(&[("spec/probe.yaml", &text)]).expect_err(cite);
        assert!(d.0.iter().any(|x| x.pos.line == 27 && x.message.contains(message)), "{cite}: {d}");
    }
}

#[test]
fn an_import_todo_is_an_error_at_its_line_and_column() {
    let text = format!("{HEAD}commands:\n  # TODO(import): section 2.2.1: check the count\n{READ_VALUE}");
    let d = load(&[("spec/probe.yaml", &text)]).expect_err("a TODO is left");
    assert_eq!(d.len(), 1, "{d}");
    assert_eq!((d.0[0].pos.line, d.0[0].pos.column), (10, 5), "{d}");
    assert!(d.0[0].message.contains("section 2.2.1: check the count"), "{d}");
}

//! The draft is the spec's document types serialized: it reads back into them,
//! and each TODO comment sits above the key it concerns.

use super::super::annotate::{annotate, key_paths};
use super::super::document::{Todo, spec_file};
use super::*;

/// The TODOs a draft was written with.
fn todos_of(d: &Draft) -> Vec<Todo> {
    spec_file(d, &d.header, "probe", "test.txt").1
}

/// The key paths that start on the first line below the comment that holds `text`.
fn paths_below(yaml: &str, text: &str) -> Vec<String> {
    let comment = format!("# {}: {text}", yosemitech_spec::IMPORT_TODO);
    let lines: Vec<&str> = yaml.lines().collect();
    let at =
        lines.iter().position(|l| l.trim_start() == comment).unwrap_or_else(|| panic!("no `{comment}` in\n{yaml}"));
    let below = (at + 1..lines.len()).find(|&k| !lines[k].trim_start().starts_with('#')).expect("a line below");
    key_paths(yaml).swap_remove(below)
}

#[test]
fn drafts_read_back_and_their_todos_sit_above_their_keys() {
    let crc = yosemitech_rtu::crc16(&[0x01, 0x03, 0x26, 0x00, 0x00, 0x02]).to_le_bytes();
    let manual = synthetic(&format!("0x{:02X}  0x{:02X}", crc[0], crc[1]));
    let cases = [
        ("no baud rate", manual.replace("Baud rate: 19200bps\n", ""), "sensor.serial"),
        ("no parity", manual.replace("No parity\n", ""), "sensor.serial"),
        ("no revision", manual.replace("hardware Rev2.0 and software Rev3.4", "a board"), "sensor.manual.revision"),
        ("placeholder data", manual.replace("17.625", "Value"), "commands[0]"),
    ];
    for (case, text, key) in cases {
        let d = import(&text).unwrap_or_else(|e| panic!("{case}: {e}"));
        let doc = document(&d);
        let names: Vec<&str> = doc.commands.iter().filter_map(|c| c.name.as_ref()).map(|n| n.value.as_str()).collect();
        let drafted: Vec<&str> = d.commands.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, drafted, "{case}");
        let todos = todos_of(&d);
        assert!(todos.iter().any(|t| t.at == key), "{case}: a TODO at {key}: {todos:?}");
        let written = d.yaml.lines().filter(|l| l.contains(yosemitech_spec::IMPORT_TODO)).count();
        assert_eq!(written, todos.len(), "{case}: one comment per TODO\n{}", d.yaml);
        for t in &todos {
            assert!(paths_below(&d.yaml, &t.text).contains(&t.at), "{case}: {t:?} is not above its key\n{}", d.yaml);
        }
    }
}

#[test]
fn key_paths_name_keys_items_and_skip_block_text() {
    let yaml = "sensor:\n  name: probe\n  doc: |\n    a: b\n    - c\ncommands:\n  - name: one\n    fields:\n      - type: u8\n  - use: two\n";
    let paths = key_paths(yaml);
    let starts = |k: usize| paths[k].iter().map(String::as_str).collect::<Vec<_>>();
    assert_eq!(starts(1), ["sensor.name"]);
    assert!(starts(3).is_empty() && starts(4).is_empty(), "block text has no keys: {paths:?}");
    assert_eq!(starts(6), ["commands[0]", "commands[0].name"]);
    assert_eq!(starts(8), ["commands[0].fields[0]", "commands[0].fields[0].type"]);
    assert_eq!(starts(9), ["commands[1]", "commands[1].use"]);
}

#[test]
fn annotate_keeps_every_todo_and_writes_addresses_in_hex() {
    let yaml = "commands:\n  - name: one\n    address: 9728\n    examples:\n      - values:\n          address: 12\n  - name: two\n";
    let todos = [
        Todo { at: "commands[1]".into(), text: "second".into() },
        Todo { at: "nowhere".into(), text: "lost key".into() },
    ];
    let out = annotate(yaml, &todos);
    let lines: Vec<&str> = out.lines().collect();
    let second = lines.iter().position(|l| *l == "  # TODO(import): second").expect("the TODO is written");
    assert_eq!(lines[second + 1], "  - name: two", "{out}");
    assert!(lines[second - 1].is_empty(), "a blank line between commands: {out}");
    assert!(out.starts_with("# TODO(import): lost key\n"), "a TODO without its key goes first: {out}");
    assert!(out.contains("    address: 0x2600\n"), "{out}");
    assert!(out.contains("          address: 12\n"), "a stated value stays decimal: {out}");
}

#[test]
fn stated_numbers_read_back_as_written() {
    use super::super::annotate::yaml_of;
    for n in [20.0, 17.625, -3.0, 0.1] {
        let yaml = yaml_of(&StatedValue::Number(n)).expect("serializes");
        let back: StatedValue = yosemitech_spec::from_yaml_str(&yaml).expect("reads back");
        assert_eq!(back, StatedValue::Number(n), "{yaml}");
        assert_eq!(yaml.trim().contains('.'), n.fract() != 0.0, "a whole number has no fraction: {yaml}");
    }
}

/// The data as the document types read it: every number an `f64` (a range
/// written `50` is written back as `50.0`, the same number), and an empty
/// list or a null the same as an absent key (`after: []`, a default).
fn as_read(value: serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match value {
        Value::Number(n) => n.as_f64().map_or(Value::Number(n), Value::from),
        Value::Array(items) => Value::Array(items.into_iter().map(as_read).collect()),
        Value::Object(map) => Value::Object(
            map.into_iter()
                .filter(|(_, v)| !v.is_null() && v.as_array().is_none_or(|a| !a.is_empty()))
                .map(|(k, v)| (k, as_read(v)))
                .collect(),
        ),
        other => other,
    }
}

/// Serializing loses nothing the document types hold: every reviewed spec,
/// read into them and written, is the same YAML data as its file.
#[test]
fn every_reviewed_spec_survives_a_read_and_a_write() {
    use super::super::annotate::yaml_of;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../spec");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("spec/")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "spec/ has YAML files");
    for path in files {
        let text = std::fs::read_to_string(&path).expect("readable");
        let data = |text: &str| -> serde_json::Value {
            as_read(yosemitech_spec::from_yaml_str(text).unwrap_or_else(|e| panic!("{}: {e}\n{text}", path.display())))
        };
        let document: SpecFile = yosemitech_spec::from_yaml_str(&text).expect("a reviewed spec reads");
        let written = yaml_of(&document).expect("serializes");
        assert_eq!(data(&written), data(&text), "{}:\n{written}", path.display());
    }
}

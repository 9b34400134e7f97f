//! The real `spec/` directory loads and holds what the manuals print.

use std::path::PathBuf;

use yosemitech_spec::{Spec, load_paths};

fn spec() -> Spec {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../spec");
    match load_paths(&[dir]) {
        Ok(spec) => spec,
        Err(d) => panic!("spec/ does not load:\n{d}"),
    }
}

#[test]
fn loads_both_manuals() {
    let spec = spec();
    assert_eq!(spec.sensors.len(), 2);
    let ph = spec.sensor("ph_orp").expect("ph_orp");
    let cond = spec.sensor("conductivity").expect("conductivity");
    assert_eq!(ph.commands.len(), 16);
    assert_eq!(cond.commands.len(), 7);
    // Every command of both manuals has one printed example.
    assert!(spec.sensors.iter().flat_map(|s| &s.commands).all(|c| c.examples.len() == 1));
    // The shared fragment is included by both.
    assert!(ph.files.iter().any(|f| f.ends_with("yosemitech-common.yaml")));
    assert_eq!(ph.command("get_sn").and_then(|c| c.shared_from.as_deref()), Some("yosemitech_common"));
}

#[test]
fn summary_counts_printed_frames_honestly() {
    let s = spec().summary();
    assert_eq!(s.sensors, 2);
    assert_eq!(s.commands, 23);
    assert_eq!(s.examples, 23);
    // Two frames per example are printed; errata E4 and E5 add a correction each.
    assert_eq!(s.printed_frames, 46);
    assert_eq!(s.frames, 48);
    assert_eq!(s.errata, 25);
}

#[test]
fn errata_are_where_the_notes_put_them() {
    let spec = spec();
    let ph = spec.sensor("ph_orp").expect("ph_orp");
    let get_orp_cal = ph.command("get_orp_calibration").expect("get_orp_calibration");
    assert_eq!(get_orp_cal.address, 0x3400);
    assert_eq!(get_orp_cal.errata[0].table_address, Some(0x1100));
    let status = ph.command("get_calibration_status").expect("get_calibration_status");
    let e5 = status.examples[0].erratum.as_ref().expect("E5");
    assert_eq!(e5.id, "E5");
    assert!(!e5.printed_decodes);
    assert_eq!(status.examples[0].true_response(), [0x01, 0x03, 0x02, 0x00, 0x00, 0xB8, 0x44]);
    let cond = spec.sensor("conductivity").expect("conductivity");
    let start = cond.command("start_measurement").expect("start_measurement");
    assert!(start.trigger);
    assert_eq!(start.count, 0);
}

#[test]
fn schema_describes_the_spec_files() {
    let schema = yosemitech_spec::json_schema();
    assert_eq!(schema["title"], "Yosemitech Modbus sensor spec");
    let command = &schema["$defs"]["CommandDoc"];
    for key in ["name", "use", "function", "address", "count", "fields", "examples"] {
        assert!(command["properties"].get(key).is_some(), "CommandDoc lacks `{key}`");
    }
    assert_eq!(command["additionalProperties"], false);
    // The committed schema is the generated one.
    let committed = std::fs::read_to_string(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../spec/schema.json"))
        .expect("spec/schema.json");
    let mut generated = serde_json::to_string_pretty(&schema).expect("json");
    generated.push('\n');
    assert!(committed == generated, "spec/schema.json is stale; run cargo xtask schema");
}

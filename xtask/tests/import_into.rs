//! `cargo xtask import MANUAL --into SPEC`: exit codes, files written or
//! not, the review and its JSON, on a made-up probe (no vendor text) and on
//! the recorded manuals of `../shared/` (skipped, loudly, without them).

use std::path::{Path, PathBuf};
use std::process::Command;

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("xtask-import-into-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs xtask with `args`: (exit code, stdout, stderr).
fn xtask(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_xtask")).args(args).output().unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The CRC of `bytes` as a manual's Value row prints it.
fn crc(bytes: &[u8]) -> String {
    let [lo, hi] = yosemitech_rtu::crc16(bytes).to_le_bytes();
    format!("0x{lo:02X}  0x{hi:02X}")
}

/// A made-up manual in the vendor's template: software `sw`, two stop
/// bits, one read section per entry (number, title, high address byte,
/// figures, the value printed in the reply).
fn manual_with(sw: &str, sections: &[(&str, &str, u8, [u32; 3], &str)]) -> String {
    let section = |(n, title, addr, figs, value): &(&str, &str, u8, [u32; 3], &str)| {
        format!(
            "{n} {title}\nStart address   Number of registers   Register 1-2   MODBUS function code\n  0x{addr:02X}00          0x02                Value           0x03\nFigure {}: Register definition of {title}\n\
Definition  Address  Function  Start address  Number of registers  CRC\n Byte  0  1  2  3  4  5  6  7\n Value  0x01  0x03  0x{addr:02X}  0x00  0x00  0x02  {}\nFigure {}: Request frame to {title}\n\
Definition  Address  Function  Number of bytes  Register value  CRC\n Byte  0  1  2  3-6  7  8\n Value  0x01  0x03  0x04  {value}\nFigure {}: Response frame for {title}\n\n",
            figs[0],
            crc(&[0x01, 0x03, *addr, 0x00, 0x00, 0x02]),
            figs[1],
            figs[2]
        )
    };
    let body: String = sections.iter().map(section).collect();
    format!(
        "Yosemitech test probe\n\nMODBUS RTU\n\n1.1 Scope\nA probe with hardware Rev2.0 and software Rev{sw} or later.\nBaud rate: 19200bps\n8 data bits\nNo parity\n2 stop bits\n\n2.2 Command Description\n\n{body}3 Procedure\nDelay 2s, then read.\n"
    )
}

/// SW 3.4: Get Pressure (new) before Get Level (as recorded, renumbered).
fn manual_text() -> String {
    manual_with(
        "3.4",
        &[("2.2.1", "Get Pressure", 0x24, [5, 6, 7], "21.5"), ("2.2.2", "Get Level", 0x26, [8, 9, 10], "17.625")],
    )
}

/// The made-up probe's spec, transcribing its SW 1.0 manual (Get Level only).
fn spec() -> String {
    let request = {
        let c = crc(&[0x01, 0x03, 0x26, 0x00, 0x00, 0x02]).replace("0x", "").replace("  ", " ");
        format!("01 03 26 00 00 02 {c}")
    };
    format!(
        "sensor:\n  name: probe\n  title: Test level probe\n  doc: A made-up probe.\n  model: Z100\n  model_code: \"99\"\n  manual:\n    title: Test level probe manual\n    revision: HW Rev2.0 / SW Rev1.0 or later\n    software: \"1.0\"\n    file: level-1.0.txt\n  serial: {{baud: 19200, data_bits: 8, parity: none, stop_bits: 1}}\n  addresses: {{min: 1, max: 247}}\n  default_address: 1\n\n\
commands:\n  - name: get_level\n    title: Get Level\n    doc: The level.\n    source: {{section: \"2.2.1\", figures: [5, 6, 7]}}\n    function: read\n    address: 0x2600\n    count: 2\n    fields:\n      - {{name: level, type: f32, byte_order: dcba, unit: m, doc: Level.}}\n    examples:\n      - figures: [6, 7]\n        request: \"{request}\"\n        response: \"01 03 04 00 00 8D 41\"\n        response_crc: missing\n        values: {{level: 17.625}}\n"
    )
}

const OTHER: &str = "sensor:\n  name: other\n  title: Made-up salinity probe\n  doc: Another made-up probe.\n  manual: {title: Salinity manual, revision: SW Rev1.0, software: \"1.0\"}\n  serial: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1}\n  addresses: {min: 1, max: 247}\n  default_address: 1\n\ncommands:\n  - name: set_k\n    function: write\n    address: 0x1100\n    count: 2\n    fields:\n      - {name: k, type: f32, byte_order: dcba}\n";

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_new_revision_is_merged_reviewed_and_refused_where_it_must_be() {
    let d = dir("made-up");
    let manual = d.join("level-3.4.txt");
    std::fs::write(&manual, manual_text()).unwrap();
    let into = d.join("probe.yaml");
    std::fs::write(&into, spec()).unwrap();
    std::fs::write(d.join("other.yaml"), OTHER).unwrap();
    let (code, _, err) = xtask(&["validate", s(&d)]);
    assert_eq!(code, 0, "the made-up specs validate: {err}");

    // --out is the spec itself: refused before anything is done.
    let (code, _, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&into)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("is the spec itself") && err.lines().count() == 1, "{err}");

    // The merge, with its review.
    let out = d.join("merged.yaml");
    let (code, review, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&out)]);
    assert_eq!(code, 0, "{err}\n{review}");
    println!("{review}");
    for want in [
        "revision: SW 3.4, newer than every recorded manual (1.0)",
        "+ get_pressure",
        "since \"3.4\"",
        "= get_level",
        "Figs 9, 10",
        "section 2.2.1 -> 2.2.2, Figs 5, 6, 7 -> 8, 9, 10",
        "the manual states 19200 8N2, the spec 19200 8N1: recorded as `serial_claims`",
        "2 s",
        "TODO(import) left in the merged file: none",
    ] {
        assert!(review.contains(want), "the review lacks `{want}`:\n{review}");
    }
    let merged = std::fs::read_to_string(&out).unwrap();
    assert!(
        merged.starts_with(&spec()[..spec().find("  serial:").unwrap()]),
        "the original's lines are kept:\n{merged}"
    );
    for want in [
        "also_in:\n          - manual: \"3.4\"\n            figures: [9, 10]",
        "since: \"3.4\"",
        "stop_bits: 2}",
        "values:\n          value: 21.5",
    ] {
        assert!(merged.contains(want), "the merged spec lacks `{want}`:\n{merged}");
    }
    assert!(
        merged.find("- name: get_pressure").unwrap() < merged.find("- name: get_level").unwrap(),
        "in the manual's order"
    );
    assert_eq!(std::fs::read_to_string(&into).unwrap(), spec(), "the original is untouched");
    let (code, _, err) = xtask(&["validate", s(&out)]);
    assert_eq!(code, 0, "the merged spec validates: {err}\n{merged}");

    // --out exists: refused, the file kept.
    let (code, _, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&out)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("exists"), "{err}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), merged);

    // The same manual into the merged spec: nothing new, exit 0, no file.
    std::fs::rename(&out, &into).unwrap();
    let again = d.join("again.yaml");
    let (code, review, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&again)]);
    assert_eq!(code, 0, "{err}");
    assert!(review.contains("nothing new"), "{review}");
    assert!(!again.exists(), "nothing written");
    let (code, json, _) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&again), "--json"]);
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&json).expect("the review as JSON");
    assert_eq!(v["nothing_new"], serde_json::Value::Bool(true), "{json}");
    assert!(!again.exists());

    // A manual of another probe: refused, naming the spec it belongs to.
    let (code, _, err) = xtask(&["import", s(&manual), "--into", s(&d.join("other.yaml")), "--out", s(&again)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("not a manual of `other`") && err.contains("probe.yaml"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!again.exists());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn the_review_as_json_carries_the_same_points() {
    let d = dir("json");
    let manual = d.join("level-3.4.txt");
    std::fs::write(&manual, manual_text()).unwrap();
    let into = d.join("probe.yaml");
    std::fs::write(&into, spec()).unwrap();
    let out = d.join("merged.yaml");
    let (code, json, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&out), "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&json).expect("JSON");
    assert_eq!(v["software"], "3.4");
    assert_eq!(v["commands_added"][0]["name"], "get_pressure");
    assert_eq!(v["commands_added"][0]["address"], "0x2400");
    assert_eq!(v["frames_cited"][0]["command"], "get_level");
    assert_eq!(v["figures_renumbered"][0]["section_to"], "2.2.2");
    assert_eq!(v["serial"]["manual"], "19200 8N2");
    assert!(v["todos"].as_array().is_some_and(Vec::is_empty), "{json}");
    assert!(out.exists());
    std::fs::remove_dir_all(&d).ok();
}

/// The made-up spec with two more reads, without examples.
fn spec3() -> String {
    let read = |name: &str, addr: u16| {
        format!(
            "  - name: {name}\n    function: read\n    address: 0x{addr:04X}\n    count: 2\n    fields:\n      - {{name: value, type: f32, byte_order: dcba}}\n"
        )
    };
    spec() + &read("get_redox", 0x2800) + &read("get_depth", 0x2200)
}

/// An older manual: the recorded command it lacks gets `since`, the one only
/// it has is a TODO (the spec language cannot say a command was removed),
/// and `validate` rejects the merged file at that TODO until it is resolved.
#[test]
fn an_older_manual_sets_since_and_leaves_a_todo_validate_rejects() {
    let d = dir("older");
    let manual = d.join("level-0.5.txt");
    let sections = [
        ("2.2.1", "Get Level", 0x26, [5, 6, 7], "17.625"),
        ("2.2.2", "Get Redox", 0x28, [8, 9, 10], "1.5"),
        ("2.2.3", "Get Pressure", 0x24, [11, 12, 13], "21.5"),
    ];
    std::fs::write(&manual, manual_with("0.5", &sections)).unwrap();
    let into = d.join("probe.yaml");
    std::fs::write(&into, spec3()).unwrap();
    let out = d.join("merged.yaml");
    let (code, review, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&out)]);
    assert_eq!(code, 0, "{err}");
    println!("{review}");
    assert!(review.contains("older than every recorded manual (1.0)"), "{review}");
    assert!(review.contains("get_depth") && review.contains("since \"1.0\""), "{review}");
    assert!(review.contains("the spec language cannot say a command was removed"), "{review}");
    let merged = std::fs::read_to_string(&out).unwrap();
    let todo = merged.lines().position(|l| l.contains("# TODO(import)")).expect("a TODO in the merged file") + 1;
    let (code, _, err) = xtask(&["validate", s(&out)]);
    assert_eq!(code, 1, "validate rejects the merged file:\n{merged}");
    assert!(err.contains(&format!("merged.yaml:{todo}:")) && err.contains("import TODO is unresolved"), "{err}");
    std::fs::remove_dir_all(&d).ok();
}

/// A frame the new manual prints otherwise: an example of its own, its
/// values decoded with the spec's fields, the bytes that differ reviewed.
#[test]
fn a_frame_that_differs_becomes_an_example_of_the_new_manual() {
    let d = dir("differs");
    let manual = d.join("level-2.0.txt");
    std::fs::write(&manual, manual_with("2.0", &[("2.2.1", "Get Level", 0x26, [5, 6, 7], "2.5")])).unwrap();
    let into = d.join("probe.yaml");
    std::fs::write(&into, spec()).unwrap();
    let out = d.join("merged.yaml");
    let (code, review, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&out)]);
    assert_eq!(code, 0, "{err}");
    println!("{review}");
    assert!(review.contains("frames that differ (1):") && review.contains("! get_level"), "{review}");
    assert!(review.contains("printed:  01 03 04 00 00 20 40") && review.contains("bytes 5, 6"), "{review}");
    let merged = std::fs::read_to_string(&out).unwrap();
    assert!(
        merged.contains("        manual: \"2.0\"\n") && merged.contains("values:\n          level: 2.5"),
        "{merged}"
    );
    let (code, _, err) = xtask(&["validate", s(&out)]);
    assert_eq!(code, 0, "{err}\n{merged}");
    std::fs::remove_dir_all(&d).ok();
}

/// A command the new manual documents at another address: a change and a
/// TODO (one layout per command), not an addition and a removal.
#[test]
fn a_command_at_another_address_is_a_change() {
    let d = dir("moved");
    let manual = d.join("level-2.0.txt");
    let sections = [
        ("2.2.1", "Get Level", 0x27, [5, 6, 7], "17.625"),
        ("2.2.2", "Get Redox", 0x28, [8, 9, 10], "1.5"),
        ("2.2.3", "Get Depth", 0x22, [11, 12, 13], "2.5"),
    ];
    std::fs::write(&manual, manual_with("2.0", &sections)).unwrap();
    let into = d.join("probe.yaml");
    std::fs::write(&into, spec3()).unwrap();
    let out = d.join("merged.yaml");
    let (code, review, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&out)]);
    assert_eq!(code, 0, "{err}");
    println!("{review}");
    assert!(review.contains("commands added: none") && review.contains("commands removed: none"), "{review}");
    assert!(review.contains("~ get_level") && review.contains("address: spec 0x2600, manual 0x2700"), "{review}");
    let merged = std::fs::read_to_string(&out).unwrap();
    assert!(
        merged.contains("# TODO(import): section 2.2.1 (\"Get Level\") of SW 2.0's manual gives address 0x2700"),
        "{merged}"
    );
    std::fs::remove_dir_all(&d).ok();
}

/// Bad input to `--into`: one message, exit 2, nothing written.
#[test]
fn bad_input_to_into_exits_2() {
    let d = dir("bad");
    let manual = d.join("level-3.4.txt");
    std::fs::write(&manual, manual_text()).unwrap();
    let into = d.join("probe.yaml");
    std::fs::write(&into, spec()).unwrap();
    let broken = d.join("broken.yaml");
    std::fs::write(&broken, "sensor: [\n").unwrap();
    let not_yosemitech = d.join("minutes.txt");
    std::fs::write(&not_yosemitech, "Minutes of the meeting\n").unwrap();
    let out = d.join("out.yaml");
    for (args, expect) in [
        (vec!["import", s(&manual), "--into", s(&d.join("absent.yaml")), "--out", s(&out)], "absent.yaml"),
        (vec!["import", s(&manual), "--into", s(&broken), "--out", s(&out)], "does not validate"),
        (vec!["import", s(&not_yosemitech), "--into", s(&into), "--out", s(&out)], "not a Yosemitech"),
        (vec!["import", s(&manual), "--into", s(&into), "--name", "x"], "--name"),
        (vec!["import", s(&manual), "--json"], "--json goes with --into"),
    ] {
        let (code, _, err) = xtask(&args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "{args:?}: nothing written");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// The vendor manuals next to the repository, when present.
fn shared() -> Option<PathBuf> {
    let s = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared");
    s.is_dir().then_some(s)
}

/// Each manual a spec of `spec/` records, imported into that spec: nothing
/// new, exit 0, no file (the drop-in corpus, which names no manual, stays out).
#[test]
fn a_recorded_manual_is_nothing_new_on_the_command_line() {
    let Some(shared) = shared() else {
        eprintln!(
            "\n*** SKIPPED: ../shared (the vendor manuals) is absent next to the repository; `import --into` on recorded manuals was NOT run ***\n"
        );
        return;
    };
    let spec_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../spec");
    let d = dir("recorded");
    let mut sensors: Vec<(PathBuf, Vec<PathBuf>)> = Vec::new();
    for e in std::fs::read_dir(&spec_dir).unwrap().flatten() {
        let p = e.path();
        if p.extension().is_none_or(|x| x != "yaml") {
            continue;
        }
        let text = std::fs::read_to_string(&p).unwrap();
        let manuals: Vec<PathBuf> = text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("file: "))
            .map(|f| f.trim().trim_matches('"'))
            .filter(|f| f.ends_with(".txt"))
            .flat_map(|f| [shared.join("seeds").join(f), shared.join("manuals").join(f)])
            .filter(|p| p.is_file())
            .collect();
        let fragment = text.lines().any(|l| l.starts_with("fragment:"));
        if fragment || !manuals.is_empty() {
            let copy = d.join(p.file_name().unwrap());
            std::fs::copy(&p, &copy).unwrap();
            if !manuals.is_empty() {
                sensors.push((copy, manuals));
            }
        }
    }
    let mut checked = 0;
    for (spec, manuals) in &sensors {
        for m in manuals {
            let out = d.join("out.yaml");
            let (code, review, err) = xtask(&["import", s(m), "--into", s(spec), "--out", s(&out)]);
            assert_eq!(code, 0, "{}: {err}", m.display());
            assert!(review.contains("nothing new"), "{}:\n{review}", m.display());
            assert!(!out.exists(), "nothing written");
            checked += 1;
        }
    }
    assert!(checked > 0);
    println!("import --into: {checked} recorded manuals, nothing new on the command line");
    std::fs::remove_dir_all(&d).ok();
}

/// A register table that disagrees with the frames it sits above: the merge
/// records it as an erratum of the new manual (its words as the spec's
/// `table:`, the address in hex), and the merged spec validates.
#[test]
fn a_register_table_the_frames_contradict_becomes_an_erratum_of_the_new_manual() {
    let d = dir("table-erratum");
    let manual = d.join("level-2.0.txt");
    let text = manual_with("2.0", &[("2.2.1", "Get Level", 0x26, [5, 6, 7], "17.625")]);
    let table_row = "  0x2600          0x02";
    assert!(text.contains(table_row), "the made-up manual's register table: {text}");
    std::fs::write(&manual, text.replacen(table_row, "  0x2700          0x02", 1)).unwrap();
    let into = d.join("probe.yaml");
    std::fs::write(&into, spec()).unwrap();
    let out = d.join("merged.yaml");
    let (code, review, err) = xtask(&["import", s(&manual), "--into", s(&into), "--out", s(&out)]);
    assert_eq!(code, 0, "{err}\n{review}");
    let merged = std::fs::read_to_string(&out).unwrap();
    let errata = merged.find("    errata:\n").unwrap_or_else(|| panic!("no errata in the merged spec:\n{merged}"));
    let erratum = &merged[errata..];
    for want in ["manual: \"2.0\"", "figure: 5", "table:\n", "address: 0x2700"] {
        assert!(erratum.contains(want), "the erratum lacks `{want}`:\n{merged}");
    }
    // A person checks the erratum the merge could not match to a known one,
    // and deletes the TODO: what is left validates.
    assert!(merged.contains("address 0x2700 against the printed frames: check erratum"), "{merged}");
    let checked: String = merged.lines().filter(|l| !l.contains("# TODO(import)")).map(|l| format!("{l}\n")).collect();
    std::fs::write(&out, &checked).unwrap();
    let (code, _, err) = xtask(&["validate", s(&out)]);
    assert_eq!(code, 0, "{err}\n{checked}");
    std::fs::remove_dir_all(&d).ok();
}

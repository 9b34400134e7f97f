//! The malformed-spec corpus: every file or directory under
//! `tests/specs/malformed/` must be rejected, without a panic, quickly, with
//! diagnostics that point at the offending place (`file:line:column`). The
//! full rendered text of each rejection is snapshotted, so a change in wording
//! or position shows up in review. The files under `hostile-but-valid/` carry
//! text that would break naive code generation but is legal; they must load.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use yosemitech_spec::sources::{MAX_FILE_BYTES, MemSources};
use yosemitech_spec::{Diagnostics, Spec, load_paths, load_with};

/// The directory of hostile files that must load.
const VALID_DIR: &str = "hostile-but-valid";

/// Where each case's first diagnostic must point: `case` -> `file:line:column`.
const FIRST_LOCATION: &[(&str, &str)] = &[
    ("alias-bomb", "alias-bomb.yaml:28:31"),
    ("ascii-size-huge", "ascii-size-huge.yaml:17:50"),
    ("bidi-override-in-doc", "bidi-override-in-doc.yaml:13:10"),
    ("byte-order-mismatch", "byte-order-mismatch.yaml:17:54"),
    ("comment-only", "comment-only.yaml:1:1"),
    ("control-chars-in-doc", "control-chars-in-doc.yaml:13:12"),
    ("count-huge", "count-huge.yaml:15:12"),
    ("count-negative", "count-negative.yaml:15:12"),
    ("count-read-126", "count-read-126.yaml:15:12"),
    ("count-write-124", "count-write-124.yaml:15:12"),
    ("count-zero-without-trigger", "count-zero-without-trigger.yaml:15:12"),
    ("crc-wrong-without-erratum", "crc-wrong-without-erratum.yaml:21:19"),
    ("deep-nesting", "deep-nesting.yaml:22:"),
    ("derived-bad-syntax", "derived-bad-syntax.yaml:31:63"),
    ("derived-example-wrong", "derived-example-wrong.yaml:33:63"),
    ("derived-result-unit", "derived-result-unit.yaml:31:12"),
    ("derived-unit-mismatch", "derived-unit-mismatch.yaml:31:61"),
    ("derived-unknown-field", "derived-unknown-field.yaml:29:37"),
    ("derived-unknown-name", "derived-unknown-name.yaml:34:11"),
    ("duplicate-command", "duplicate-command.yaml:18:11"),
    ("duplicate-field", "duplicate-field.yaml:18:16"),
    ("duplicate-key", "duplicate-key.yaml:16:5"),
    ("duplicate-register", "duplicate-register.yaml:18:11"),
    ("duplicate-sensor", "duplicate-sensor/second.yaml:3:9"),
    ("duplicate-variant-and-constant", "duplicate-variant-and-constant.yaml:22:20"),
    ("empty-file", "empty-file.yaml:1:1"),
    ("enum-code-too-big", "enum-code-too-big.yaml:22:41"),
    ("enum-duplicate-codes", "enum-duplicate-codes.yaml:23:43"),
    ("erratum-correction-equals-printed", "erratum-correction-equals-printed.yaml:27:31"),
    ("example-unknown-field", "example-unknown-field.yaml:22:17"),
    ("fragment-with-sensor-keys", "fragment-with-sensor-keys.yaml:7:10"),
    ("frame-not-hex", "frame-not-hex.yaml:21:19"),
    ("gap-between-fields", "gap-between-fields.yaml:18:55"),
    ("huge-file", "huge.yaml:1:1"),
    ("import-todo-left", "import-todo-left.yaml:13:5"),
    ("include-cycle", "include-cycle/b.yaml:7:5"),
    ("include-non-fragment", "include-non-fragment/sensor.yaml:12:5"),
    ("include-not-relative-yaml", "include-not-relative-yaml.yaml:12:5"),
    ("keyword-name-self", "keyword-name-self.yaml:12:11"),
    ("keyword-name-type", "keyword-name-type.yaml:17:16"),
    ("missing-include", "missing-include.yaml:12:5"),
    ("missing-required-key", "missing-required-key.yaml:2:1"),
    ("name-carries-code", "name-carries-code.yaml:12:11"),
    ("name-not-snake-case", "name-not-snake-case.yaml:12:11"),
    ("names-collide-after-conversion", "names-collide-after-conversion.yaml:18:11"),
    ("not-utf8", "not-utf8.yaml:4:13"),
    ("overlapping-fields", "overlapping-fields.yaml:18:57"),
    ("partial-request-wrong-length", "partial-request-wrong-length.yaml:21:18"),
    ("printed-decodes-wrong", "printed-decodes-wrong.yaml:34:28"),
    ("request-does-not-encode", "request-does-not-encode.yaml:20:18"),
    ("request-wrong-register", "request-wrong-register.yaml:20:18"),
    ("sensor-and-fragment", "sensor-and-fragment.yaml:11:1"),
    ("sensor-settings-out-of-range", "sensor-settings-out-of-range.yaml:7:18"),
    ("sensor-without-commands", "sensor-without-commands.yaml:3:9"),
    ("size-too-few", "size-too-few.yaml:15:12"),
    ("size-too-many", "size-too-many.yaml:15:12"),
    ("stated-value-disagrees", "stated-value-disagrees.yaml:22:22"),
    ("stated-value-is-a-list", "stated-value-is-a-list.yaml:22:22"),
    ("two-documents", "two-documents.yaml:10:1"),
    ("unknown-function", "unknown-function.yaml:13:15"),
    ("unknown-key", "unknown-key.yaml:14:5"),
    ("use-changes-definition", "use-changes-definition/sensor.yaml:16:12"),
    ("user-calibration-shape", "user-calibration-shape.yaml:25:11"),
    ("user-calibration-unknown-field", "user-calibration-unknown-field.yaml:27:25"),
    ("user-calibration-unpaired", "user-calibration-unpaired.yaml:18:11"),
    ("use-unknown-command", "use-unknown-command/sensor.yaml:15:10"),
    ("wrong-type", "wrong-type.yaml:15:12"),
    ("yaml-1-1-boolean", "yaml-1-1-boolean.yaml:16:14"),
    ("yaml-tab-indent", "yaml-tab-indent.yaml:14:1"),
    ("yaml-three-errors", "yaml-three-errors.yaml:13:12"),
    ("yaml-unclosed-bracket", "yaml-unclosed-bracket.yaml:19:18"),
    ("yaml-unclosed-quote", "yaml-unclosed-quote.yaml:13:12"),
    ("yaml-unquoted-comma", "yaml-unquoted-comma.yaml:17:60"),
];

/// Replacements for one byte of a real spec file: YAML's special characters.
const MUTATIONS: &[&str] = &["\t", "\"", "[", "&a ", "*", ":", "- ", "9", "{", "\u{0}"];

/// Longest a case may take to load (debug build, busy machine).
const TIME_LIMIT: Duration = Duration::from_secs(10);

fn corpus() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("specs").join("malformed")
}

/// Loads `paths`, turning a panic into a test failure that names the case.
fn load_case(name: &str, paths: &[PathBuf]) -> Result<Spec, Diagnostics> {
    let start = Instant::now();
    let result = catch_unwind(AssertUnwindSafe(|| load_paths(paths)));
    let elapsed = start.elapsed();
    assert!(elapsed < TIME_LIMIT, "{name}: loading took {elapsed:?}");
    match result {
        Ok(r) => r,
        Err(_) => panic!("{name}: the loader panicked"),
    }
}

/// The rendered diagnostics with `base` stripped from every path, so the
/// snapshot does not depend on where the repository is checked out.
fn render(mut diags: Diagnostics, base: &Path) -> String {
    for d in &mut diags.0 {
        if let Ok(rel) = d.file.strip_prefix(base) {
            d.file = rel.to_path_buf();
        }
    }
    let prefix = format!("{}{}", base.display(), std::path::MAIN_SEPARATOR);
    diags.to_string().replace(&prefix, "")
}

/// Checks one rejected case and snapshots its text.
fn check_rejected(name: &str, result: Result<Spec, Diagnostics>, base: &Path) {
    let diags = match result {
        Ok(spec) => panic!("{name}: expected errors, but it loaded {:?}", spec.summary()),
        Err(d) => d,
    };
    assert!(!diags.is_empty(), "{name}: an error without diagnostics");
    for d in &diags.0 {
        assert!(d.pos.line > 0, "{name}: a diagnostic without a position:\n{d}");
        assert!(!d.message.is_empty(), "{name}: an empty message");
    }
    let text = render(diags, base);
    let arrows: Vec<&str> = text.lines().filter_map(|l| l.trim_start().strip_prefix("--> ")).collect();
    assert!(!arrows.is_empty(), "{name}: no `-->` line in\n{text}");
    for a in &arrows {
        let mut parts = a.rsplitn(3, ':');
        let column = parts.next().and_then(|c| c.parse::<u32>().ok());
        let line = parts.next().and_then(|l| l.parse::<u32>().ok());
        assert!(
            line.is_some_and(|l| l > 0) && column.is_some_and(|c| c > 0),
            "{name}: `--> {a}` has no line:column in\n{text}"
        );
    }
    let want = FIRST_LOCATION
        .iter()
        .find(|(case, _)| *case == name)
        .map(|(_, at)| *at)
        .unwrap_or_else(|| panic!("{name}: add the expected first location to FIRST_LOCATION"));
    assert!(arrows[0].starts_with(want), "{name}: first diagnostic at `{}`, expected `{want}`:\n{text}", arrows[0]);
    insta::assert_snapshot!(name, text);
}

/// The cases: every `*.yaml` file and every directory but the valid one.
fn cases() -> Vec<(String, PathBuf)> {
    let mut out: Vec<(String, PathBuf)> = std::fs::read_dir(corpus())
        .expect("the corpus directory exists")
        .map(|e| e.expect("a readable directory entry").path())
        .filter(|p| p.file_name().is_some_and(|n| n != VALID_DIR))
        .filter(|p| p.is_dir() || p.extension().is_some_and(|e| e == "yaml"))
        .map(|p| {
            let stem = p.file_stem().expect("a file name").to_string_lossy().into_owned();
            (stem, p)
        })
        .collect();
    out.sort();
    out
}

#[test]
fn malformed_specs_are_rejected_with_positions() {
    let base = corpus();
    let cases = cases();
    for (name, path) in &cases {
        let result = load_case(name, std::slice::from_ref(path));
        check_rejected(name, result, &base);
    }
    let huge = huge_file_case();
    let total = cases.len() + usize::from(huge);
    assert!(total >= 30, "the corpus has only {total} cases");
    assert_eq!(total, FIRST_LOCATION.len(), "FIRST_LOCATION lists a case that no longer exists");
    println!("spec corpus: {total} malformed cases rejected");
}

/// A file over the size limit, generated rather than committed.
fn huge_file_case() -> bool {
    let dir = std::env::temp_dir().join(format!("yosemitech-spec-corpus-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let path = dir.join("huge.yaml");
    let line = format!("# {}\n", "x".repeat(77));
    let text = line.repeat((MAX_FILE_BYTES as usize) / line.len() + 1);
    std::fs::write(&path, &text).expect("the huge file is written");
    let result = load_case("huge-file", std::slice::from_ref(&path));
    check_rejected("huge-file", result, &dir);
    std::fs::remove_dir_all(&dir).ok();
    true
}

#[test]
fn hostile_but_valid_specs_load() {
    let dir = corpus().join(VALID_DIR);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("the valid directory exists")
        .map(|e| e.expect("a readable directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .collect();
    files.sort();
    assert!(!files.is_empty());
    for file in &files {
        let name = file.file_stem().expect("a file name").to_string_lossy().into_owned();
        match load_case(&name, std::slice::from_ref(file)) {
            Ok(spec) => assert_eq!(spec.sensors.len(), 1, "{name}"),
            Err(d) => panic!("{name}: expected to load, got\n{}", render(d, &dir)),
        }
    }
    // The text survives verbatim (trimmed): escaping is the generator's job.
    let spec = load_case("doc-text", &[dir.join("doc-text.yaml")]).expect("doc-text loads");
    // The file's one command, whose doc tries to close the doc comment.
    let cmd = spec.sensor("probe").and_then(|s| s.commands.first()).expect("a command");
    assert_eq!(cmd.doc, "*/ fn evil() {} /* \"#] r#\"raw\"#");
    println!("spec corpus: {} hostile but valid files loaded", files.len());
}

/// Every prefix of the real spec files, and every byte of them flipped to a
/// few hostile values, loads or fails cleanly: never a panic.
#[test]
fn truncated_and_mutated_real_specs_never_panic() {
    // Every file of spec/ (found by listing it), each mutated with the
    // others intact so that includes resolve. The steps grow with the
    // directory so that the number of variants stays about the same.
    let files: Vec<(PathBuf, String)> = yosemitech_tests::spec_files()
        .into_iter()
        .map(|path| {
            let name = path.file_name().expect("a file name").to_owned();
            (PathBuf::from("spec").join(name), std::fs::read_to_string(&path).expect("a spec file"))
        })
        .collect();
    let total: usize = files.iter().map(|(_, text)| text.len()).sum();
    let stretch = (total / 20_000).max(1);
    let all = files.iter().fold(MemSources::default(), |s, (path, text)| s.with(path.clone(), text.clone()));
    let mut checked = 0usize;
    for (root, text) in &files {
        let root = root.clone();
        let mut variants: Vec<String> = Vec::new();
        for cut in (0..text.len()).step_by(211 * stretch).filter(|&i| text.is_char_boundary(i)) {
            variants.push(text[..cut].to_string());
        }
        for (n, at) in (0..text.len())
            .step_by(173 * stretch)
            .filter(|&i| text.is_char_boundary(i) && text.is_char_boundary(i + 1))
            .enumerate()
        {
            for replacement in MUTATIONS.iter().cycle().skip(2 * n).take(2) {
                let mut mutated = text.clone();
                mutated.replace_range(at..at + 1, replacement);
                variants.push(mutated);
            }
        }
        for v in variants {
            let sources = all.clone().with(root.clone(), v.clone());
            let result = catch_unwind(AssertUnwindSafe(|| load_with(&sources, std::slice::from_ref(&root))));
            match result {
                Ok(Ok(_)) => {}
                Ok(Err(d)) => {
                    assert!(!d.is_empty());
                    let _ = d.to_string();
                }
                Err(_) => panic!("the loader panicked on this variant of {}:\n{v}", root.display()),
            }
            checked += 1;
        }
    }
    println!("spec corpus: {checked} truncated or mutated real spec files loaded without a panic");
}

/// One row of the key table of docs/spec-language.md.
struct KeyRow {
    /// `commands[].fields[].type`.
    path: String,
    /// `required`, `required for ...` or `required with(out) ...`.
    required: bool,
}

/// The rows of the table under "Required and optional keys".
fn key_table() -> Vec<KeyRow> {
    let docs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/spec-language.md");
    let text = std::fs::read_to_string(&docs).expect("docs/spec-language.md");
    let section = text.split("## Required and optional keys").nth(1).expect("the key table's section");
    let section = section.split("\n## ").next().unwrap_or(section);
    section
        .lines()
        .filter_map(|line| {
            let cells: Vec<&str> = line.trim().strip_prefix('|')?.split('|').map(str::trim).collect();
            let path = cells.first()?.strip_prefix('`')?.strip_suffix('`')?.to_owned();
            let status = *cells.get(1)?;
            assert!(status.starts_with("required") || status == "optional", "{path}: `{status}`");
            Some(KeyRow { path, required: status.starts_with("required") })
        })
        .collect()
}

/// Leading spaces of `line`, a list item's dash counted as indentation.
fn key_indent(line: &str) -> usize {
    let spaces = line.len() - line.trim_start().len();
    if line.trim_start().starts_with("- ") { spaces + 2 } else { spaces }
}

/// The end of the block that starts at `at` (its deeper-indented lines).
fn block_end(lines: &[String], at: usize, indent: usize) -> usize {
    let deeper = |l: &String| l.trim().is_empty() || (l.len() - l.trim_start().len()) > indent;
    at + 1 + lines[at + 1..].iter().take_while(|l| deeper(l)).count()
}

/// `lines[start..end]` (a mapping whose keys sit at `indent`) without the
/// key at `path`; `false` when the mapping lacks it.
fn remove_key(lines: &mut Vec<String>, start: usize, end: usize, indent: usize, path: &[&str]) -> bool {
    let Some((segment, rest)) = path.split_first() else { return false };
    let (name, list) = match segment.strip_suffix("[]") {
        Some(n) => (n, true),
        None => (*segment, false),
    };
    let at = (start..end).find(|&i| {
        let l = &lines[i];
        key_indent(l) == indent && l.trim_start().trim_start_matches("- ").starts_with(&format!("{name}:"))
    });
    let Some(at) = at else { return false };
    let key_end = block_end(lines, at, indent);
    if rest.is_empty() {
        let on_dash = lines[at].trim_start().starts_with("- ");
        lines.drain(at..key_end);
        if on_dash {
            // The item's next key moves up onto its dash.
            let Some(next) = lines.get(at).cloned().filter(|l| key_indent(l) == indent) else { return false };
            lines[at] = format!("{}- {}", " ".repeat(indent - 2), next.trim_start());
        }
        return true;
    }
    if !list {
        return remove_key(lines, at + 1, key_end, indent + 2, rest);
    }
    // Each item of the list, first to last, until one has the key.
    let items: Vec<usize> = (at + 1..key_end)
        .filter(|&i| lines[i].trim_start().starts_with("- ") && key_indent(&lines[i]) == indent + 4)
        .collect();
    for (k, &item) in items.iter().enumerate() {
        let item_end = items.get(k + 1).copied().unwrap_or(key_end);
        if remove_key(lines, item, item_end, indent + 4, rest) {
            return true;
        }
    }
    false
}

/// The every-key sensor and its fragment, one key removed from the file
/// that holds it; `None` when neither has it.
fn every_key_without(path: &str) -> Option<MemSources> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("specs/every-key");
    let files = ["probe.yaml", "shared.yaml", "unsourced.yaml"];
    let segments: Vec<&str> = path.split('.').collect();
    let mut sources = MemSources::default();
    let mut removed = false;
    for file in files {
        let text = std::fs::read_to_string(dir.join(file)).expect("an every-key file");
        let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
        let end = lines.len();
        if !removed {
            removed = remove_key(&mut lines, 0, end, 0, &segments);
        }
        sources = sources.with(PathBuf::from("spec").join(file), lines.join("\n") + "\n");
    }
    removed.then_some(sources)
}

/// Every key of the table, removed in turn from the every-key sensor: a
/// required key's absence is a located error that names it and says what
/// to add; without an optional one the spec loads and generates. Every
/// key of spec/schema.json is in the table.
#[test]
fn the_key_table_holds_for_every_key() {
    let rows = key_table();
    let spec_dir = [PathBuf::from("spec")];
    let complete = every_key_without("no_such_key");
    assert!(complete.is_none(), "removing a key the files lack removes nothing");
    let (mut required, mut optional) = (0, 0);
    let mut wrong = Vec::new();
    for row in &rows {
        let sources = every_key_without(&row.path)
            .unwrap_or_else(|| panic!("{}: tests/specs/every-key uses no such key; add it there", row.path));
        let leaf = row.path.rsplit('.').next().unwrap_or_default().trim_end_matches("[]");
        let result = catch_unwind(AssertUnwindSafe(|| load_with(&sources, &spec_dir)))
            .unwrap_or_else(|_| panic!("{}: the loader panicked", row.path));
        match (row.required, result) {
            (true, Ok(_)) => wrong.push(format!("{}: documented as required, but the spec loads without it", row.path)),
            (true, Err(diags)) => {
                // Located, naming the key (in the message, the key path or
                // the hint), and saying what to add.
                let named = diags.0.iter().any(|d| {
                    let help = d.help.as_deref().unwrap_or_default();
                    d.pos.line > 0
                        && !help.is_empty()
                        && (d.message.contains(&format!("`{leaf}`"))
                            || d.key.ends_with(leaf)
                            || help.contains(&format!("`{leaf}"))
                            || help.contains(&format!(".{leaf}`")))
                });
                if !named {
                    wrong.push(format!("{}: no located error naming `{leaf}` with a hint:\n{diags}", row.path));
                }
                required += 1;
            }
            (false, Err(diags)) => wrong.push(format!("{}: documented as optional, but\n{diags}", row.path)),
            (false, Ok(spec)) => {
                if let Err(e) = yosemitech_codegen::Config::new().generate_spec(&spec) {
                    wrong.push(format!("{}: loads without it, but does not generate: {e}", row.path));
                }
                optional += 1;
            }
        }
    }
    assert!(wrong.is_empty(), "{} rows of the key table do not hold:\n{}", wrong.len(), wrong.join("\n"));
    // Every key the schema knows is in the table.
    let schema: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(yosemitech_tests::spec_dir().join("schema.json")).expect("spec/schema.json"),
    )
    .expect("the schema is JSON");
    let mut names = std::collections::BTreeSet::new();
    schema_keys(&schema, &mut names);
    for name in &names {
        let listed = rows.iter().any(|r| r.path.rsplit('.').next().is_some_and(|l| l.trim_end_matches("[]") == name));
        assert!(listed, "the schema's key `{name}` is not in the key table of docs/spec-language.md");
    }
    yosemitech_tests::report!(
        "key table: {required} required keys refused with a located error, {optional} optional keys left out; \
         {} schema keys listed",
        names.len()
    );
}

/// Every property name anywhere in a JSON schema.
fn schema_keys(value: &serde_json::Value, out: &mut std::collections::BTreeSet<String>) {
    match value {
        serde_json::Value::Object(map) => {
            if let Some(serde_json::Value::Object(props)) = map.get("properties") {
                out.extend(props.keys().cloned());
            }
            map.values().for_each(|v| schema_keys(v, out));
        }
        serde_json::Value::Array(items) => items.iter().for_each(|v| schema_keys(v, out)),
        _ => {}
    }
}

/// A file of many numbers, one a line, generated: each number is read from
/// its own text, which must not cost time that grows with the line it is
/// on. It loads, or is refused with positions, within the deadline.
#[test]
fn many_numbers_on_many_lines_load_in_time() {
    let dir = std::env::temp_dir().join(format!("yosemitech-spec-numbers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let path = dir.join("numbers.yaml");
    let mut text = String::from(concat!(
        "sensor:\n  name: probe\n  title: Probe\n  doc: A probe.\n",
        "  manual: {title: Manual, revision: Rev 1}\n",
        "  serial: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1}\n",
        "  addresses: {min: 1, max: 247}\n  default_address: 1\n",
        "commands:\n  - name: get_x\n    title: X\n    doc: X.\n    function: read\n",
        "    address: 0x2800\n    count: 1\n    fields:\n      - {name: x, type: u16}\n",
        "    extra_byte_counts:\n",
    ));
    // Most of a file's allowed size, well inside its allowed node count.
    let line = "      - 7\n";
    let numbers = (MAX_FILE_BYTES as usize - text.len()) / line.len() * 3 / 4;
    text.push_str(&line.repeat(numbers));
    std::fs::write(&path, &text).expect("the file is written");
    if let Err(diags) = load_case("many-numbers", std::slice::from_ref(&path)) {
        assert!(diags.0.iter().all(|d| d.pos.line > 0), "{diags}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

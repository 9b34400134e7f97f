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
    ("alias-bomb", "alias-bomb.yaml:28:27"),
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
    ("printed-decodes-wrong", "printed-decodes-wrong.yaml:34:28"),
    ("request-does-not-encode", "request-does-not-encode.yaml:20:18"),
    ("request-wrong-register", "request-wrong-register.yaml:20:18"),
    ("sensor-and-fragment", "sensor-and-fragment.yaml:11:1"),
    ("sensor-settings-out-of-range", "sensor-settings-out-of-range.yaml:7:18"),
    ("size-too-few", "size-too-few.yaml:15:12"),
    ("size-too-many", "size-too-many.yaml:15:12"),
    ("stated-value-disagrees", "stated-value-disagrees.yaml:22:22"),
    ("stated-value-is-a-list", "stated-value-is-a-list.yaml:22:22"),
    ("two-documents", "two-documents.yaml:10:1"),
    ("unknown-function", "unknown-function.yaml:13:15"),
    ("unknown-key", "unknown-key.yaml:14:5"),
    ("use-changes-definition", "use-changes-definition/sensor.yaml:16:12"),
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

//! No hand-written Rust names a sensor, a probe model or a command of
//! `spec/`, except the files listed in [`EXEMPT`] with why.
//!
//! The names come from the spec files the project holds (tracked by git;
//! a file just dropped into `spec/` is not): every sensor's name, its probe
//! model and every command name, fragments' commands included. Names that are also command roles of the spec language
//! (`start_measurement`, `serial_number`, `wipe`...) are not per-sensor:
//! tests and tools are meant to pick commands by them.
//!
//! What counts as naming one: an identifier or a word of a string literal
//! whose snake_case form (`GetLevel` is `get_level`) holds the name as a run
//! of whole `_`-separated words. For a made-up command `get_level` and
//! sensors `probe_xy` and `nox`: `get_level`, `read_probe_xy`, `GetLevel`,
//! `probe_xy::Device` all count; `noxious` does not contain `nox`, nor
//! `get_levels` `get_level`. The rule needs identifier or string context,
//! so a one-word name that is also English counts in code and strings but
//! not in comments: comments and rustdoc prose may
//! cite a manual ("the pH manual's Fig 23") without selecting anything by
//! name. Doc-tests are prose to this scan; the README's and the crate
//! docs' doctests show the typed API of named sensors on purpose.
//!
//! Not scanned: `target/`, the generated snapshots
//! (`crates/yosemitech/generated/`) and `spec/` itself.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use heck::ToSnakeCase;
use yosemitech_spec::Role;

/// Files and folders whose naming of sensors is their point, with why.
/// A folder entry ends in `/` and covers what it holds.
const EXEMPT: &[(&str, &str)] = &[
    ("crates/yosemitech/src/procedures/ph.rs", "the pH manual's own three-point calibration"),
    (
        "crates/yosemitech/src/procedures/ph_electrode.rs",
        "the pH probe's electrode model: its coefficients computed from its buffers' potentials",
    ),
    ("crates/yosemitech/src/procedures/conductivity.rs", "the conductivity manual's own measurement with TDS"),
    (
        "crates/yosemitech/src/procedures/coefficients.rs",
        "the pH and conductivity manuals' coefficient blocks as typed backups",
    ),
    ("crates/yosemitech/src/procedures/mod.rs", "declares the one-manual procedure modules above"),
    (
        "crates/yosemitech-cli/src/commands/calibrate/mod.rs",
        "`calibrate ph`, the command line of the pH manual's three-point calibration above: it hands that \
         procedure the manual's typed device (its backup and restore go through the spec's coefficient blocks)",
    ),
    (
        "crates/yosemitech-cli/src/commands/calibrate/electrode.rs",
        "`calibrate ph --compute`, the command line of the pH electrode model above, on the pH probe's typed device",
    ),
    ("crates/yosemitech/examples/", "examples show the typed API of named sensors"),
    (
        "crates/yosemitech-bench/",
        "benchmarks time one fixed transaction, the pH manual's get_ph frames, against rmodbus and across \
         harnesses: BENCHMARKS.md's figures compare only because every harness uses the same frame",
    ),
    ("tests/tests/procedures.rs", "tests of the one-manual procedures above, each naming the manual it covers"),
    ("tests/tests/write_safety.rs", "the one-manual coefficient writes above, refused on a wrong reply"),
    (
        "crates/yosemitech-mqtt/src/home_assistant.rs",
        "Home Assistant's sensor device classes, one of which is spelt `conductivity` like a sensor: \
         its table maps units to them and selects nothing of the spec",
    ),
    (
        "crates/yosemitech-cli/tests/cli_home_assistant.rs",
        "Home Assistant's documented device classes and their units, one spelt like a sensor, to check \
         the discovery configs against",
    ),
    (
        "tests/tests/no_sensor_names.rs",
        "this scan: only its exempt list names files above; its own tests use made-up names",
    ),
];

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The spec files the project holds (tracked by git), by file name; `None`
/// when git cannot tell (not a checkout), and then every file counts.
fn project_spec_files() -> Option<BTreeSet<String>> {
    let out = std::process::Command::new("git")
        .arg("-C")
        .arg(workspace())
        .args(["ls-files", "spec"])
        .output()
        .ok()
        .filter(|o| o.status.success())?;
    let files: BTreeSet<String> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| Path::new(l).file_name().map(|f| f.to_string_lossy().into_owned()))
        .collect();
    (!files.is_empty()).then_some(files)
}

/// The lower-case names no hand-written Rust may use: those of the spec
/// files the project holds. A file just dropped into `spec/` (not yet
/// tracked) may use any name, even one our code uses for something else
/// (`keep_alive`): the rule is about our code selecting our sensors.
fn forbidden_names() -> BTreeSet<String> {
    let spec = yosemitech_tests::spec();
    let roles: BTreeSet<&str> = Role::ALL.iter().map(|r| r.name()).collect();
    let project = project_spec_files();
    let held = |file: &Path| {
        project.as_ref().is_none_or(|p| file.file_name().is_some_and(|f| p.contains(f.to_string_lossy().as_ref())))
    };
    let mut names = BTreeSet::new();
    let dropped = spec.sensors.iter().filter(|s| !held(&s.file)).count();
    if dropped > 0 {
        yosemitech_tests::report!("{dropped} sensors of untracked spec files are not scanned for");
    }
    for sensor in spec.sensors.iter().filter(|s| held(&s.file)) {
        names.insert(sensor.name.clone());
        names.extend(sensor.model.iter().map(|m| m.to_lowercase()));
        names.extend(sensor.commands.iter().map(|c| c.name.clone()));
    }
    for fragment in spec.fragments.iter().filter(|f| held(&f.file)) {
        names.extend(fragment.commands.iter().map(|c| c.name.clone()));
    }
    names.retain(|n| !roles.contains(n.as_str()));
    names
}

/// Every `.rs` file under `dir`, skipping `target` and the generated snapshots.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        if path.is_dir() {
            if name != "target" && name != "generated" && name != "spec" && name != ".git" {
                rust_files(&path, out);
            }
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Identifiers and the words of string literals, with their line numbers:
/// the code of a Rust file without its comments.
fn code_words(text: &str) -> Vec<(usize, String)> {
    let chars: Vec<char> = text.chars().collect();
    let mut words = Vec::new();
    let (mut i, mut line) = (0, 1);
    let mut word = String::new();
    let flush = |word: &mut String, words: &mut Vec<(usize, String)>, line: usize| {
        if !word.is_empty() {
            words.push((line, std::mem::take(word)));
        }
    };
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            flush(&mut word, &mut words, line);
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
            continue;
        }
        if c == '/' && next == Some('*') {
            flush(&mut word, &mut words, line);
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    line += usize::from(chars[i] == '\n');
                    i += 1;
                }
            }
            continue;
        }
        if c == '\'' && next.is_some_and(|n| n != '\\') && chars.get(i + 2) == Some(&'\'') {
            i += 3; // a char literal, never a name
            continue;
        }
        if c.is_alphanumeric() || c == '_' {
            word.push(c);
        } else {
            flush(&mut word, &mut words, line);
        }
        line += usize::from(c == '\n');
        i += 1;
    }
    flush(&mut word, &mut words, line);
    words
}

/// The name `word` holds as a run of whole snake_case words, if any.
fn named<'n>(word: &str, names: &'n BTreeSet<String>) -> Option<&'n str> {
    let snake = word.to_snake_case();
    let parts: Vec<&str> = snake.split('_').filter(|p| !p.is_empty()).collect();
    names.iter().map(String::as_str).find(|name| {
        let want: Vec<&str> = name.split('_').collect();
        parts.windows(want.len()).any(|w| w == want.as_slice())
    })
}

fn exempt(relative: &str) -> bool {
    EXEMPT.iter().any(|(path, _)| if path.ends_with('/') { relative.starts_with(path) } else { relative == *path })
}

#[test]
fn no_hand_written_rust_names_a_sensor_or_command() {
    let names = forbidden_names();
    assert!(names.len() > yosemitech_tests::spec().sensors.len(), "the scan has names to look for");
    let root = workspace();
    let mut files = Vec::new();
    for dir in ["crates", "tests", "xtask", "fuzz"] {
        rust_files(&root.join(dir), &mut files);
    }
    files.sort();
    assert!(files.len() > 50, "the scan reads the workspace's Rust files ({} found)", files.len());
    let mut offences = Vec::new();
    for file in &files {
        let relative = file.strip_prefix(&root).unwrap_or(file).to_string_lossy().replace('\\', "/");
        if exempt(&relative) {
            continue;
        }
        let text = std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{relative}: {e}"));
        let found: Vec<String> = code_words(&text)
            .into_iter()
            .filter_map(|(line, word)| {
                named(&word, &names).map(|name| format!("{relative}:{line}: `{word}` names `{name}`"))
            })
            .collect();
        offences.extend(found);
    }
    for (path, why) in EXEMPT {
        assert!(root.join(path).exists(), "exempt path {path} ({why}) does not exist");
    }
    yosemitech_tests::report!("{} files scanned for {} spec names", files.len(), names.len());
    assert!(offences.is_empty(), "hand-written Rust names the spec's sensors or commands:\n{}", offences.join("\n"));
}

#[test]
fn the_rule_catches_names_in_every_form() {
    // Made-up names, so this test names nothing of `spec/` itself.
    let names: BTreeSet<String> = ["get_level", "probe_xy", "salinity", "nox"].map(String::from).into();
    for word in ["get_level", "GetLevel", "read_probe_xy", "ProbeXy", "salinity", "ReadDepthAndNox"] {
        assert!(named(word, &names).is_some(), "{word}");
    }
    for word in ["noxious", "get_levels", "xy", "level", "levelled"] {
        assert_eq!(named(word, &names), None, "{word}");
    }
    let words: Vec<String> = code_words("let x = \"salinity\"; // get_level in a comment\n/* probe_xy */ y")
        .into_iter()
        .map(|(_, w)| w)
        .collect();
    assert_eq!(words, ["let", "x", "salinity", "y"]);
}

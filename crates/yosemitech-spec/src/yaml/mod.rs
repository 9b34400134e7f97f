//! YAML parsing with hardened limits, and its errors turned into messages
//! a spec author can act on.
//!
//! The parser (granit-parser) gives events; `load` builds a tree of located
//! nodes from them under the limits of `limits`, `tree` reads the document
//! types from it (a scalar as the type asked for, `scalar`), and `messages`
//! says what each error kind means in the spec's terms and, where we can
//! tell, what would be valid. Positions come from the parser, corrected
//! where its position is not the offending place (a tab is reported at the
//! scalar before it).
//!
//! The parser stops at a file's first error. To report more in one run,
//! parsing resumes after it at the next top-level key or item of a
//! top-level list (each command, constant, erratum), so independent
//! mistakes in separate entries are all reported, with their positions in
//! the file (see [`parse`]).
//!
//! It is the workspace's one YAML reader: the tools that draft spec files
//! read YAML back through [`from_yaml_str`] (the same tree, limits and
//! messages, the first problem only). serde-saphyr only writes drafts
//! (`cargo xtask import`) and, in this crate's tests, is the oracle the
//! tree's reading is compared with.

mod comma;
mod error;
mod keypath;
mod lexer;
mod limits;
mod load;
mod messages;
mod recovery;
mod scalar;
mod tree;

use std::borrow::Cow;
use std::fmt;

use serde::de::DeserializeOwned;

use self::error::{Error, Kind};

use self::comma::unquoted_comma;
use self::keypath::{KeyPaths, parent_path};
use self::lexer::unclosed_flow;
pub use self::limits::{MAX_ALIAS_REPLAY, MAX_YAML_ALIASES, MAX_YAML_DEPTH, MAX_YAML_NODES};
use self::limits::{MAX_LAYOUT_RESETS, MAX_YAML_PARSES, MAX_YAML_PROBLEMS};
use self::messages::{explain, is_shape_error};
use self::recovery::{Layout, Resume, keep_lines};
use crate::diag::Pos;
use crate::document::SpecFile;
use crate::names::escape;

/// A YAML problem: where, what, and what would be valid.
pub(crate) struct Problem {
    pub pos: Pos,
    /// The offending key, as a path (`commands[0] (get_ph).count`), when it can be told.
    pub key: String,
    pub message: String,
    pub help: Option<String>,
}

/// Parses one spec file; on failure, every problem the parser lets us find,
/// in line order.
///
/// The parser stops at the first error. To find more, parsing resumes
/// after it at the next top-level key or item of a top-level list (see
/// [`Layout`]), the lines before blanked so that positions stay those of
/// the file: independent mistakes in separate commands are all reported.
/// Parsing stops at errors that concern the whole file (limits, a second
/// document).
pub(crate) fn parse(text: &str) -> Result<SpecFile, Vec<Problem>> {
    let mut error = match tree::from_str::<SpecFile>(text) {
        Ok(doc) => return Ok(doc),
        Err(e) => e,
    };
    let mut layout = Layout::of(text);
    let mut resets = MAX_LAYOUT_RESETS;
    let mut problems: Vec<Problem> = Vec::new();
    // The text parsed last: the file, or the file from a resume point on.
    let mut part = Part { text: Cow::Borrowed(text), from: None };
    for _ in 0..MAX_YAML_PARSES {
        let mut problem = problem(&error, &part.text, layout.as_ref());
        if let Some(list) = part.from.as_ref().and_then(|r| r.list.as_ref()) {
            problem.key = list.shift(&problem.key);
        }
        let stop = match swallowed_from(&error, &part.text, problem.pos) {
            // A quote or bracket never closed swallowed the lines after it:
            // read them as if it closed at the end of its line (a few times:
            // each costs a pass over the rest of the file).
            Some(line) => {
                if resets > 0 && layout.as_mut().is_some_and(|l| l.reset(text, line)) {
                    resets -= 1;
                }
                line
            }
            // Where the parser stopped: everything before it parsed.
            None => (problem.pos.line as usize).max(error.at().map_or(0, |at| at.line as usize)),
        };
        let report = part.from.is_none() || !anchor_defined_before(&error, text, problem.pos);
        if report && !problems.iter().any(|p| p.pos == problem.pos && p.message == problem.message) {
            problems.push(problem);
        }
        if !recoverable(&error) || problems.len() >= MAX_YAML_PROBLEMS {
            break;
        }
        let Some(next) = layout.as_ref().and_then(|l| l.resume_after(stop, part.from.as_ref())) else {
            break;
        };
        let preamble = layout.as_ref().map_or(0, |l| l.preamble);
        let keep = |i: usize| i < preamble || i >= next.line || next.list.as_ref().is_some_and(|l| l.header == i);
        part = Part { text: Cow::Owned(keep_lines(text, keep)), from: Some(next) };
        match tree::from_str::<SpecFile>(&part.text) {
            Ok(_) => break,
            Err(e) => error = e,
        }
    }
    problems.sort_by_key(|p| p.pos);
    Err(problems)
}

/// Reads a `T` from YAML text the way spec files are read: the same limits
/// ([`MAX_YAML_NODES`], [`MAX_YAML_DEPTH`], [`MAX_YAML_ALIASES`],
/// [`MAX_ALIAS_REPLAY`]), scalars read by YAML 1.2's core schema as the
/// type asked for (`yes` is text, not `true`; `.inf` only where a float is
/// asked for), a key written twice refused, one document only, and an
/// empty text (or only comments) read as an empty mapping.
///
/// For tools that read YAML beside the loader (`cargo xtask import` reads
/// its drafts back with it), so that what they accept is what a spec file
/// may hold. Unlike [`crate::load_paths`], it stops at the first problem
/// and checks nothing beyond the shape of `T`.
///
/// ```
/// use yosemitech_spec::document::StatedValue;
///
/// let value: StatedValue = yosemitech_spec::from_yaml_str("7.6").unwrap();
/// assert_eq!(value, StatedValue::Number(7.6));
/// let error = yosemitech_spec::from_yaml_str::<StatedValue>("[7, 6]").unwrap_err();
/// assert_eq!(error.to_string(), "1:1: a stated value is a number or text");
/// ```
///
/// # Errors
///
/// The first problem, at its line and column, worded as for a spec
/// file's author (a tab where YAML expects spaces is reported at the tab, a
/// quote never closed where it opens).
pub fn from_yaml_str<T: DeserializeOwned>(text: &str) -> Result<T, YamlError> {
    tree::from_str(text).map_err(|e| {
        let Problem { pos, key, message, help } = problem(&e, text, Layout::of(text).as_ref());
        YamlError { pos, key, message, help }
    })
}

/// Why YAML text does not read as the type asked for ([`from_yaml_str`]).
///
/// Displayed as `line:column: message`, with the key path before the
/// message when it is known (`3:5: commands[0] (get_ph).count: ...`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct YamlError {
    /// Where (1-based line and column).
    pub pos: Pos,
    /// The offending key as a path (`commands[0] (get_ph).count`), or empty.
    pub key: String,
    /// What is wrong.
    pub message: String,
    /// What would be valid, when it can be told.
    pub help: Option<String>,
}

impl fmt::Display for YamlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: ", self.pos.line, self.pos.column)?;
        if !self.key.is_empty() {
            write!(f, "{}: ", self.key)?;
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for YamlError {}

/// The text parsed to find more problems, and where it resumes.
struct Part<'a> {
    text: Cow<'a, str>,
    from: Option<Resume>,
}

/// The line (1-based) of a quote or flow collection never closed that made
/// the parser fail further down, swallowing the lines between.
fn swallowed_from(e: &Error, text: &str, pos: Pos) -> Option<usize> {
    let raw = e.at().map_or(0, |at| at.line as usize);
    match e.kind {
        // `syntax` points at the opening quote or bracket.
        Kind::Syntax { .. } if (pos.line as usize) < raw => Some(pos.line as usize),
        Kind::Syntax { .. } => unclosed_flow(text, pos).map(|(line, _, _)| line as usize).filter(|&l| l < raw),
        _ => None,
    }
    .filter(|&line| line > 0)
}

/// Errors after which the rest of the file can still be parsed on its own.
fn recoverable(e: &Error) -> bool {
    matches!(e.kind, Kind::Syntax { .. } | Kind::UnknownAnchor) || is_shape_error(e)
}

/// Whether the error is an alias (`*name`) at `pos` whose anchor (`&name`)
/// is written before it in `text`: true of an alias whose anchor was
/// blanked out of a resumed parse, which is no mistake.
fn anchor_defined_before(e: &Error, text: &str, pos: Pos) -> bool {
    if !matches!(e.kind, Kind::UnknownAnchor) {
        return false;
    }
    let Some(line) = text.lines().nth((pos.line as usize).saturating_sub(1)) else { return false };
    let rest: String = line.chars().skip((pos.column as usize).saturating_sub(1)).collect();
    let name: String = rest
        .trim_start_matches('*')
        .chars()
        .take_while(|c| !c.is_whitespace() && !matches!(c, ',' | '[' | ']' | '{' | '}'))
        .collect();
    if name.is_empty() {
        return false;
    }
    let anchor = format!("&{name}");
    text.lines().take((pos.line as usize).saturating_sub(1)).any(|line| {
        line.match_indices(&anchor).any(|(i, _)| {
            let after = line.get(i + anchor.len()..).and_then(|r| r.chars().next());
            after.is_none_or(|c| c.is_whitespace() || matches!(c, ',' | '[' | ']' | '{' | '}'))
        })
    })
}

/// Turns an error from parsing `text` into a [`Problem`], with the key path
/// of shape errors and a clear message for an unquoted comma inside `{...}`.
fn problem(e: &Error, text: &str, layout: Option<&Layout>) -> Problem {
    let mut problem = explain(e, text);
    if !is_shape_error(e) {
        return problem;
    }
    // The YAML is well-formed (up to the error at least) but does not fit
    // the spec's shape: find the key. If the text has a syntax error
    // further down, the lines after the error's entry are left out.
    let raw_line = e.at().map_or(0, |at| at.line as usize);
    let line = (problem.pos.line as usize).max(raw_line);
    let entry_end = layout.and_then(|l| l.next_start_after(line));
    let paths = entry_end
        .and_then(|end| KeyPaths::of(&keep_lines(text, |i| i < end)))
        .or_else(|| KeyPaths::of(text))
        .or_else(|| KeyPaths::of(&keep_lines(text, |i| i < line)));
    let missing = matches!(e.inner().kind, Kind::MissingField { .. });
    if let Some((pos, key)) = paths.as_ref().and_then(|p| p.at(problem.pos, missing)) {
        problem.key = key;
        if missing {
            problem.pos = pos;
        }
    }
    let stray = matches!(e.inner().kind, Kind::UnknownField { .. } | Kind::DuplicateKey { .. });
    if let Some(comma) = stray.then(|| unquoted_comma(text, problem.pos)).flatten() {
        let key = paths.as_ref().and_then(|p| p.exact(comma.key_pos)).unwrap_or_else(|| {
            parent_path(&problem.key).map_or_else(|| comma.key.clone(), |up| format!("{up}.{}", comma.key))
        });
        // Escaped for a double-quoted YAML string, and for the terminal.
        let quoted: String = comma
            .value
            .chars()
            .map(|c| match c {
                '\\' | '"' => format!("\\{c}"),
                c => escape(&c.to_string()),
            })
            .collect();
        problem = Problem {
            pos: comma.pos,
            key,
            message: "an unquoted comma ends the value inside `{...}`".into(),
            help: Some(format!(
                "inside `{{...}}` a comma separates entries, so `{}` is read as a key of its own; \
                 quote the text: {}: \"{}\"",
                escape(&comma.stray),
                escape(&comma.key),
                quoted,
            )),
        };
    }
    problem
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sensor header, then `commands`.
    pub(super) fn spec(commands: &str) -> String {
        format!(
            "sensor:\n  name: probe\n  title: Probe\n  doc: A probe.\n  manual: {{title: Manual, revision: Rev 1}}\n  \
             serial: {{baud: 9600, data_bits: 8, parity: none, stop_bits: 1}}\n  addresses: {{min: 1, max: 247}}\n  \
             default_address: 1\ncommands:\n{commands}"
        )
    }

    /// Line, column and message of each problem.
    pub(super) fn problems(text: &str) -> Vec<(u32, u32, String)> {
        match parse(text) {
            Ok(_) => Vec::new(),
            Err(problems) => problems.into_iter().map(|p| (p.pos.line, p.pos.column, p.message)).collect(),
        }
    }

    #[test]
    fn independent_errors_in_separate_commands_are_all_reported() {
        let text = spec(concat!(
            "  - name: a\n",    // 10
            "    title: \"A\n", // 11: a quote never closed...
            "    function: read\n",
            "  - name: b\n",
            "\tfunction: read\n", // 14: a tab
            "  - name: c\n",
            "    fields: [{name: x, type: u16}\n", // 16: a `[` never closed
            "  - name: d\n",
            "    title: \"D\"\n", // ...until here
            "    function: read\n",
        ));
        let found = problems(&text);
        let at: Vec<(u32, u32)> = found.iter().map(|p| (p.0, p.1)).collect();
        assert_eq!(at, [(11, 12), (14, 1), (16, 13)], "{found:?}");
        assert_eq!(found[0].2, "this quoted string is never closed");
        assert_eq!(found[1].2, "a tab character where YAML expects spaces");
        assert_eq!(found[2].2, "this `[` is never closed");
    }

    #[test]
    fn shape_errors_after_a_syntax_error_keep_their_key_paths() {
        let text = spec("  - name: a\n\tcount: 1\n  - name: b\n  - name: c\n    adress: 1\n  - {name: d, count: x}\n");
        let Err(found) = parse(&text) else { panic!("expected errors") };
        let keys: Vec<(u32, &str)> = found.iter().map(|p| (p.pos.line, p.key.as_str())).collect();
        assert_eq!(keys, [(11, ""), (14, "commands[2] (c).adress"), (15, "commands[3] (d).count")]);
    }

    #[test]
    fn no_false_errors_from_text_running_over_lines() {
        // A quoted string and a flow list may continue on unindented lines
        // that look like keys or items: parsing must not resume there.
        let text = spec(concat!(
            "  - name: a\n",
            "\tcount: 1\n",
            "  - name: b\n",
            "    title: \"first line\n",
            "constants: not a key\"\n",
            "    fields: [{name: x, type: u16},\n",
            "  - name: y]\n",
            "  - name: c\n",
            "    doc: |\n",
            "      \"not a quote, [not a list\n",
            "  - name: e\n",
            "    function: raed\n",
        ));
        let lines: Vec<u32> = problems(&text).iter().map(|p| p.0).collect();
        assert_eq!(lines[0], 11);
        assert!(!lines.contains(&14) && !lines.contains(&16), "{lines:?}");
        // Well-formed text is never split.
        let valid = spec("  - name: b\n    title: \"first line\nconstants: not a key\"\n");
        assert!(parse(&valid).is_ok());
    }

    #[test]
    fn aliases_to_anchors_before_a_resume_point_are_no_errors() {
        let text = spec(concat!(
            "  - name: a\n",
            "    fields: &f [{name: x, type: u16}]\n",
            "  - name: b\n",
            "\tcount: 1\n",
            "  - name: c\n",
            "    fields: *f\n",
        ));
        assert_eq!(problems(&text).len(), 1);
    }

    /// Commands written as the real spec files write them.
    const SAMPLE: &str = concat!(
        "  - name: start_measurement\n",
        "    title: Start Measurement\n",
        "    doc: |\n",
        "      Starts measuring: a write of [zero registers\n",
        "      (erratum E11), \"answered\" with the usual echo.\n",
        "    source: {section: \"2.2.3\", figures: [22, 23, 24]}\n",
        "    function: write\n",
        "    address: 0x1C00\n",
        "    count: 0\n",
        "    trigger: true\n",
        "    examples:\n",
        "      - figures: [23, 24]\n",
        "        request: \"01 10 1C 00 00 00 00 D8 92\"\n",
        "        response: \"01 10 1C 00 00 00 C7 99\"\n",
        "        values: {}\n",
        "\n",
        "  - name: get_user_factors\n",
        "    title: Get User Calibration Coefficients\n",
        "    doc: Reads K and B, applied as Cond = K·Cond + B (defaults K = 1, B = 0).\n",
        "    source: {section: \"2.2.6\", figures: [32, 33]}\n",
        "    function: read\n",
        "    address: 0x1100\n",
        "    count: 4\n",
        "    fields:\n",
        "      - {name: k_slope, type: f32, byte_order: dcba, doc: Slope K.}\n",
        "      - name: b_offset\n",
        "        type: f32\n",
        "        byte_order: dcba\n",
        "        doc: 'Offset B; it''s in mS/cm.'\n",
        "    examples:\n",
        "      - figures: [33]\n",
        "        request: \"01 03 11 00 00 04 41 35\"\n",
        "        response: \"01 03 08 00 00 80 3F 00 00 00 00 9E 12\"\n",
        "        values: {k_slope: 1.0, b_offset: 0.0}\n",
        "  # A comment between commands.\n",
        "  - use: get_revision\n",
        "    source: {section: \"2.2.5\", figures: [29,\n",
        "      30, 31]}\n",
        "constants:\n",
        "  - name: reading_interval_ms\n",
        "    type: u32\n",
        "    value: 3000\n",
        "    doc: >-\n",
        "      Interval between readings.\n",
        "  - {name: readings_to_average, type: u32, value: 10, doc: \"Readings, averaged.\"}\n",
    );

    #[test]
    fn one_mistake_is_one_problem() {
        // Each line of real-looking commands broken in a few ways: the rest
        // is valid, so exactly one problem, and nothing after the line's item.
        let text = spec(SAMPLE);
        assert_eq!(problems(&text), []);
        let lines: Vec<&str> = text.lines().collect();
        let first = lines.iter().position(|l| *l == "commands:").unwrap_or_default() + 1;
        // The line where each line's top-level item ends.
        let item_end = |n: usize| {
            (n + 1..lines.len())
                .find(|&i| lines[i].starts_with("  - ") || !lines[i].starts_with(' '))
                .unwrap_or(lines.len())
        };
        for n in first..lines.len() {
            let line = lines[n];
            let mut broken: Vec<String> = Vec::new();
            if let Some(rest) = line.strip_prefix("    ") {
                broken.push(format!("\t{rest}"));
            }
            for close in [']', '}', '"', '\''] {
                if let Some(i) = line.rfind(close) {
                    broken.push(format!("{}{}", &line[..i], &line[i + 1..]));
                }
            }
            for b in broken {
                let mut mutated = lines.clone();
                mutated[n] = &b;
                let mutated = mutated.join("\n") + "\n";
                let Err(found) = parse(&mutated) else { continue };
                let end = item_end(n) as u32;
                assert!(
                    found.len() == 1 && found[0].pos.line <= end,
                    "line {} broken as {b:?}: {:?}",
                    n + 1,
                    found.iter().map(|p| (p.pos.line, p.pos.column, &p.message)).collect::<Vec<_>>()
                );
            }
        }
    }

    #[test]
    fn any_type_reads_through_the_tree_with_its_limits_and_messages() {
        use std::collections::BTreeMap;

        #[derive(Debug, serde::Deserialize, PartialEq)]
        #[serde(deny_unknown_fields)]
        struct Entry {
            name: String,
            count: u32,
            #[serde(default)]
            flag: bool,
        }
        #[derive(Debug, serde::Deserialize, PartialEq)]
        #[serde(deny_unknown_fields)]
        struct Doc {
            entries: Vec<Entry>,
        }
        let read = |text: &str| from_yaml_str::<Doc>(text).map_err(|e| e.to_string());
        let doc = read("entries:\n  - {name: a, count: 0x10}\n  - name: b\n    count: 2\n    flag: true\n");
        assert_eq!(
            doc,
            Ok(Doc {
                entries: vec![
                    Entry { name: "a".into(), count: 16, flag: false },
                    Entry { name: "b".into(), count: 2, flag: true },
                ]
            })
        );
        for (text, expected) in [
            ("entries:\n  - name: a\n    cuont: 1\n", "3:5: entries[0] (a).cuont: unknown key `cuont`"),
            ("entries:\n  - {name: a, count: two}\n", "2:22: entries[0] (a).count: `two` is not a whole number"),
            ("entries:\n  - {name: a, count: 1, flag: yes}\n", "2:31: entries[0] (a).flag: `yes` is not true or false"),
            ("entries:\n  - name: a\n    count: 1\n    count: 2\n", "4:5: entries[0] (a).count: duplicate key `count`"),
            ("entries:\n  - name: \"a\n    count: 1\n", "2:11: this quoted string is never closed"),
            ("entries:\n  - name: a\n\tcount: 1\n", "3:1: a tab character where YAML expects spaces"),
            (
                "entries: []\n---\nentries: []\n",
                "2:1: a second YAML document starts here; a spec file holds exactly one",
            ),
        ] {
            assert_eq!(read(text), Err(expected.to_owned()), "{text:?}");
        }
        // An empty text is an empty mapping.
        assert_eq!(from_yaml_str::<BTreeMap<String, u32>>("# nothing\n"), Ok(BTreeMap::new()));
        // The limits are the loader's.
        let bomb: String = (0..12).fold("a: &a0 [x, x, x, x, x, x, x, x, x, x]\n".to_owned(), |text, i| {
            format!("{text}a{}: &a{} [{}]\n", i + 1, i + 1, vec![format!("*a{i}"); 10].join(", "))
        });
        let Err(e) = from_yaml_str::<BTreeMap<String, serde::de::IgnoredAny>>(&bomb) else { panic!("a bomb read") };
        assert!(e.message.contains(&MAX_ALIAS_REPLAY.to_string()), "{e}");
    }

    proptest::proptest! {
        #[test]
        fn parse_never_panics(text in "([a-z ]{0,6}[-:\\[\\]{},\"'#|>&*\\t\\n]){0,60}") {
            let _ = parse(&spec(&text));
            let _ = parse(&text);
        }
    }
}

//! YAML parsing with hardened limits, and serde-saphyr's errors turned into
//! messages a spec author can act on.
//!
//! serde-saphyr's own texts are written for developers ("invalid u32",
//! "set DuplicateKeyPolicy in Options"); here each error kind gets a message
//! that says what is wrong in the spec's terms and, where we can tell, what
//! would be valid. Positions come from serde-saphyr, corrected where its
//! position is not the offending place (a tab is reported at the scalar
//! before it).
//!
//! serde-saphyr stops at a file's first error. To report more in one run,
//! parsing resumes after it at the next top-level key or item of a
//! top-level list (each command, constant, erratum), so independent
//! mistakes in separate entries are all reported, with their positions in
//! the file (see [`parse`]).

use std::borrow::Cow;
use std::fmt;

use serde::Deserialize;
use serde::de::{self, MapAccess, SeqAccess, Visitor};
use serde_saphyr::budget::BudgetBreach;
use serde_saphyr::{DuplicateKeyPolicy, Error, Spanned};

use crate::diag::Pos;
use crate::document::SpecFile;
use crate::names::{check_snake, escape};

/// Most YAML nodes (scalars, sequences, mappings) one file may hold, aliases
/// expanded. The real specs have a few thousand.
pub const MAX_YAML_NODES: usize = 100_000;
/// Deepest nesting of YAML collections. The spec language needs eight.
pub const MAX_YAML_DEPTH: usize = 32;
/// Most alias (`*name`) uses in one file.
pub const MAX_YAML_ALIASES: usize = 1_000;
/// Most events aliases may replay in one file: stops exponential "billion
/// laughs" expansion long before it costs time or memory.
pub const MAX_ALIAS_REPLAY: usize = 50_000;

/// A YAML problem: where, what, and what would be valid.
pub(crate) struct Problem {
    pub pos: Pos,
    /// The offending key, as a path (`commands[0] (get_ph).count`), when it can be told.
    pub key: String,
    pub message: String,
    pub help: Option<String>,
}

fn options() -> serde_saphyr::Options {
    serde_saphyr::options! {
        budget: serde_saphyr::budget! {
            max_nodes: MAX_YAML_NODES,
            max_events: 4 * MAX_YAML_NODES,
            max_depth: MAX_YAML_DEPTH,
            max_aliases: MAX_YAML_ALIASES,
            max_anchors: MAX_YAML_ALIASES,
            max_documents: 1,
            flow_nesting_limit: MAX_YAML_DEPTH,
            max_recorded_anchor_events: 4 * MAX_YAML_NODES,
        },
        alias_limits: serde_saphyr::alias_limits! {
            max_total_replayed_events: MAX_ALIAS_REPLAY,
            max_replay_stack_depth: MAX_YAML_DEPTH,
        },
        duplicate_keys: DuplicateKeyPolicy::Error,
        // `yes`, `no`, `on`, `off` are text, not booleans (YAML 1.2).
        strict_booleans: true,
        with_snippet: false,
    }
}

/// Most problems reported for one file's YAML.
const MAX_YAML_PROBLEMS: usize = 20;
/// Most times one file is parsed (again) to find its problems: bounds the
/// work on hostile input to this many parses of at most the whole file.
const MAX_YAML_PARSES: usize = 2 * MAX_YAML_PROBLEMS;

/// Most times the lines after a quote or bracket never closed are read
/// again as if it closed on its line.
const MAX_LAYOUT_RESETS: usize = 4;

/// Parses one spec file; on failure, every problem the parser lets us find,
/// in line order.
///
/// serde-saphyr stops at the first error. To find more, parsing resumes
/// after it at the next top-level key or item of a top-level list (see
/// [`Layout`]), the lines before blanked so that positions stay those of
/// the file: independent mistakes in separate commands are all reported.
/// Parsing stops at errors that concern the whole file (limits, a second
/// document).
pub(crate) fn parse(text: &str) -> Result<SpecFile, Vec<Problem>> {
    let mut error = match serde_saphyr::from_str_with_options::<SpecFile>(text, options()) {
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
            None => (problem.pos.line as usize).max(error.location().map_or(0, |l| l.line() as usize)),
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
        match serde_saphyr::from_str_with_options::<SpecFile>(&part.text, options()) {
            Ok(_) => break,
            Err(e) => error = e,
        }
    }
    problems.sort_by_key(|p| p.pos);
    Err(problems)
}

/// The text parsed to find more problems, and where it resumes.
struct Part<'a> {
    text: Cow<'a, str>,
    from: Option<Resume>,
}

/// The line (1-based) of a quote or flow collection never closed that made
/// the parser fail further down, swallowing the lines between.
fn swallowed_from(e: &Error, text: &str, pos: Pos) -> Option<usize> {
    let raw = e.location().map_or(0, |l| l.line() as usize);
    match e.without_snippet() {
        // `syntax` points at the opening quote or bracket.
        Error::ExternalMessage { .. } if (pos.line as usize) < raw => Some(pos.line as usize),
        Error::Eof { .. } => unclosed_flow(text, pos).map(|(line, _, _)| line as usize).filter(|&l| l < raw),
        _ => None,
    }
    .filter(|&line| line > 0)
}

/// Errors after which the rest of the file can still be parsed on its own.
fn recoverable(e: &Error) -> bool {
    matches!(e.without_snippet(), Error::ExternalMessage { .. } | Error::Eof { .. } | Error::UnknownAnchor { .. })
        || is_shape_error(e)
}

/// Whether the error is an alias (`*name`) at `pos` whose anchor (`&name`)
/// is written before it in `text`: true of an alias whose anchor was
/// blanked out of a resumed parse, which is no mistake.
fn anchor_defined_before(e: &Error, text: &str, pos: Pos) -> bool {
    if !matches!(e.without_snippet(), Error::UnknownAnchor { .. }) {
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
    let raw_line = e.location().map_or(0, |l| l.line() as usize);
    let line = (problem.pos.line as usize).max(raw_line);
    let entry_end = layout.and_then(|l| l.next_start_after(line));
    let paths = entry_end
        .and_then(|end| KeyPaths::of(&keep_lines(text, |i| i < end)))
        .or_else(|| KeyPaths::of(text))
        .or_else(|| KeyPaths::of(&keep_lines(text, |i| i < line)));
    let missing = matches!(e.without_snippet(), Error::SerdeMissingField { .. });
    if let Some((pos, key)) = paths.as_ref().and_then(|p| p.at(problem.pos, missing)) {
        problem.key = key;
        if missing {
            problem.pos = pos;
        }
    }
    let stray = matches!(e.without_snippet(), Error::SerdeUnknownField { .. } | Error::DuplicateMappingKey { .. });
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

/// Errors about the shape of well-formed YAML, which have a key path.
fn is_shape_error(e: &Error) -> bool {
    match e.without_snippet() {
        Error::AliasError { error, .. } => is_shape_error(error),
        Error::SerdeUnknownField { .. }
        | Error::SerdeUnknownVariant { .. }
        | Error::SerdeMissingField { .. }
        | Error::InvalidScalar { .. }
        | Error::SerdeInvalidType { .. }
        | Error::SerdeInvalidValue { .. }
        | Error::SerdeInvalidLength { .. }
        | Error::NullIntoString { .. }
        | Error::Unexpected { .. }
        | Error::NonFiniteFloat { .. }
        | Error::InvalidBooleanStrict { .. }
        | Error::DuplicateMappingKey { .. }
        | Error::Message { .. } => true,
        _ => false,
    }
}

/// Turns a serde-saphyr error into a [`Problem`].
pub(crate) fn explain(e: &Error, text: &str) -> Problem {
    let pos = e.location().map(Pos::of).filter(|p| p.line > 0).unwrap_or(Pos { line: 1, column: 1 });
    let schema = "spec/schema.json describes every key and its type";
    let problem = |message: String, help: Option<String>| Problem { pos, key: String::new(), message, help };
    match e.without_snippet() {
        Error::AliasError { error, .. } => {
            let inner = explain(error, text);
            Problem { pos, ..inner }
        }
        Error::SerdeUnknownField { field, expected, .. } => {
            let field = escape(field);
            let help = match (closest(&field, expected), expected.is_empty()) {
                (_, true) => "no keys are allowed here".to_string(),
                (Some(best), _) => format!("did you mean `{best}`? valid keys here: {}", expected.join(", ")),
                (None, _) => format!("valid keys here: {}", expected.join(", ")),
            };
            problem(format!("unknown key `{field}`"), Some(help))
        }
        Error::SerdeUnknownVariant { variant, expected, .. } => {
            let variant = escape(variant);
            let help = match closest(&variant, expected) {
                Some(best) => format!("did you mean `{best}`? valid values: {}", expected.join(", ")),
                None => format!("valid values: {}", expected.join(", ")),
            };
            problem(format!("`{variant}` is not a valid value here"), Some(help))
        }
        Error::SerdeMissingField { field, .. } => {
            problem(format!("missing key `{field}`"), Some(format!("add `{field}:` to this mapping; {schema}")))
        }
        Error::InvalidScalar { ty, .. } => {
            let found = scalar_at(text, pos).unwrap_or_default();
            let (message, help) = invalid_scalar(ty, &found);
            problem(message, Some(help))
        }
        Error::SerdeInvalidType { unexpected, expected, .. } => {
            problem(format!("expected {expected}, found {unexpected}"), Some(schema.into()))
        }
        Error::SerdeInvalidValue { unexpected, expected, .. } => {
            problem(format!("invalid value {unexpected}, expected {expected}"), Some(schema.into()))
        }
        Error::SerdeInvalidLength { len, expected, .. } => {
            problem(format!("a list of {len} items, expected {expected}"), Some(schema.into()))
        }
        Error::NullIntoString { .. } => problem(
            "expected text, found nothing".into(),
            Some("write the text after the key; quote it if it contains `: ` or ` #`".into()),
        ),
        Error::Unexpected { expected, .. } => {
            let what = match *expected {
                "mapping start" => "a mapping (`key: value` entries)",
                "sequence start" => "a list (`- item` lines or `[a, b]`)",
                "mapping end" => "the end of the mapping",
                "scalar" | "value" => "a single value",
                "string scalar" | "str expected" => "text",
                other => other,
            };
            problem(format!("expected {what} here"), Some(schema.into()))
        }
        Error::DuplicateMappingKey { key, .. } => {
            let key = key.as_deref().map(escape).unwrap_or_else(|| "?".into());
            let first = first_occurrence(text, pos, &key);
            let help = match first {
                Some(p) => {
                    format!("`{key}` is first given at line {}, column {}; remove one of them", p.line, p.column)
                }
                None => "each key may appear once in a mapping; remove one of them".into(),
            };
            problem(format!("duplicate key `{key}`"), Some(help))
        }
        Error::MultipleDocuments { .. } => problem(
            "a second YAML document starts here; a spec file holds exactly one".into(),
            Some("remove the `---` separator, or move the second document to its own file".into()),
        ),
        Error::Budget { breach, .. } => {
            let (message, help) = budget(breach);
            problem(message, Some(help))
        }
        Error::AliasReplayLimitExceeded { max_total_replayed_events, .. } => problem(
            format!("aliases expand to more than {max_total_replayed_events} YAML events"),
            Some("this looks like an alias bomb; spec files use aliases (`*name`) only to share small lists".into()),
        ),
        Error::AliasExpansionLimitExceeded { max_expansions_per_anchor, .. } => problem(
            format!("an anchor is expanded more than {max_expansions_per_anchor} times"),
            Some("spec files use aliases (`*name`) only to share small lists".into()),
        ),
        Error::AliasReplayStackDepthExceeded { max_depth, .. } => problem(
            format!("aliases nest more than {max_depth} deep"),
            Some("spec files use aliases (`*name`) only to share small lists".into()),
        ),
        Error::UnknownAnchor { .. } => problem(
            "this alias refers to no anchor".into(),
            Some("define `&name` before using `*name`; anchors do not cross files".into()),
        ),
        Error::Eof { .. } => problem("unexpected end of file".into(), unclosed_help(text, pos)),
        Error::NonFiniteFloat { value, .. } => {
            problem(format!("`{}` is not a finite number", escape(value)), Some("write a finite number".into()))
        }
        Error::ExternalMessage { msg, .. } => syntax(msg, text, pos),
        Error::InvalidBooleanStrict { .. } => {
            let found = scalar_at(text, pos).unwrap_or_default();
            let (message, help) = invalid_scalar("bool", &found);
            problem(message, Some(help))
        }
        Error::Message { msg, .. } if msg.contains("untagged enum StatedValue") => problem(
            "a stated value is a number or text".into(),
            Some("write the value as the manual states it: `7.6`, `\"1.1\"` or a variant name".into()),
        ),
        Error::Message { msg, .. } => problem(first_line(msg), Some(schema.into())),
        other => problem(first_line(&other.to_string()), Some(schema.into())),
    }
}

/// A YAML syntax error from the parser.
fn syntax(msg: &str, text: &str, pos: Pos) -> Problem {
    let msg = first_line(msg);
    if msg.contains("tab") {
        // The parser reports the scalar or key before the tab; point at the tab.
        let tab = text
            .lines()
            .enumerate()
            .skip((pos.line as usize).saturating_sub(1))
            .take(3)
            .find_map(|(i, l)| l.chars().position(|c| c == '\t').map(|c| (i, c)));
        let pos = tab.map_or(pos, |(i, c)| Pos { line: i as u32 + 1, column: c as u32 + 1 });
        return Problem {
            pos,
            key: String::new(),
            message: "a tab character where YAML expects spaces".into(),
            help: Some("YAML indents with spaces only; replace the tab with spaces".into()),
        };
    }
    if msg.contains("recursion limit") || msg.contains("nesting limit") || msg.contains("too deep") {
        return Problem {
            pos,
            key: String::new(),
            message: format!("the YAML nests more than {MAX_YAML_DEPTH} levels deep"),
            help: Some("spec files nest a few levels; flatten the structure".into()),
        };
    }
    if msg.contains("quote") {
        // A quote left open runs on to the next one, often lines further down.
        if let Some(start) = quote_start(text, pos) {
            return Problem {
                pos: start,
                key: String::new(),
                message: "this quoted string is never closed".into(),
                help: Some(format!(
                    "close the string with the quote it opens with; left open, it runs on to line {}, where the YAML parser stopped: {msg}",
                    pos.line
                )),
            };
        }
        return Problem {
            pos,
            key: String::new(),
            message: "this quoted string is never closed".into(),
            help: Some("close the string with the quote it opens with".into()),
        };
    }
    // A flow collection left open on an earlier line is the usual cause of
    // a confusing parser message further down: point at it.
    if let Some((line, column, open)) = unclosed_flow(text, pos).filter(|(line, _, _)| *line < pos.line) {
        let close = if open == '[' { ']' } else { '}' };
        return Problem {
            pos: Pos { line, column },
            key: String::new(),
            message: format!("this `{open}` is never closed"),
            help: Some(format!("add `{close}` before line {}, where the YAML parser stopped: {msg}", pos.line)),
        };
    }
    Problem { pos, key: String::new(), message: format!("invalid YAML: {msg}"), help: None }
}

/// A help pointing at a `[` or `{` opened before `pos` and never closed.
fn unclosed_help(text: &str, pos: Pos) -> Option<String> {
    let (line, column, open) = unclosed_flow(text, pos)?;
    let close = if open == '[' { ']' } else { '}' };
    Some(format!("the `{open}` at line {line}, column {column} is never closed; add `{close}`"))
}

/// The innermost flow collection opened before `pos` and still open there.
fn unclosed_flow(text: &str, pos: Pos) -> Option<(u32, u32, char)> {
    let mut stack: Vec<(u32, u32, char)> = Vec::new();
    for (i, line) in text.lines().enumerate().take(pos.line as usize) {
        let line_no = i as u32 + 1;
        let mut quote: Option<char> = None;
        // The last non-blank character before this one on the line.
        let mut prev: Option<char> = None;
        let mut after_blank = true;
        for (j, c) in line.chars().enumerate() {
            let col = j as u32 + 1;
            if line_no == pos.line && col >= pos.column {
                break;
            }
            // A value starts at the line's start, after `: `, `- `, `, ` or an opener.
            let value_start =
                (matches!(prev, None | Some(':' | ',' | '-')) && after_blank) || matches!(prev, Some('[' | '{'));
            match quote {
                Some(q) if c == q => quote = None,
                Some(_) => {}
                None => match c {
                    '#' if after_blank => break,
                    '"' | '\'' if value_start => quote = Some(c),
                    '[' | '{' if value_start => stack.push((line_no, col, c)),
                    ']' | '}' if !stack.is_empty() => {
                        stack.pop();
                    }
                    _ => {}
                },
            }
            after_blank = c == ' ' || c == '\t';
            if !after_blank {
                prev = Some(c);
            }
        }
    }
    stack.pop()
}

fn first_line(msg: &str) -> String {
    let first = msg.lines().next().unwrap_or("invalid YAML").trim();
    let first = first.strip_prefix("error: ").unwrap_or(first);
    // Drop a leading "line L column C: "; the position is shown separately.
    let first = match (first.starts_with("line "), first.find(": ")) {
        (true, Some(i)) => first.get(i + 2..).unwrap_or(first),
        _ => first,
    };
    let first = match first.find(" at line ") {
        Some(i) => first.get(..i).unwrap_or(first),
        None => first,
    };
    // Library advice ("set DuplicateKeyPolicy in Options") does not help a spec author.
    let first = match first.find(", set ").or_else(|| first.find("; use from_str")) {
        Some(i) => first.get(..i).unwrap_or(first),
        None => first,
    };
    escape(first)
}

fn budget(breach: &BudgetBreach) -> (String, String) {
    let bomb = "spec files are small; aliases (`*name`) that expand exponentially (an alias bomb) are refused";
    match breach {
        BudgetBreach::Nodes { .. } => (format!("the YAML holds more than {MAX_YAML_NODES} values"), bomb.into()),
        BudgetBreach::Events { .. } => (format!("the YAML holds more than {MAX_YAML_NODES} values"), bomb.into()),
        BudgetBreach::Aliases { .. } => (format!("the YAML uses more than {MAX_YAML_ALIASES} aliases"), bomb.into()),
        BudgetBreach::Anchors { .. } => (format!("the YAML defines more than {MAX_YAML_ALIASES} anchors"), bomb.into()),
        BudgetBreach::Depth { .. } => (
            format!("the YAML nests more than {MAX_YAML_DEPTH} levels deep"),
            "spec files nest a few levels; flatten the structure".into(),
        ),
        BudgetBreach::Documents { .. } => (
            "a second YAML document starts here; a spec file holds exactly one".into(),
            "remove the `---` separator, or move the second document to its own file".into(),
        ),
        other => (format!("the YAML exceeds a parser limit ({other:?})"), bomb.into()),
    }
}

/// The message and help for a scalar that is not a `ty`.
fn invalid_scalar(ty: &str, found: &str) -> (String, String) {
    let found = escape(found);
    let max: Option<u128> = match ty {
        "u8" => Some(u8::MAX.into()),
        "u16" => Some(u16::MAX.into()),
        "u32" => Some(u32::MAX.into()),
        "u64" | "usize" => Some(u64::MAX.into()),
        _ => None,
    };
    if let Some(max) = max {
        let range = format!("a whole number in 0..={max}, decimal or 0x hex");
        return match parse_int(&found) {
            Some(n) if n < 0 => (format!("`{found}` is negative, but this key takes an unsigned number"), range),
            Some(_) => (format!("`{found}` is too large for this key"), range),
            None => (format!("`{found}` is not a whole number"), range),
        };
    }
    match ty {
        "f32" | "f64" | "floating point" => {
            (format!("`{found}` is not a number"), "write a decimal number like `7.6` or `-0.5`".into())
        }
        "bool" | "boolean" => (format!("`{found}` is not true or false"), "write `true` or `false`".into()),
        "i8" | "i16" | "i32" | "i64" | "isize" => {
            (format!("`{found}` is not a whole number in range"), format!("write a whole number that fits an {ty}"))
        }
        _ => (format!("`{found}` is not a valid {ty}"), "spec/schema.json describes every key and its type".into()),
    }
}

fn parse_int(text: &str) -> Option<i128> {
    let (negative, digits) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text.strip_prefix('+').unwrap_or(text)),
    };
    let value = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        Some(hex) => i128::from_str_radix(&hex.replace('_', ""), 16).ok()?,
        None => digits.replace('_', "").parse::<i128>().ok()?,
    };
    Some(if negative { -value } else { value })
}

/// The scalar written at `pos`, without quotes.
fn scalar_at(text: &str, pos: Pos) -> Option<String> {
    let line = text.lines().nth((pos.line as usize).checked_sub(1)?)?;
    let rest: String = line.chars().skip((pos.column as usize).saturating_sub(1)).collect();
    let rest = rest.trim_start();
    if let Some(q) = rest.chars().next().filter(|c| *c == '"' || *c == '\'') {
        let inner = &rest[1..];
        return Some(inner.split(q).next().unwrap_or(inner).chars().take(40).collect());
    }
    let end = rest.find([',', ']', '}']).unwrap_or(rest.len());
    let token = rest[..end].split(" #").next().unwrap_or("").trim();
    Some(token.chars().take(40).collect())
}

/// Where `key` is first written in the mapping holding the duplicate at `pos`
/// (block mappings; a flow mapping on one line is searched on that line).
fn first_occurrence(text: &str, pos: Pos, key: &str) -> Option<Pos> {
    let lines: Vec<&str> = text.lines().collect();
    let at = (pos.line as usize).checked_sub(1)?;
    let col = (pos.column as usize).saturating_sub(1);
    let is_key_at = |line: &str, c: usize| {
        let chars: Vec<char> = line.chars().collect();
        let rest: String = chars.get(c..).unwrap_or(&[]).iter().collect();
        rest.strip_prefix(key).is_some_and(|r| r.trim_start().starts_with(':'))
    };
    // Same line, earlier (flow mapping).
    if let Some(line) = lines.get(at) {
        for c in 0..col {
            let before: String = line.chars().take(c).collect();
            if (before.ends_with('{') || before.ends_with(", ") || before.ends_with("{ ")) && is_key_at(line, c) {
                return Some(Pos { line: pos.line, column: c as u32 + 1 });
            }
        }
    }
    for i in (0..at).rev() {
        let line = lines.get(i)?;
        let trimmed = line.trim_start();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let prefix: String = line.chars().take(col).collect();
        if prefix.chars().all(|c| c == ' ' || c == '-') && is_key_at(line, col) {
            return Some(Pos { line: i as u32 + 1, column: col as u32 + 1 });
        }
        if line.len() - trimmed.len() < col {
            return None; // The first line of this mapping, or a parent.
        }
    }
    None
}

/// Where parsing may resume after an error: top-level keys and the items
/// of top-level block lists, found by indentation.
///
/// A line only counts where no quoted text or flow collection (`[...]`,
/// `{...}`) is open, or where every one open there is never closed (an
/// error that would swallow the rest of the file): YAML lets both run over
/// lines, even unindented ones.
struct Layout {
    /// The lines (comments, directives) before the first key, kept when parsing from a resume point.
    preamble: usize,
    /// What each line is.
    lines: Vec<Line>,
    /// For each line, whether parsing may start afresh there (see [`fresh_starts`]).
    fresh: Vec<bool>,
    /// In line order.
    resumes: Vec<Resume>,
}

/// What a line is, for [`Layout`].
#[derive(Debug, Clone, PartialEq, Eq)]
enum Line {
    /// Blank, or only a comment.
    Blank,
    /// A directive (`%YAML`) or a document start (`---`).
    Directive,
    /// `key: ...` at column 0; `list` when nothing follows the colon, so
    /// that a block list may.
    Key { key: String, list: bool },
    /// `- ...`, indented this much.
    Item(usize),
    /// Anything else.
    Other,
}

impl Line {
    fn of(line: &str) -> Self {
        if is_blank_or_comment(line) {
            Line::Blank
        } else if is_directive(line) {
            Line::Directive
        } else if let Some(key) = top_key(line) {
            Line::Key { key: key.to_string(), list: is_list_header(line) }
        } else if is_item(line) {
            Line::Item(indentation(line))
        } else {
            Line::Other
        }
    }
}

/// A line (0-based) where parsing may resume.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Resume {
    line: usize,
    /// For an item of a top-level list: the list.
    list: Option<List>,
}

/// The top-level list an item belongs to.
#[derive(Debug, Clone, PartialEq, Eq)]
struct List {
    /// The line (0-based) of the list's key, kept when parsing from the item.
    header: usize,
    key: String,
    /// The item's index in the list.
    index: usize,
}

impl List {
    /// A key path of the text parsed from this item (where it is item 0)
    /// as a path of the file: `commands[1] (x)` -> `commands[4] (x)`.
    fn shift(&self, path: &str) -> String {
        let shifted = path.strip_prefix(self.key.as_str()).and_then(|r| r.strip_prefix('[')).and_then(|r| {
            let digits = r.find(']')?;
            let n: usize = r.get(..digits)?.parse().ok()?;
            Some(format!("{}[{}{}", self.key, n + self.index, r.get(digits..)?))
        });
        shifted.unwrap_or_else(|| path.to_string())
    }
}

impl Layout {
    /// The resume points of `text`, if it has the usual shape: a mapping of
    /// block keys at column 0, after nothing but comments and directives.
    fn of(text: &str) -> Option<Self> {
        // A lone `\r` ends a line for YAML but not for `str::lines`.
        if text.match_indices('\r').any(|(i, _)| text.as_bytes().get(i + 1) != Some(&b'\n')) {
            return None;
        }
        let lines: Vec<&str> = text.lines().collect();
        let mut layout = Self {
            lines: lines
                .iter()
                .enumerate()
                .map(|(i, l)| Line::of(if i == 0 { l.trim_start_matches('\u{feff}') } else { l }))
                .collect(),
            fresh: fresh_starts(&lines),
            preamble: 0,
            resumes: Vec::new(),
        };
        layout.preamble = layout.lines.iter().take_while(|l| matches!(l, Line::Blank | Line::Directive)).count();
        layout.resumes = layout.resumes()?;
        Some(layout)
    }

    /// After an error found a quote or bracket at line `line` (1-based) that
    /// closes only further down, reads the lines after as if it closed at
    /// the end of its line. False if nothing changes.
    fn reset(&mut self, text: &str, line: usize) -> bool {
        if self.fresh.get(line).is_none_or(|&f| f) {
            // Nothing open after that line closes again: nothing to reset.
            return false;
        }
        let after: Vec<&str> = text.lines().skip(line).collect();
        let fresh = fresh_starts(&after);
        self.fresh.truncate(line);
        self.fresh.extend(fresh);
        self.resumes = self.resumes().unwrap_or_default();
        true
    }

    /// The resume points, if the file is a mapping of block keys.
    fn resumes(&self) -> Option<Vec<Resume>> {
        let fresh = |i: usize| self.fresh.get(i).copied().unwrap_or(false);
        let tops: Vec<usize> =
            (0..self.lines.len()).filter(|&i| fresh(i) && matches!(self.lines[i], Line::Key { .. })).collect();
        if tops.first() != Some(&self.preamble) {
            return None;
        }
        let mut resumes = Vec::new();
        for (n, &top) in tops.iter().enumerate() {
            resumes.push(Resume { line: top, list: None });
            let Line::Key { key, list: true } = &self.lines[top] else { continue };
            let end = tops.get(n + 1).copied().unwrap_or(self.lines.len());
            let mut body = (top + 1..end).filter(|&i| self.lines[i] != Line::Blank).peekable();
            let Some(&Line::Item(indent)) = body.peek().map(|&i| &self.lines[i]) else { continue };
            let items = body.filter(|&i| self.lines[i] == Line::Item(indent));
            for (index, line) in items.enumerate() {
                if fresh(line) {
                    resumes.push(Resume { line, list: Some(List { header: top, key: key.clone(), index }) });
                }
            }
        }
        Some(resumes)
    }

    /// Where to resume after an error that stopped the parser at `stop`
    /// (1-based line), having parsed from `from`: after both, and past the
    /// list whose key line `stop` is on.
    fn resume_after(&self, stop: usize, from: Option<&Resume>) -> Option<Resume> {
        let after = stop.max(from.map_or(0, |r| r.line + 1));
        let bad_header = from.and_then(|r| r.list.as_ref()).filter(|l| l.header + 1 == stop).map(|l| l.header);
        self.resumes
            .iter()
            .find(|r| r.line + 1 > after && (bad_header.is_none() || r.list.as_ref().map(|l| l.header) != bad_header))
            .cloned()
    }

    /// The first resume line (0-based) after line `line` (1-based): where
    /// the entry holding `line` ends.
    fn next_start_after(&self, line: usize) -> Option<usize> {
        self.resumes.iter().map(|r| r.line).find(|&l| l + 1 > line)
    }
}

/// `text` with the lines (0-based) that `keep` refuses emptied, their line
/// breaks kept, so that positions stay those of `text`.
fn keep_lines(text: &str, keep: impl Fn(usize) -> bool) -> String {
    let mut out = String::with_capacity(text.len());
    for (i, line) in text.split_inclusive('\n').enumerate() {
        if keep(i) {
            out.push_str(line);
        } else {
            out.extend(line.chars().filter(|c| matches!(c, '\r' | '\n')));
        }
    }
    out
}

fn indentation(line: &str) -> usize {
    line.len() - line.trim_start_matches(' ').len()
}

fn is_blank_or_comment(line: &str) -> bool {
    let t = line.trim();
    t.is_empty() || t.starts_with('#')
}

/// A directive (`%YAML 1.2`) or a document start (`---`), which may come before the first key.
fn is_directive(line: &str) -> bool {
    let t = line.trim_end();
    t.starts_with('%')
        || t.strip_prefix("---")
            .is_some_and(|r| r.is_empty() || r.starts_with([' ', '\t']) && r.trim_start().starts_with('#'))
}

/// A list item's line: `- ...` or a lone `-`.
fn is_item(line: &str) -> bool {
    let t = line.trim_start_matches(' ');
    t == "-" || t.starts_with("- ") || t.starts_with("-\t")
}

/// The key of a line `key: ...` at column 0 with a plain key, if it is one.
fn top_key(line: &str) -> Option<&str> {
    let first = line.chars().next()?;
    if !(first.is_alphanumeric() || first == '_') {
        return None;
    }
    let colon = line.char_indices().find(|&(i, c)| {
        c == ':' && line.get(i + 1..).and_then(|r| r.chars().next()).is_none_or(|n| n == ' ' || n == '\t')
    })?;
    let key = line.get(..colon.0)?;
    (!key.contains(|c: char| "#[]{},\"'&*!|>%@`".contains(c) || c.is_control())).then(|| key.trim_end())
}

/// A key line with nothing after the colon but a comment: `commands:`.
fn is_list_header(line: &str) -> bool {
    let Some(colon) = line.find(':') else { return false };
    let rest = line.get(colon + 1..).unwrap_or("");
    let t = rest.trim_start();
    t.is_empty() || t.starts_with('#') && rest.starts_with([' ', '\t'])
}

/// Quoted scalars and flow collections opened and closed line by line, as
/// YAML's scanner sees them (block scalars skipped, comments ignored).
#[derive(Default)]
struct Lexer {
    /// What is open (`"`, `'`, `[` or `{`) and where (0-based line and character).
    open: Vec<(char, usize, usize)>,
    /// Inside a block scalar: lines indented more than this belong to it.
    block: Option<usize>,
}

impl Lexer {
    /// Lexes line `n`, calling `closed(kind, opened at, closed at column, depth after)`
    /// for each quoted scalar or collection it closes.
    fn line(&mut self, n: usize, line: &str, mut closed: impl FnMut(char, (usize, usize), usize, usize)) {
        if let Some(parent) = self.block {
            if line.trim().is_empty() || indentation(line) > parent {
                return;
            }
            self.block = None;
        }
        // The last non-blank character before this one on the line.
        let mut prev: Option<char> = None;
        let mut after_blank = true;
        let mut chars = line.char_indices().enumerate().peekable();
        while let Some((i, (byte, c))) = chars.next() {
            let top = self.open.last().map(|o| o.0);
            let next = chars.peek().map(|(_, (_, c))| *c);
            let mut close = false;
            match top {
                Some('"') if c == '\\' => {
                    chars.next();
                }
                Some('"') if c == '"' => close = true,
                Some('\'') if c == '\'' && next == Some('\'') => {
                    chars.next();
                }
                Some('\'') if c == '\'' => close = true,
                Some('"' | '\'') => {}
                _ => {
                    let in_flow = top.is_some();
                    // A value starts at the line's start, after `: `, `- `, `? `, or in a flow after `[`, `{`, `,`, `:`.
                    let value_start = (matches!(prev, None | Some(':' | '-' | '?')) && after_blank)
                        || (in_flow && matches!(prev, Some('[' | '{' | ',' | ':')));
                    match c {
                        '#' if after_blank => break,
                        '"' | '\'' | '[' | '{' if value_start => self.open.push((c, n, i)),
                        ']' | '}' if in_flow => close = true,
                        '|' | '>' if !in_flow && value_start && is_block_header(line.get(byte + 1..).unwrap_or("")) => {
                            self.block = Some(block_parent(line));
                            break;
                        }
                        _ => {}
                    }
                }
            }
            if close && let Some((kind, line, column)) = self.open.pop() {
                closed(kind, (line, column), i, self.open.len());
            }
            after_blank = c == ' ' || c == '\t';
            if !after_blank {
                prev = Some(c);
            }
        }
    }
}

/// For each line, whether parsing may start afresh there: no quoted scalar
/// or flow collection is open at its start, or every one open there stays
/// open to the end of the file.
fn fresh_starts(lines: &[&str]) -> Vec<bool> {
    let mut lexer = Lexer::default();
    let mut depth_at_start = Vec::with_capacity(lines.len());
    let mut least_depth = Vec::with_capacity(lines.len());
    for (n, line) in lines.iter().enumerate() {
        let depth = lexer.open.len();
        let mut least = depth;
        lexer.line(n, line, |_, _, _, after| least = least.min(after));
        depth_at_start.push(depth);
        least_depth.push(least);
    }
    let mut fresh = vec![false; lines.len()];
    let mut least_after = lexer.open.len();
    for n in (0..lines.len()).rev() {
        least_after = least_after.min(least_depth[n]);
        fresh[n] = least_after >= depth_at_start[n];
    }
    fresh
}

/// Where the quoted scalar starts that is open at `pos`, or that closed on
/// its line just before it, if it starts on an earlier line: a quote never
/// closed on its own line runs on until the next quote.
fn quote_start(text: &str, pos: Pos) -> Option<Pos> {
    let target = (pos.line as usize).checked_sub(1)?;
    let column = (pos.column as usize).saturating_sub(1);
    let mut lexer = Lexer::default();
    let mut start = None;
    for (n, line) in text.lines().enumerate().take(target + 1) {
        lexer.line(n, line, |kind, from, at, _| {
            if n == target && at < column && matches!(kind, '"' | '\'') {
                start = Some(from);
            }
        });
    }
    let open = lexer.open.iter().find(|o| matches!(o.0, '"' | '\'')).map(|o| (o.1, o.2));
    let (line, column) = open.or(start).filter(|(line, _)| *line < target)?;
    Some(Pos { line: line as u32 + 1, column: column as u32 + 1 })
}

/// What may follow `|` or `>` to start a block scalar: chomping and
/// indentation indicators, then nothing or a comment.
fn is_block_header(rest: &str) -> bool {
    let indicators = rest.chars().take(2).take_while(|c| matches!(c, '-' | '+' | '1'..='9')).count();
    let tail = rest.get(indicators..).unwrap_or("");
    let comment = tail.trim_start_matches([' ', '\t']);
    comment.is_empty() || comment.starts_with('#') && comment.len() < tail.len()
}

/// The indentation a block scalar started on `line` must exceed: the
/// column of its key, or of its `-` in a list.
fn block_parent(line: &str) -> usize {
    let mut column = indentation(line);
    let mut dash = None;
    let mut rest = line.get(column..).unwrap_or("");
    while is_item(rest) {
        dash = Some(column);
        let after = rest.get(1..).unwrap_or("");
        let skipped = after.len() - after.trim_start_matches([' ', '\t']).len();
        column += 1 + skipped;
        rest = after.get(skipped..).unwrap_or("");
    }
    if rest.starts_with(['|', '>']) {
        // `- |`: the list's column; `|` alone on a line: its parent's, at most.
        return dash.unwrap_or(column.saturating_sub(1));
    }
    column
}

/// An unquoted comma that ended a value inside a flow mapping, making the
/// rest of the text a key of its own: `{doc: Slope K, the gain.}`.
#[derive(Debug, PartialEq, Eq)]
struct Comma {
    /// The comma.
    pos: Pos,
    /// The key whose value it ended, and where that is written.
    key: String,
    key_pos: Pos,
    /// The value as meant: `Slope K, the gain.`.
    value: String,
    /// The text read as a key: `the gain.`.
    stray: String,
}

/// The unquoted comma that made the entry at `pos` of a flow mapping: the
/// entry has no value (or a key with a space, which no spec key has) and
/// follows a `key: plain text` entry.
fn unquoted_comma(text: &str, pos: Pos) -> Option<Comma> {
    let line: Vec<char> = text.lines().nth((pos.line as usize).checked_sub(1)?)?.chars().collect();
    let column = (pos.column as usize).checked_sub(1)?;
    // A flow mapping opened on an earlier line continues on this one.
    let continued = unclosed_flow(text, Pos { line: pos.line, column: 1 }).is_some_and(|(_, _, c)| c == '{');
    let (entries, at) = flow_entries(&line, column, continued)?;
    // An entry's characters without the blanks around it, and where they start.
    let trimmed = |&(start, end): &(usize, usize)| -> (usize, &[char]) {
        let chars = line.get(start..end).unwrap_or(&[]);
        let lead = chars.iter().take_while(|c| c.is_whitespace()).count();
        let trail = chars.iter().rev().take_while(|c| c.is_whitespace()).count();
        (start + lead, chars.get(lead..chars.len().saturating_sub(trail)).unwrap_or(&[]))
    };
    let plain = |t: &[char]| t.first().is_some_and(|c| !"\"'[]{}&*!|>%@`#?:-".contains(*c));
    let valueless = |e: &(usize, usize)| {
        let (_, t) = trimmed(e);
        plain(t) && entry_colon(t).is_none()
    };
    let (_, stray) = trimmed(entries.get(at)?);
    let spaced_key =
        entry_colon(stray).is_some_and(|c| plain(stray) && stray.get(..c).is_some_and(|k| k.contains(&' ')));
    if !valueless(entries.get(at)?) && !spaced_key {
        return None;
    }
    // Back over earlier valueless entries to the one whose value the comma ended.
    let mut first = at;
    while first > 0 && entries.get(first - 1).is_some_and(valueless) {
        first -= 1;
    }
    let owner = entries.get(first.checked_sub(1)?)?;
    let (key_column, owner_text) = trimmed(owner);
    let colon = entry_colon(owner_text)?;
    let key: String = owner_text.get(..colon)?.iter().collect();
    let value = owner_text.get(colon + 1..)?;
    let value_column = key_column + colon + 1 + value.iter().take_while(|c| c.is_whitespace()).count();
    if !plain(owner_text) || !plain(line.get(value_column..)?) || key.trim().is_empty() {
        return None;
    }
    // Forward over later valueless entries: the rest of the text meant.
    let mut last = at;
    while entries.get(last + 1).is_some_and(valueless) {
        last += 1;
    }
    let (_, meant) = trimmed(&(value_column, entries.get(last)?.1));
    Some(Comma {
        pos: Pos { line: pos.line, column: owner.1 as u32 + 1 },
        key: key.trim().to_string(),
        key_pos: Pos { line: pos.line, column: key_column as u32 + 1 },
        value: meant.iter().collect(),
        stray: stray.iter().collect(),
    })
}

/// Where the colon of a `key: value` (or `key:`) entry is.
fn entry_colon(entry: &[char]) -> Option<usize> {
    (0..entry.len()).find(|&i| entry.get(i) == Some(&':') && entry.get(i + 1).is_none_or(|n| *n == ' ' || *n == '\t'))
}

/// A flow collection open on a line, for [`flow_entries`].
struct Flow {
    /// `[` or `{`, and its column.
    opener: char,
    column: usize,
    /// Where the entry being read starts.
    entry: usize,
    /// The entries read: character ranges, between commas.
    entries: Vec<(usize, usize)>,
}

impl Flow {
    /// Its entries, the last ending at `end`, and which holds `column`, if
    /// it is a mapping.
    fn holding(mut self, end: usize, column: usize) -> Option<(Vec<(usize, usize)>, usize)> {
        self.entries.push((self.entry, end));
        let at = self.entries.iter().position(|&(s, e)| s <= column && column <= e)?;
        (self.opener == '{').then_some((self.entries, at))
    }
}

/// The entries (character ranges, between commas) of the innermost flow
/// collection of `line` holding character `column`, if it is a mapping,
/// and which entry holds it. With `continued`, the line starts inside a
/// flow mapping.
fn flow_entries(line: &[char], column: usize, continued: bool) -> Option<(Vec<(usize, usize)>, usize)> {
    let mut open: Vec<Flow> = Vec::new();
    if continued {
        open.push(Flow { opener: '{', column: 0, entry: 0, entries: Vec::new() });
    }
    let mut quote: Option<char> = None;
    let mut prev: Option<char> = None;
    let mut after_blank = true;
    let mut end = line.len();
    let mut i = 0;
    while let Some(&c) = line.get(i) {
        match quote {
            Some('"') if c == '\\' => i += 1,
            Some('\'') if c == '\'' && line.get(i + 1) == Some(&'\'') => i += 1,
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None => {
                let value_start = (matches!(prev, None | Some(':' | '-' | '?')) && after_blank)
                    || (!open.is_empty() && matches!(prev, Some('[' | '{' | ',' | ':')));
                match c {
                    '#' if after_blank => {
                        end = i;
                        break;
                    }
                    '"' | '\'' if value_start => quote = Some(c),
                    '[' | '{' if value_start => {
                        open.push(Flow { opener: c, column: i, entry: i + 1, entries: Vec::new() })
                    }
                    ',' => {
                        if let Some(top) = open.last_mut() {
                            top.entries.push((top.entry, i));
                            top.entry = i + 1;
                        }
                    }
                    ']' | '}' => {
                        // The innermost collection holding `column` closes here.
                        if let Some(flow) = open.pop()
                            && flow.column <= column
                            && column <= i
                        {
                            return flow.holding(i, column);
                        }
                    }
                    _ => {}
                }
            }
        }
        after_blank = c == ' ' || c == '\t';
        if !after_blank {
            prev = Some(c);
        }
        i += 1;
    }
    // Still open at the end of the line: a flow mapping running over lines.
    open.pop().filter(|flow| flow.column <= column)?.holding(end, column)
}

/// Any YAML node, with positions: used to tell the key path of a position
/// when the typed parse fails.
enum Node {
    Map(Vec<(Spanned<Scalar>, Spanned<Node>)>),
    Seq(Vec<Spanned<Node>>),
    Scalar(String),
}

/// A scalar of any type, as text.
struct Scalar(String);

struct ScalarVisitor;

impl Visitor<'_> for ScalarVisitor {
    type Value = Scalar;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a scalar")
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Scalar, E> {
        Ok(Scalar(v.to_owned()))
    }
    fn visit_bool<E: de::Error>(self, v: bool) -> Result<Scalar, E> {
        Ok(Scalar(v.to_string()))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Scalar, E> {
        Ok(Scalar(v.to_string()))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Scalar, E> {
        Ok(Scalar(v.to_string()))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Scalar, E> {
        Ok(Scalar(v.to_string()))
    }
    fn visit_unit<E: de::Error>(self) -> Result<Scalar, E> {
        Ok(Scalar(String::new()))
    }
}

impl<'de> Deserialize<'de> for Scalar {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ScalarVisitor)
    }
}

struct NodeVisitor;

impl<'de> Visitor<'de> for NodeVisitor {
    type Value = Node;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("any YAML node")
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_owned()))
    }
    fn visit_bool<E: de::Error>(self, v: bool) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_string()))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_string()))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_string()))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_string()))
    }
    fn visit_unit<E: de::Error>(self) -> Result<Node, E> {
        Ok(Node::Scalar(String::new()))
    }
    fn visit_none<E: de::Error>(self) -> Result<Node, E> {
        Ok(Node::Scalar(String::new()))
    }
    fn visit_some<D: de::Deserializer<'de>>(self, d: D) -> Result<Node, D::Error> {
        Node::deserialize(d)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Node, A::Error> {
        let mut items = Vec::new();
        while let Some(item) = seq.next_element()? {
            items.push(item);
        }
        Ok(Node::Seq(items))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Node, A::Error> {
        let mut entries = Vec::new();
        while let Some(entry) = map.next_entry()? {
            entries.push(entry);
        }
        Ok(Node::Map(entries))
    }
}

impl<'de> Deserialize<'de> for Node {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(NodeVisitor)
    }
}

/// Every key and value of a document with its position and key path.
struct KeyPaths(Vec<(Pos, String)>);

impl KeyPaths {
    /// The key paths of `text`, if it is well-formed YAML (within the limits).
    fn of(text: &str) -> Option<Self> {
        let mut options = options();
        options.duplicate_keys = DuplicateKeyPolicy::LastWins;
        options.non_finite_float_policy = serde_saphyr::NonFiniteFloatPolicy::PassThrough;
        let root = serde_saphyr::from_str_with_options::<Spanned<Node>>(text, options).ok()?;
        let mut out = Vec::new();
        walk(&root, String::new(), &mut out);
        out.sort_by_key(|(pos, _)| *pos);
        Some(Self(out))
    }

    /// The key path of the key or value written exactly at `pos`.
    fn exact(&self, pos: Pos) -> Option<String> {
        self.0.iter().rev().find(|(p, _)| *p == pos).map(|(_, path)| path.clone())
    }

    /// The key path at `pos` (the last key or value starting at or before
    /// it). With `parent`, the path of the mapping holding that key instead,
    /// and where that mapping's key is written.
    fn at(&self, pos: Pos, parent: bool) -> Option<(Pos, String)> {
        let (at, path) = self.0.iter().rev().find(|(p, _)| *p <= pos)?;
        if !parent {
            return Some((*at, path.clone()));
        }
        let up = parent_path(path)?;
        let start = self.0.iter().find(|(_, p)| *p == up).map_or(*at, |(p, _)| *p);
        Some((start, up))
    }
}

/// `a.b[2] (x).c` -> `a.b[2] (x)`; `a.b[2] (x)` -> `a.b`.
fn parent_path(path: &str) -> Option<String> {
    match path.rfind(['.', '[']) {
        Some(i) => path.get(..i).map(str::to_string),
        None if path.is_empty() => None,
        None => Some(String::new()),
    }
}

fn walk(node: &Spanned<Node>, path: String, out: &mut Vec<(Pos, String)>) {
    out.push((Pos::at(node), path.clone()));
    match &node.value {
        Node::Scalar(_) => {}
        Node::Seq(items) => {
            for (i, item) in items.iter().enumerate() {
                // Entries with a valid `name` (or `use`) are shown by it: `commands[3] (get_ph)`.
                let name = match &item.value {
                    Node::Map(entries) => entries.iter().find_map(|(k, v)| match &v.value {
                        Node::Scalar(s) if (k.value.0 == "name" || k.value.0 == "use") && check_snake(s).is_none() => {
                            Some(s.clone())
                        }
                        _ => None,
                    }),
                    _ => None,
                };
                let item_path = match name {
                    Some(n) => format!("{path}[{i}] ({n})"),
                    None => format!("{path}[{i}]"),
                };
                walk(item, item_path, out);
            }
        }
        Node::Map(entries) => {
            for (k, v) in entries {
                let key = escape(&k.value.0);
                let key_path = if path.is_empty() { key } else { format!("{path}.{key}") };
                out.push((Pos::at(k), key_path.clone()));
                walk(v, key_path, out);
            }
        }
    }
}

/// The candidate closest to `word` by edit distance, if close enough to be a typo.
pub(crate) fn closest<'a>(word: &str, candidates: &[&'a str]) -> Option<&'a str> {
    candidates
        .iter()
        .map(|c| (edit_distance(word, c), *c))
        .filter(|(d, c)| *d <= c.len().max(word.len()).div_ceil(3).max(1))
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// Edit distance counting a swap of neighbours as one edit (optimal string alignment).
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let width = b.len() + 1;
    let mut d = vec![0usize; (a.len() + 1) * width];
    for (i, row) in d.chunks_mut(width).enumerate() {
        row[0] = i;
    }
    for (j, cell) in d.iter_mut().enumerate().take(width) {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut best =
                (d[(i - 1) * width + j] + 1).min(d[i * width + j - 1] + 1).min(d[(i - 1) * width + j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(d[(i - 2) * width + j - 2] + 1);
            }
            d[i * width + j] = best;
        }
    }
    d[a.len() * width + b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typos() {
        let keys = ["name", "use", "address", "count"];
        assert_eq!(closest("adress", &keys), Some("address"));
        assert_eq!(closest("cuont", &keys), Some("count"));
        assert_eq!(closest("banana", &keys), None);
    }

    #[test]
    fn scalars() {
        assert_eq!(scalar_at("a: two\n", Pos { line: 1, column: 4 }).as_deref(), Some("two"));
        assert_eq!(scalar_at("{a: 1x, b: 2}", Pos { line: 1, column: 5 }).as_deref(), Some("1x"));
        assert_eq!(scalar_at("a: \"x y\" # c", Pos { line: 1, column: 4 }).as_deref(), Some("x y"));
        assert_eq!(parse_int("-2"), Some(-2));
        assert_eq!(parse_int("0x10"), Some(16));
        assert_eq!(parse_int("two"), None);
    }

    #[test]
    fn unclosed() {
        let text = "a:\n  b: [1, 2\n  c: 3\n";
        assert_eq!(unclosed_flow(text, Pos { line: 3, column: 4 }), Some((2, 6, '[')));
        assert_eq!(unclosed_flow("a: [1, 2]\nb: x[y\n", Pos { line: 2, column: 5 }), None);
    }

    #[test]
    fn duplicate_keys() {
        let text = "x:\n  - name: a\n    count: 1\n    count: 2\n";
        assert_eq!(first_occurrence(text, Pos { line: 4, column: 5 }, "count"), Some(Pos { line: 3, column: 5 }));
        let flow = "{count: 1, count: 2}";
        assert_eq!(first_occurrence(flow, Pos { line: 1, column: 12 }, "count"), Some(Pos { line: 1, column: 2 }));
    }

    /// A sensor header, then `commands`.
    fn spec(commands: &str) -> String {
        format!(
            "sensor:\n  name: probe\n  title: Probe\n  doc: A probe.\n  manual: {{title: Manual, revision: Rev 1}}\n  \
             serial: {{baud: 9600, data_bits: 8, parity: none, stop_bits: 1}}\n  addresses: {{min: 1, max: 247}}\n  \
             default_address: 1\ncommands:\n{commands}"
        )
    }

    /// Line, column and message of each problem.
    fn problems(text: &str) -> Vec<(u32, u32, String)> {
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

    #[test]
    fn unquoted_comma_in_a_flow_mapping() {
        let text = spec("  - name: k\n    fields:\n      - {name: k, type: f32, doc: Slope K, the gain.}\n");
        let Err(found) = parse(&text) else { panic!("expected an error") };
        assert_eq!(found.len(), 1);
        let p = &found[0];
        assert_eq!(p.message, "an unquoted comma ends the value inside `{...}`");
        assert_eq!((p.pos.line, p.pos.column), (12, 42));
        assert_eq!(p.key, "commands[0] (k).fields[0] (k).doc");
        let help = p.help.as_deref().unwrap_or_default();
        assert!(help.ends_with("quote the text: doc: \"Slope K, the gain.\""), "{help}");
        assert!(help.contains("`the gain.` is read as a key of its own"), "{help}");

        let comma = |line: &str, column| unquoted_comma(line, Pos { line: 1, column });
        // Several commas; the error may point at a later stray part.
        let c = comma("{note: a, b, c, name: x}", 14).expect("a comma");
        assert_eq!((c.pos, c.key.as_str(), c.value.as_str()), (Pos { line: 1, column: 9 }, "note", "a, b, c"));
        // A stray part with `: ` in it.
        let c = comma("{doc: Range 0, the max: 14}", 16).expect("a comma");
        assert_eq!((c.value.as_str(), c.stray.as_str()), ("Range 0, the max: 14", "the max: 14"));
        // A flow mapping over two lines.
        let c = unquoted_comma("- {name: k,\n   doc: a, b}", Pos { line: 2, column: 12 }).expect("a comma");
        assert_eq!((c.pos, c.value.as_str()), (Pos { line: 2, column: 10 }, "a, b"));
        // Not a comma slip: a misspelt key, a quoted value, a list.
        assert_eq!(comma("{name: k, dox: 1}", 11), None);
        assert_eq!(
            comma("{name: k, dox}", 11),
            Some(Comma {
                pos: Pos { line: 1, column: 9 },
                key: "name".into(),
                key_pos: Pos { line: 1, column: 2 },
                value: "k, dox".into(),
                stray: "dox".into(),
            })
        );
        assert_eq!(comma("{doc: \"a\", b}", 12), None);
        assert_eq!(comma("[doc: a, b]", 10), None);
        assert_eq!(comma("{a: [x, y], b}", 13), None);
        // Quoted, the comma is fine.
        assert!(parse(&spec("  - {name: k, doc: \"Slope K, the gain.\"}\n")).is_ok());
        // A genuine unknown key keeps its message.
        let found = problems(&spec("  - {name: k, dox: 1}\n"));
        assert_eq!(found, [(10, 15, "unknown key `dox`".to_string())]);
    }

    #[test]
    fn lines_where_parsing_may_start_afresh() {
        let fresh = |text: &str| fresh_starts(&text.lines().collect::<Vec<_>>());
        assert_eq!(fresh("a: [1,\n2]\nb: 3"), [true, false, true]);
        assert_eq!(fresh("a: \"x\nb: y\"\nc: 'it''s\nd'"), [true, false, true, false]);
        // Never closed: the rest of the file would be swallowed, so start afresh.
        assert_eq!(fresh("a: [1\nb: 2\nc: 3"), [true, true, true]);
        assert_eq!(fresh("a: |\n  \"x [\nb: 2 # ]\n"), [true, true, true]);
        assert_eq!(fresh("a: x'y\nb: [1] # \"\nc: 3"), [true, true, true]);
    }

    #[test]
    fn quotes_left_open_are_found_where_they_start() {
        let text = "a:\n  b: \"x\n  c: y\n  d: \"z\"\n";
        assert_eq!(quote_start(text, Pos { line: 4, column: 9 }), Some(Pos { line: 2, column: 6 }));
        assert_eq!(quote_start(text, Pos { line: 4, column: 7 }), Some(Pos { line: 2, column: 6 }));
        assert_eq!(quote_start("a: \"x\"\nb: \"y", Pos { line: 2, column: 4 }), None);
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

    proptest::proptest! {
        #[test]
        fn parse_never_panics(text in "([a-z ]{0,6}[-:\\[\\]{},\"'#|>&*\\t\\n]){0,60}") {
            let _ = parse(&spec(&text));
            let _ = parse(&text);
        }
    }
}

//! The YAML errors in the spec's terms: what is wrong and, where it can be
//! told, what would be valid, at the offending place.

use super::Problem;
use super::error::{Error, Kind, Limit};
use super::lexer::{quote_start, unclosed_flow};
use super::limits::{MAX_ALIAS_REPLAY, MAX_YAML_ALIASES, MAX_YAML_DEPTH, MAX_YAML_NODES};
use super::scalar::whole;
use crate::diag::Pos;
use crate::names::escape;
use crate::suggest::closest;

/// Errors about the shape of well-formed YAML, which have a key path.
pub(super) fn is_shape_error(e: &Error) -> bool {
    matches!(
        e.inner().kind,
        Kind::UnknownField { .. }
            | Kind::UnknownVariant { .. }
            | Kind::MissingField { .. }
            | Kind::InvalidScalar { .. }
            | Kind::WrongTag { .. }
            | Kind::InvalidType { .. }
            | Kind::InvalidValue { .. }
            | Kind::InvalidLength { .. }
            | Kind::NullIntoString
            | Kind::Unexpected { .. }
            | Kind::NonFiniteFloat { .. }
            | Kind::DuplicateKey { .. }
            | Kind::Message { .. }
    )
}

/// Turns an error into a [`Problem`].
pub(super) fn explain(e: &Error, text: &str) -> Problem {
    let pos = e.at().unwrap_or(Pos { line: 1, column: 1 });
    let schema = "spec/schema.json describes every key and its type";
    let problem = |message: String, help: Option<String>| Problem { pos, key: String::new(), message, help };
    let bomb = "spec files use aliases (`*name`) only to share small lists";
    match &e.kind {
        Kind::Alias { error, .. } => {
            let inner = explain(error, text);
            Problem { pos, ..inner }
        }
        Kind::UnknownField { field, expected } => {
            let field = escape(field);
            let help = match (closest(&field, expected), expected.is_empty()) {
                (_, true) => "no keys are allowed here".to_string(),
                (Some(best), _) => format!("did you mean `{best}`? valid keys here: {}", expected.join(", ")),
                (None, _) => format!("valid keys here: {}", expected.join(", ")),
            };
            problem(format!("unknown key `{field}`"), Some(help))
        }
        Kind::UnknownVariant { variant, expected } => {
            let variant = escape(variant);
            let help = match closest(&variant, expected) {
                Some(best) => format!("did you mean `{best}`? valid values: {}", expected.join(", ")),
                None => format!("valid values: {}", expected.join(", ")),
            };
            problem(format!("`{variant}` is not a valid value here"), Some(help))
        }
        Kind::MissingField { field } => {
            problem(format!("missing key `{field}`"), Some(format!("add `{field}:` to this mapping; {schema}")))
        }
        Kind::InvalidScalar { ty } => {
            let found = scalar_at(text, pos).unwrap_or_default();
            let (message, help) = invalid_scalar(ty, &found);
            problem(message, Some(help))
        }
        Kind::WrongTag { tag, ty } => {
            // A core-schema tag is kept by its suffix (`str`), any other as written.
            let tag = if tag.starts_with('!') { escape(tag) } else { format!("!!{}", escape(tag)) };
            let takes = match *ty {
                "f32" | "f64" => "a number",
                "bool" => "`true` or `false`",
                "u8" | "u16" | "u32" | "u64" | "i8" | "i16" | "i32" | "i64" => "a whole number",
                _ => "a value of another type",
            };
            problem(
                format!("the tag `{tag}` does not fit this key"),
                Some(format!("remove the tag; this key takes {takes}")),
            )
        }
        Kind::InvalidType { unexpected, expected } => {
            problem(format!("expected {expected}, found {unexpected}"), Some(schema.into()))
        }
        Kind::InvalidValue { unexpected, expected } => {
            problem(format!("invalid value {unexpected}, expected {expected}"), Some(schema.into()))
        }
        Kind::InvalidLength { len, expected } => {
            problem(format!("a list of {len} items, expected {expected}"), Some(schema.into()))
        }
        Kind::NullIntoString => problem(
            "expected text, found nothing".into(),
            Some("write the text after the key; quote it if it contains `: ` or ` #`".into()),
        ),
        Kind::Unexpected { expected } => {
            let what = match *expected {
                "mapping start" => "a mapping (`key: value` entries)",
                "sequence start" => "a list (`- item` lines or `[a, b]`)",
                "string scalar" => "text",
                other => other,
            };
            problem(format!("expected {what} here"), Some(schema.into()))
        }
        Kind::DuplicateKey { key } => {
            let key = escape(key);
            let first = first_occurrence(text, pos, &key);
            let help = match first {
                Some(p) => {
                    format!("`{key}` is first given at line {}, column {}; remove one of them", p.line, p.column)
                }
                None => "each key may appear once in a mapping; remove one of them".into(),
            };
            problem(format!("duplicate key `{key}`"), Some(help))
        }
        Kind::MultipleDocuments => problem(
            "a second YAML document starts here; a spec file holds exactly one".into(),
            Some("remove the `---` separator, or move the second document to its own file".into()),
        ),
        Kind::Limit { limit } => {
            let (message, help) = match limit {
                Limit::Nodes => (
                    format!("the YAML holds more than {MAX_YAML_NODES} values"),
                    "spec files are small; aliases (`*name`) that expand exponentially (an alias bomb) are refused"
                        .into(),
                ),
                Limit::Aliases => (format!("the YAML uses more than {MAX_YAML_ALIASES} aliases"), bomb.into()),
                Limit::Anchors => (format!("the YAML defines more than {MAX_YAML_ALIASES} anchors"), bomb.into()),
                Limit::AliasReplay => (
                    format!("aliases expand to more than {MAX_ALIAS_REPLAY} YAML values"),
                    "this looks like an alias bomb; spec files use aliases (`*name`) only to share small lists".into(),
                ),
                Limit::Depth => (
                    format!("the YAML nests more than {MAX_YAML_DEPTH} levels deep"),
                    "spec files nest a few levels; flatten the structure".into(),
                ),
            };
            problem(message, Some(help))
        }
        Kind::UnknownAnchor => problem(
            "this alias refers to no anchor".into(),
            Some("define `&name` before using `*name`; anchors do not cross files".into()),
        ),
        Kind::NonFiniteFloat { value } => {
            problem(format!("`{}` is not a finite number", escape(value)), Some("write a finite number".into()))
        }
        Kind::Syntax { msg } => syntax(msg, text, pos),
        Kind::Message { msg } if msg.contains("untagged enum StatedValue") => problem(
            "a stated value is a number or text".into(),
            Some("write the value as the manual states it: `7.6`, `\"1.1\"` or a variant name".into()),
        ),
        Kind::Message { msg } => problem(first_line(msg), Some(schema.into())),
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
        return match whole(&found) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalars() {
        assert_eq!(scalar_at("a: two\n", Pos { line: 1, column: 4 }).as_deref(), Some("two"));
        assert_eq!(scalar_at("{a: 1x, b: 2}", Pos { line: 1, column: 5 }).as_deref(), Some("1x"));
        assert_eq!(scalar_at("a: \"x y\" # c", Pos { line: 1, column: 4 }).as_deref(), Some("x y"));
        assert_eq!(whole("-2"), Some(-2));
        assert_eq!(whole("0x10"), Some(16));
        assert_eq!(whole("two"), None);
        // The same rules as reading the value: a leading zero is no number, not a large one.
        assert_eq!(invalid_scalar("u32", "012").0, "`012` is not a whole number");
        assert_eq!(invalid_scalar("u8", "256").0, "`256` is too large for this key");
    }

    #[test]
    fn duplicate_keys() {
        let text = "x:\n  - name: a\n    count: 1\n    count: 2\n";
        assert_eq!(first_occurrence(text, Pos { line: 4, column: 5 }, "count"), Some(Pos { line: 3, column: 5 }));
        let flow = "{count: 1, count: 2}";
        assert_eq!(first_occurrence(flow, Pos { line: 1, column: 12 }, "count"), Some(Pos { line: 1, column: 2 }));
    }
}

//! Checks shared by every part of a spec file: text, names, erratum ids,
//! figure references, hex frames and stated values.
//!
//! This is a leaf: it depends on the documents, the model and the
//! interpreter, never on the loader, so that both [`crate::resolve`] and the
//! example replay ([`crate::examples`]) use it. Every check reports its
//! problems through the [`Reporter`] it is given and still returns a usable
//! value where one exists (trimmed text, the figures that parse), so that one
//! mistake does not hide the next: text holds no control or bidi-override
//! characters and at most [`MAX_TEXT_LEN`] bytes, names are snake_case
//! identifiers, erratum ids are short and unique per command, and a hex frame
//! is whole bytes no longer than an RTU frame.

use std::collections::BTreeSet;

use crate::Spanned;
use yosemitech_rtu::{Hex, crc16};

use crate::diag::{Pos, Reporter};
use crate::document::{FigureDoc, StatedValue};
use crate::interp::{Value, parse_version};
use crate::model::{Field, FieldKind, Figure};
use crate::names::{check_snake, escape};

/// Longest text (doc, title, note).
pub const MAX_TEXT_LEN: usize = 4096;

/// Characters that reorder text on screen (Trojan Source, CVE-2021-42574):
/// rustc refuses them in comments and literals, and a reader cannot see them.
const BIDI_CONTROLS: &[char] =
    &['\u{202A}', '\u{202B}', '\u{202C}', '\u{202D}', '\u{202E}', '\u{2066}', '\u{2067}', '\u{2068}', '\u{2069}'];

/// Name of a control character, for messages.
fn char_name(c: char) -> String {
    let name = match c {
        '\0' => " (NUL)",
        '\u{7}' => " (BEL)",
        '\u{8}' => " (backspace)",
        '\r' => " (carriage return)",
        '\u{b}' => " (vertical tab)",
        '\u{c}' => " (form feed)",
        '\u{1b}' => " (ESC)",
        '\u{7f}' => " (DEL)",
        c if BIDI_CONTROLS.contains(&c) => " (bidi override)",
        _ => "",
    };
    format!("U+{:04X}{name}", u32::from(c))
}

pub(crate) fn check_text(value: &Spanned<String>, key: &str, r: &mut Reporter<'_>) -> String {
    let text = &value.value;
    let mut bad: Vec<char> = Vec::new();
    for c in text.chars() {
        let control = c.is_control() && c != '\n' && c != '\t';
        if (control || BIDI_CONTROLS.contains(&c)) && !bad.contains(&c) {
            bad.push(c);
        }
    }
    if !bad.is_empty() {
        let names: Vec<String> = bad.iter().take(8).map(|c| char_name(*c)).collect();
        let what = if names.len() == 1 { "an invisible control character" } else { "invisible control characters" };
        r.error(
            Pos::at(value),
            key,
            format!("text contains {what}: {}", names.join(", ")),
            Some(
                "remove them; text may hold newlines and tabs, but no other control or bidi-override characters".into(),
            ),
        );
    }
    if text.len() > MAX_TEXT_LEN {
        r.error(
            Pos::at(value),
            key,
            format!("text is {} bytes long; at most {MAX_TEXT_LEN} are allowed", text.len()),
            Some("shorten it; long explanations belong in docs/".into()),
        );
    }
    text.trim().to_string()
}

pub(crate) fn check_name(value: &Spanned<String>, key: &str, r: &mut Reporter<'_>) -> bool {
    match check_snake(&value.value) {
        None => true,
        Some(why) => {
            r.error(
                Pos::at(value),
                key,
                format!("invalid name: {why}"),
                Some("names are snake_case ASCII (a-z, 0-9, _), start with a letter, and are not Rust keywords".into()),
            );
            false
        }
    }
}

/// A name valid as such that cannot name this kind of item (`rule`), reported with `help`.
pub(crate) fn check_role(
    value: &Spanned<String>,
    key: &str,
    rule: fn(&str) -> Option<String>,
    help: &str,
    r: &mut Reporter<'_>,
) -> bool {
    match rule(&value.value) {
        None => true,
        Some(why) => {
            r.error(Pos::at(value), key, format!("invalid name: {why}"), Some(help.replace("<name>", &value.value)));
            false
        }
    }
}

/// Figure references: numbers, `T<n>` tables, `<n>b` repeated numbers.
pub(crate) fn resolve_figures(docs: &[FigureDoc], key: &str, at: Pos, r: &mut Reporter<'_>) -> Vec<Figure> {
    docs.iter().enumerate().filter_map(|(i, f)| resolve_figure(f, &format!("{key}[{i}]"), at, r)).collect()
}

pub(crate) fn resolve_figure(doc: &FigureDoc, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<Figure> {
    let parsed = match doc {
        FigureDoc::Number(n) => Ok(Figure::number(*n)),
        FigureDoc::Text(t) => Figure::parse(t),
    };
    match parsed {
        Ok(f) => Some(f),
        Err(why) => {
            r.error(
                at,
                key,
                why,
                Some("figures are `23`, `\"T4\"` (Table 4) or `\"43b\"` (the second figure 43)".into()),
            );
            None
        }
    }
}

pub(crate) fn check_erratum_id(id: &Spanned<String>, key: &str, ids: &mut BTreeSet<String>, r: &mut Reporter<'_>) {
    let v = &id.value;
    let valid = !v.is_empty() && v.len() <= 16 && v.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !valid {
        r.error(
            Pos::at(id),
            key,
            format!("erratum id `{}` is not a short identifier", escape(v)),
            Some("use the id from datasheet-notes.md, like `E4`".into()),
        );
    } else if !ids.insert(v.clone()) {
        r.error(
            Pos::at(id),
            key,
            format!("erratum `{v}` is recorded twice here"),
            Some("record each erratum once per command".into()),
        );
    }
}

/// Parses "01 03 28 00" (spaces optional between bytes).
pub fn parse_hex(text: &str) -> Result<Vec<u8>, String> {
    let compact: String = text.chars().filter(|c| !c.is_whitespace()).collect();
    if compact.is_empty() {
        return Err("the frame is empty".into());
    }
    if let Some(bad) = compact.chars().find(|c| !c.is_ascii_hexdigit()) {
        return Err(format!("{bad:?} is not a hex digit"));
    }
    if !compact.len().is_multiple_of(2) {
        return Err(format!("{} hex digits is an odd number; each byte takes two", compact.len()));
    }
    if compact.len() / 2 > yosemitech_rtu::frame::MAX_ADU {
        return Err(format!("{} bytes is longer than any RTU frame (256)", compact.len() / 2));
    }
    (0..compact.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(compact.get(i..i + 2).unwrap_or("zz"), 16).map_err(|e| e.to_string()))
        .collect()
}

/// The CRC a frame should carry, shown as wire bytes.
pub(crate) fn crc_text(frame: &[u8]) -> String {
    let body = frame.get(..frame.len().saturating_sub(2)).unwrap_or(&[]);
    Hex(&crc16(body).to_le_bytes()).to_string()
}

/// Converts a stated value to the field's value type.
pub(crate) fn stated_value(field: &Field, v: &StatedValue) -> Result<Value, String> {
    let ty = field.kind.type_name();
    match (&field.kind, v) {
        (FieldKind::F32 { .. }, StatedValue::Number(n)) => Ok(Value::Float(*n as f32)),
        (
            FieldKind::U8
            | FieldKind::I8
            | FieldKind::U16 { .. }
            | FieldKind::I16 { .. }
            | FieldKind::U32 { .. }
            | FieldKind::I32 { .. },
            StatedValue::Number(n),
        ) => {
            if n.fract() != 0.0 || !n.is_finite() || n.abs() > 4.3e9 {
                Err(format!("{n} is not a whole number for a `{ty}` field"))
            } else {
                Ok(Value::Int(*n as i64))
            }
        }
        (FieldKind::Bcd, StatedValue::Number(n)) => {
            if n.fract() != 0.0 || !(0.0..=99.0).contains(n) {
                Err(format!("{n} is not a two-digit number for a `bcd` field"))
            } else {
                yosemitech_rtu::Bcd::from_value(*n as u8)
                    .map(Value::Bcd)
                    .ok_or_else(|| format!("{n} is not a two-digit number"))
            }
        }
        (FieldKind::Flags { flags, .. }, StatedValue::Number(n)) => {
            let all: u32 = flags.iter().map(|f| u32::from(f.mask)).sum();
            if n.fract() != 0.0 || *n < 0.0 || *n > f64::from(all) {
                Err(format!("{n} is not a combination of this field's flags"))
            } else {
                Ok(Value::Int(*n as i64))
            }
        }
        (FieldKind::Flags { flags, .. }, StatedValue::Text(t)) => {
            let mut raw = 0i64;
            for part in t.split('|').map(str::trim).filter(|p| !p.is_empty() && *p != "none") {
                match flags.iter().find(|f| f.name == part) {
                    Some(f) => raw |= i64::from(f.mask),
                    None => {
                        return Err(format!(
                            "`{}` is not a flag; flags: {}",
                            escape(part),
                            flags.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(", ")
                        ));
                    }
                }
            }
            Ok(Value::Int(raw))
        }
        (FieldKind::Ascii { .. }, StatedValue::Text(t)) => Ok(Value::Text(t.clone())),
        (FieldKind::Version, StatedValue::Text(t)) => {
            parse_version(t).map(Value::Version).ok_or_else(|| format!("`{t}` is not a version like \"1.1\""))
        }
        (FieldKind::Version, StatedValue::Number(n)) => Err(format!("write the version {n} as text, e.g. \"1.1\"")),
        (FieldKind::Enum { variants, .. }, StatedValue::Text(t)) => variants
            .iter()
            .find(|v| &v.name == t)
            .map(|v| Value::Enum { raw: v.value, name: Some(v.name.clone()) })
            .ok_or_else(|| {
                format!(
                    "`{}` is not a variant; variants: {}",
                    escape(t),
                    variants.iter().map(|v| v.name.as_str()).collect::<Vec<_>>().join(", ")
                )
            }),
        (_, StatedValue::Number(n)) => Err(format!("a `{ty}` field takes text, not the number {n}")),
        (_, StatedValue::Text(t)) => Err(format!("a `{ty}` field takes a number, not the text {:?}", escape(t))),
    }
}

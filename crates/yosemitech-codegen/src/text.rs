//! Spec text into documentation and literals.
//!
//! Spec text reaches generated code only as string literals built by
//! `proc_macro2` (`#[doc = "..."]` attributes and `&str` constants), never
//! pasted into source, so `*/`, `"#]`, backticks or quotes in a spec cannot
//! change the code.

use std::fmt::Write as _;

use proc_macro2::{Literal, TokenStream};
use quote::quote;
use yosemitech_rtu::{ByteOrder2, ByteOrder4, LineSettings};
use yosemitech_spec::{Example, Field, FieldKind, Source, Value};

/// `#[doc = " line"]` for each line of `text` (control characters replaced,
/// since a bare CR is not allowed in a doc comment).
pub fn doc(text: &str) -> TokenStream {
    let mut out = TokenStream::new();
    for line in clean(text).lines() {
        let line = line.trim_end();
        // A spec line that starts with `+ ` is arithmetic ("+ B"), not a Markdown list.
        let escaped;
        let line = match line.trim_start().strip_prefix("+ ") {
            Some(rest) => {
                escaped = format!("{}\\+ {rest}", &line[..line.len() - line.trim_start().len()]);
                escaped.as_str()
            }
            None => line,
        };
        let line = if line.is_empty() { String::new() } else { format!(" {line}") };
        out.extend(quote!(#[doc = #line]));
    }
    out
}

/// `text` with control characters other than newlines replaced by spaces.
pub fn clean(text: &str) -> String {
    text.replace("\r\n", "\n").chars().map(|c| if c.is_control() && c != '\n' { ' ' } else { c }).collect()
}

/// One line of text: newlines and control characters become spaces.
pub fn one_line(text: &str) -> String {
    clean(text).split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A string literal.
pub fn lit(text: &str) -> Literal {
    Literal::string(text)
}

/// `Some("text")` or `None`.
pub fn opt_lit(text: Option<&str>) -> TokenStream {
    match text {
        Some(t) => {
            let t = lit(t);
            quote!(Some(#t))
        }
        None => quote!(None),
    }
}

/// An integer literal in hex with the given digits: `0x2800`.
pub fn hex(value: u32, digits: usize) -> TokenStream {
    let lit = format!("0x{value:0digits$X}").parse().unwrap_or_else(|_| Literal::u32_unsuffixed(value));
    quote!(#lit)
}

/// "Manual section 2.2.3, figures 22, 23, 24, 25."
pub fn source(source: &Source) -> Option<String> {
    if source.section.is_empty() && source.figures.is_empty() {
        return None;
    }
    let mut s = String::from("Manual");
    if !source.section.is_empty() {
        let _ = write!(s, " section {}", one_line(&source.section));
    }
    if !source.figures.is_empty() {
        let word = if source.figures.len() == 1 { "figure" } else { "figures" };
        let sep = if source.section.is_empty() { " " } else { ", " };
        let _ = write!(s, "{sep}{word} {}", join(&source.figures));
    }
    s.push('.');
    Some(s)
}

/// `22, 23, 24`.
pub fn join<T: ToString>(items: &[T]) -> String {
    items.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
}

/// Bytes as `01 03 28 00`.
pub fn hex_bytes(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

/// How a field sits on the wire: "`f32`, little-endian image (`dcba`), data bytes 0..4".
pub fn encoding(field: &Field) -> String {
    let end = field.offset + field.size();
    let what = match &field.kind {
        FieldKind::F32 { order } => format!("`f32`, {}", order4(*order)),
        FieldKind::U8 => "`u8`".to_owned(),
        FieldKind::I8 => "`i8`".to_owned(),
        FieldKind::U16 { order } => format!("`u16`, {}", order2(*order)),
        FieldKind::I16 { order } => format!("`i16`, {}", order2(*order)),
        FieldKind::U32 { order } => format!("`u32`, {}", order4(*order)),
        FieldKind::I32 { order } => format!("`i32`, {}", order4(*order)),
        FieldKind::Ascii { len, padding } => format!("{len} ASCII bytes padded with 0x{padding:02X}"),
        FieldKind::Version => "major byte, minor byte".to_owned(),
        FieldKind::Enum { repr: yosemitech_spec::EnumRepr::U8, .. } => "one-byte code".to_owned(),
        FieldKind::Enum { repr: yosemitech_spec::EnumRepr::U16(order), .. } => {
            format!("two-byte code, {}", order2(*order))
        }
        FieldKind::Reserved { len, fill } => format!("{len} reserved bytes, sent as 0x{fill:02X}"),
        FieldKind::Bcd => "one byte, two decimal digits (BCD: 0x59 = 59)".to_owned(),
        FieldKind::Flags { repr: yosemitech_spec::EnumRepr::U8, flags } => {
            format!("one byte of bit flags ({})", flag_list(flags))
        }
        FieldKind::Flags { repr: yosemitech_spec::EnumRepr::U16(order), flags } => {
            format!("two bytes of bit flags, {} ({})", order2(*order), flag_list(flags))
        }
    };
    if field.size() == 1 {
        format!("{what}, data byte {}", field.offset)
    } else {
        format!("{what}, data bytes {}..{end}", field.offset)
    }
}

/// `0x01 brush, 0x04 supply`.
fn flag_list(flags: &[yosemitech_spec::Flag]) -> String {
    flags.iter().map(|f| format!("0x{:02X} {}", f.mask, one_line(&f.name))).collect::<Vec<_>>().join(", ")
}

/// A printed frame: known bytes in hex, `??` placeholders, `...`, and a
/// note when its CRC was computed rather than printed.
pub fn printed_frame(frame: &yosemitech_spec::PrintedFrame) -> String {
    let mut parts: Vec<String> =
        frame.bytes.iter().map(|b| b.map_or_else(|| "??".to_owned(), |b| format!("{b:02X}"))).collect();
    if frame.open_ended {
        parts.push("...".into());
    }
    let mut s = parts.join(" ");
    if !frame.crc_printed {
        match &frame.complete {
            Some(all) if all.len() >= 2 => {
                let _ = write!(s, " [{}] (CRC not printed; computed)", hex_bytes(&all[all.len() - 2..]));
            }
            _ => s.push_str(" (CRC not printed)"),
        }
    }
    s
}

/// One line per manual of a sensor, oldest software first when stated:
/// `SW 1.1: "TITLE" (REVISION), 9600 baud, 8N2`.
pub fn manuals(sensor: &yosemitech_spec::Sensor) -> Vec<String> {
    let mut manuals: Vec<(&yosemitech_spec::Manual, LineSettings, Option<&str>)> =
        sensor.manual.iter().map(|m| (m, sensor.serial, None)).collect();
    manuals.extend(sensor.revisions.iter().map(|r| (&r.manual, r.serial, r.doc.as_deref())));
    manuals.sort_by(|a, b| {
        let key = |m: &yosemitech_spec::Manual| {
            m.software.as_deref().map(|s| s.split('.').map(|p| p.parse::<u32>().unwrap_or(0)).collect::<Vec<_>>())
        };
        key(a.0).cmp(&key(b.0))
    });
    manuals
        .into_iter()
        .map(|(m, serial_settings, doc)| {
            let software = m.software.as_deref().map(|s| format!("SW {}: ", one_line(s))).unwrap_or_default();
            let note = doc.map(|d| format!(" {}", one_line(d))).unwrap_or_default();
            let claims: Vec<String> = m
                .serial_claims
                .iter()
                .map(|c| match &c.file {
                    Some(file) => format!("{} ({})", c.serial, one_line(file)),
                    None => c.serial.to_string(),
                })
                .collect();
            let claimed =
                if claims.is_empty() { String::new() } else { format!(" (the manual states {})", claims.join("; ")) };
            format!(
                "{software}\"{}\" ({}), {}{claimed}.{note}",
                one_line(&m.title),
                one_line(&m.revision),
                serial_settings
            )
        })
        .collect()
}

/// "figure 23", "table 4", or "an unnumbered table".
pub fn figure_ref(figure: Option<yosemitech_spec::Figure>) -> String {
    match figure {
        Some(yosemitech_spec::Figure::Table(n)) => format!("table {n}"),
        Some(f) => format!("figure {f}"),
        None => "an unnumbered table".to_owned(),
    }
}

/// A 4-byte order in words and by its spec name: "little-endian image (`dcba`)".
pub fn order4(order: ByteOrder4) -> String {
    format!("{} (`{}`)", order.meaning(), order.name())
}

/// A 2-byte order in words and by its spec name: "big-endian (`ab`)".
pub fn order2(order: ByteOrder2) -> String {
    format!("{} (`{}`)", order.meaning(), order.name())
}

/// A stated value as the manual gives it.
pub fn value(v: &Value) -> String {
    match v {
        Value::Float(f) => format!("{f}"),
        Value::Int(i) => format!("{i}"),
        Value::Text(t) => format!("{:?}", one_line(t)),
        Value::Version(v) => format!("{v}"),
        Value::Bcd(v) => format!("{v}"),
        Value::Enum { name: Some(name), .. } => name.clone(),
        Value::Enum { raw, name: None } => format!("{raw}"),
    }
}

/// The examples, each a `text` block plus remarks, in Markdown.
pub fn examples(examples: &[Example], field_order: &[&str]) -> String {
    // Manuals that print the same example again (a revision, a sibling
    // model) are one example with every source named.
    let mut groups: Vec<(Vec<String>, String)> = Vec::new();
    for ex in examples {
        let body = example_body(ex, field_order);
        let source = example_source(ex);
        match groups.iter_mut().find(|(_, b)| *b == body) {
            Some((sources, _)) => sources.push(source),
            None => groups.push((vec![source], body)),
        }
    }
    let mut s = String::new();
    for (sources, body) in groups {
        let sources: Vec<String> = sources.into_iter().filter(|l| !l.is_empty()).collect();
        s.push('\n');
        if sources.is_empty() {
            s.push_str("Example:\n\n");
        } else {
            let _ = writeln!(s, "Example ({}):\n", sources.join("; "));
        }
        s.push_str(&body);
    }
    s
}

/// Where a manual prints an example: its figures and, for a revision's
/// manual, which one.
fn example_source(ex: &Example) -> String {
    let manual = ex.manual.as_ref().map(|m| format!("manual for software {}", one_line(m)));
    let figures = (!ex.figures.is_empty()).then(|| format!("figures {}", join(&ex.figures)));
    manual.into_iter().chain(figures).collect::<Vec<_>>().join(", ")
}

fn example_body(ex: &Example, field_order: &[&str]) -> String {
    let mut s = String::new();
    s.push_str("```text\n");
    match &ex.request {
        Some(f) => {
            let _ = writeln!(s, "request:  {}", printed_frame(f));
        }
        None => s.push_str("request:  (not printed)\n"),
    }
    match &ex.response {
        Some(f) => {
            let _ = writeln!(s, "response: {}", printed_frame(f));
        }
        None => s.push_str("response: (not printed)\n"),
    }
    if let Some(err) = &ex.erratum {
        if let Some(r) = &err.corrected_request {
            let _ = writeln!(s, "true request:  {}", hex_bytes(r));
        }
        if let Some(r) = &err.corrected_response {
            let _ = writeln!(s, "true response: {}", hex_bytes(r));
        }
    }
    let mut values: Vec<String> = Vec::new();
    for name in field_order {
        if let Some(v) = ex.values.get(*name) {
            values.push(format!("{name} = {}", value(v)));
        }
    }
    if !values.is_empty() {
        let _ = writeln!(s, "values:   {}", values.join(", "));
    }
    s.push_str("```\n");
    if let Some(doc) = &ex.doc {
        let _ = writeln!(s, "\n{}", clean(doc).trim_end());
    }
    if let Some(err) = &ex.erratum {
        let verdict = if err.printed_decodes {
            "the printed frame decodes (the decoder accepts it on purpose)"
        } else {
            "the printed frame is rejected"
        };
        let _ = writeln!(
            s,
            "\nErratum {} (figure {}): {} Here {verdict}.",
            one_line(&err.id),
            err.figure,
            one_line(&err.printed)
        );
    }
    s
}

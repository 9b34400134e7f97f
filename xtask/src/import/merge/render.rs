//! The YAML the merge adds: examples of this manual and the revision's `doc`.

use yosemitech_spec::{CommandSpec, Value};

use super::super::review::{CommandRow, Review};
use super::super::{DExample, fig_list, q};
use super::Place;

/// A value as an example's `values:` writes it.
pub(super) fn value_yaml(v: &Value) -> Option<String> {
    Some(match v {
        Value::Float(f) if f.is_finite() => format!("{f:?}"),
        Value::Float(_) => return None,
        Value::Int(i) => i.to_string(),
        Value::Text(t) => q(t),
        Value::Version(v) => q(&v.to_string()),
        Value::Bcd(b) => b.value()?.to_string(),
        Value::Enum { name: Some(n), .. } => n.clone(),
        Value::Enum { raw, name: None } => raw.to_string(),
    })
}

/// The values a drafted example's frames give, decoded with the spec's fields.
pub(super) fn stated_values(c: &CommandSpec, e: &DExample) -> Vec<(String, String)> {
    let (frame, start) = if c.is_read() { (&e.response, 3) } else { (&e.request, 7) };
    let Some(frame) = frame else { return Vec::new() };
    let mut out = Vec::new();
    for f in c.named_fields() {
        let bytes: Option<Vec<u8>> =
            (start + f.offset..start + f.offset + f.size()).map(|i| frame.bytes.get(i).copied().flatten()).collect();
        let Some(bytes) = bytes else { continue };
        if let (Some(name), Some(v)) = (&f.name, value_yaml(&yosemitech_spec::interp::decode_field(f, &bytes))) {
            out.push((name.clone(), v));
        }
    }
    out
}

/// An example item (indent 0) for frames this manual prints.
pub(super) fn example_item(
    c: Option<&CommandSpec>,
    e: &DExample,
    figures: &[String],
    manual: &str,
    next_id: &mut dyn FnMut() -> String,
) -> String {
    let mut y = String::new();
    y.push_str(&format!("- figures: {}\n  manual: {}\n", fig_list(figures), q(manual)));
    let mut erratum = None;
    for (key, f) in [("request", &e.request), ("response", &e.response)] {
        let Some(f) = f else { continue };
        y.push_str(&format!("  {key}: {}\n", q(&f.text())));
        if f.crc.is_none() {
            y.push_str(&format!("  {key}_crc: missing\n"));
        }
        if f.crc_wrong() {
            erratum = Some((key, f));
        }
    }
    if let Some(c) = c {
        let values = stated_values(c, e);
        if !values.is_empty() {
            let v: Vec<String> = values.iter().map(|(n, v)| format!("{n}: {v}")).collect();
            y.push_str(&format!("  values: {{{}}}\n", v.join(", ")));
        }
    }
    if let Some((key, f)) = erratum {
        let fig = e
            .figures
            .get(if key == "request" { 0 } else { e.figures.len().saturating_sub(1) })
            .cloned()
            .unwrap_or_default();
        let correct = f.computed_crc().unwrap_or([0, 0]);
        let printed = f.crc.unwrap_or([0, 0]);
        y.push_str(&format!(
            "  erratum:\n    id: {}\n    figure: {}\n",
            next_id(),
            fig_list(&[fig]).trim_matches(['[', ']'])
        ));
        y.push_str(&format!(
            "    printed: {}\n",
            q(&format!(
                "The printed CRC {:02X} {:02X} is wrong; the frame's CRC is {:02X} {:02X}.",
                printed[0], printed[1], correct[0], correct[1]
            ))
        ));
        y.push_str(&format!("    corrected_{key}: {}\n    printed_decodes: false\n", q(&f.spec_text(Some(correct)))));
    }
    y
}

/// The revision's `doc`: what changed, in a sentence or two of our own.
pub(super) fn revision_doc(review: &Review, software: &str, place: &Place, newest: &str, oldest: &str) -> String {
    let list = |rows: &[CommandRow]| -> String {
        rows.iter().map(|r| format!("{} ({})", r.title, r.section)).collect::<Vec<_>>().join(", ")
    };
    let mut parts = Vec::new();
    match place {
        Place::Newer => parts.push(format!("SW {software}, newer than SW {newest}.")),
        Place::Older => parts.push(format!("SW {software}, older than SW {oldest}.")),
        _ => parts.push(format!("SW {software}.")),
    }
    if !review.commands_added.is_empty() {
        parts.push(format!("Adds {}.", list(&review.commands_added)));
    }
    if !review.since.is_empty() {
        let names: Vec<&str> = review.since.iter().map(|s| s.name.as_str()).collect();
        parts.push(format!("Lacks {}.", names.join(", ")));
    }
    if !review.commands_removed.is_empty() {
        parts.push(format!("Does not document {}.", list(&review.commands_removed)));
    }
    match review.figures_renumbered.as_slice() {
        [] => {}
        [r] => parts.push(format!(
            "Numbers {} otherwise (section {} -> {}, figures {} -> {}).",
            r.command,
            r.section_from,
            r.section_to,
            r.figures_from.join(", "),
            r.figures_to.join(", ")
        )),
        [first, ..] => parts.push(format!(
            "Numbers the sections or figures of {} commands otherwise, from {} (section {}) on.",
            review.figures_renumbered.len(),
            first.command,
            first.section_to
        )),
    }
    if review.frames_differ.is_empty() {
        parts.push("Every frame both manuals print is identical.".into());
    } else {
        parts.push(format!("{} printed frames differ.", review.frames_differ.len()));
    }
    parts.push("Merged by `cargo xtask import --into`.".into());
    parts.join(" ")
}

//! The YAML the merge adds: examples, errata and citations of this manual
//! (the spec crate's document types, serialized as list items) and the
//! revision's `doc`.

use yosemitech_spec::document::{CitationDoc, StatedValue};
use yosemitech_spec::{CommandSpec, Spanned, Value};

use super::super::annotate::{annotate, yaml_of};
use super::super::document::{StatedValues, example_doc, figures, table_erratum_doc};
use super::super::review::{CommandRow, Review};
use super::super::{DExample, one_line_text};
use super::Place;

/// A value as an example's `values:` states it; `None` for one no manual
/// could print (a NaN).
fn stated_value(v: &Value) -> Option<StatedValue> {
    Some(match v {
        // The f32's own shortest spelling (7.1), not its f64 widening.
        Value::Float(f) if f.is_finite() => StatedValue::Number(format!("{f:?}").parse().ok()?),
        Value::Float(_) => return None,
        Value::Int(i) => StatedValue::Number(*i as f64),
        Value::Text(t) => StatedValue::Text(t.clone()),
        Value::Version(v) => StatedValue::Text(v.to_string()),
        Value::Bcd(b) => StatedValue::Number(f64::from(b.value()?)),
        Value::Enum { name: Some(n), .. } => StatedValue::Text(n.clone()),
        Value::Enum { raw, name: None } => StatedValue::Number(f64::from(*raw)),
    })
}

/// The values a drafted example's frames give, decoded with the spec's fields.
fn stated_values(c: &CommandSpec, e: &DExample) -> StatedValues {
    let (frame, start) = if c.is_read() { (&e.response, 3) } else { (&e.request, 7) };
    let frame = frame.as_ref()?;
    let mut out = Vec::new();
    for f in c.named_fields() {
        let bytes: Option<Vec<u8>> =
            (start + f.offset..start + f.offset + f.size()).map(|i| frame.bytes.get(i).copied().flatten()).collect();
        let Some(bytes) = bytes else { continue };
        if let (Some(name), Some(v)) = (&f.name, stated_value(&yosemitech_spec::interp::decode_field(f, &bytes))) {
            out.push((name.clone(), Spanned::unplaced(v)));
        }
    }
    (!out.is_empty()).then(|| Spanned::unplaced(out.into_iter().collect()))
}

/// A document value as an item of a block list (indent 0): `- key: ...`,
/// written as a draft's are.
fn list_item<T: serde::Serialize>(value: &T) -> String {
    match yaml_of(&[value]) {
        Ok(text) => annotate(&text, &[]),
        // The document types serialize whatever their values; should that
        // ever fail, the item is a comment validation stops at.
        Err(e) => format!("- # {}: {}\n", yosemitech_spec::IMPORT_TODO, one_line_text(&e.to_string())),
    }
}

/// An example item for frames this manual prints, with the values the
/// spec's fields decode from them.
pub(super) fn example_item(
    c: Option<&CommandSpec>,
    e: &DExample,
    figure_labels: &[String],
    manual: &str,
    next_id: &mut dyn FnMut() -> String,
) -> String {
    let values = c.and_then(|c| stated_values(c, e));
    list_item(&example_doc(e, figure_labels, Some(Spanned::unplaced(manual.to_owned())), values, next_id))
}

/// An erratum item for a register table that disagrees with the frames,
/// and the TODO when its words are not a `table:` the spec reads.
pub(super) fn table_erratum_item(
    id: String,
    fig: &str,
    (key, value): (&str, &str),
    manual: &str,
    note: String,
) -> (String, Option<String>) {
    let (erratum, todo) = table_erratum_doc(id, fig, key, value, Some(Spanned::unplaced(manual.to_owned())), note);
    (list_item(&erratum), todo)
}

/// An `also_in` item: this manual prints an example's frames too.
pub(in crate::import) fn citation_item(manual: &str, figure_labels: &[String]) -> String {
    list_item(&CitationDoc { manual: Spanned::unplaced(manual.to_owned()), figures: figures(figure_labels) })
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

#[cfg(test)]
mod tests {
    use yosemitech_spec::Value;
    use yosemitech_spec::document::StatedValue;

    use super::stated_value;

    #[test]
    fn a_stated_float_is_the_number_its_f32_spells() {
        // Widened, 7.1f32 is 7.099999904632568; the manual printed 7.1.
        assert_eq!(stated_value(&Value::Float(7.1)), Some(StatedValue::Number(7.1)));
        assert_eq!(stated_value(&Value::Float(f32::NAN)), None);
        assert_eq!(stated_value(&Value::Int(-3)), Some(StatedValue::Number(-3.0)));
    }
}

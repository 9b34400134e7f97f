//! The draft as YAML text.

use std::fmt::Write as _;

use yosemitech_spec::IMPORT_TODO;

use super::annotate::{annotate, yaml_of};
use super::document::{Todo, command_doc, spec_file};
use super::draft::{DCommand, Draft};
use super::header::Header;

pub(super) fn q(s: &str) -> String {
    format!("{s:?}")
}

/// The draft as the text of a spec file: the spec's document types,
/// serialized, under a header that says what the file is and how to finish it.
pub(super) fn render(d: &Draft, h: &Header, name: &str, file: &str) -> String {
    let (spec, todos) = spec_file(d, h, name, file);
    let mut y = String::new();
    let _ = writeln!(y, "# yaml-language-server: $schema=schema.json");
    let _ = writeln!(y, "#");
    let _ = writeln!(y, "# DRAFT imported by `cargo xtask import` from {file}.");
    let _ = writeln!(y, "# Every byte and number below comes from the manual. Resolve each TODO");
    let _ = writeln!(y, "# point the importer left (and delete its comment) until `cargo xtask validate` passes.");
    match yaml_of(&spec) {
        Ok(text) => y.push_str(&annotate(&text, &todos)),
        // The document types serialize to YAML whatever their values; should
        // that ever fail, the draft says so where validation stops.
        Err(e) => {
            let _ = writeln!(y, "# {IMPORT_TODO}: the draft could not be written: {}", one_line_text(&e.to_string()));
        }
    }
    y
}

/// How [`render_command`] writes a drafted command: into a new file, or
/// merged into a spec as another revision's (`manual`, `since`).
pub(crate) struct CommandRender<'a> {
    /// The revision's software, written as `manual:` on the source, the examples and the errata.
    pub manual: Option<&'a str>,
    /// The `since:` to write.
    pub since: Option<&'a str>,
    /// The TODOs to write instead of the command's own.
    pub todos: Option<&'a [String]>,
    /// Notes of the table errata, in order (default: a neutral note).
    pub table_notes: Vec<String>,
    /// The next erratum id.
    pub next_id: &'a mut dyn FnMut() -> String,
}

/// Text on one line (a TODO comment must not end early).
pub(crate) fn one_line_text(t: &str) -> String {
    t.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Writes one drafted command as an item of `commands:` (two-space indent),
/// after a blank line.
pub(crate) fn render_command(y: &mut String, c: &DCommand, o: &mut CommandRender<'_>) {
    let (doc, todos) = command_doc(c, o);
    let todos: Vec<Todo> = todos.into_iter().map(|t| Todo { at: format!("[0]{}", t.at), ..t }).collect();
    let item = match yaml_of(&[doc]) {
        Ok(text) => annotate(&text, &todos),
        Err(e) => format!("# {IMPORT_TODO}: section {}: not written: {}\n", c.section, one_line_text(&e.to_string())),
    };
    y.push('\n');
    for line in item.lines() {
        if !line.is_empty() {
            y.push_str("  ");
            y.push_str(line);
        }
        y.push('\n');
    }
}

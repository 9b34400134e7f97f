//! The draft as YAML text.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::draft::{DCommand, DField, Draft};
use super::header::Header;
use super::parse::variant_name;

pub(super) fn q(s: &str) -> String {
    format!("{s:?}")
}

pub(super) fn fig_list(figs: &[String]) -> String {
    let items: Vec<String> =
        figs.iter().map(|f| if f.chars().all(|c| c.is_ascii_digit()) { f.clone() } else { q(f) }).collect();
    format!("[{}]", items.join(", "))
}

pub(super) fn render(d: &Draft, h: &Header, name: &str, file: &str) -> String {
    let mut y = String::new();
    let _ = writeln!(y, "# yaml-language-server: $schema=schema.json");
    let _ = writeln!(y, "#");
    let _ = writeln!(y, "# DRAFT imported by `cargo xtask import` from {file}.");
    let _ = writeln!(y, "# Every byte and number below comes from the manual. Resolve each TODO");
    let _ = writeln!(y, "# point the importer left (and delete its comment) until `cargo xtask validate` passes.");
    let _ = writeln!(y, "sensor:");
    let _ = writeln!(y, "  name: {name}");
    let _ = writeln!(y, "  title: {}", q(if h.title.is_empty() { name } else { &h.title }));
    let _ = writeln!(y, "  doc: {}", q(&format!("Imported from {file}.")));
    let _ = writeln!(y, "  manual:");
    let _ = writeln!(y, "    title: {}", q(&h.manual_title));
    if let Some(r) = &h.revision {
        let _ = writeln!(y, "    revision: {}", q(r));
    }
    if let Some(s) = &h.software {
        let _ = writeln!(y, "    software: {}", q(s));
    }
    let _ = writeln!(y, "    file: {}", q(file));
    match h.baud {
        Some(b) => {
            let _ = writeln!(
                y,
                "  serial: {{baud: {b}, data_bits: {}, parity: {}, stop_bits: {}}}",
                h.data_bits.unwrap_or(8),
                h.parity.unwrap_or("none"),
                h.stop_bits.unwrap_or(1)
            );
            if h.data_bits.is_none() || h.parity.is_none() || h.stop_bits.is_none() {
                let _ = writeln!(y, "  # TODO(import): data bits, parity or stop bits not stated; defaults 8N1 shown");
            }
        }
        None => {
            let _ = writeln!(y, "  # TODO(import): the manual states no baud rate; add `serial:`");
        }
    }
    let _ = writeln!(y, "  addresses: {{min: 1, max: 247}}");
    let _ = writeln!(y, "  default_address: 1");
    // Includes.
    let mut includes: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for c in &d.commands {
        if let Some((f, n)) = &c.uses {
            includes.entry(f.as_str()).or_default().push(n.as_str());
        }
    }
    if !includes.is_empty() {
        let _ = writeln!(y, "\ninclude:");
        for (f, names) in &includes {
            let _ = writeln!(y, "  - {{file: {f}, only: [{}]}}", names.join(", "));
        }
    }
    let _ = writeln!(y, "\ncommands:");
    let mut erratum_id = 0;
    let mut next_id = || {
        erratum_id += 1;
        format!("import-{erratum_id}")
    };
    for c in &d.commands {
        let mut o =
            CommandRender { manual: None, since: None, todos: None, table_notes: Vec::new(), next_id: &mut next_id };
        render_command(&mut y, c, &mut o);
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

/// Writes one drafted command as an item of `commands:` (two-space indent).
pub(crate) fn render_command(y: &mut String, c: &DCommand, o: &mut CommandRender<'_>) {
    let manual_key = o.manual.map(|m| format!("manual: {}, ", q(m))).unwrap_or_default();
    let _ = writeln!(y);
    for t in o.todos.unwrap_or(&c.todos) {
        let _ = writeln!(y, "  # TODO(import): section {}: {}", c.section, one_line_text(t));
    }
    match &c.uses {
        Some((_, n)) => {
            let _ = writeln!(y, "  - use: {n}");
            let _ = writeln!(y, "    title: {}", q(&c.title));
        }
        None => {
            let _ = writeln!(y, "  - name: {}", c.name);
            let _ = writeln!(y, "    title: {}", q(&c.title));
            let _ = writeln!(y, "    doc: {}", q(&format!("Section {} of the manual.", c.section)));
        }
    }
    let source_manual = o.manual.map(|m| format!(", manual: {}", q(m))).unwrap_or_default();
    let _ = writeln!(y, "    source: {{section: {}, figures: {}{source_manual}}}", q(&c.section), fig_list(&c.figures));
    if let Some(since) = o.since {
        let _ = writeln!(y, "    since: {}", q(since));
    }
    if c.uses.is_none() {
        match c.function {
            Some(0x03) => {
                let _ = writeln!(y, "    function: read");
            }
            Some(_) => {
                let _ = writeln!(y, "    function: write");
            }
            None => {}
        }
        if let Some(a) = c.address {
            let _ = writeln!(y, "    address: 0x{a:04X}");
        }
        if let Some(n) = c.count {
            let _ = writeln!(y, "    count: {n}");
            let is_trigger_read = c.function == Some(0x03)
                && c.fields.is_empty()
                && c.examples
                    .iter()
                    .any(|e| e.response.as_ref().is_some_and(|r| r.open_ended && r.bytes.get(2) == Some(&Some(0))));
            if n == 0 || is_trigger_read {
                let _ = writeln!(y, "    trigger: true");
            }
        }
        if c.examples.iter().any(|e| e.request.as_ref().and_then(|r| r.bytes.first().copied().flatten()) == Some(0xFF))
        {
            let _ = writeln!(y, "    fixed_slave: 0xFF");
        }
        if !c.fields.is_empty() {
            let _ = writeln!(y, "    fields:");
            for f in &c.fields {
                render_field(y, f);
            }
        }
    }
    if !c.table_errata.is_empty() {
        let _ = writeln!(y, "    errata:");
        for (k, (fig, key, val)) in c.table_errata.iter().enumerate() {
            let id = (o.next_id)();
            let figure = if fig.is_empty() { String::new() } else { format!("figure: {fig}, ") };
            let note =
                o.table_notes.get(k).cloned().unwrap_or_else(|| {
                    "The register table disagrees with the printed frames; the frames are used.".into()
                });
            let _ =
                writeln!(y, "      - {{id: {id}, {manual_key}{figure}table: {{{key}: {val}}}, note: {}}}", q(&note));
        }
    }
    if !c.examples.is_empty() {
        let _ = writeln!(y, "    examples:");
    }
    for e in &c.examples {
        let _ = writeln!(y, "      - figures: {}", fig_list(&e.figures));
        if let Some(m) = o.manual {
            let _ = writeln!(y, "        manual: {}", q(m));
        }
        let mut erratum = None;
        for (key, f) in [("request", &e.request), ("response", &e.response)] {
            let Some(f) = f else { continue };
            let _ = writeln!(y, "        {key}: {}", q(&f.text()));
            if f.crc.is_none() {
                let _ = writeln!(y, "        {key}_crc: missing");
            }
            if f.crc_wrong() {
                erratum = Some((key, f));
            }
        }
        if !e.values.is_empty() || c.fields.iter().all(|f| f.name.is_none()) {
            let vals: Vec<String> = e
                .values
                .iter()
                .filter_map(|(off, v)| {
                    c.fields.iter().find(|f| f.offset == *off).and_then(|f| f.name.clone()).map(|n| format!("{n}: {v}"))
                })
                .collect();
            let _ = writeln!(y, "        values: {{{}}}", vals.join(", "));
        }
        if let Some((key, f)) = erratum {
            let id = (o.next_id)();
            let fig = e
                .figures
                .get(if key == "request" { 0 } else { e.figures.len().saturating_sub(1) })
                .cloned()
                .unwrap_or_default();
            let correct = f.computed_crc().unwrap_or([0, 0]);
            let printed = f.crc.unwrap_or([0, 0]);
            let _ = writeln!(y, "        erratum:");
            let _ = writeln!(y, "          id: {id}");
            let _ = writeln!(
                y,
                "          figure: {}",
                if fig.chars().all(|c| c.is_ascii_digit()) { fig } else { q(&fig) }
            );
            let _ = writeln!(
                y,
                "          printed: {}",
                q(&format!(
                    "The printed CRC {:02X} {:02X} is wrong; the frame's CRC is {:02X} {:02X}.",
                    printed[0], printed[1], correct[0], correct[1]
                ))
            );
            let _ = writeln!(y, "          corrected_{key}: {}", q(&f.spec_text(Some(correct))));
            let _ = writeln!(y, "          printed_decodes: false");
        }
    }
}

fn render_field(y: &mut String, f: &DField) {
    match f.ty {
        "reserved" => {
            let _ = writeln!(y, "      - {{type: reserved, size: {}}}", f.size);
        }
        "ascii" => {
            let _ = writeln!(
                y,
                "      - {{name: {}, type: ascii, size: {}, doc: Text.}}",
                f.name.as_deref().unwrap_or("text"),
                f.size
            );
        }
        "enum" | "flags" => {
            let _ = writeln!(y, "      - name: {}", f.name.as_deref().unwrap_or("code"));
            let _ = writeln!(y, "        type: {}", f.ty);
            let _ = writeln!(y, "        size: {}", f.size);
            let _ = writeln!(y, "        doc: Code (see the section's table).");
            let _ = writeln!(y, "        {}:", if f.ty == "enum" { "variants" } else { "flags" });
            for (v, label) in &f.codes {
                let key = if f.ty == "enum" { "value" } else { "mask" };
                let _ = writeln!(
                    y,
                    "          - {{name: {}, {key}: 0x{v:02X}, doc: {}}}",
                    variant_name(label, *v),
                    q(label)
                );
            }
        }
        ty => {
            let order = f.order.map(|o| format!(", byte_order: {o}")).unwrap_or_default();
            let _ = writeln!(
                y,
                "      - {{name: {}, type: {ty}{order}, doc: Value.}}",
                f.name.as_deref().unwrap_or("value")
            );
        }
    }
}

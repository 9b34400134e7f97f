//! `cargo xtask docs [--check]`: writes `docs/sensors/<sensor>.md`, one
//! register map per sensor, from `spec/`. `--check` fails when a map is stale
//! or left over (CI).

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::fs;
use std::path::Path;
use std::process::ExitCode;

use anyhow::Context as _;
use yosemitech_codegen::text;
use yosemitech_spec::{Command, EnumRepr, Field, FieldKind, Order2, Order4, Sensor, Value};

const USAGE: &str = "usage: cargo xtask docs [--check]";

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let Some(check) = crate::check_flag(args, USAGE)? else {
        return Ok(ExitCode::SUCCESS);
    };
    let root = crate::root();
    let spec = yosemitech_spec::load_paths(&[root.join("spec")]).map_err(|e| anyhow::anyhow!("{e}"))?;
    let dir = root.join("docs/sensors");
    let files: Vec<(String, String)> =
        spec.sensors.iter().map(|s| (format!("{}.md", s.name), register_map(s))).collect();
    let wanted: BTreeSet<&str> = files.iter().map(|(n, _)| n.as_str()).collect();
    let mut extra = Vec::new();
    if let Ok(entries) = fs::read_dir(&dir) {
        for entry in entries {
            let name = entry?.file_name().to_string_lossy().into_owned();
            if name.ends_with(".md") && !wanted.contains(name.as_str()) {
                extra.push(name);
            }
        }
    }
    extra.sort();

    if check {
        let mut stale = Vec::new();
        for (name, contents) in &files {
            if fs::read_to_string(dir.join(name)).ok().as_deref() != Some(contents.as_str()) {
                stale.push(format!("docs/sensors/{name} is stale or missing"));
            }
        }
        for name in &extra {
            stale.push(format!("docs/sensors/{name} describes no sensor of the spec"));
        }
        if stale.is_empty() {
            println!("register maps are up to date ({} files)", files.len());
            return Ok(ExitCode::SUCCESS);
        }
        for s in &stale {
            eprintln!("error: {s}");
        }
        eprintln!("run `cargo xtask docs` and commit the result");
        return Ok(ExitCode::FAILURE);
    }

    fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, contents) in &files {
        let path = dir.join(name);
        if fs::read_to_string(&path).ok().as_deref() == Some(contents.as_str()) {
            continue;
        }
        fs::write(&path, contents).with_context(|| format!("writing {}", path.display()))?;
        println!("wrote docs/sensors/{name}");
    }
    for name in &extra {
        fs::remove_file(dir.join(name)).with_context(|| format!("removing docs/sensors/{name}"))?;
        println!("removed docs/sensors/{name}");
    }
    println!("register maps are up to date ({} files)", files.len());
    Ok(ExitCode::SUCCESS)
}

/// Text on one line, safe inside a Markdown table cell.
fn cell(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ").replace('|', "\\|")
}

fn hex_bytes(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

fn join<T: ToString>(items: &[T]) -> String {
    items.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
}

fn file_name(path: &Path) -> String {
    path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
}

fn order4(o: Order4) -> &'static str {
    match o {
        Order4::Abcd => "ABCD (big-endian)",
        Order4::Dcba => "DCBA (little-endian image)",
        Order4::Cdab => "CDAB (word-swapped)",
        Order4::Badc => "BADC (byte-swapped)",
    }
}

fn order2(o: Order2) -> &'static str {
    match o {
        Order2::Ab => "AB (big-endian)",
        Order2::Ba => "BA (little-endian)",
    }
}

/// Type and byte order columns of a field.
fn type_and_order(f: &Field) -> (String, String) {
    match &f.kind {
        FieldKind::F32 { order } => ("f32".into(), order4(*order).into()),
        FieldKind::U8 => ("u8".into(), "–".into()),
        FieldKind::I8 => ("i8".into(), "–".into()),
        FieldKind::U16 { order } => ("u16".into(), order2(*order).into()),
        FieldKind::I16 { order } => ("i16".into(), order2(*order).into()),
        FieldKind::U32 { order } => ("u32".into(), order4(*order).into()),
        FieldKind::I32 { order } => ("i32".into(), order4(*order).into()),
        FieldKind::Ascii { len, padding } => (format!("ascii[{len}], padded 0x{padding:02X}"), "as sent".into()),
        FieldKind::Version => ("version (major, minor)".into(), "major first".into()),
        FieldKind::Enum { repr: EnumRepr::U8, .. } => ("enum (1 byte)".into(), "–".into()),
        FieldKind::Enum { repr: EnumRepr::U16(order), .. } => ("enum (2 bytes)".into(), order2(*order).into()),
        FieldKind::Reserved { fill, .. } => (format!("reserved, sent as 0x{fill:02X}"), "–".into()),
        FieldKind::Bcd => ("bcd (two decimal digits)".into(), "–".into()),
        FieldKind::Flags { repr: EnumRepr::U8, .. } => ("flags (1 byte)".into(), "–".into()),
        FieldKind::Flags { repr: EnumRepr::U16(order), .. } => ("flags (2 bytes)".into(), order2(*order).into()),
    }
}

fn value(v: &Value) -> String {
    match v {
        Value::Enum { name: Some(name), raw } => format!("{name} ({raw})"),
        other => text::value(other),
    }
}

/// The Markdown register map of one sensor.
pub fn register_map(s: &Sensor) -> String {
    let mut d = String::new();
    let _ = writeln!(d, "<!-- Generated by `cargo xtask docs` from spec/{}. Do not edit. -->\n", file_name(&s.file));
    let _ = writeln!(d, "# {} (`{}`)\n", cell(&s.title), s.name);
    let _ = writeln!(d, "{}\n", s.doc.trim());
    if let (Some(model), Some(code)) = (&s.model, &s.model_code) {
        let _ =
            writeln!(d, "- Model: {} (model code {}, serial numbers `YL{}...`)", cell(model), cell(code), cell(code));
    }
    for line in text::manuals(s) {
        let _ = writeln!(d, "- Manual {}", cell(&line));
    }
    let _ = writeln!(d, "- Serial: {} (newest firmware)", text::serial(&s.serial));
    let _ = writeln!(d, "- Slave addresses: {}..={} (factory: {})", s.min_address, s.max_address, s.default_address);
    let _ = writeln!(d, "- Rust module: `yosemitech::{}`\n", s.name);
    let _ = writeln!(
        d,
        "Addresses are wire (PDU) addresses. Offsets count bytes of register data (after the byte count of a read reply, after the byte count of a write request).\n"
    );

    d.push_str(
        "## Commands\n\n| Command | Title | Function | Address | Registers | Section | Since |\n|---|---|---|---|---|---|---|\n",
    );
    for c in &s.commands {
        let _ = writeln!(
            d,
            "| [`{}`](#{}) | {} | 0x{:02X} ({}) | 0x{:04X} | {} | {} | {} |",
            c.name,
            c.name.replace('_', "-").to_lowercase(),
            cell(&c.title),
            c.function.code(),
            if c.is_read() { "read" } else { "write" },
            c.address,
            c.count,
            cell(&c.source.section),
            c.since.as_deref().map_or_else(|| "every revision".to_owned(), |v| format!("SW {}", cell(v)))
        );
    }
    d.push('\n');

    for c in &s.commands {
        command_section(&mut d, c);
    }

    if !s.constants.is_empty() {
        d.push_str("## Constants\n\n| Name | Type | Value | Unit | Meaning |\n|---|---|---|---|---|\n");
        for c in &s.constants {
            let ty = format!("{:?}", c.ty).to_lowercase();
            let values: Vec<String> = c.values.iter().map(|v| format!("{v}")).collect();
            let values = if c.is_list { format!("[{}]", values.join(", ")) } else { values.join(", ") };
            let _ = writeln!(
                d,
                "| `{}` | {ty} | {values} | {} | {} |",
                c.name,
                cell(c.unit.as_deref().unwrap_or("")),
                cell(&c.doc)
            );
        }
        d.push('\n');
    }

    if !s.errata.is_empty() {
        d.push_str("## Manual errata\n\n| Id | Figures | Sections | Note |\n|---|---|---|---|\n");
        for e in &s.errata {
            let _ = writeln!(
                d,
                "| {} | {} | {} | {} |",
                cell(&e.id),
                join(&e.figures),
                cell(&e.sections.join(", ")),
                cell(&e.note)
            );
        }
        d.push('\n');
    }
    while d.ends_with("\n\n") {
        d.pop();
    }
    d
}

fn command_section(d: &mut String, c: &Command) {
    let _ = writeln!(d, "### {}\n", c.name);
    let _ = writeln!(d, "**{}**. {}\n", cell(&c.title), c.doc.trim());
    let func = if c.is_read() { "0x03 (read holding registers)" } else { "0x10 (write multiple registers)" };
    let _ = writeln!(d, "- Function: {func}");
    let _ = writeln!(d, "- Start address: 0x{:04X}", c.address);
    let _ = writeln!(d, "- Registers: {} ({} data bytes)", c.count, 2 * usize::from(c.count));
    let layout = c.layout();
    let _ = writeln!(d, "- Frames: request {} bytes, reply {} bytes", layout.request_len(), layout.response_len());
    if let Some(slave) = c.fixed_slave {
        let _ = writeln!(d, "- Slave address: always 0x{slave:02X} (request and reply)");
    }
    if !c.extra_byte_counts.is_empty() {
        let counts: Vec<String> = c.extra_byte_counts.iter().map(|b| format!("0x{b:02X}")).collect();
        let _ =
            writeln!(d, "- Reply byte count: 0x{:02X}, also accepted: {}", 2 * usize::from(c.count), counts.join(", "));
    }
    if c.trigger {
        let _ = writeln!(d, "- Trigger: a write of zero registers with byte count 0");
    }
    let mut source = format!("section {}", cell(&c.source.section));
    if !c.source.figures.is_empty() {
        let _ = write!(source, ", figures {}", join(&c.source.figures));
    }
    let _ = writeln!(d, "- Manual: {source}");
    if let Some(from) = &c.shared_from {
        let _ = writeln!(d, "- Shared definition: `{from}`");
    }
    d.push('\n');

    if !c.fields.is_empty() {
        let which = if c.is_read() { "Reply data" } else { "Request data" };
        let _ = writeln!(d, "{which}:\n");
        d.push_str("| Offset | Bytes | Field | Type | Byte order | Unit | Range | Meaning |\n|---|---|---|---|---|---|---|---|\n");
        for f in &c.fields {
            let (ty, order) = type_and_order(f);
            let range = f.range.map(|(a, b)| format!("{a}..={b}")).unwrap_or_default();
            let name = match &f.name {
                Some(n) => format!("`{n}`"),
                None => "(reserved)".into(),
            };
            let _ = writeln!(
                d,
                "| {} | {} | {name} | {} | {} | {} | {range} | {} |",
                f.offset,
                f.size(),
                cell(&ty),
                order,
                cell(f.unit.as_deref().unwrap_or("")),
                cell(f.doc.as_deref().unwrap_or(""))
            );
        }
        d.push('\n');
        for f in &c.fields {
            if let (FieldKind::Enum { variants, .. }, Some(name)) = (&f.kind, &f.name) {
                let _ = writeln!(d, "Codes of `{name}`:\n\n| Code | Name | Meaning |\n|---|---|---|");
                for v in variants {
                    let _ =
                        writeln!(d, "| 0x{:02X} | `{}` | {} |", v.value, v.name, cell(v.doc.as_deref().unwrap_or("")));
                }
                d.push_str("| other | unknown | kept as received |\n\n");
            }
        }
    }

    for ex in &c.examples {
        let figures = if ex.figures.is_empty() { String::new() } else { format!(" (figures {})", join(&ex.figures)) };
        let manual = ex.manual.as_ref().map(|m| format!(", manual for software {m}")).unwrap_or_default();
        let _ = writeln!(d, "Example{figures}{manual}:\n\n```text");
        let shown = |f: &Option<yosemitech_spec::PrintedFrame>| {
            f.as_ref().map_or_else(|| "(not printed)".to_owned(), text::printed_frame)
        };
        let _ = writeln!(d, "request:  {}", shown(&ex.request));
        let _ = writeln!(d, "response: {}", shown(&ex.response));
        if let Some(err) = &ex.erratum {
            if let Some(r) = &err.corrected_request {
                let _ = writeln!(d, "true request:  {}", hex_bytes(r));
            }
            if let Some(r) = &err.corrected_response {
                let _ = writeln!(d, "true response: {}", hex_bytes(r));
            }
        }
        let values: Vec<String> = c
            .fields
            .iter()
            .filter_map(|f| {
                let name = f.name.as_deref()?;
                Some(format!("{name} = {}", value(ex.values.get(name)?)))
            })
            .collect();
        if !values.is_empty() {
            let _ = writeln!(d, "values:   {}", values.join(", "));
        }
        d.push_str("```\n\n");
        if let Some(doc) = &ex.doc {
            let _ = writeln!(d, "{}\n", doc.trim());
        }
        if let Some(err) = &ex.erratum {
            let verdict = if err.printed_decodes { "accepted by the decoder" } else { "rejected by the decoder" };
            let _ = writeln!(
                d,
                "Erratum **{}** (figure {}): {} The printed frame is {verdict}.\n",
                cell(&err.id),
                err.figure,
                err.printed.trim()
            );
        }
    }

    if !c.errata.is_empty() {
        for e in &c.errata {
            let table = e.table_says();
            let _ = writeln!(
                d,
                "Erratum **{}** ({}): the table gives {}. {}\n",
                cell(&e.id),
                text::figure_ref(e.figure),
                table.join(", "),
                e.note.trim()
            );
        }
    }
}

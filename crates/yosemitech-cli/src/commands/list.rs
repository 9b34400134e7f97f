//! `yosemitech list`: the sensors and commands of the spec.

use std::io::Write;

use serde_json::{Value as Json, json};
use yosemitech_spec::{Command, Field, Sensor};

use crate::catalog::{Catalog, Entry, Origin};
use crate::cli::ListArgs;
use crate::error::Result;
use crate::format::{byte_order, unit};

/// Runs `list`.
pub fn run(catalog: &Catalog, args: &ListArgs, out: &mut dyn Write) -> Result<()> {
    let entries: Vec<&Entry> = match &args.sensor {
        Some(name) => vec![catalog.entry(name)?],
        None => catalog.entries().iter().collect(),
    };
    if args.json {
        let sensors: Vec<Json> = entries.iter().map(|e| sensor_json(e)).collect();
        writeln!(out, "{}", serde_json::to_string_pretty(&json!({ "sensors": sensors })).unwrap_or_default())?;
        return Ok(());
    }
    for (i, entry) in entries.iter().enumerate() {
        if i > 0 {
            writeln!(out)?;
        }
        show_sensor(entry, args.sensor.is_some(), out)?;
    }
    if args.sensor.is_none() {
        writeln!(out, "\n`yosemitech list SENSOR` shows each command's fields; --json for programs.")?;
    }
    Ok(())
}

fn origin_text(origin: &Origin) -> String {
    match origin {
        Origin::BuiltIn => "built in".into(),
        Origin::Loaded(path) => format!("from {}", path.display()),
    }
}

fn show_sensor(entry: &Entry, with_fields: bool, out: &mut dyn Write) -> Result<()> {
    let s: &Sensor = &entry.sensor;
    writeln!(out, "{} — {} ({})", s.name, s.title, origin_text(&entry.origin))?;
    writeln!(out, "  manual: {} ({})", s.manual.title, s.manual.revision)?;
    writeln!(
        out,
        "  serial: {} baud, {}{}{}; addresses {}..={}, factory address {}",
        s.serial.baud,
        s.serial.data_bits,
        match s.serial.parity {
            yosemitech_spec::Parity::None => 'N',
            yosemitech_spec::Parity::Even => 'E',
            yosemitech_spec::Parity::Odd => 'O',
        },
        s.serial.stop_bits,
        s.min_address,
        s.max_address,
        s.default_address
    )?;
    let width = s.commands.iter().map(|c| c.name.len()).max().unwrap_or(0);
    for c in &s.commands {
        let function = if c.is_read() { "read " } else { "write" };
        let fixed = c.fixed_slave.map(|a| format!(" (to address 0x{a:02X})")).unwrap_or_default();
        writeln!(
            out,
            "  {:width$}  {function} 0x{:04X} x{:<2}  {}{fixed}",
            c.name,
            c.address,
            c.count,
            c.title,
            width = width
        )?;
        if with_fields {
            for f in c.named_fields() {
                writeln!(out, "  {:width$}      {}", "", field_line(f), width = width)?;
            }
        }
    }
    Ok(())
}

fn field_line(f: &Field) -> String {
    let mut text = format!("{}: {}", f.display_name(), f.kind.type_name());
    if let Some(order) = byte_order(f) {
        text.push_str(&format!(" {order}"));
    }
    if let Some(u) = &f.unit {
        text.push_str(&format!(" [{}]", unit(u)));
    }
    if let Some((min, max)) = f.range {
        text.push_str(&format!(" {min}..={max}"));
    }
    text.push_str(&format!(" (bytes {}..{})", f.offset, f.offset + f.size()));
    text
}

/// One sensor as JSON.
pub fn sensor_json(entry: &Entry) -> Json {
    let s = &entry.sensor;
    json!({
        "name": s.name,
        "title": s.title,
        "doc": s.doc,
        "origin": match &entry.origin { Origin::BuiltIn => "built-in".to_owned(), Origin::Loaded(p) => p.display().to_string() },
        "manual": { "title": s.manual.title, "revision": s.manual.revision },
        "serial": s.serial,
        "addresses": { "min": s.min_address, "max": s.max_address, "default": s.default_address },
        "commands": s.commands.iter().map(command_json).collect::<Vec<_>>(),
    })
}

/// One command as JSON.
pub fn command_json(c: &Command) -> Json {
    json!({
        "name": c.name,
        "title": c.title,
        "function": if c.is_read() { "read" } else { "write" },
        "function_code": c.function.code(),
        "address": c.address,
        "address_hex": format!("0x{:04X}", c.address),
        "count": c.count,
        "fixed_slave": c.fixed_slave,
        "trigger": c.trigger,
        "request_len": c.layout().request_len(),
        "response_len": c.layout().response_len(),
        "fields": c.fields.iter().map(|f| json!({
            "name": f.name,
            "type": f.kind.type_name(),
            "unit": f.unit,
            "offset": f.offset,
            "size": f.size(),
            "byte_order": byte_order(f),
            "range": f.range.map(|(min, max)| json!({ "min": min, "max": max })),
        })).collect::<Vec<_>>(),
    })
}

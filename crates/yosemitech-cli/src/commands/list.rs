//! `yosemitech list`: the sensors and commands of the spec.

use std::io::Write;

use serde_json::{Value as Json, json};
use yosemitech_ops::software_revision;
use yosemitech_rtu::{LineSettings, StopBits};
use yosemitech_spec::{CommandSpec, Field, LineSettingsJson, Manual, Sensor};

use crate::catalog::{Catalog, Entry, Origin};
use crate::error::Result;
use crate::format::unit;
use clap::Args;

/// `list`.
#[derive(Args, Debug)]
pub struct ListArgs {
    /// Only this sensor.
    pub sensor: Option<String>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

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
        writeln!(out)?;
        for line in models_summary(entries.iter().map(|e| e.sensor.as_ref())) {
            writeln!(out, "{line}")?;
        }
        let model = entries.iter().find_map(|e| e.sensor.model.as_deref()).unwrap_or("MODEL");
        writeln!(
            out,
            "\n`yosemitech list SENSOR` (or a model: `list {model}`) shows each command's fields; --json for programs."
        )?;
    }
    Ok(())
}

/// The models the sensors speak for: those with a Modbus manual, those
/// known from other sources (aliases and sensors with a provenance), and
/// other hardware of a model that has a manual.
pub fn models_summary<'s>(sensors: impl Iterator<Item = &'s Sensor> + Clone) -> Vec<String> {
    let with_manual: Vec<&str> =
        sensors.clone().filter(|s| s.manual.is_some()).filter_map(|s| s.model.as_deref()).collect();
    let mut from_sources: Vec<String> = Vec::new();
    let mut other_hardware: Vec<String> = Vec::new();
    for s in sensors.clone() {
        for alias in &s.aliases {
            from_sources.push(format!("{} (as {})", alias.model, s.name));
        }
        if let (None, Some(model)) = (&s.manual, &s.model) {
            if with_manual.contains(&model.as_str()) {
                other_hardware.push(format!("{model} ({})", s.name));
            } else {
                from_sources.push(format!("{model} ({})", s.name));
            }
        }
    }
    let mut lines = vec![format!(
        "{} models: {} with a Modbus manual ({}), {} without one, from the field's drivers and loggers ({})",
        with_manual.len() + from_sources.len(),
        with_manual.len(),
        with_manual.join(", "),
        from_sources.len(),
        from_sources.join(", ")
    )];
    if !other_hardware.is_empty() {
        lines.push(format!("other hardware of a model with a manual: {}", other_hardware.join(", ")));
    }
    lines
}

fn origin_text(origin: &Origin) -> String {
    match origin {
        Origin::BuiltIn => "built in".into(),
        Origin::Loaded(path) => format!("from {}", path.display()),
    }
}

/// `9600 baud, 8N1` (and `2 stop bits` spelled out when there are two, the easy detail to miss).
pub fn serial_text(serial: &LineSettings) -> String {
    let stops = if serial.format.stop_bits == StopBits::Two { " (2 stop bits)" } else { "" };
    format!("{serial}{stops}")
}

/// `model Y520, model code 09 (serial numbers YL09...)`, as far as the spec states them.
pub fn model_text(s: &Sensor) -> Option<String> {
    let model = s.model.as_ref().map(|m| format!("model {m}"));
    let code = s.model_code.as_ref().map(|c| {
        let also: Vec<String> = s.also_model_codes.iter().map(|a| format!("; also {a}, YL{a}...")).collect();
        format!("model code {c} (serial numbers YL{c}...{})", also.concat())
    });
    let parts: Vec<String> = model.into_iter().chain(code).collect();
    (!parts.is_empty()).then(|| parts.join(", "))
}

/// The manuals of a sensor, oldest firmware first (manuals without a
/// software revision last), each with the serial settings of that firmware.
pub fn manuals(s: &Sensor) -> Vec<(&Manual, LineSettings, Option<&str>, bool)> {
    let mut all: Vec<(&Manual, LineSettings, Option<&str>, bool)> = s
        .manual
        .iter()
        .map(|m| (m, None, true))
        .chain(s.revisions.iter().map(|r| (&r.manual, r.doc.as_deref(), false)))
        .map(|(m, doc, main)| (m, m.software.as_deref().map_or(s.serial, |sw| s.serial_for(sw)), doc, main))
        .collect();
    all.sort_by_key(|(m, ..)| m.software.as_deref().map_or((u16::MAX, u16::MAX), software_revision));
    all
}

fn show_sensor(entry: &Entry, with_fields: bool, out: &mut dyn Write) -> Result<()> {
    let s: &Sensor = &entry.sensor;
    writeln!(out, "{} — {} ({})", s.name, s.title, origin_text(&entry.origin))?;
    if let Some(model) = model_text(s) {
        writeln!(out, "  {model}")?;
    }
    if let Some(p) = &s.provenance {
        writeln!(out, "  {}", p.summary())?;
    }
    for alias in &s.aliases {
        let code = alias.model_code.as_deref().map(|c| format!(", model code {c}")).unwrap_or_default();
        writeln!(out, "  also model {}{code}: same commands ({})", alias.model, alias.provenance.summary())?;
    }
    for (manual, serial, _, main) in manuals(s) {
        let sw = manual.software.as_deref().map(|v| format!("SW {v}: ")).unwrap_or_default();
        let cited = if main && !s.revisions.is_empty() { " [figures cited by default]" } else { "" };
        writeln!(out, "  manual {sw}{} ({}), {}{cited}", manual.title, manual.revision, serial_text(&serial))?;
    }
    writeln!(
        out,
        "  serial: {} (newest firmware); addresses {} to {}, factory address {}",
        serial_text(&s.serial),
        s.min_address,
        s.max_address,
        s.default_address
    )?;
    if let Some(p) = &s.procedure {
        let timing = yosemitech_ops::procedure::Timing::of(p);
        writeln!(
            out,
            "  procedure: {} (`yosemitech measure {}`)",
            yosemitech_ops::procedure::describe(p, timing),
            s.name
        )?;
    }
    let width = s.commands.iter().map(|c| c.name.len()).max().unwrap_or(0);
    for c in &s.commands {
        let function = if c.is_read() { "read " } else { "write" };
        let fixed = c.fixed_slave.map(|a| format!(" (to address 0x{a:02X})")).unwrap_or_default();
        let role = c.role.map(|r| format!(" [{}]", r.name())).unwrap_or_default();
        let since = c.since.as_ref().map(|v| format!(" (since SW {v})")).unwrap_or_default();
        let sourced = c.provenance.as_ref().map(|p| format!(" ({})", p.summary())).unwrap_or_default();
        writeln!(
            out,
            "  {:width$}  {function} 0x{:04X} x{:<2}  {}{fixed}{role}{since}{sourced}",
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
    if let Some(order) = f.kind.byte_order_name() {
        text.push_str(&format!(" {order}"));
    }
    if let Some(u) = &f.unit {
        text.push_str(&format!(" [{}]", unit(u)));
    }
    if let Some((min, max)) = f.range {
        text.push_str(&format!(" {min} to {max}"));
    }
    text.push_str(&format!(" (bytes {}..{})", f.offset, f.offset + f.size()));
    text
}

/// One sensor as JSON.
pub fn sensor_json(entry: &Entry) -> Json {
    let s = &entry.sensor;
    let manual_json =
        |m: &Manual| json!({ "title": m.title, "revision": m.revision, "software": m.software, "file": m.file });
    json!({
        "name": s.name,
        "title": s.title,
        "doc": s.doc,
        "model": s.model,
        "model_code": s.model_code,
        "origin": match &entry.origin { Origin::BuiltIn => "built-in".to_owned(), Origin::Loaded(p) => p.display().to_string() },
        "also_model_codes": s.also_model_codes,
        "aliases": s.aliases,
        "provenance": s.provenance,
        "manual": s.manual.as_ref().map(manual_json),
        "manuals": manuals(s).into_iter().map(|(m, serial, doc, main)| {
            let mut j = manual_json(m);
            if let Some(o) = j.as_object_mut() {
                o.insert("serial".into(), json!(LineSettingsJson(serial)));
                o.insert("doc".into(), json!(doc));
                o.insert("default".into(), json!(main));
            }
            j
        }).collect::<Vec<_>>(),
        "serial": LineSettingsJson(s.serial),
        "addresses": { "min": s.min_address, "max": s.max_address, "default": s.default_address },
        "procedure": s.procedure,
        "commands": s.commands.iter().map(command_json).collect::<Vec<_>>(),
    })
}

/// One command as JSON.
pub fn command_json(c: &CommandSpec) -> Json {
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
        "role": c.role.map(|r| r.name()),
        "since": c.since,
        "request_len": c.layout().request_len(),
        "response_len": c.layout().response_len(),
        "fields": c.fields.iter().map(|f| json!({
            "name": f.name,
            "type": f.kind.type_name(),
            "unit": f.unit,
            "offset": f.offset,
            "size": f.size(),
            "byte_order": f.kind.byte_order_name(),
            "range": f.range.map(|(min, max)| json!({ "min": min, "max": max })),
        })).collect::<Vec<_>>(),
    })
}

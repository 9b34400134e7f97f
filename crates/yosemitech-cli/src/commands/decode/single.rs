//! A frame on its own, rendered: the block (or JSON) that explains it, and
//! the error it ends with.

use std::io::Write;

use serde_json::{Value as Json, json};
use yosemitech_rtu::frame::EXCEPTION_BIT;

use crate::error::{CliError, Result};
use crate::explain::{Decoding, Frame, FrameStatus, Kind};
use crate::format::{fields_json, hex, value_with_unit, values_json};

use crate::explained::{values_text, words};

use super::{error_json, pretty};

/// `conductivity/ph_orp get_sn (0x0900, 7 registers)`.
fn candidate_label(d: &Decoding<'_>) -> String {
    let Some(c) = d.command() else { return String::new() };
    format!(
        "{} {} (0x{:04X}, {} register{})",
        d.sensors().join("/"),
        c.name,
        c.address,
        c.count,
        if c.count == 1 { "" } else { "s" }
    )
}

/// Prints `frame`'s explanation; a wrong CRC, a failed check, an ambiguity
/// or a command that does not fit is the error it returns.
pub(super) fn print_frame(frame: &Frame<'_>, json_out: bool, out: &mut dyn Write) -> Result<()> {
    match &frame.status {
        FrameStatus::NotTheCommand(name) => Err(not_the_command(frame, name)),
        FrameStatus::Ambiguous => print_ambiguous(frame, json_out, out),
        FrameStatus::Explained => print_explained(frame, json_out, out),
    }
}

fn not_the_command(frame: &Frame<'_>, name: &str) -> CliError {
    let (kind, len) = (frame.kind.name(), frame.bytes.len());
    let what = match (frame.address, frame.count) {
        (Some(a), Some(n)) => format!("a {kind} of {len} bytes for 0x{a:04X} x{n}"),
        _ => format!("a {kind} of {len} bytes"),
    };
    CliError::usage(format!("the frame does not fit `{name}`: it is {what}"))
        .hint("check the frame, or leave out --command to see what fits")
}

/// The error of a frame that fits several commands. A wrong CRC comes
/// first: it is what the technician must fix, and with it no reading of the
/// bytes is worth choosing.
fn ambiguity_error(frame: &Frame<'_>) -> CliError {
    let (kind, len, fits) = (frame.kind.name(), frame.bytes.len(), frame.candidates.len());
    let mut e = if frame.crc.ok() {
        let why = if frame.kind.is_request() {
            String::new()
        } else {
            " (a reply does not say which registers it answers)".to_owned()
        };
        CliError::usage(format!("this {kind} of {len} bytes fits {fits} commands{why}"))
            .hint("give its request too (`decode REQUEST REPLY` names the command), or choose one of the above with --sensor and --command")
    } else {
        CliError::device(format!(
            "the CRC is wrong: the frame carries {}, its bytes give {}",
            hex(&frame.crc.received),
            hex(&frame.crc.expected)
        ))
        .hint(format!(
            "the frame was corrupted on the line or copied wrongly; as received, the {kind} would fit {fits} commands (above)"
        ))
    };
    for d in &frame.candidates {
        e = e.detail(format!("{}: {}", candidate_label(d), values_text(d)));
    }
    e
}

fn print_ambiguous(frame: &Frame<'_>, json_out: bool, out: &mut dyn Write) -> Result<()> {
    let e = ambiguity_error(frame);
    if json_out {
        let listed: Vec<Json> = frame
            .candidates
            .iter()
            .filter_map(|d| {
                let c = d.command()?;
                Some(json!({
                    "sensors": d.sensors(),
                    "command": c.name,
                    "values": values_json(&d.values),
                    "fields": fields_json(c, &d.values),
                }))
            })
            .collect();
        let doc = json!({
            "frame": hex(&frame.bytes),
            "length": frame.bytes.len(),
            "kind": frame.kind.json_name(),
            "slave": frame.slave,
            "function": frame.function,
            "status": "ambiguous",
            "crc": { "ok": frame.crc.ok(), "received": hex(&frame.crc.received), "expected": hex(&frame.crc.expected) },
            "candidates": listed,
            "error": error_json(&e),
        });
        writeln!(out, "{}", pretty(&doc))?;
    }
    Err(e)
}

fn print_explained(frame: &Frame<'_>, json_out: bool, out: &mut dyn Write) -> Result<()> {
    let (kind, slave, function, len) = (frame.kind, frame.slave, frame.function, frame.bytes.len());
    let chosen = frame.chosen().and_then(|d| Some((d, d.command()?)));
    let function_name = frame.function_name();
    let (received, expected) = (frame.crc.received, frame.crc.expected);
    if json_out {
        let command = chosen.map(|(d, c)| {
            json!({
                "sensor": d.sensors().first(),
                "sensors": d.sensors(),
                "name": c.name,
                "title": c.title,
                "address": c.address,
                "count": c.count,
            })
        });
        let candidates: Vec<Json> = frame
            .candidates
            .iter()
            .map(|d| json!({ "sensors": d.sensors(), "command": d.command().map(|c| &c.name) }))
            .collect();
        let doc = json!({
            "frame": hex(&frame.bytes),
            "length": len,
            "kind": kind.json_name(),
            "slave": slave,
            "function": function,
            "function_name": function_name,
            "address": frame.address,
            "count": frame.count,
            "byte_count": frame.byte_count,
            "command": command,
            "candidates": candidates,
            "fields": chosen.map_or(Json::Array(Vec::new()), |(_, c)| fields_json(c, &frame.values)),
            "values": values_json(&frame.values),
            "exception": frame.exception.map(|e| json!({ "code": e.to_u8(), "name": e.to_string() })),
            "crc": { "ok": frame.crc.ok(), "received": hex(&received), "expected": hex(&expected) },
            "notes": words(&frame.notes),
            "problems": words(&frame.problems),
        });
        writeln!(out, "{}", pretty(&doc))?;
    } else {
        let fname = function_name.map(|n| format!(" ({n})")).unwrap_or_default();
        writeln!(out, "frame       {} ({len} bytes)", hex(&frame.bytes))?;
        let direction = match kind {
            k if k.is_request() => format!("{} to address {slave}, function 0x{function:02X}{fname}", k.name()),
            Kind::Exception => {
                format!("exception reply from address {slave} to function 0x{:02X}{fname}", function & !EXCEPTION_BIT)
            }
            k => format!("{} from address {slave}, function 0x{function:02X}{fname}", k.name()),
        };
        writeln!(out, "kind        {direction}")?;
        if let (Some(a), Some(n)) = (frame.address, frame.count) {
            writeln!(out, "registers   0x{a:04X}, {n} register{}", if n == 1 { "" } else { "s" })?;
        }
        match (chosen, frame.candidates.len()) {
            (Some((d, c)), _) => writeln!(out, "command     {} {}: {}", d.sensors().join("/"), c.name, c.title)?,
            (None, 0) if kind != Kind::Exception => writeln!(out, "command     none of the loaded sensors' commands")?,
            (None, 0) => {}
            (None, _) => {
                let labels: Vec<String> = frame.candidates.iter().map(candidate_label).collect();
                writeln!(out, "command     one of: {}", labels.join("; "))?;
            }
        }
        if let Some(n) = frame.byte_count {
            writeln!(out, "byte count  {n}")?;
        }
        if let Some(code) = frame.exception {
            writeln!(out, "exception   {code}")?;
        }
        if let Some((_, c)) = chosen {
            let width = frame.values.iter().map(|(n, _)| n.len()).max().unwrap_or(0).max(10);
            for (name, value) in &frame.values {
                writeln!(out, "  {name:width$}  {}", value_with_unit(value, c.field(name)))?;
            }
        }
        if frame.crc.ok() {
            writeln!(out, "CRC         {} (ok)", hex(&received))?;
        } else {
            writeln!(out, "CRC         {} (wrong: the bytes give {})", hex(&received), hex(&expected))?;
        }
        for note in &frame.notes {
            writeln!(out, "note        {note}")?;
        }
        for problem in &frame.problems {
            writeln!(out, "problem     {problem}")?;
        }
    }
    out.flush()?;
    if !frame.crc.ok() {
        return Err(CliError::device(format!(
            "the CRC is wrong: the frame carries {}, its bytes give {}",
            hex(&received),
            hex(&expected)
        ))
        .hint("the frame was corrupted on the line or copied wrongly; the fields above are shown as received"));
    }
    if let Some(first) = frame.problems.first() {
        return Err(CliError::device(format!("the frame fails a check: {first}"))
            .hint("see the lines above; -v on a live bus shows every frame"));
    }
    Ok(())
}

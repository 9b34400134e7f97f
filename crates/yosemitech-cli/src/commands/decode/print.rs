//! Printing reports: a request and its reply as a block, several entries
//! one line (or one JSON document) each, then a summary.

use std::io::Write;

use serde_json::{Value as Json, json};
use yosemitech_rtu::bytes::byte;
use yosemitech_rtu::frame::EXCEPTION_BIT;
use yosemitech_rtu::{Function, crc_ok};
use yosemitech_spec::CommandSpec;

use crate::error::{CliError, Result};
use crate::explain::candidates::label;
use crate::explain::exchange::describe;
use crate::explain::scan::Framed;
use crate::explain::{CaptureMode, Decoding, Exchange, Report, Status};
use crate::format::{fields_json, hex, value_with_unit, values_json};

use super::{error_json, pretty, words};

/// `ph = 7.6 pH, temperature_c = 25 °C`.
pub(super) fn values_text(d: &Decoding<'_>) -> String {
    let command = d.command();
    d.values
        .iter()
        .map(|(n, v)| format!("{n} = {}", value_with_unit(v, command.and_then(|c| c.field(n)))))
        .collect::<Vec<_>>()
        .join(", ")
}

fn decoding_json(d: &Decoding<'_>) -> Json {
    let empty = Json::Array(Vec::new());
    json!({
        "command": d.name(),
        "sensors": d.sensors(),
        "commands": d.cands.iter().map(|c| json!({ "sensor": c.sensor, "command": c.command.name })).collect::<Vec<_>>(),
        "title": d.command().map(|c| c.title.as_str()),
        "values": values_json(&d.values),
        "fields": d.command().map_or(empty, |c| fields_json(c, &d.values)),
    })
}

/// A frame's bytes and place, as JSON.
pub(super) fn framed_json(f: &Framed) -> Json {
    json!({
        "frame": hex(&f.bytes),
        "length": f.bytes.len(),
        "line": (f.place.line > 0).then_some(f.place.line),
        "offset": f.place.offset,
        "crc_ok": f.bytes.len() >= 4 && crc_ok(&f.bytes),
    })
}

pub(super) fn exchange_json(x: &Exchange<'_>) -> Json {
    let header = x.request.as_ref().map(|(_, h)| *h);
    let function = header
        .map(|h| h.function)
        .or_else(|| x.reply.as_ref().map(|r| byte(&r.bytes, 1).unwrap_or(0) & !EXCEPTION_BIT));
    let function_name = function.and_then(Function::from_code).map(|f| match f {
        Function::Read => "read",
        Function::Write => "write",
    });
    let decodings: Vec<Json> = x.decodings.iter().map(decoding_json).collect();
    // The one decoding, at the top level too.
    let chosen = match decodings.as_slice() {
        [only] => only.clone(),
        _ => json!({ "command": null, "sensors": [], "commands": [], "title": null, "values": {}, "fields": [] }),
    };
    let mut doc = json!({
        "type": if x.request.is_some() { "transaction" } else { "reply" },
        "status": x.status.name(),
        "ok": x.status.ok(),
        "slave": x.slave(),
        "function": function,
        "function_name": function_name,
        "address": header.map(|h| h.address),
        "count": header.map(|h| h.count),
        "request": x.request.as_ref().map(|(f, _)| framed_json(f)),
        "reply": x.reply.as_ref().map(framed_json),
        "decodings": decodings,
        "exception": x.exception.map(|e| json!({ "code": e.to_u8(), "name": e.to_string() })),
        "notes": words(&x.notes),
        "problems": words(&x.problems),
        "error": Json::Null,
    });
    if let (Json::Object(doc), Json::Object(chosen)) = (&mut doc, chosen) {
        doc.extend(chosen);
    }
    doc
}

pub(super) fn report_json(r: &Report<'_>) -> Json {
    match r {
        Report::Exchange(x) => exchange_json(x),
        Report::Noise(f) => json!({
            "type": "noise",
            "status": "noise",
            "ok": false,
            "bytes": hex(&f.bytes),
            "length": f.bytes.len(),
            "line": (f.place.line > 0).then_some(f.place.line),
            "offset": f.place.offset,
            "problems": [format!("{} byte(s) that are no frame", f.bytes.len())],
        }),
        Report::Unreadable { place, text, problem } => json!({
            "type": "unreadable",
            "status": "unreadable",
            "ok": false,
            "line": place.line,
            "text": text,
            "problems": [problem],
        }),
    }
}

/// The error a single transaction ends with, if any.
pub(super) fn exchange_error(x: &Exchange<'_>) -> Option<CliError> {
    let first = x.problems.first().map(ToString::to_string).unwrap_or_default();
    match x.status {
        Status::Decoded | Status::Exception | Status::Broadcast => None,
        Status::Ambiguous => {
            let what = x.request.as_ref().map_or_else(|| "the reply".to_owned(), |(_, h)| describe(h));
            let mut e = CliError::usage(format!(
                "the reply to {what} decodes {} ways, as different commands; say which one",
                x.decodings.len()
            ));
            for d in &x.decodings {
                e = e.detail(format!("{}: {}", label(&d.cands), values_text(d)));
            }
            let example = x
                .decodings
                .first()
                .and_then(|d| d.cands.first())
                .map_or(String::new(), |c| format!(", e.g. --sensor {} --command {}", c.sensor, c.command.name));
            Some(e.hint(format!("choose with --sensor and/or --command{example}")))
        }
        Status::UnknownCommand => Some(
            CliError::device(first)
                .hint("`yosemitech list` shows the commands; --spec DIR loads more sensors' spec files"),
        ),
        _ => Some(
            CliError::device(format!("the reply does not decode: {first}"))
                .hint("a reply comes from the request's slave with the command's length and a valid CRC"),
        ),
    }
}

/// One request and its reply: a block like a single frame's, or one JSON document.
pub(super) fn print_pair(x: &Exchange<'_>, json_out: bool, out: &mut dyn Write) -> Result<()> {
    let error = exchange_error(x);
    if json_out {
        let mut doc = exchange_json(x);
        if let (Some(e), Some(slot)) = (&error, doc.get_mut("error")) {
            *slot = error_json(e);
        }
        writeln!(out, "{}", pretty(&doc))?;
    } else {
        if let Some((request, header)) = &x.request {
            let to = if header.slave == 0 { "broadcast".to_owned() } else { format!("to address {}", header.slave) };
            writeln!(out, "request     {} ({}, {to})", hex(&request.bytes), describe(header))?;
        }
        if let Some(reply) = &x.reply {
            let from = byte(&reply.bytes, 0).unwrap_or(0);
            writeln!(out, "reply       {} ({} bytes from address {from})", hex(&reply.bytes), reply.bytes.len())?;
        }
        let many = x.decodings.len() > 1;
        for (i, d) in x.decodings.iter().enumerate() {
            let head = if many { format!("decoding {}", i + 1) } else { "command".to_owned() };
            let title = d.command().map_or(String::new(), |c| format!(": {}", c.title));
            writeln!(out, "{head:<12}{}{title}", label(&d.cands))?;
            let width = d.values.iter().map(|(n, _)| n.len()).max().unwrap_or(0).max(10);
            for (name, value) in &d.values {
                let field = d.command().and_then(|c| c.field(name));
                writeln!(out, "  {name:width$}  {}", value_with_unit(value, field))?;
            }
        }
        if let Some(code) = x.exception {
            writeln!(out, "exception   {code}")?;
        }
        writeln!(out, "status      {}", x.status.name().replace('_', " "))?;
        for note in &x.notes {
            writeln!(out, "note        {note}")?;
        }
        for problem in &x.problems {
            writeln!(out, "problem     {problem}")?;
        }
    }
    out.flush()?;
    error.map_or(Ok(()), Err)
}

/// Where an entry is, for the text output: `line 3`, `lines 3-4` or `byte 17`.
pub(super) fn place_text(r: &Report<'_>) -> String {
    let (first, last) = match r {
        Report::Exchange(x) => {
            let first = x.request.as_ref().map(|(f, _)| f.place).or_else(|| x.reply.as_ref().map(|f| f.place));
            (first.unwrap_or_default(), x.reply.as_ref().map(|f| f.place))
        }
        Report::Noise(f) => (f.place, None),
        Report::Unreadable { place, .. } => (*place, None),
    };
    match last {
        _ if first.line == 0 => format!("byte {}", first.offset),
        Some(last) if last.line != first.line => format!("lines {}-{}", first.line, last.line),
        _ => format!("line {}", first.line),
    }
}

/// Bytes as hex, the first 32 of a long run.
pub(super) fn hex_short(bytes: &[u8]) -> String {
    match bytes.get(..32) {
        Some(head) if bytes.len() > 32 => format!("{} …", hex(head)),
        _ => hex(bytes),
    }
}

/// An entry in one line of text.
pub(super) fn report_text(r: &Report<'_>) -> String {
    let x = match r {
        Report::Noise(f) => {
            return format!("noise       {} byte(s) that are no frame: {}", f.bytes.len(), hex_short(&f.bytes));
        }
        Report::Unreadable { text, problem, .. } => {
            let shown: String = match text.chars().count() {
                n if n > 60 => format!("{}…", text.chars().take(60).collect::<String>()),
                _ => text.clone(),
            };
            return format!("unreadable  `{shown}`: {problem}");
        }
        Report::Exchange(x) => x,
    };
    let who = match x.slave() {
        Some(0) => "broadcast   ".to_owned(),
        Some(s) => format!("{:<12}", format!("address {s}")),
        None => String::new(),
    };
    let decoded = |d: &Decoding<'_>| {
        let values = values_text(d);
        let written = match (d.command().is_some_and(CommandSpec::is_read), x.status) {
            (true, _) => "",
            (false, Status::Broadcast) => " (broadcast, not answered)",
            (false, _) => " (write acknowledged)",
        };
        if values.is_empty() {
            format!("{}{written}", label(&d.cands))
        } else {
            format!("{}: {values}{written}", label(&d.cands))
        }
    };
    let labels = x.decodings.iter().map(|d| label(&d.cands)).collect::<Vec<_>>().join(" | ");
    let first = x.problems.first().map(ToString::to_string).unwrap_or_default();
    let what = match x.status {
        Status::Decoded | Status::Broadcast => x.chosen().map(decoded).unwrap_or_default(),
        Status::Exception => {
            format!("{labels}: exception {}", x.exception.map(|e| e.to_string()).unwrap_or_default())
        }
        Status::Ambiguous => format!(
            "ambiguous, {} decodings: {}",
            x.decodings.len(),
            x.decodings.iter().map(decoded).collect::<Vec<_>>().join(" | ")
        ),
        Status::Undecodable | Status::NoReply => format!("{labels}: {first}"),
        Status::UnknownCommand => first.to_owned(),
        Status::Unpaired => {
            let frame = x.reply.as_ref().map_or(String::new(), |r| hex_short(&r.bytes));
            match (x.exception, labels.is_empty()) {
                (Some(e), _) => format!("unpaired exception reply {frame}: {e}"),
                (None, true) => format!("unpaired reply {frame}: no loaded command fits it"),
                (None, false) => format!("unpaired reply {frame} (could be {labels})"),
            }
        }
        Status::Noise | Status::Unreadable => String::new(),
    };
    format!("{who}{what}")
}

/// Several entries (a stream or a capture): one line of text or JSON each, then a summary.
pub(super) fn print_reports(
    reports: &[Report<'_>],
    mode: CaptureMode,
    json_out: bool,
    out: &mut dyn Write,
) -> Result<()> {
    let failed = reports.iter().filter(|r| !r.status().ok()).count();
    let transactions = reports.iter().filter(|r| matches!(r, Report::Exchange(x) if x.request.is_some())).count();
    let decoded = reports.iter().filter(|r| r.status().ok()).count();
    let places: Vec<String> = reports.iter().map(place_text).collect();
    let width = places.iter().map(|p| p.chars().count() + 1).max().unwrap_or(0).max(12);
    for (r, place) in reports.iter().zip(&places) {
        if json_out {
            writeln!(out, "{}", serde_json::to_string(&report_json(r)).unwrap_or_default())?;
        } else {
            writeln!(out, "{place:<width$}{}", report_text(r))?;
        }
    }
    let (mode, how) = match mode {
        CaptureMode::Lines => ("lines", "frames by line"),
        CaptureMode::Stream => ("stream", "one hex stream"),
    };
    if json_out {
        let summary = json!({
            "type": "summary",
            "mode": mode,
            "entries": reports.len(),
            "transactions": transactions,
            "decoded": decoded,
            "failed": failed,
            "ok": failed == 0,
        });
        writeln!(out, "{}", serde_json::to_string(&summary).unwrap_or_default())?;
    } else {
        writeln!(
            out,
            "{:<width$}{} entr{} ({transactions} transaction{}, read as {how}): {decoded} decoded, {failed} failed",
            "summary",
            reports.len(),
            if reports.len() == 1 { "y" } else { "ies" },
            if transactions == 1 { "" } else { "s" },
        )?;
    }
    out.flush()?;
    if failed > 0 {
        return Err(CliError::device(format!("{failed} of {} entries could not be decoded", reports.len())).hint(
            "see the entries above (with --json, those with \"ok\": false); --sensor / --command resolve ambiguities",
        ));
    }
    Ok(())
}

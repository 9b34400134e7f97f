//! Printing reports: a request and its reply as a block, several entries
//! one line (or one JSON document) each ([`crate::explained`]), then a summary.

use std::io::Write;

use serde_json::json;
use yosemitech_rtu::bytes::byte;

use crate::error::{CliError, Result};
use crate::explain::candidates::label;
use crate::explain::exchange::describe;
use crate::explain::{CaptureMode, Exchange, Report, Status};
use crate::explained::{exchange_json, report_json, report_text, values_text};
use crate::format::{hex, value_with_unit};

use super::{error_json, pretty};

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

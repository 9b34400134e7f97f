//! An explained entry ([`crate::explain::Report`]) as one line of text or
//! one JSON document: what `decode` prints for a stream or a capture, and
//! `sniff` for what it hears.

use serde_json::{Value as Json, json};
use yosemitech_rtu::Function;
use yosemitech_rtu::bytes::byte;
use yosemitech_rtu::crc_ok;
use yosemitech_rtu::frame::EXCEPTION_BIT;
use yosemitech_spec::CommandSpec;

use crate::explain::candidates::label;
use crate::explain::scan::Framed;
use crate::explain::{Decoding, Exchange, Finding, Report, Status};
use crate::format::{fields_json, hex, value_with_unit, values_json};

/// Findings as the words JSON carries.
pub fn words(findings: &[Finding]) -> Vec<String> {
    findings.iter().map(ToString::to_string).collect()
}

/// `ph = 7.6 pH, temperature_c = 25 °C`.
pub fn values_text(d: &Decoding<'_>) -> String {
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
pub fn framed_json(f: &Framed) -> Json {
    json!({
        "frame": hex(&f.bytes),
        "length": f.bytes.len(),
        "line": (f.place.line > 0).then_some(f.place.line),
        "offset": f.place.offset,
        "crc_ok": f.bytes.len() >= 4 && crc_ok(&f.bytes),
    })
}

pub fn exchange_json(x: &Exchange<'_>) -> Json {
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

pub fn report_json(r: &Report<'_>) -> Json {
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

/// Bytes as hex, the first 32 of a long run.
pub fn hex_short(bytes: &[u8]) -> String {
    match bytes.get(..32) {
        Some(head) if bytes.len() > 32 => format!("{} …", hex(head)),
        _ => hex(bytes),
    }
}

/// An entry in one line of text.
pub fn report_text(r: &Report<'_>) -> String {
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

//! One frame decoded on its own: its kind from its function code and
//! length, the commands it fits, and the block (or JSON) that explains it.

use std::io::Write;

use serde_json::{Value as Json, json};
use yosemitech_rtu::bytes::{byte, word};
use yosemitech_rtu::frame::{EXCEPTION_BIT, REPLY_BYTE_COUNT_AT, REQUEST_BYTE_COUNT_AT};
use yosemitech_rtu::{ExceptionCode, Function, crc16};
use yosemitech_spec::interp::decode_fields;
use yosemitech_spec::{CommandSpec, Values};

use crate::error::{CliError, Result};
use crate::format::{fields_json, hex, value_with_unit, values_json};

use super::candidates::{Cand, Candidate, Filter, fits_slave, reply_lens, shared};
use super::{error_json, pretty};

/// What a frame is, from its function code and length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    ReadRequest,
    ReadReply,
    WriteRequest,
    WriteReply,
    Exception,
    Unknown,
}

impl Kind {
    pub(super) fn name(self) -> &'static str {
        match self {
            Kind::ReadRequest => "read request",
            Kind::ReadReply => "read reply",
            Kind::WriteRequest => "write request",
            Kind::WriteReply => "write reply",
            Kind::Exception => "exception reply",
            Kind::Unknown => "unknown frame",
        }
    }

    pub(super) fn json_name(self) -> &'static str {
        match self {
            Kind::ReadRequest => "read_request",
            Kind::ReadReply => "read_reply",
            Kind::WriteRequest => "write_request",
            Kind::WriteReply => "write_reply",
            Kind::Exception => "exception",
            Kind::Unknown => "unknown",
        }
    }

    pub(super) fn is_request(self) -> bool {
        matches!(self, Kind::ReadRequest | Kind::WriteRequest)
    }

    /// Whether the frame carries field values (so the command must be known to decode it).
    pub(super) fn has_values(self) -> bool {
        matches!(self, Kind::ReadReply | Kind::WriteRequest)
    }
}

/// Decodes one frame on its own: the command is found from the frame alone.
pub(super) fn decode_one(filter: &Filter<'_>, json_out: bool, frame: &[u8], out: &mut dyn Write) -> Result<()> {
    if frame.len() < 4 {
        return Err(CliError::usage(format!("{} byte(s) is too short for a frame", frame.len()))
            .hint("an RTU frame has at least an address, a function code and a 2-byte CRC"));
    }
    let entries = &filter.entries;
    let len = frame.len();
    let (slave, function) = (byte(frame, 0).unwrap_or(0), byte(frame, 1).unwrap_or(0));
    let body = frame.get(..len - 2).unwrap_or(&[]);
    let received = word(frame, len - 2).unwrap_or(0).to_be_bytes();
    let expected = crc16(body).to_le_bytes();
    let crc_ok = received == expected;

    let kind = match Function::from_code(function) {
        _ if function & EXCEPTION_BIT != 0 => Kind::Exception,
        Some(Function::Read) if len == Function::Read.request_len(0) => Kind::ReadRequest,
        Some(Function::Read) => Kind::ReadReply,
        Some(Function::Write) if len == Function::Write.response_len(0) => Kind::WriteReply,
        Some(Function::Write) => Kind::WriteRequest,
        None => Kind::Unknown,
    };
    let (address, count) = match kind {
        Kind::ReadRequest | Kind::WriteRequest | Kind::WriteReply => {
            (Some(word(frame, 2).unwrap_or(0)), Some(word(frame, 4).unwrap_or(0)))
        }
        _ => (None, None),
    };
    let wanted = filter.command.clone();
    // Without --command, the slave address narrows the candidates too: a
    // command with a fixed slave address is only ever to and from it, and a
    // frame of address 248..=255 (the wildcard 0xFF) fits only such a command.
    let slave_fits = |c: &CommandSpec| wanted.is_some() || fits_slave(c, slave);
    let fits = |c: &CommandSpec| {
        slave_fits(c)
            && match kind {
                Kind::ReadRequest => c.is_read() && Some(c.address) == address && Some(c.count) == count,
                Kind::ReadReply => c.is_read() && reply_lens(c).contains(&Some(len)),
                Kind::WriteRequest | Kind::WriteReply => {
                    !c.is_read() && Some(c.address) == address && Some(c.count) == count
                }
                Kind::Exception => c.function.code() == function & !EXCEPTION_BIT,
                Kind::Unknown => false,
            }
    };
    let fitting = entries
        .iter()
        .flat_map(|e| e.sensor.commands.iter().map(|command| Cand { sensor: &e.sensor.name, command }))
        .filter(|c| fits(c.command) && wanted.as_ref().is_none_or(|w| *w == c.command.name));
    let mut candidates = shared(fitting);
    if kind == Kind::Exception && wanted.is_none() {
        candidates.clear();
    }

    if let Some(name) = &wanted
        && candidates.is_empty()
        && kind != Kind::Unknown
    {
        let what = match (address, count) {
            (Some(a), Some(n)) => format!("a {} of {len} bytes for 0x{a:04X} x{n}", kind.name()),
            _ => format!("a {} of {len} bytes", kind.name()),
        };
        return Err(CliError::usage(format!("the frame does not fit `{name}`: it is {what}"))
            .hint("check the frame, or leave out --command to see what fits"));
    }
    if kind.has_values() && candidates.len() > 1 {
        let mut e = CliError::usage(format!(
            "this {} of {len} bytes fits {} commands; say which one",
            kind.name(),
            candidates.len()
        ));
        for c in &candidates {
            let data = match kind {
                Kind::ReadReply => frame.get(3..len - 2),
                _ => frame.get(7..len - 2),
            };
            let values = decode_fields(c.command, data.unwrap_or(&[]));
            let shown: Vec<String> =
                values.iter().map(|(n, v)| format!("{n} = {}", value_with_unit(v, c.command.field(n)))).collect();
            e = e.detail(format!("{}: {}", c.label(), shown.join(", ")));
        }
        let example = candidates.first().map_or(String::new(), |c| {
            format!(", e.g. --sensor {} --command {}", c.sensors.first().copied().unwrap_or(""), c.command.name)
        });
        let e = e.hint(format!("choose with --sensor and/or --command{example}"));
        if json_out {
            let data = match kind {
                Kind::ReadReply => frame.get(3..len - 2),
                _ => frame.get(7..len - 2),
            };
            let listed: Vec<Json> = candidates
                .iter()
                .map(|c| {
                    let values = decode_fields(c.command, data.unwrap_or(&[]));
                    json!({
                        "sensors": c.sensors,
                        "command": c.command.name,
                        "values": values_json(&values),
                        "fields": fields_json(c.command, &values),
                    })
                })
                .collect();
            let doc = json!({
                "frame": hex(frame),
                "length": len,
                "kind": kind.json_name(),
                "slave": slave,
                "function": function,
                "status": "ambiguous",
                "candidates": listed,
                "error": error_json(&e),
            });
            writeln!(out, "{}", pretty(&doc))?;
        }
        return Err(e);
    }

    let chosen = if candidates.len() == 1 { candidates.first() } else { None };
    let mut problems: Vec<String> = Vec::new();
    let mut notes: Vec<String> = Vec::new();
    let mut values: Values = Vec::new();
    let mut byte_count = None;
    let mut exception = None;
    match kind {
        Kind::ReadReply => {
            let n = byte(frame, REPLY_BYTE_COUNT_AT).unwrap_or(0);
            byte_count = Some(n);
            if let Some(c) = chosen.map(|c| c.command) {
                let data = frame.get(3..len.saturating_sub(2)).unwrap_or(&[]);
                values = decode_fields(c, data);
                let want = 2 * usize::from(c.count);
                if usize::from(n) != want {
                    if c.trigger && c.layout().accepts_byte_count(n) {
                        notes.push(format!("byte count 0x{n:02X}: a trigger's reply carries no value, accepted"));
                    } else if c.layout().accepts_byte_count(n) {
                        notes.push(format!(
                            "byte count 0x{n:02X} over {want} data bytes: a firmware quirk the spec documents, accepted"
                        ));
                    } else {
                        problems.push(format!("byte count 0x{n:02X}, expected 0x{want:02X}"));
                    }
                }
            }
        }
        Kind::WriteRequest => {
            let n = byte(frame, REQUEST_BYTE_COUNT_AT).unwrap_or(0);
            byte_count = Some(n);
            if let Some(c) = chosen.map(|c| c.command) {
                let want_len = c.layout().request_len();
                if len != want_len {
                    problems.push(format!("{len} bytes, a {} request has {want_len}", c.name));
                } else {
                    values = decode_fields(c, frame.get(7..len - 2).unwrap_or(&[]));
                }
                if usize::from(n) != 2 * usize::from(c.count) {
                    problems.push(format!("byte count 0x{n:02X}, expected 0x{:02X}", 2 * c.count));
                }
            }
        }
        Kind::Exception => {
            let code = ExceptionCode::from_u8(byte(frame, 2).unwrap_or(0));
            exception = Some(code);
            if len != 5 {
                problems.push(format!("an exception reply has 5 bytes, this one {len}"));
            }
        }
        Kind::Unknown => {
            problems.push(format!("function 0x{function:02X} is not one the probes use (0x03 read, 0x10 write)"))
        }
        Kind::ReadRequest | Kind::WriteReply => {}
    }
    if let Some(c) = chosen.map(|c| c.command) {
        match c.fixed_slave {
            Some(fixed) if fixed != slave => {
                problems.push(format!("{} is sent to and answered from address 0x{fixed:02X}, not {slave}", c.name));
            }
            Some(fixed) => notes.push(format!("{} uses the wildcard address 0x{fixed:02X} (erratum E3)", c.name)),
            None if slave == 0 && kind == Kind::WriteRequest => {
                notes.push("address 0: a broadcast, never answered".into())
            }
            None if !(1..=247).contains(&slave) => problems.push(format!("address {slave} is outside 1..=247")),
            None => {}
        }
    }
    if candidates.is_empty()
        && matches!(kind, Kind::ReadRequest | Kind::ReadReply | Kind::WriteRequest | Kind::WriteReply)
    {
        problems.push(format!("no command of the loaded sensors fits this {}", kind.name()));
    }

    let function_name = Function::from_code(function & !EXCEPTION_BIT).map(|f| match f {
        Function::Read => "read",
        Function::Write => "write",
    });
    if json_out {
        let command = chosen.map(|c| {
            json!({
                "sensor": c.sensors.first(),
                "sensors": c.sensors,
                "name": c.command.name,
                "title": c.command.title,
                "address": c.command.address,
                "count": c.command.count,
            })
        });
        let doc = json!({
            "frame": hex(frame),
            "length": len,
            "kind": kind.json_name(),
            "slave": slave,
            "function": function,
            "function_name": function_name,
            "address": address,
            "count": count,
            "byte_count": byte_count,
            "command": command,
            "candidates": candidates.iter().map(|c| json!({ "sensors": c.sensors, "command": c.command.name })).collect::<Vec<_>>(),
            "fields": chosen.map_or(Json::Array(Vec::new()), |c| fields_json(c.command, &values)),
            "values": values_json(&values),
            "exception": exception.map(|e| json!({ "code": e.to_u8(), "name": e.to_string() })),
            "crc": { "ok": crc_ok, "received": hex(&received), "expected": hex(&expected) },
            "notes": notes,
            "problems": problems,
        });
        writeln!(out, "{}", pretty(&doc))?;
    } else {
        let fname = function_name.map(|n| format!(" ({n})")).unwrap_or_default();
        writeln!(out, "frame       {} ({len} bytes)", hex(frame))?;
        let direction = match kind {
            k if k.is_request() => format!("{} to address {slave}, function 0x{function:02X}{fname}", k.name()),
            Kind::Exception => {
                format!("exception reply from address {slave} to function 0x{:02X}{fname}", function & !EXCEPTION_BIT)
            }
            k => format!("{} from address {slave}, function 0x{function:02X}{fname}", k.name()),
        };
        writeln!(out, "kind        {direction}")?;
        if let (Some(a), Some(n)) = (address, count) {
            writeln!(out, "registers   0x{a:04X}, {n} register{}", if n == 1 { "" } else { "s" })?;
        }
        match (chosen, candidates.len()) {
            (Some(c), _) => {
                writeln!(out, "command     {} {}: {}", c.sensors.join("/"), c.command.name, c.command.title)?
            }
            (None, 0) if kind != Kind::Exception => writeln!(out, "command     none of the loaded sensors' commands")?,
            (None, 0) => {}
            (None, _) => {
                let labels: Vec<String> = candidates.iter().map(Candidate::label).collect();
                writeln!(out, "command     one of: {}", labels.join("; "))?;
            }
        }
        if let Some(n) = byte_count {
            writeln!(out, "byte count  {n}")?;
        }
        if let Some(code) = exception {
            writeln!(out, "exception   {code}")?;
        }
        if let Some(c) = chosen {
            let width = values.iter().map(|(n, _)| n.len()).max().unwrap_or(0).max(10);
            for (name, value) in &values {
                writeln!(out, "  {name:width$}  {}", value_with_unit(value, c.command.field(name)))?;
            }
        }
        if crc_ok {
            writeln!(out, "CRC         {} (ok)", hex(&received))?;
        } else {
            writeln!(out, "CRC         {} (wrong: the bytes give {})", hex(&received), hex(&expected))?;
        }
        for note in &notes {
            writeln!(out, "note        {note}")?;
        }
        for problem in &problems {
            writeln!(out, "problem     {problem}")?;
        }
    }
    out.flush()?;
    if !crc_ok {
        return Err(CliError::device(format!(
            "the CRC is wrong: the frame carries {}, its bytes give {}",
            hex(&received),
            hex(&expected)
        ))
        .hint("the frame was corrupted on the line or copied wrongly; the fields above are shown as received"));
    }
    if let Some(first) = problems.first() {
        return Err(CliError::device(format!("the frame fails a check: {first}"))
            .hint("see the lines above; -v on a live bus shows every frame"));
    }
    Ok(())
}

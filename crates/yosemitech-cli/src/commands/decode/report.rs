//! What the scanner found, decoded: each exchange as a value (status,
//! decodings, notes, problems), before any of it is printed.

use serde_json::{Value as Json, json};
use yosemitech_rtu::bytes::byte;
use yosemitech_rtu::frame::{EXCEPTION_BIT, EXCEPTION_LEN};
use yosemitech_rtu::{ExceptionCode, Function, crc16};
use yosemitech_spec::{CommandSpec, Values};

use crate::format::{fields_json, hex, value_with_unit, values_json};

use super::candidates::{Cand, Filter, fits_slave, label, reply_lens};
use super::scan::{Found, Framed, Header, Place};

/// How a transaction or a frame ended up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Status {
    /// The reply decoded, one way.
    Decoded,
    /// The device answered with a Modbus exception.
    Exception,
    /// A broadcast write: never answered.
    Broadcast,
    /// The reply decodes differently as different commands.
    Ambiguous,
    /// The reply does not decode as any command the request names.
    Undecodable,
    /// No reply followed the request.
    NoReply,
    /// No loaded command (left by --sensor/--command) fits the request.
    UnknownCommand,
    /// A reply with no request before it.
    Unpaired,
    /// Bytes that are no frame.
    Noise,
    /// A capture line that is not hex.
    Unreadable,
}

impl Status {
    pub(super) fn name(self) -> &'static str {
        match self {
            Status::Decoded => "decoded",
            Status::Exception => "exception",
            Status::Broadcast => "broadcast",
            Status::Ambiguous => "ambiguous",
            Status::Undecodable => "undecodable",
            Status::NoReply => "no_reply",
            Status::UnknownCommand => "unknown_command",
            Status::Unpaired => "unpaired",
            Status::Noise => "noise",
            Status::Unreadable => "unreadable",
        }
    }

    /// Whether the entry counts as decoded for the exit code.
    pub(super) fn ok(self) -> bool {
        matches!(self, Status::Decoded | Status::Exception | Status::Broadcast)
    }
}

/// One way to read a transaction: the commands that read it so, and the values.
pub(super) struct Decoding<'c> {
    pub(super) cands: Vec<Cand<'c>>,
    pub(super) values: Values,
}

impl<'c> Decoding<'c> {
    pub(super) fn command(&self) -> Option<&'c CommandSpec> {
        self.cands.first().map(|c| c.command)
    }

    /// `get_sn of conductivity, ph_orp`.
    pub(super) fn label(&self) -> String {
        label(&self.cands)
    }

    /// `ph = 7.6 pH, temperature_c = 25 °C`.
    pub(super) fn values_text(&self) -> String {
        let command = self.command();
        self.values
            .iter()
            .map(|(n, v)| format!("{n} = {}", value_with_unit(v, command.and_then(|c| c.field(n)))))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The command's name, when every candidate has the same one.
    pub(super) fn name(&self) -> Option<&str> {
        let first = self.command()?;
        self.cands.iter().all(|c| c.command.name == first.name).then_some(first.name.as_str())
    }

    pub(super) fn json(&self) -> Json {
        let empty = Json::Array(Vec::new());
        json!({
            "command": self.name(),
            "sensors": self.cands.iter().map(|c| c.sensor).collect::<Vec<_>>(),
            "commands": self.cands.iter().map(|c| json!({ "sensor": c.sensor, "command": c.command.name })).collect::<Vec<_>>(),
            "title": self.command().map(|c| c.title.as_str()),
            "values": values_json(&self.values),
            "fields": self.command().map_or(empty, |c| fields_json(c, &self.values)),
        })
    }
}

/// Candidates with their values, the equal ones together: same fields, same
/// values (bit for bit), same units.
pub(super) fn group<'c>(decoded: impl IntoIterator<Item = (Cand<'c>, Values)>) -> Vec<Decoding<'c>> {
    let mut groups: Vec<Decoding<'c>> = Vec::new();
    for (cand, values) in decoded {
        let same = groups.iter_mut().find(|g| {
            let unit = |c: Option<&CommandSpec>, n: &str| c.and_then(|c| c.field(n)).and_then(|f| f.unit.clone());
            g.values.len() == values.len()
                && g.values.iter().zip(&values).all(|((n1, v1), (n2, v2))| {
                    n1 == n2 && v1.same_as(v2) && unit(g.command(), n1) == unit(Some(cand.command), n2)
                })
        });
        match same {
            Some(g) => g.cands.push(cand),
            None => groups.push(Decoding { cands: vec![cand], values }),
        }
    }
    groups
}

/// A request and its reply (or a reply alone), decoded.
pub(super) struct Exchange<'c> {
    pub(super) request: Option<(Framed, Header)>,
    pub(super) reply: Option<Framed>,
    pub(super) status: Status,
    /// Every way to read it; one when decoded.
    pub(super) decodings: Vec<Decoding<'c>>,
    pub(super) exception: Option<ExceptionCode>,
    pub(super) notes: Vec<String>,
    pub(super) problems: Vec<String>,
}

impl<'c> Exchange<'c> {
    pub(super) fn slave(&self) -> Option<u8> {
        match (&self.request, &self.reply) {
            (Some((_, header)), _) => Some(header.slave),
            (None, Some(reply)) => reply.bytes.first().copied(),
            (None, None) => None,
        }
    }

    /// The one decoding, when there is exactly one.
    pub(super) fn chosen(&self) -> Option<&Decoding<'c>> {
        match self.decodings.as_slice() {
            [only] => Some(only),
            _ => None,
        }
    }
}

/// An entry of the output.
pub(super) enum Report<'c> {
    Exchange(Exchange<'c>),
    Noise(Framed),
    Unreadable { place: Place, text: String, problem: String },
}

impl Report<'_> {
    pub(super) fn status(&self) -> Status {
        match self {
            Report::Exchange(x) => x.status,
            Report::Noise(_) => Status::Noise,
            Report::Unreadable { .. } => Status::Unreadable,
        }
    }
}

/// `a read of 0x2800, 2 registers`.
pub(super) fn describe(header: &Header) -> String {
    let registers =
        format!("0x{:04X}, {} register{}", header.address, header.count, if header.count == 1 { "" } else { "s" });
    match Function::from_code(header.function) {
        Some(Function::Read) => format!("a read of {registers}"),
        Some(Function::Write) => format!("a write of {registers}"),
        None => format!("function 0x{:02X} on {registers}", header.function),
    }
}

/// Decodes what the scanner found, with the commands --sensor/--command leave.
pub(super) fn report<'c>(filter: &Filter<'_>, all: &[Cand<'c>], found: Found<'c>) -> Report<'c> {
    match found {
        Found::Noise(f) => Report::Noise(f),
        Found::Unreadable { place, text, problem } => Report::Unreadable { place, text, problem },
        Found::Pair { request, header, cands, reply, intact } => {
            Report::Exchange(transaction(filter, request, header, &cands, reply, intact))
        }
        Found::Lone(reply) => Report::Exchange(lone(filter, all, reply)),
    }
}

pub(super) fn transaction<'c>(
    filter: &Filter<'_>,
    request: Framed,
    header: Header,
    cands: &[Cand<'c>],
    reply: Option<Framed>,
    intact: bool,
) -> Exchange<'c> {
    let allowed: Vec<Cand<'c>> = cands.iter().filter(|c| filter.allows(c)).copied().collect();
    let written = |c: &Cand<'_>| -> Values {
        if c.command.is_read() {
            Vec::new()
        } else {
            c.command.decode_request(&request.bytes).map(|(_, values)| values).unwrap_or_default()
        }
    };
    let mut x = Exchange {
        request: None,
        reply: None,
        status: Status::Decoded,
        decodings: Vec::new(),
        exception: None,
        notes: Vec::new(),
        problems: Vec::new(),
    };
    let what = describe(&header);
    match (&reply, intact) {
        _ if allowed.is_empty() => {
            x.status = Status::UnknownCommand;
            x.problems.push(if cands.is_empty() {
                format!("no loaded sensor has a command for {what}")
            } else {
                format!("{what} is {}, which --sensor/--command leave out", label(cands))
            });
        }
        (None, _) => {
            x.decodings = group(allowed.iter().map(|c| (*c, written(c))));
            if header.slave == 0 {
                x.status = Status::Broadcast;
                x.notes.push("address 0: a broadcast, never answered".into());
            } else {
                x.status = Status::NoReply;
                x.problems.push(format!("no reply from address {} follows the request", header.slave));
            }
        }
        (Some(reply), false) => {
            x.decodings = group(allowed.iter().map(|c| (*c, written(c))));
            x.status = Status::Undecodable;
            let bytes = &reply.bytes;
            let expected = if byte(bytes, 1).unwrap_or(0) & EXCEPTION_BIT != 0 {
                EXCEPTION_LEN
            } else {
                allowed.iter().filter_map(|c| reply_lens(c.command)[0]).max().unwrap_or(0)
            };
            let n = bytes.len();
            x.problems.push(if n < expected {
                format!("the reply is cut short: {n} of {expected} bytes")
            } else {
                let carried = bytes.get(n.saturating_sub(2)..).unwrap_or(&[]);
                let computed = crc16(bytes.get(..n.saturating_sub(2)).unwrap_or(&[])).to_le_bytes();
                format!("the reply's CRC is wrong: it carries {}, its bytes give {}", hex(carried), hex(&computed))
            });
        }
        (Some(reply), true) if byte(&reply.bytes, 1).unwrap_or(0) & EXCEPTION_BIT != 0 => {
            x.status = Status::Exception;
            x.exception = Some(ExceptionCode::from_u8(byte(&reply.bytes, 2).unwrap_or(0)));
            x.decodings = group(allowed.iter().map(|c| (*c, written(c))));
        }
        (Some(reply), true) => {
            let mut decoded = Vec::new();
            let mut rejected = Vec::new();
            for c in &allowed {
                match c.command.decode_response(header.slave, &reply.bytes) {
                    Ok(values) => decoded.push((*c, if c.command.is_read() { values } else { written(c) })),
                    Err(e) => rejected.push(format!("not {} of {}: {e}", c.command.name, c.sensor)),
                }
            }
            x.decodings = group(decoded);
            x.status = match x.decodings.len() {
                0 => Status::Undecodable,
                1 => Status::Decoded,
                _ => Status::Ambiguous,
            };
            if x.status == Status::Undecodable {
                x.problems.extend(rejected);
            } else {
                x.notes.extend(rejected);
            }
            if let Some(c) = x.chosen().and_then(Decoding::command) {
                let n = byte(&reply.bytes, 2).unwrap_or(0);
                if c.is_read() && !c.trigger && usize::from(n) != 2 * usize::from(c.count) {
                    x.notes.push(format!(
                        "byte count 0x{n:02X} over {} data bytes: a firmware quirk the spec documents, accepted",
                        2 * c.count
                    ));
                }
                if let Some(fixed) = c.fixed_slave {
                    x.notes.push(format!("{} is sent to and answered from the address 0x{fixed:02X}", c.name));
                }
            }
        }
    }
    x.request = Some((request, header));
    x.reply = reply;
    x
}

/// A reply with no request: what it could be, for information.
pub(super) fn lone<'c>(filter: &Filter<'_>, all: &[Cand<'c>], reply: Framed) -> Exchange<'c> {
    let (slave, function) = (byte(&reply.bytes, 0).unwrap_or(0), byte(&reply.bytes, 1).unwrap_or(0));
    let mut x = Exchange {
        request: None,
        reply: None,
        status: Status::Unpaired,
        decodings: Vec::new(),
        exception: None,
        notes: Vec::new(),
        problems: vec![format!(
            "no request to address {slave} before this reply (lost, or sent before the capture began)"
        )],
    };
    if function & EXCEPTION_BIT != 0 {
        x.exception = Some(ExceptionCode::from_u8(byte(&reply.bytes, 2).unwrap_or(0)));
    } else {
        // A reply from 0xFF fits only a command with that fixed address.
        let decoded = all
            .iter()
            .filter(|c| filter.allows(c) && c.command.function.code() == function)
            .filter(|c| slave != 0 && fits_slave(c.command, slave))
            .filter_map(|c| {
                let values = c.command.decode_response(c.command.fixed_slave.unwrap_or(slave), &reply.bytes).ok()?;
                Some((*c, values))
            });
        x.decodings = group(decoded);
    }
    x.reply = Some(reply);
    x
}

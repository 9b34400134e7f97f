//! What the scanner found, decoded: each exchange as a value (status,
//! decodings, notes, problems), for a front end to render.

use yosemitech_rtu::bytes::byte;
use yosemitech_rtu::frame::EXCEPTION_LEN;
use yosemitech_rtu::{ExceptionCode, Function, Hex, crc16};
use yosemitech_spec::Values;

use super::candidates::{Candidate, Commands, Decoding, by_equal_values, fits_slave, label, reply_lens};
use super::finding::Finding;
use super::frame::Kind;
use super::scan::{Found, Framed, Header, Place};

/// How a transaction or a frame ended up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
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
    /// `no_reply`: its name in JSON (and, spaced, in text).
    pub fn name(self) -> &'static str {
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
    pub fn ok(self) -> bool {
        matches!(self, Status::Decoded | Status::Exception | Status::Broadcast)
    }
}

/// A request and its reply (or a reply alone), decoded.
pub struct Exchange<'c> {
    /// The request and what it asks, if one was seen.
    pub request: Option<(Framed, Header)>,
    /// The reply, if one followed (or came alone).
    pub reply: Option<Framed>,
    /// How it ended up.
    pub status: Status,
    /// Every way to read it; one when decoded.
    pub decodings: Vec<Decoding<'c>>,
    /// The exception the reply carries.
    pub exception: Option<ExceptionCode>,
    /// What is unusual but accepted.
    pub notes: Vec<Finding>,
    /// What is wrong, first the reason of the status.
    pub problems: Vec<Finding>,
}

impl<'c> Exchange<'c> {
    /// The slave address the request names, else the reply's.
    pub fn slave(&self) -> Option<u8> {
        match (&self.request, &self.reply) {
            (Some((_, header)), _) => Some(header.slave),
            (None, Some(reply)) => reply.bytes.first().copied(),
            (None, None) => None,
        }
    }

    /// The one decoding, when there is exactly one.
    pub fn chosen(&self) -> Option<&Decoding<'c>> {
        match self.decodings.as_slice() {
            [only] => Some(only),
            _ => None,
        }
    }
}

/// An entry of the output.
pub enum Report<'c> {
    /// A request and its reply, or one of them alone.
    Exchange(Exchange<'c>),
    /// Bytes that are no frame.
    Noise(Framed),
    /// A capture line that is not hex: where, its text and why.
    #[allow(missing_docs)]
    Unreadable { place: Place, text: String, problem: String },
}

impl Report<'_> {
    /// How the entry ended up.
    pub fn status(&self) -> Status {
        match self {
            Report::Exchange(x) => x.status,
            Report::Noise(_) => Status::Noise,
            Report::Unreadable { .. } => Status::Unreadable,
        }
    }
}

/// `a read of 0x2800, 2 registers`.
pub fn describe(header: &Header) -> String {
    let registers =
        format!("0x{:04X}, {} register{}", header.address, header.count, if header.count == 1 { "" } else { "s" });
    match Function::from_code(header.function) {
        Some(Function::Read) => format!("a read of {registers}"),
        Some(Function::Write) => format!("a write of {registers}"),
        None => format!("function 0x{:02X} on {registers}", header.function),
    }
}

/// Decodes what the scanner found, with the commands --sensor/--command leave.
pub fn report<'c>(commands: &Commands<'c>, found: Found<'c>) -> Report<'c> {
    match found {
        Found::Noise(f) => Report::Noise(f),
        Found::Unreadable { place, text, problem } => Report::Unreadable { place, text, problem },
        Found::Pair { request, header, cands, reply, intact } => {
            Report::Exchange(transaction(commands, request, header, &cands, reply, intact))
        }
        Found::Lone(reply) => Report::Exchange(lone(commands, reply)),
    }
}

/// A request and what followed it, decoded as the commands it fits that the choice leaves.
pub fn transaction<'c>(
    commands: &Commands<'c>,
    request: Framed,
    header: Header,
    cands: &[Candidate<'c>],
    reply: Option<Framed>,
    intact: bool,
) -> Exchange<'c> {
    let allowed: Vec<Candidate<'c>> = cands.iter().filter(|c| commands.allows(c)).copied().collect();
    let written = |c: &Candidate<'_>| -> Values {
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
                Finding::NoCommandFor { what }
            } else {
                Finding::LeftOut { what, commands: label(cands) }
            });
        }
        (None, _) => {
            x.decodings = by_equal_values(allowed.iter().map(|c| (*c, written(c))));
            if header.slave == 0 {
                x.status = Status::Broadcast;
                x.notes.push(Finding::Broadcast);
            } else {
                x.status = Status::NoReply;
                x.problems.push(Finding::NoReply { slave: header.slave });
            }
        }
        (Some(reply), false) => {
            x.decodings = by_equal_values(allowed.iter().map(|c| (*c, written(c))));
            x.status = Status::Undecodable;
            let bytes = &reply.bytes;
            let expected = if Kind::of(bytes) == Kind::Exception {
                EXCEPTION_LEN
            } else {
                allowed.iter().filter_map(|c| reply_lens(c.command)[0]).max().unwrap_or(0)
            };
            let n = bytes.len();
            x.problems.push(if n < expected {
                Finding::ReplyCutShort { len: n, expected }
            } else {
                let carried = bytes.get(n.saturating_sub(2)..).unwrap_or(&[]);
                let computed = crc16(bytes.get(..n.saturating_sub(2)).unwrap_or(&[])).to_le_bytes();
                Finding::ReplyCrc { carried: Hex(carried).to_string(), computed: Hex(&computed).to_string() }
            });
        }
        (Some(reply), true) if Kind::of(&reply.bytes) == Kind::Exception => {
            x.status = Status::Exception;
            x.exception = Some(ExceptionCode::from_u8(byte(&reply.bytes, 2).unwrap_or(0)));
            x.decodings = by_equal_values(allowed.iter().map(|c| (*c, written(c))));
        }
        (Some(reply), true) => {
            let mut decoded = Vec::new();
            let mut rejected = Vec::new();
            for c in &allowed {
                match c.command.decode_response(header.slave, &reply.bytes) {
                    Ok(values) => decoded.push((*c, if c.command.is_read() { values } else { written(c) })),
                    Err(e) => rejected.push(Finding::NotDecodedAs {
                        command: c.command.name.clone(),
                        sensor: c.sensor.to_string(),
                        reason: e.to_string(),
                    }),
                }
            }
            x.decodings = by_equal_values(decoded);
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
                    x.notes.push(Finding::QuirkByteCount { byte_count: n, data_bytes: 2 * usize::from(c.count) });
                }
                if let Some(fixed) = c.fixed_slave {
                    x.notes.push(Finding::FixedAddressExchange { command: c.name.clone(), address: fixed });
                }
            }
        }
    }
    x.request = Some((request, header));
    x.reply = reply;
    x
}

/// A reply with no request: what it could be, for information.
pub fn lone<'c>(commands: &Commands<'c>, reply: Framed) -> Exchange<'c> {
    let (slave, function) = (byte(&reply.bytes, 0).unwrap_or(0), byte(&reply.bytes, 1).unwrap_or(0));
    let mut x = Exchange {
        request: None,
        reply: None,
        status: Status::Unpaired,
        decodings: Vec::new(),
        exception: None,
        notes: Vec::new(),
        problems: vec![Finding::NoRequest { slave }],
    };
    if Kind::of(&reply.bytes) == Kind::Exception {
        x.exception = Some(ExceptionCode::from_u8(byte(&reply.bytes, 2).unwrap_or(0)));
    } else {
        // A reply from 0xFF fits only a command with that fixed address.
        let decoded = commands
            .all
            .iter()
            .filter(|c| commands.allows(c) && c.command.function.code() == function)
            .filter(|c| slave != 0 && fits_slave(c.command, slave))
            .filter_map(|c| {
                let values = c.command.decode_response(c.command.fixed_slave.unwrap_or(slave), &reply.bytes).ok()?;
                Some((*c, values))
            });
        x.decodings = by_equal_values(decoded);
    }
    x.reply = Some(reply);
    x
}

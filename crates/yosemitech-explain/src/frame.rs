//! One frame explained on its own: its kind from its function code and
//! length, the commands it fits, its values and what is wrong with it.

use yosemitech_rtu::bytes::{byte, word};
use yosemitech_rtu::frame::{EXCEPTION_BIT, REPLY_BYTE_COUNT_AT, REQUEST_BYTE_COUNT_AT};
use yosemitech_rtu::{ExceptionCode, Function, crc16};
use yosemitech_spec::interp::decode_fields;
use yosemitech_spec::{CommandSpec, Values};

use super::candidates::{Commands, Decoding, by_shared_command, fits_slave, reply_lens};
use super::finding::Finding;

/// What a frame is, from its function code and length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A read's request: address, function, register block, CRC.
    ReadRequest,
    /// A read's reply: a byte count and the data.
    ReadReply,
    /// A write's request: the register block, a byte count and the data.
    WriteRequest,
    /// A write's reply: the register block echoed.
    WriteReply,
    /// A Modbus exception.
    Exception,
    /// A function no probe serves.
    Unknown,
}

impl Kind {
    /// The kind of `frame`: a read request and a write reply have the fixed
    /// length of their header, an exception the function's high bit.
    pub fn of(frame: &[u8]) -> Kind {
        let function = byte(frame, 1).unwrap_or(0);
        match Function::from_code(function) {
            _ if function & EXCEPTION_BIT != 0 => Kind::Exception,
            Some(Function::Read) if frame.len() == Function::Read.request_len(0) => Kind::ReadRequest,
            Some(Function::Read) => Kind::ReadReply,
            Some(Function::Write) if frame.len() == Function::Write.response_len(0) => Kind::WriteReply,
            Some(Function::Write) => Kind::WriteRequest,
            None => Kind::Unknown,
        }
    }

    /// `read request`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::ReadRequest => "read request",
            Kind::ReadReply => "read reply",
            Kind::WriteRequest => "write request",
            Kind::WriteReply => "write reply",
            Kind::Exception => "exception reply",
            Kind::Unknown => "unknown frame",
        }
    }

    /// `read_request`.
    pub fn json_name(self) -> &'static str {
        match self {
            Kind::ReadRequest => "read_request",
            Kind::ReadReply => "read_reply",
            Kind::WriteRequest => "write_request",
            Kind::WriteReply => "write_reply",
            Kind::Exception => "exception",
            Kind::Unknown => "unknown",
        }
    }

    /// Whether a master sends it.
    pub fn is_request(self) -> bool {
        matches!(self, Kind::ReadRequest | Kind::WriteRequest)
    }

    /// Whether the frame carries field values (so the command must be known to decode it).
    pub fn has_values(self) -> bool {
        matches!(self, Kind::ReadReply | Kind::WriteRequest)
    }

    /// Where the field values start.
    fn data_at(self) -> usize {
        match self {
            Kind::ReadReply => 3,
            _ => 7,
        }
    }
}

/// How a frame on its own came out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FrameStatus {
    /// Explained: with one command, several that carry no values, or none.
    Explained,
    /// The chosen command (named) does not fit the frame.
    NotTheCommand(String),
    /// Several commands fit and the frame carries values: each decoding has its own.
    Ambiguous,
}

/// The CRC a frame carries and the one its bytes give.
#[derive(Debug, Clone, Copy)]
pub struct Crc {
    /// As the frame carries it.
    pub received: [u8; 2],
    /// As its bytes give it.
    pub expected: [u8; 2],
}

impl Crc {
    /// Whether they agree.
    pub fn ok(&self) -> bool {
        self.received == self.expected
    }
}

/// One frame, explained.
pub struct Frame<'c> {
    /// The frame.
    pub bytes: Vec<u8>,
    /// What it is.
    pub kind: Kind,
    /// Its first byte.
    pub slave: u8,
    /// Its function code (with the exception bit, if set).
    pub function: u8,
    /// The register block a request (or a write's reply) names.
    pub address: Option<u16>,
    /// The register count a request (or a write's reply) names.
    pub count: Option<u16>,
    /// The byte count a read's reply or a write's request carries.
    pub byte_count: Option<u8>,
    /// The exception an exception reply carries.
    pub exception: Option<ExceptionCode>,
    /// Its CRC.
    pub crc: Crc,
    /// How it came out.
    pub status: FrameStatus,
    /// The commands the frame fits, a command every probe shares as one.
    pub candidates: Vec<Decoding<'c>>,
    /// The values, decoded as the one candidate.
    pub values: Values,
    /// What is unusual but accepted.
    pub notes: Vec<Finding>,
    /// What is wrong.
    pub problems: Vec<Finding>,
}

impl<'c> Frame<'c> {
    /// The one candidate, when there is exactly one.
    pub fn chosen(&self) -> Option<&Decoding<'c>> {
        match self.candidates.as_slice() {
            [only] => Some(only),
            _ => None,
        }
    }

    /// `read` or `write`: the function the frame (or the exception) is of.
    pub fn function_name(&self) -> Option<&'static str> {
        Function::from_code(self.function & !EXCEPTION_BIT).map(|f| match f {
            Function::Read => "read",
            Function::Write => "write",
        })
    }
}

/// Explains `frame` on its own (at least 4 bytes: `None` for fewer): the
/// command is found from the frame alone.
pub fn explain_frame<'c>(commands: &Commands<'c>, frame: &[u8]) -> Option<Frame<'c>> {
    let len = frame.len();
    let body = frame.get(..len.checked_sub(2).filter(|&n| n >= 2)?)?;
    let (slave, function) = (byte(frame, 0).unwrap_or(0), byte(frame, 1).unwrap_or(0));
    let crc = Crc { received: word(frame, len - 2).unwrap_or(0).to_be_bytes(), expected: crc16(body).to_le_bytes() };
    let kind = Kind::of(frame);
    let (address, count) = match kind {
        Kind::ReadRequest | Kind::WriteRequest | Kind::WriteReply => {
            (Some(word(frame, 2).unwrap_or(0)), Some(word(frame, 4).unwrap_or(0)))
        }
        _ => (None, None),
    };
    let wanted = commands.command.as_ref();
    // Without a chosen command, the slave address narrows the candidates too:
    // a command with a fixed slave address is only ever to and from it, and a
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
    let fitting = commands
        .of_chosen_sensors()
        .filter(|c| fits(c.command) && wanted.is_none_or(|w| *w == c.command.name))
        .copied();
    let mut candidates = by_shared_command(fitting);
    if kind == Kind::Exception && wanted.is_none() {
        candidates.clear();
    }
    let mut explained = Frame {
        bytes: frame.to_vec(),
        kind,
        slave,
        function,
        address,
        count,
        byte_count: None,
        exception: None,
        crc,
        status: FrameStatus::Explained,
        candidates,
        values: Vec::new(),
        notes: Vec::new(),
        problems: Vec::new(),
    };
    if let Some(name) = wanted
        && explained.candidates.is_empty()
        && kind != Kind::Unknown
    {
        explained.status = FrameStatus::NotTheCommand(name.clone());
        return Some(explained);
    }
    let data = frame.get(kind.data_at()..len - 2).unwrap_or(&[]);
    if kind.has_values() && explained.candidates.len() > 1 {
        explained.status = FrameStatus::Ambiguous;
        for d in &mut explained.candidates {
            if let Some(c) = d.command() {
                d.values = decode_fields(c, data);
            }
        }
        return Some(explained);
    }
    check(&mut explained, data);
    Some(explained)
}

/// The values and the checks of a frame with at most one candidate.
fn check(x: &mut Frame<'_>, data: &[u8]) {
    let (kind, slave, len) = (x.kind, x.slave, x.bytes.len());
    let chosen = x.chosen().and_then(Decoding::command);
    let (notes, problems) = (&mut x.notes, &mut x.problems);
    match kind {
        Kind::ReadReply => {
            let n = byte(&x.bytes, REPLY_BYTE_COUNT_AT).unwrap_or(0);
            x.byte_count = Some(n);
            if let Some(c) = chosen {
                x.values = decode_fields(c, data);
                let want = 2 * usize::from(c.count);
                if usize::from(n) != want {
                    if c.trigger && c.layout().accepts_byte_count(n) {
                        notes.push(Finding::TriggerByteCount { byte_count: n });
                    } else if c.layout().accepts_byte_count(n) {
                        notes.push(Finding::QuirkByteCount { byte_count: n, data_bytes: want });
                    } else {
                        problems.push(Finding::ByteCount { byte_count: n, expected: want });
                    }
                }
            }
        }
        Kind::WriteRequest => {
            let n = byte(&x.bytes, REQUEST_BYTE_COUNT_AT).unwrap_or(0);
            x.byte_count = Some(n);
            if let Some(c) = chosen {
                let want_len = c.layout().request_len();
                if len != want_len {
                    problems.push(Finding::RequestLength { command: c.name.clone(), len, expected: want_len });
                } else {
                    x.values = decode_fields(c, data);
                }
                if usize::from(n) != 2 * usize::from(c.count) {
                    problems.push(Finding::ByteCount { byte_count: n, expected: 2 * usize::from(c.count) });
                }
            }
        }
        Kind::Exception => {
            x.exception = Some(ExceptionCode::from_u8(byte(&x.bytes, 2).unwrap_or(0)));
            if len != 5 {
                problems.push(Finding::ExceptionLength { len });
            }
        }
        Kind::Unknown => problems.push(Finding::UnknownFunction { function: x.function }),
        Kind::ReadRequest | Kind::WriteReply => {}
    }
    if let Some(c) = chosen {
        match c.fixed_slave {
            Some(fixed) if fixed != slave => {
                problems.push(Finding::NotItsFixedAddress { command: c.name.clone(), address: fixed, slave });
            }
            Some(fixed) => notes.push(Finding::WildcardAddress { command: c.name.clone(), address: fixed }),
            None if slave == 0 && kind == Kind::WriteRequest => notes.push(Finding::Broadcast),
            None if !(1..=247).contains(&slave) => problems.push(Finding::AddressOutOfRange { slave }),
            None => {}
        }
    }
    if x.candidates.is_empty()
        && matches!(kind, Kind::ReadRequest | Kind::ReadReply | Kind::WriteRequest | Kind::WriteReply)
    {
        problems.push(Finding::NoCommandFits { kind: kind.name() });
    }
}

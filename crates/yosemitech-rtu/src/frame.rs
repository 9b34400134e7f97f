//! RTU framing shared by the generated codecs, the spec interpreter and the
//! simulator: one implementation of every header, length, CRC and echo check.
//!
//! A frame is `slave, function, PDU data, CRC low, CRC high`. Reads (0x03)
//! carry a byte count and register data in the reply; writes (0x10) carry a
//! byte count and data in the request and an echo of address and count in the
//! reply. Frames are delimited by length, never by their own byte count, so a
//! firmware that misprints the byte count (pH manual Fig 54) still frames.

use core::ops::Deref;

use crate::bytes::{byte, word};
use crate::crc::crc16;
use crate::error::{EchoField, EncodeError, FrameError};

/// The largest RTU frame (address + PDU + CRC).
pub const MAX_ADU: usize = 256;

/// The highest unicast slave address.
pub const MAX_SLAVE: u8 = 247;

/// The broadcast address: writes only, never answered.
pub const BROADCAST: u8 = 0;

/// The bit set in the function code of an exception reply.
pub const EXCEPTION_BIT: u8 = 0x80;

/// Length of an exception reply: slave, function | 0x80, code, CRC.
pub const EXCEPTION_LEN: usize = 5;

/// The Modbus functions Yosemitech probes implement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Function {
    /// 0x03, read holding registers.
    Read,
    /// 0x10, write multiple registers.
    Write,
}

impl Function {
    /// The function code on the wire.
    pub const fn code(self) -> u8 {
        match self {
            Self::Read => 0x03,
            Self::Write => 0x10,
        }
    }

    /// The function for a wire code.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            0x03 => Some(Self::Read),
            0x10 => Some(Self::Write),
            _ => None,
        }
    }

    /// Bytes of a request's head that give its length: a read's function
    /// code says it all; a write's byte count is its seventh byte.
    pub const fn request_head_len(self) -> usize {
        match self {
            Self::Read => 2,
            Self::Write => REQUEST_BYTE_COUNT_AT + 1,
        }
    }

    /// Bytes in a request carrying `data_len` bytes of register data (none
    /// for a read): slave, function, address, count, [byte count, data], CRC.
    /// The one length rule of requests: [`Layout::request_len`] and the
    /// segmenter ([`crate::segment`]) both apply it.
    pub const fn request_len(self, data_len: usize) -> usize {
        match self {
            Self::Read => 8,
            Self::Write => 9 + data_len,
        }
    }

    /// Bytes in a normal reply carrying `data_len` bytes of register data
    /// (a read's; a write's echo has none): slave, function, byte count and
    /// data, or address and count; CRC. The one length rule of replies.
    pub const fn response_len(self, data_len: usize) -> usize {
        match self {
            Self::Read => 5 + data_len,
            Self::Write => 8,
        }
    }
}

/// Where a write request carries its byte count.
pub const REQUEST_BYTE_COUNT_AT: usize = 6;

/// Where a read reply carries its byte count.
pub const REPLY_BYTE_COUNT_AT: usize = 2;

/// Where a command sits on the wire: everything framing needs to know.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Layout<'a> {
    /// `Read` (0x03) or `Write` (0x10).
    pub function: Function,
    /// The first register, as sent on the wire (no 1-based offset).
    pub address: u16,
    /// Registers read or written; zero only for trigger writes.
    pub count: u16,
    /// A slave address the command must use in request and reply (get slave id: 0xFF).
    pub fixed_slave: Option<u8>,
    /// Byte counts a read reply may carry besides `2 * count` (documented firmware quirks).
    pub extra_byte_counts: &'a [u8],
    /// A command that carries no value. A trigger write sends zero registers.
    /// A trigger read (optical Start/Stop Measurement) ignores its reply's
    /// data: the manuals print byte count 0 followed by "meaningless" bytes,
    /// so a reply is accepted with byte count 0 and no data
    /// ([`Layout::short_response_len`]), with byte count 0 or `2 * count`
    /// followed by `2 * count` bytes; the data is never returned.
    pub trigger: bool,
}

impl Layout<'static> {
    /// A plain read of `count` registers from `address`: no fixed slave, no
    /// byte-count quirks, not a trigger.
    pub const fn read(address: u16, count: u16) -> Self {
        Self { function: Function::Read, address, count, fixed_slave: None, extra_byte_counts: &[], trigger: false }
    }

    /// A plain write of `count` registers at `address`: no fixed slave, not a trigger.
    pub const fn write(address: u16, count: u16) -> Self {
        Self { function: Function::Write, address, count, fixed_slave: None, extra_byte_counts: &[], trigger: false }
    }
}

impl Layout<'_> {
    /// Register data bytes: `2 * count`.
    pub const fn data_len(&self) -> usize {
        2 * self.count as usize
    }

    /// Bytes in a request frame.
    pub const fn request_len(&self) -> usize {
        self.function.request_len(self.request_data_len())
    }

    /// Bytes in a normal (non-exception) reply frame: the longest form a
    /// trigger read may take.
    pub const fn response_len(&self) -> usize {
        let data_len = match self.function {
            Function::Read => self.data_len(),
            Function::Write => 0,
        };
        self.function.response_len(data_len)
    }

    /// The length of the short reply a trigger read may also get (`slave 03
    /// 00 CRC`), `None` for every other command. A reader that has this many
    /// bytes with byte count 0 and a valid CRC has the whole reply.
    pub const fn short_response_len(&self) -> Option<usize> {
        match (self.function, self.trigger) {
            (Function::Read, true) if self.count > 0 => Some(Function::Read.response_len(0)),
            _ => None,
        }
    }

    /// Whether a read reply may carry byte count `count` in front of its
    /// `2 * count` data bytes: the Modbus count, a documented firmware quirk
    /// (`extra_byte_counts`), or 0 for a trigger read. The one rule every
    /// decoder, the spec validator and the CLI apply.
    // A loop, not `contains`: on bytes that is a `memchr`, 150 bytes of
    // firmware flash to search a list of one or two.
    #[allow(clippy::manual_contains)]
    pub fn accepts_byte_count(&self, count: u8) -> bool {
        usize::from(count) == self.data_len()
            || self.extra_byte_counts.iter().any(|&extra| extra == count)
            || (self.trigger && count == 0)
    }

    /// Bytes of register data in the request (writes) or zero (reads).
    pub const fn request_data_len(&self) -> usize {
        match self.function {
            Function::Read => 0,
            Function::Write => self.data_len(),
        }
    }

    /// Bytes of register data in the reply that carry values: `2 * count`
    /// for reads, zero for writes and trigger reads.
    pub const fn response_data_len(&self) -> usize {
        match self.function {
            Function::Read if !self.trigger => self.data_len(),
            _ => 0,
        }
    }

    /// The slave address a request for this command to the device at
    /// `address` goes to: the command's fixed slave address when it has
    /// one (a read at the wildcard address 0xFF), else `address`.
    pub const fn request_slave(&self, address: u8) -> u8 {
        match self.fixed_slave {
            Some(fixed) => fixed,
            None => address,
        }
    }

    /// The slave address a reply to a request sent to `slave` must carry:
    /// the one the request went to ([`Layout::request_slave`]).
    pub const fn reply_slave(&self, slave: u8) -> u8 {
        self.request_slave(slave)
    }

    /// Checks that `slave` may be used in a request for this command.
    #[inline]
    pub fn check_slave(&self, slave: u8) -> Result<(), EncodeError> {
        let ok = match self.fixed_slave {
            Some(fixed) => slave == fixed,
            None => (1..=MAX_SLAVE).contains(&slave) || (slave == BROADCAST && self.function == Function::Write),
        };
        if ok { Ok(()) } else { Err(EncodeError::InvalidSlave { slave }) }
    }

    /// Writes the request frame to `out`. `data` is the register data of a
    /// write (exactly [`Layout::request_data_len`] bytes) and empty for a read.
    #[inline(always)]
    pub fn encode_request(&self, slave: u8, data: &[u8], out: &mut [u8]) -> Result<usize, EncodeError> {
        self.check_slave(slave)?;
        let len = self.request_len();
        check_data_len(data, self.request_data_len(), len)?;
        let out = out.get_mut(..len).ok_or(EncodeError::BufferTooSmall { needed: len })?;
        let mut w = Writer::new(out);
        w.byte(slave);
        w.byte(self.function.code());
        w.word(self.address);
        w.word(self.count);
        if self.function == Function::Write {
            // data_len() <= 2 * 0xFFFF is checked against MAX_ADU by `len` above.
            w.byte(self.data_len() as u8);
            w.bytes(data);
        }
        w.crc();
        Ok(len)
    }

    /// Writes a normal reply to `out`. `data` is the register data of a read
    /// reply (exactly [`Layout::response_data_len`] bytes) and empty for a write.
    #[inline]
    pub fn encode_response(&self, slave: u8, data: &[u8], out: &mut [u8]) -> Result<usize, EncodeError> {
        let len = self.response_len();
        check_data_len(data, self.response_data_len(), len)?;
        let out = out.get_mut(..len).ok_or(EncodeError::BufferTooSmall { needed: len })?;
        let mut w = Writer::new(out);
        w.byte(self.reply_slave(slave));
        w.byte(self.function.code());
        match self.function {
            Function::Read if self.trigger => {
                // The manuals' form: byte count 0, then the "meaningless" registers.
                w.byte(0);
                for _ in 0..self.data_len() {
                    w.byte(0);
                }
            }
            Function::Read => {
                w.byte(self.data_len() as u8);
                w.bytes(data);
            }
            Function::Write => {
                w.word(self.address);
                w.word(self.count);
            }
        }
        w.crc();
        Ok(len)
    }

    /// Checks a request frame and returns its slave address and register data.
    #[inline]
    pub fn decode_request<'f>(&self, frame: &'f [u8]) -> Result<(u8, &'f [u8]), FrameError> {
        check_len(frame, self.request_len())?;
        check_crc(frame)?;
        let slave = byte(frame, 0).unwrap_or(0);
        if let Some(fixed) = self.fixed_slave
            && slave != fixed
        {
            return Err(FrameError::WrongSlave { expected: fixed, actual: slave });
        }
        check_function(frame, self.function.code())?;
        check_echo(frame, EchoField::Address, 2, self.address)?;
        check_echo(frame, EchoField::Count, 4, self.count)?;
        match self.function {
            Function::Read => Ok((slave, &[])),
            Function::Write => {
                check_byte_count(byte(frame, REQUEST_BYTE_COUNT_AT).unwrap_or(0), self.data_len(), &[])?;
                Ok((slave, frame.get(7..7 + self.data_len()).unwrap_or(&[])))
            }
        }
    }

    /// Checks a reply to a request sent to `slave` and returns its register
    /// data (exactly [`Layout::response_data_len`] bytes). An exception reply
    /// becomes [`FrameError::Exception`].
    #[inline(always)]
    pub fn decode_response<'f>(&self, slave: u8, frame: &'f [u8]) -> Result<&'f [u8], FrameError> {
        let expected_slave = self.reply_slave(slave);
        let function = self.function.code();
        let exception = frame.get(1) == Some(&(function | EXCEPTION_BIT));
        let short = !exception && self.short_response_len() == Some(frame.len());
        // Each form checks its own length and CRC. One check of a length
        // chosen at run time was smaller, but a known layout's CRC loop no
        // longer unrolled: a client transaction cost about 50 instructions
        // more. The slave and function checks are shared by all three forms.
        if exception {
            check_len(frame, EXCEPTION_LEN)?;
            check_crc(frame)?;
        } else if short {
            check_crc(frame)?;
        } else {
            check_len(frame, self.response_len())?;
            check_crc(frame)?;
        }
        check_slave(frame, expected_slave)?;
        if exception {
            return Err(FrameError::Exception {
                function,
                code: crate::ExceptionCode::from_u8(byte(frame, 2).unwrap_or(0)),
            });
        }
        check_function(frame, function)?;
        if short {
            check_byte_count(byte(frame, REPLY_BYTE_COUNT_AT).unwrap_or(0), 0, &[])?;
            return Ok(&[]);
        }
        match self.function {
            Function::Read => {
                let count = byte(frame, REPLY_BYTE_COUNT_AT).unwrap_or(0);
                if !self.accepts_byte_count(count) {
                    let expected = u8::try_from(self.data_len()).unwrap_or(u8::MAX);
                    return Err(FrameError::ByteCount { expected, actual: count });
                }
                Ok(frame.get(3..3 + self.response_data_len()).unwrap_or(&[]))
            }
            Function::Write => {
                check_echo(frame, EchoField::Address, 2, self.address)?;
                check_echo(frame, EchoField::Count, 4, self.count)?;
                Ok(&[])
            }
        }
    }
}

/// Writes an exception reply (`slave`, `function | 0x80`, `code`, CRC) to `out`.
pub fn encode_exception(slave: u8, function: u8, code: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
    let out = out.get_mut(..EXCEPTION_LEN).ok_or(EncodeError::BufferTooSmall { needed: EXCEPTION_LEN })?;
    let mut w = Writer::new(out);
    w.byte(slave);
    w.byte(function | EXCEPTION_BIT);
    w.byte(code);
    w.crc();
    Ok(EXCEPTION_LEN)
}

/// The total length of a reply to `function`, known from its first `head`
/// bytes (at least two): an exception reply is 5 bytes, a normal reply
/// `normal_len`. Used by readers that must decide how much more to read.
pub fn reply_len(head: &[u8], function: u8, normal_len: usize) -> Option<usize> {
    match head.get(1) {
        Some(&f) if f == function | EXCEPTION_BIT => Some(EXCEPTION_LEN),
        Some(_) => Some(normal_len),
        None => None,
    }
}

/// Checks the register data an encoder was given and the frame length it makes.
#[inline(always)]
fn check_data_len(data: &[u8], expected: usize, frame_len: usize) -> Result<(), EncodeError> {
    if data.len() != expected {
        Err(EncodeError::DataLength { expected, actual: data.len() })
    } else if frame_len > MAX_ADU {
        Err(EncodeError::FrameTooLong { len: frame_len })
    } else {
        Ok(())
    }
}

#[inline]
fn check_len(frame: &[u8], expected: usize) -> Result<(), FrameError> {
    let actual = frame.len();
    if actual < expected {
        Err(FrameError::Truncated { expected, actual })
    } else if actual > expected {
        Err(FrameError::TooLong { expected, actual })
    } else {
        Ok(())
    }
}

/// The CRC computed once: the error reports the value the check compared.
#[inline]
fn check_crc(frame: &[u8]) -> Result<(), FrameError> {
    let n = frame.len().saturating_sub(2);
    let computed = crc16(frame.get(..n).unwrap_or(&[]));
    let received = word(frame, n).map_or(0, u16::swap_bytes);
    if frame.len() >= 2 && computed == received { Ok(()) } else { Err(FrameError::Crc { received, computed }) }
}

#[inline]
fn check_slave(frame: &[u8], expected: u8) -> Result<(), FrameError> {
    let actual = byte(frame, 0).unwrap_or(0);
    if actual == expected { Ok(()) } else { Err(FrameError::WrongSlave { expected, actual }) }
}

#[inline]
fn check_function(frame: &[u8], expected: u8) -> Result<(), FrameError> {
    let actual = byte(frame, 1).unwrap_or(0);
    if actual == expected { Ok(()) } else { Err(FrameError::WrongFunction { expected, actual }) }
}

#[inline]
fn check_echo(frame: &[u8], field: EchoField, at: usize, expected: u16) -> Result<(), FrameError> {
    let actual = word(frame, at).unwrap_or(0);
    if actual == expected { Ok(()) } else { Err(FrameError::EchoMismatch { field, expected, actual }) }
}

#[inline]
fn check_byte_count(actual: u8, data_len: usize, extra: &[u8]) -> Result<(), FrameError> {
    if usize::from(actual) == data_len || extra.contains(&actual) {
        Ok(())
    } else {
        Err(FrameError::ByteCount { expected: u8::try_from(data_len).unwrap_or(u8::MAX), actual })
    }
}

/// A cursor over a buffer whose length the caller has already checked.
struct Writer<'b> {
    out: &'b mut [u8],
    at: usize,
}

impl<'b> Writer<'b> {
    #[inline]
    fn new(out: &'b mut [u8]) -> Self {
        Self { out, at: 0 }
    }

    #[inline]
    fn byte(&mut self, b: u8) {
        if let Some(slot) = self.out.get_mut(self.at) {
            *slot = b;
        }
        self.at += 1;
    }

    #[inline]
    fn word(&mut self, w: u16) {
        self.bytes(&w.to_be_bytes());
    }

    #[inline]
    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.byte(b);
        }
    }

    #[inline]
    fn crc(&mut self) {
        let crc = crc16(self.out.get(..self.at).unwrap_or(&[]));
        self.bytes(&crc.to_le_bytes());
    }
}

/// An encoded frame on the stack.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Frame {
    bytes: [u8; MAX_ADU],
    len: usize,
}

impl Frame {
    /// An empty frame to encode into with [`Frame::fill`].
    pub const fn empty() -> Self {
        Self { bytes: [0; MAX_ADU], len: 0 }
    }

    /// Encodes with `encode` (which writes into a buffer and returns the length).
    pub fn fill<E>(encode: impl FnOnce(&mut [u8]) -> Result<usize, E>) -> Result<Self, E> {
        let mut frame = Self::empty();
        frame.len = encode(&mut frame.bytes)?.min(MAX_ADU);
        Ok(frame)
    }

    /// The frame's bytes, CRC included (at most `MAX_ADU`).
    pub fn as_bytes(&self) -> &[u8] {
        self.bytes.get(..self.len).unwrap_or(&[])
    }
}

impl Deref for Frame {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        self.as_bytes()
    }
}

impl core::fmt::Debug for Frame {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "Frame({})", crate::Hex(self.as_bytes()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ExceptionCode;

    const READ_FLOAT: Layout<'static> = Layout::read(0x2800, 2);
    const START: Layout<'static> = Layout { trigger: true, ..Layout::write(0x1C00, 0) };

    #[test]
    fn encodes_manual_requests() {
        let f = Frame::fill(|b| READ_FLOAT.encode_request(1, &[], b)).unwrap();
        assert_eq!(f.as_bytes(), [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB]);
        // Conductivity Fig 23: zero-register write with byte count 0.
        let f = Frame::fill(|b| START.encode_request(1, &[], b)).unwrap();
        assert_eq!(f.as_bytes(), [0x01, 0x10, 0x1C, 0x00, 0x00, 0x00, 0x00, 0xD8, 0x92]);
        let f = Frame::fill(|b| START.encode_response(1, &[], b)).unwrap();
        assert_eq!(f.as_bytes(), [0x01, 0x10, 0x1C, 0x00, 0x00, 0x00, 0xC7, 0x99]);
    }

    const START_OPTICAL: Layout<'static> = Layout { trigger: true, ..Layout::read(0x2500, 1) };

    #[test]
    fn trigger_reads_accept_each_form_the_manuals_allow_and_return_no_data() {
        let request = Frame::fill(|b| START_OPTICAL.encode_request(1, &[], b)).unwrap();
        assert_eq!(request.as_bytes(), [0x01, 0x03, 0x25, 0x00, 0x00, 0x01, 0x8F, 0x06]);
        let manual_form = Frame::fill(|b| START_OPTICAL.encode_response(1, &[], b)).unwrap();
        assert_eq!(&manual_form[..5], [0x01, 0x03, 0x00, 0x00, 0x00]);
        assert_eq!(START_OPTICAL.decode_response(1, &manual_form), Ok(&[][..]));
        let mut short = [0x01, 0x03, 0x00, 0, 0];
        let crc = crate::crc16(&short[..3]).to_le_bytes();
        short[3..].copy_from_slice(&crc);
        assert_eq!(START_OPTICAL.short_response_len(), Some(5));
        assert_eq!(START_OPTICAL.decode_response(1, &short), Ok(&[][..]));
        let mut standard = [0x01, 0x03, 0x02, 0xAB, 0xCD, 0, 0];
        let crc = crate::crc16(&standard[..5]).to_le_bytes();
        standard[5..].copy_from_slice(&crc);
        assert_eq!(START_OPTICAL.decode_response(1, &standard), Ok(&[][..]));
        // Still a checked frame: slave, CRC and byte count.
        assert!(matches!(START_OPTICAL.decode_response(2, &short), Err(FrameError::WrongSlave { .. })));
        let mut bad_count = standard;
        bad_count[2] = 0x04;
        let crc = crate::crc16(&bad_count[..5]).to_le_bytes();
        bad_count[5..].copy_from_slice(&crc);
        assert!(matches!(START_OPTICAL.decode_response(1, &bad_count), Err(FrameError::ByteCount { .. })));
        let mut short_bad_crc = short;
        short_bad_crc[4] ^= 1;
        assert!(matches!(START_OPTICAL.decode_response(1, &short_bad_crc), Err(FrameError::Crc { .. })));
        assert_eq!(READ_FLOAT.short_response_len(), None);
    }

    #[test]
    fn decodes_and_rejects_replies() {
        let ok = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];
        assert_eq!(READ_FLOAT.decode_response(1, &ok), Ok(&ok[3..7]));
        assert_eq!(READ_FLOAT.decode_response(2, &ok), Err(FrameError::WrongSlave { expected: 2, actual: 1 }));
        assert!(matches!(
            READ_FLOAT.decode_response(1, &ok[..8]),
            Err(FrameError::Truncated { expected: 9, actual: 8 })
        ));
        let mut bad = ok;
        bad[4] ^= 1;
        assert!(matches!(READ_FLOAT.decode_response(1, &bad), Err(FrameError::Crc { .. })));
        let mut exc = [0x01, 0x83, 0x02, 0, 0];
        let crc = crc16(&exc[..3]).to_le_bytes();
        exc[3..].copy_from_slice(&crc);
        assert_eq!(
            READ_FLOAT.decode_response(1, &exc),
            Err(FrameError::Exception { function: 0x03, code: ExceptionCode::IllegalDataAddress })
        );
    }

    #[test]
    fn each_encoding_failure_has_its_own_error() {
        let write = Layout { function: Function::Write, count: 2, ..START };
        let mut out = [0u8; MAX_ADU];
        assert_eq!(write.encode_request(1, &[1, 2], &mut out), Err(EncodeError::DataLength { expected: 4, actual: 2 }));
        assert_eq!(
            READ_FLOAT.encode_response(1, &[], &mut out),
            Err(EncodeError::DataLength { expected: 4, actual: 0 })
        );
        assert_eq!(READ_FLOAT.encode_request(1, &[], &mut out[..4]), Err(EncodeError::BufferTooSmall { needed: 8 }));
        let huge = Layout { count: 200, ..READ_FLOAT };
        assert_eq!(huge.encode_response(1, &[0; 400], &mut out), Err(EncodeError::FrameTooLong { len: 405 }));
    }

    #[test]
    fn slave_rules() {
        assert!(READ_FLOAT.check_slave(0).is_err(), "reads cannot broadcast");
        assert!(READ_FLOAT.check_slave(248).is_err());
        assert!(START.check_slave(0).is_ok());
        let fixed = Layout { fixed_slave: Some(0xFF), ..READ_FLOAT };
        assert!(fixed.check_slave(1).is_err());
        assert!(fixed.check_slave(0xFF).is_ok());
    }

    proptest::proptest! {
        #[test]
        fn decoding_noise_never_panics(frame in proptest::collection::vec(proptest::num::u8::ANY, 0..300), slave in 0u8..=255) {
            let _ = READ_FLOAT.decode_response(slave, &frame);
            let _ = START.decode_response(slave, &frame);
            let _ = READ_FLOAT.decode_request(&frame);
            let _ = START.decode_request(&frame);
        }
    }
}

//! Splitting bytes into RTU frames without knowing the commands: a capture
//! to explain, a server's input, a fuzzer's bytes.
//!
//! An RTU frame has no delimiter but silence, which a capture or a socket
//! loses; what is left is the function code, the length rules of
//! [`Function::request_len`] and [`Function::response_len`] (the ones
//! [`Layout`](crate::Layout) frames by), and the CRC. At each position the
//! segmenter lists the lengths a frame starting there may have, in order of
//! preference, and takes the first whose CRC holds:
//!
//! - 0x03: a request of 8 bytes and a reply of `5 + byte count`, shorter
//!   first (a longer reading would swallow the start of the next frame). A
//!   read frame of 8 bytes with byte count 3 is both, bit for bit:
//!   [`SpanKind::RequestOrReply`]. Then, as the manuals print them, replies
//!   whose byte count is not their data's (a trigger's count 0 before
//!   "meaningless" registers, a misprinted count): `5 + 2n` bytes, shortest
//!   first.
//! - 0x10: a reply of 8 bytes, then a request of `9 + byte count`, then of
//!   `9 + 2 * register count` (a byte count the request gets wrong).
//! - an exception (function code with 0x80 set): 5 bytes.
//!
//! Bytes where no frame starts are noise, one span per run. When the bytes
//! end before every length a frame there may have could be checked,
//! [`next_span`] answers [`Incomplete`]: a streaming caller reads more and
//! asks again, and gets the spans it would have got from all the bytes at
//! once. At the end of the input ([`next_span_at_end`], [`spans`]) a frame
//! cut short is noise.
//!
//! `no_std`, no allocation, and no panic: every read of the input is
//! checked.

use core::ops::Range;

use crate::bytes::{byte, word};
use crate::crc::{CRC_INIT, crc16_update};
use crate::frame::{EXCEPTION_BIT, EXCEPTION_LEN, Function, MAX_ADU, REPLY_BYTE_COUNT_AT, REQUEST_BYTE_COUNT_AT};

/// What a span of bytes is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SpanKind {
    /// A request (0x03 or 0x10) with a valid CRC.
    Request,
    /// A normal reply (0x03 or 0x10) with a valid CRC.
    Reply,
    /// An exception reply (function code with 0x80 set), 5 bytes, valid CRC.
    Exception,
    /// A read frame that is a whole, valid request and a whole, valid reply
    /// alike: 8 bytes of 0x03 whose third byte (register address high, or
    /// byte count) is 3. Only the exchange it is part of tells which.
    RequestOrReply,
    /// Bytes where no frame starts.
    Noise,
}

impl SpanKind {
    /// Whether the span is a frame (anything but noise).
    pub const fn is_frame(self) -> bool {
        !matches!(self, Self::Noise)
    }
}

/// A run of bytes and what it is: `start..end` of the bytes it was found in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Span {
    /// What the bytes are.
    pub kind: SpanKind,
    /// The first byte's index.
    pub start: usize,
    /// One past the last byte's index.
    pub end: usize,
}

impl Span {
    /// The span's bytes as a range of the input.
    pub const fn range(&self) -> Range<usize> {
        self.start..self.end
    }

    /// Bytes in the span.
    pub const fn len(&self) -> usize {
        self.end.saturating_sub(self.start)
    }

    /// True for a span of no bytes (the segmenter makes none).
    pub const fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The span's bytes, out of the input it was found in.
    pub fn bytes<'b>(&self, input: &'b [u8]) -> &'b [u8] {
        input.get(self.range()).unwrap_or(&[])
    }

    const fn shifted(self, by: usize) -> Self {
        Self { kind: self.kind, start: self.start + by, end: self.end + by }
    }
}

/// More bytes are needed before the next span can be told: the input ends
/// where a frame may still be arriving.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Incomplete;

impl core::fmt::Display for Incomplete {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("the bytes end where a frame may still be arriving")
    }
}

/// The first span of `bytes`, for a caller that may get more bytes: a frame
/// starting at index 0, or the noise before the first frame. [`Incomplete`]
/// when the bytes end before that can be told (and for no bytes).
pub fn next_span(bytes: &[u8]) -> Result<Span, Incomplete> {
    match first_span(bytes, false) {
        Ok(Some(span)) => Ok(span),
        Ok(None) | Err(Incomplete) => Err(Incomplete),
    }
}

/// The first span of `bytes` when no more bytes will come: a frame cut
/// short is noise. `None` for no bytes.
pub fn next_span_at_end(bytes: &[u8]) -> Option<Span> {
    first_span(bytes, true).ok().flatten()
}

/// Every span of `bytes`, a whole input (no more bytes will come): they
/// follow each other and cover it exactly.
pub fn spans(bytes: &[u8]) -> Spans<'_> {
    Spans { bytes, at: 0 }
}

/// The spans of a whole input, in order: see [`spans`].
#[derive(Debug, Clone)]
pub struct Spans<'b> {
    bytes: &'b [u8],
    at: usize,
}

impl Iterator for Spans<'_> {
    type Item = Span;

    fn next(&mut self) -> Option<Span> {
        let span = next_span_at_end(self.bytes.get(self.at..)?)?.shifted(self.at);
        self.at = span.end;
        Some(span)
    }
}

/// The bytes of a request's head a server must have before
/// [`request_len`] can answer: 2 for a read, 7 for a write. `None` before
/// the function code is in, and for a function the probes do not serve
/// (its length is not known from its head).
pub fn request_head_len(head: &[u8]) -> Option<usize> {
    Function::from_code(byte(head, 1)?).map(Function::request_head_len)
}

/// The length of the request whose head is `head`, for a server reading a
/// request: `None` until [`request_head_len`] bytes are in, and for a
/// function the probes do not serve.
pub fn request_len(head: &[u8]) -> Option<usize> {
    match Function::from_code(byte(head, 1)?)? {
        Function::Read => Some(Function::Read.request_len(0)),
        Function::Write => Some(Function::Write.request_len(usize::from(byte(head, REQUEST_BYTE_COUNT_AT)?))),
    }
}

/// The first span, or `Err` when the bytes end too soon to tell (never at
/// the `end` of the input); `Ok(None)` for no bytes.
fn first_span(bytes: &[u8], end: bool) -> Result<Option<Span>, Incomplete> {
    let mut at = 0;
    loop {
        let Some(rest) = bytes.get(at..).filter(|rest| !rest.is_empty()) else {
            // Only the end of the input ends noise without a frame.
            return Ok((at > 0).then_some(Span { kind: SpanKind::Noise, start: 0, end: at }));
        };
        match frame_at(rest, end)? {
            Some((kind, len)) if at == 0 => return Ok(Some(Span { kind, start: 0, end: len })),
            Some(_) => return Ok(Some(Span { kind: SpanKind::Noise, start: 0, end: at })),
            None => at += 1,
        }
    }
}

/// The lengths a frame at the start of some bytes may have, checked in
/// turn against the CRC.
struct Candidates<'b> {
    rest: &'b [u8],
    /// No more bytes will come: a length beyond them is no frame.
    end: bool,
}

impl Candidates<'_> {
    /// Whether the first `len` bytes are a frame: `Err` when they are not
    /// all in yet.
    fn holds(&self, len: usize) -> Result<bool, Incomplete> {
        if !(EXCEPTION_LEN..=MAX_ADU).contains(&len) {
            return Ok(false);
        }
        match self.rest.get(..len) {
            Some(frame) => Ok(crate::crc_ok(frame)),
            None if self.end => Ok(false),
            None => Err(Incomplete),
        }
    }

    /// A byte of the head, or `Err` while it may still come.
    fn head_byte(&self, at: usize) -> Result<Option<u8>, Incomplete> {
        match byte(self.rest, at) {
            Some(b) => Ok(Some(b)),
            None if self.end => Ok(None),
            None => Err(Incomplete),
        }
    }

    /// The first of `lens` (in order) that holds.
    fn first(&self, lens: &[(SpanKind, Option<usize>)]) -> Result<Option<(SpanKind, usize)>, Incomplete> {
        for &(kind, len) in lens {
            if let Some(len) = len
                && self.holds(len)?
            {
                return Ok(Some((kind, len)));
            }
        }
        Ok(None)
    }

    /// The shortest read reply of `5 + 2n` bytes that holds, other than
    /// `skip` (already tried): the CRC runs once over the bytes, checked at
    /// each even data length.
    fn read_reply_by_crc(&self, skip: Option<usize>) -> Result<Option<usize>, Incomplete> {
        let head = REPLY_BYTE_COUNT_AT + 1;
        let Some(first) = self.rest.get(..head) else { return if self.end { Ok(None) } else { Err(Incomplete) } };
        let mut crc = crc16_update(CRC_INIT, first);
        let mut body = head;
        while Function::Read.response_len(body - head) <= MAX_ADU {
            let len = body + 2;
            match word(self.rest, body) {
                Some(carried) if Some(len) != skip && carried.swap_bytes() == crc => return Ok(Some(len)),
                Some(_) => {}
                None if self.end => return Ok(None),
                None => return Err(Incomplete),
            }
            let Some(data) = self.rest.get(body..body + 2) else { return Ok(None) };
            crc = crc16_update(crc, data);
            body += 2;
        }
        Ok(None)
    }
}

/// The frame starting at the first byte of `rest`, its kind and length;
/// `Ok(None)` where none starts, `Err` while the bytes that would tell may
/// still come.
fn frame_at(rest: &[u8], end: bool) -> Result<Option<(SpanKind, usize)>, Incomplete> {
    let c = Candidates { rest, end };
    let Some(code) = c.head_byte(1)? else { return Ok(None) };
    if code & EXCEPTION_BIT != 0 {
        return Ok(c.holds(EXCEPTION_LEN)?.then_some((SpanKind::Exception, EXCEPTION_LEN)));
    }
    match Function::from_code(code) {
        Some(Function::Read) => {
            let request = Function::Read.request_len(0);
            let reply = c.head_byte(REPLY_BYTE_COUNT_AT)?.map(|n| Function::Read.response_len(usize::from(n)));
            if reply == Some(request) {
                if c.holds(request)? {
                    return Ok(Some((SpanKind::RequestOrReply, request)));
                }
            } else {
                let (request, reply) = ((SpanKind::Request, Some(request)), (SpanKind::Reply, reply));
                let shorter_first = if reply.1 < request.1 { [reply, request] } else { [request, reply] };
                if let Some(found) = c.first(&shorter_first)? {
                    return Ok(Some(found));
                }
            }
            Ok(c.read_reply_by_crc(reply)?.map(|len| (SpanKind::Reply, len)))
        }
        Some(Function::Write) => {
            let reply = Function::Write.response_len(0);
            let by_count = c.head_byte(REQUEST_BYTE_COUNT_AT)?.map(|n| Function::Write.request_len(usize::from(n)));
            let by_registers = match word(rest, 4) {
                Some(count) => Some(Function::Write.request_len(2 * usize::from(count))),
                None if end => None,
                None => return Err(Incomplete),
            };
            c.first(&[
                (SpanKind::Reply, Some(reply)),
                (SpanKind::Request, by_count),
                (SpanKind::Request, by_registers.filter(|&len| Some(len) != by_count)),
            ])
        }
        None => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crc16;

    /// `body` with its CRC.
    fn framed(body: &[u8]) -> ([u8; MAX_ADU], usize) {
        let mut out = [0u8; MAX_ADU];
        let len = body.len() + 2;
        out[..body.len()].copy_from_slice(body);
        out[body.len()..len].copy_from_slice(&crc16(body).to_le_bytes());
        (out, len)
    }

    const READ: [u8; 8] = [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB];
    const REPLY: [u8; 9] = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];
    const TRIGGER: [u8; 9] = [0x01, 0x10, 0x1C, 0x00, 0x00, 0x00, 0x00, 0xD8, 0x92];
    const TRIGGER_REPLY: [u8; 8] = [0x01, 0x10, 0x1C, 0x00, 0x00, 0x00, 0xC7, 0x99];

    fn kinds(bytes: &[u8]) -> ([(SpanKind, usize, usize); 8], usize) {
        let mut out = [(SpanKind::Noise, 0, 0); 8];
        let mut n = 0;
        for span in spans(bytes) {
            if let Some(slot) = out.get_mut(n) {
                *slot = (span.kind, span.start, span.end);
            }
            n += 1;
        }
        (out, n)
    }

    #[test]
    fn a_request_and_its_reply_are_two_spans() {
        let mut stream = [0u8; 17];
        stream[..8].copy_from_slice(&READ);
        stream[8..].copy_from_slice(&REPLY);
        let (found, n) = kinds(&stream);
        assert_eq!(&found[..n], [(SpanKind::Request, 0, 8), (SpanKind::Reply, 8, 17)]);
        let mut stream = [0u8; 17];
        stream[..9].copy_from_slice(&TRIGGER);
        stream[9..].copy_from_slice(&TRIGGER_REPLY);
        let (found, n) = kinds(&stream);
        assert_eq!(&found[..n], [(SpanKind::Request, 0, 9), (SpanKind::Reply, 9, 17)]);
    }

    #[test]
    fn an_exception_is_five_bytes() {
        let (exception, len) = framed(&[0x01, 0x83, 0x02]);
        assert_eq!(len, 5);
        assert_eq!(next_span(&exception[..5]), Ok(Span { kind: SpanKind::Exception, start: 0, end: 5 }));
        assert_eq!(next_span(&exception[..4]), Err(Incomplete));
    }

    #[test]
    fn noise_is_one_span_up_to_the_frame() {
        let mut stream = [0u8; 11];
        stream[..3].copy_from_slice(&[0xAA, 0x55, 0x00]);
        stream[3..].copy_from_slice(&READ);
        let (found, n) = kinds(&stream);
        assert_eq!(&found[..n], [(SpanKind::Noise, 0, 3), (SpanKind::Request, 3, 11)]);
        // Noise ends only where a frame starts: more bytes may be one.
        assert_eq!(next_span(&stream[..5]), Err(Incomplete));
        assert_eq!(next_span(&stream), Ok(Span { kind: SpanKind::Noise, start: 0, end: 3 }));
    }

    #[test]
    fn a_frame_cut_short_is_incomplete_then_noise_at_the_end() {
        for cut in 1..READ.len() {
            assert_eq!(next_span(&READ[..cut]), Err(Incomplete), "{cut} bytes");
            assert_eq!(next_span_at_end(&READ[..cut]), Some(Span { kind: SpanKind::Noise, start: 0, end: cut }));
        }
        assert_eq!(next_span(&[]), Err(Incomplete));
        assert_eq!(next_span_at_end(&[]), None);
    }

    #[test]
    fn a_read_frame_of_eight_bytes_with_count_three_is_either() {
        let (frame, len) = framed(&[0x01, 0x03, 0x03, 0x00, 0x00, 0x01]);
        assert_eq!(len, 8);
        assert_eq!(next_span(&frame[..8]), Ok(Span { kind: SpanKind::RequestOrReply, start: 0, end: 8 }));
    }

    #[test]
    fn replies_whose_byte_count_is_not_their_length_frame_by_crc() {
        // A trigger read's reply: byte count 0, then two "meaningless" bytes.
        // Seven bytes may still be the start of a read request of eight.
        let (trigger, len) = framed(&[0x01, 0x03, 0x00, 0x00, 0x00]);
        assert_eq!(next_span(&trigger[..len]), Err(Incomplete));
        assert_eq!(next_span_at_end(&trigger[..len]), Some(Span { kind: SpanKind::Reply, start: 0, end: 7 }));
        // A byte count in registers over 4 data bytes.
        let (misprinted, len) = framed(&[0x01, 0x03, 0x02, 0x41, 0x20, 0x00, 0x00]);
        assert_eq!(next_span(&misprinted[..len]), Ok(Span { kind: SpanKind::Reply, start: 0, end: 9 }));
        // A write whose byte count is wrong frames by its register count.
        let (write, len) = framed(&[0x01, 0x10, 0x23, 0x00, 0x00, 0x01, 0x04, 0x12, 0x34]);
        assert_eq!(next_span(&write[..len]), Err(Incomplete), "the byte count announces 13 bytes");
        assert_eq!(next_span_at_end(&write[..len]), Some(Span { kind: SpanKind::Request, start: 0, end: 11 }));
    }

    #[test]
    fn a_damaged_frame_is_noise() {
        let mut damaged = READ;
        damaged[4] ^= 0x01;
        let (found, n) = kinds(&damaged);
        assert_eq!(&found[..n], [(SpanKind::Noise, 0, 8)]);
    }

    #[test]
    fn a_server_knows_a_request_s_length_from_its_head() {
        assert_eq!(request_head_len(&READ[..1]), None);
        assert_eq!(request_head_len(&READ[..2]), Some(2));
        assert_eq!(request_len(&READ[..2]), Some(8));
        assert_eq!(request_head_len(&TRIGGER[..2]), Some(7));
        assert_eq!(request_len(&TRIGGER[..6]), None, "the byte count is not in yet");
        assert_eq!(request_len(&TRIGGER[..7]), Some(9));
        let write_head = [0x01, 0x10, 0x23, 0x00, 0x00, 0x02, 0x04];
        assert_eq!(request_len(&write_head), Some(13));
        assert_eq!(request_len(&[0x01, 0x2B, 0x0E]), None, "a function the probes do not serve");
        assert_eq!(request_head_len(&[0x01, 0x2B]), None);
    }

    #[test]
    fn every_split_gives_the_spans_of_the_whole() {
        let mut stream = [0u8; 38];
        stream[..2].copy_from_slice(&[0xAA, 0x55]);
        stream[2..10].copy_from_slice(&READ);
        stream[10..19].copy_from_slice(&REPLY);
        stream[19..28].copy_from_slice(&TRIGGER);
        stream[28..36].copy_from_slice(&TRIGGER_REPLY);
        stream[36..].copy_from_slice(&[0x01, 0x03]);
        let (whole, n) = kinds(&stream);
        assert_eq!(n, 6);
        for chunk in 1..=stream.len() {
            // Fed `chunk` bytes at a time; spans taken as soon as they are told.
            let (mut have, mut done, mut seen) = (0, 0, 0);
            while have < stream.len() {
                have = (have + chunk).min(stream.len());
                while let Ok(span) = next_span(&stream[done..have]) {
                    let span = span.shifted(done);
                    assert_eq!((span.kind, span.start, span.end), whole[seen], "chunks of {chunk}");
                    done = span.end;
                    seen += 1;
                }
            }
            for span in spans(&stream[done..]) {
                let span = span.shifted(done);
                assert_eq!((span.kind, span.start, span.end), whole[seen], "chunks of {chunk}, at the end");
                seen += 1;
            }
            assert_eq!(seen, n, "chunks of {chunk}");
        }
    }

    proptest::proptest! {
        #[test]
        fn spans_cover_any_bytes_exactly(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..600)) {
            let mut at = 0;
            for span in spans(&bytes) {
                proptest::prop_assert_eq!(span.start, at);
                proptest::prop_assert!(span.end > span.start);
                if span.kind.is_frame() {
                    proptest::prop_assert!(crate::crc_ok(span.bytes(&bytes)));
                }
                at = span.end;
            }
            proptest::prop_assert_eq!(at, bytes.len());
        }
    }
}

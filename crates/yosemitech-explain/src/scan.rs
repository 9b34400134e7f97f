//! Splitting bytes into frames and pairing each request with its reply.

use yosemitech_rtu::bytes::{byte, word};
use yosemitech_rtu::frame::{EXCEPTION_BIT, EXCEPTION_LEN, MAX_SLAVE, REQUEST_BYTE_COUNT_AT};
use yosemitech_rtu::segment::{self, SpanKind};
use yosemitech_rtu::{Function, Layout, crc_ok};

use super::candidates::{Candidate, fits_slave, reply_lens};

/// One capture line: its number, its text, and the byte strings it may hold
/// (with and without leading label words), best guess first.
pub struct Line<'t> {
    /// Counted from 1.
    pub number: usize,
    /// Trimmed.
    pub text: &'t str,
    /// The bytes it may hold, best guess first.
    pub readings: Vec<Vec<u8>>,
    /// Why it is not hex, if it is not.
    pub problem: Option<String>,
}

/// Maps offsets in all the bytes to capture lines.
#[derive(Default)]
pub(crate) struct LineMap {
    /// (offset of the line's first byte, line number), by offset.
    pub(crate) starts: Vec<(usize, usize)>,
}

impl LineMap {
    pub(crate) fn line(&self, offset: usize) -> usize {
        let after = self.starts.partition_point(|&(start, _)| start <= offset);
        after.checked_sub(1).and_then(|i| self.starts.get(i)).map_or(0, |&(_, line)| line)
    }
}

/// What a request asks: its header.
#[derive(Debug, Clone, Copy)]
pub struct Header {
    /// The slave addressed.
    pub slave: u8,
    /// The function code.
    pub function: u8,
    /// The first register.
    pub address: u16,
    /// Registers.
    pub count: u16,
}

/// Where bytes are: the capture line of the first byte (0 for arguments) and
/// its offset in all the bytes read.
#[derive(Debug, Clone, Copy, Default)]
pub struct Place {
    /// Counted from 1; 0 for bytes not from a capture.
    pub line: usize,
    /// Bytes before it.
    pub offset: usize,
}

/// Bytes and where they were.
#[derive(Debug, Clone)]
pub struct Framed {
    /// The bytes.
    pub bytes: Vec<u8>,
    /// Where they start.
    pub place: Place,
}

/// A request waiting for its reply.
#[derive(Clone)]
struct Pending<'c> {
    request: Framed,
    header: Header,
    /// Every loaded command the request fits (before --sensor/--command).
    cands: Vec<Candidate<'c>>,
}

/// What the scanner found, in input order.
#[derive(Clone)]
pub enum Found<'c> {
    /// A request, with its reply if one followed (`intact` false: the reply
    /// is cut short or its CRC is wrong).
    #[allow(missing_docs)]
    Pair { request: Framed, header: Header, cands: Vec<Candidate<'c>>, reply: Option<Framed>, intact: bool },
    /// A reply (or exception) with no request before it.
    Lone(Framed),
    /// Bytes that are no frame.
    Noise(Framed),
    /// A capture line that is not hex.
    #[allow(missing_docs)]
    Unreadable { place: Place, text: String, problem: String },
}

impl Found<'_> {
    /// Where it starts.
    pub fn place(&self) -> Place {
        match self {
            Found::Pair { request, .. } => request.place,
            Found::Lone(f) | Found::Noise(f) => f.place,
            Found::Unreadable { place, .. } => *place,
        }
    }

    /// Frames in it.
    pub fn frames(&self) -> usize {
        match self {
            Found::Pair { reply, .. } => 1 + usize::from(reply.is_some()),
            Found::Lone(_) => 1,
            _ => 0,
        }
    }

    /// Bytes in whole, CRC-valid frames.
    pub fn frame_bytes(&self) -> usize {
        match self {
            Found::Pair { request, reply, intact, .. } => {
                request.bytes.len() + reply.as_ref().filter(|_| *intact).map_or(0, |r| r.bytes.len())
            }
            Found::Lone(f) => f.bytes.len(),
            _ => 0,
        }
    }

    /// Bytes in no frame, or in a damaged one.
    pub fn noise_bytes(&self) -> usize {
        match self {
            Found::Noise(f) => f.bytes.len(),
            Found::Pair { reply: Some(r), intact: false, .. } => r.bytes.len(),
            _ => 0,
        }
    }
}

/// Bytes in whole, CRC-valid frames of all `found`.
pub fn frame_bytes(found: &[Found<'_>]) -> usize {
    found.iter().map(Found::frame_bytes).sum()
}

/// Splits bytes into frames and pairs requests with replies.
pub struct Scanner<'a, 'c> {
    /// Every command of every loaded sensor: framing does not depend on --sensor/--command.
    all: &'a [Candidate<'c>],
    pending: Option<Pending<'c>>,
    noise: Option<Framed>,
    found: Vec<Found<'c>>,
}

impl<'a, 'c> Scanner<'a, 'c> {
    /// A scanner framing by `all`, with no request pending.
    pub fn new(all: &'a [Candidate<'c>]) -> Self {
        Self { all, pending: None, noise: None, found: Vec::new() }
    }

    /// A fresh scanner that continues from this one's pending request.
    fn trial(&self) -> Self {
        Self { all: self.all, pending: self.pending.clone(), noise: None, found: Vec::new() }
    }

    /// All of `bytes`, as one stream.
    pub fn scan_stream(&self, bytes: &[u8]) -> Vec<Found<'c>> {
        let mut scanner = self.trial();
        scanner.feed(bytes, 0, &LineMap::default());
        scanner.finish()
    }

    /// A capture read one frame (or a few) per line: frames do not span lines.
    /// Of a line's readings, the one that is most frames wins.
    pub fn scan_lines(&self, lines: &[Line<'_>]) -> Vec<Found<'c>> {
        let mut scanner = self.trial();
        let mut offset = 0;
        for line in lines {
            let chosen = match line.readings.as_slice() {
                [] => None,
                [only] => Some(only),
                several => {
                    // Bytes in frames and bytes that are not, of a reading.
                    let score = |bytes: &Vec<u8>| {
                        let mut trial = scanner.trial();
                        trial.feed(bytes, 0, &LineMap::default());
                        let noise: usize = trial.found.iter().map(Found::noise_bytes).sum();
                        (bytes.len().saturating_sub(noise), noise)
                    };
                    let scored: Vec<(usize, usize)> = several.iter().map(score).collect();
                    let best = scored.iter().map(|&(frames, _)| frames).max().unwrap_or(0);
                    if best == 0 {
                        several.first()
                    } else {
                        // Most frame bytes, then least noise, then the longest reading.
                        scored
                            .iter()
                            .enumerate()
                            .filter(|(_, (frames, _))| *frames == best)
                            .min_by_key(|(_, (_, noise))| *noise)
                            .and_then(|(i, _)| several.get(i))
                    }
                }
            };
            let place = Place { line: line.number, offset };
            match chosen {
                Some(bytes) => {
                    let map = LineMap { starts: vec![(offset, line.number)] };
                    scanner.feed(bytes, offset, &map);
                    scanner.end_noise();
                    offset += bytes.len();
                }
                None => scanner.found.push(Found::Unreadable {
                    place,
                    text: line.text.to_owned(),
                    problem: line.problem.clone().unwrap_or_else(|| "not hex".to_owned()),
                }),
            }
        }
        scanner.finish()
    }

    /// A capture read as one hex stream that may wrap over lines.
    pub fn scan_joined(&self, lines: &[Line<'_>]) -> Vec<Found<'c>> {
        let mut scanner = self.trial();
        let mut bytes = Vec::new();
        let mut map = LineMap::default();
        for line in lines {
            match line.readings.first() {
                Some(reading) => {
                    map.starts.push((bytes.len(), line.number));
                    bytes.extend_from_slice(reading);
                }
                None => scanner.found.push(Found::Unreadable {
                    place: Place { line: line.number, offset: bytes.len() },
                    text: line.text.to_owned(),
                    problem: line.problem.clone().unwrap_or_else(|| "not hex".to_owned()),
                }),
            }
        }
        scanner.feed(&bytes, 0, &map);
        scanner.finish()
    }

    /// Scans bytes that came as one burst (silence before and after, as a
    /// sniffer hears them): frames never span bursts, but a request pending
    /// from an earlier burst takes its reply from this one. Returns what is
    /// complete, in order; a request with no reply yet stays pending.
    pub fn feed_burst(&mut self, burst: &[u8], start: usize) -> Vec<Found<'c>> {
        self.feed(burst, start, &LineMap::default());
        std::mem::take(&mut self.found)
    }

    /// The request waiting for its reply, if any.
    pub fn pending_request(&self) -> Option<&Framed> {
        self.pending.as_ref().map(|p| &p.request)
    }

    /// Stops waiting for the pending request's reply: the request without one.
    pub fn give_up_pending(&mut self) -> Option<Found<'c>> {
        let Pending { request, header, cands } = self.pending.take()?;
        Some(Found::Pair { request, header, cands, reply: None, intact: true })
    }

    /// Scans one piece (a line, or the whole stream): frames never span pieces.
    fn feed(&mut self, piece: &[u8], start: usize, lines: &LineMap) {
        let mut p = 0;
        while p < piece.len() {
            let place = Place { line: lines.line(start + p), offset: start + p };
            let take = |len: usize| Framed { bytes: piece.get(p..p + len).unwrap_or(&[]).to_vec(), place };
            let to_pending = self.pending.as_ref().and_then(|pending| self.reply_at(piece, p, pending));
            if let Some((len, true)) = to_pending {
                self.pair(take(len), true);
                p += len;
                continue;
            }
            if let Some((len, header, cands)) = self.request_at(piece, p) {
                self.end_noise();
                self.close_pending();
                let request = take(len);
                if header.slave == 0 {
                    // A broadcast is never answered.
                    self.found.push(Found::Pair { request, header, cands, reply: None, intact: true });
                } else {
                    self.pending = Some(Pending { request, header, cands });
                }
                p += len;
                continue;
            }
            if let Some(len) = self.lone_reply_at(piece, p) {
                self.end_noise();
                self.close_pending();
                self.found.push(Found::Lone(take(len)));
                p += len;
                continue;
            }
            if let Some((len, false)) = to_pending {
                self.pair(take(len), false);
                p += len.max(1);
                continue;
            }
            match &mut self.noise {
                Some(noise) => noise.bytes.push(byte(piece, p).unwrap_or(0)),
                None => self.noise = Some(take(1)),
            }
            p += 1;
        }
        self.end_noise();
    }

    /// The pending request's reply.
    fn pair(&mut self, reply: Framed, intact: bool) {
        self.end_noise();
        if let Some(Pending { request, header, cands }) = self.pending.take() {
            self.found.push(Found::Pair { request, header, cands, reply: Some(reply), intact });
        }
    }

    fn end_noise(&mut self) {
        if let Some(noise) = self.noise.take() {
            self.found.push(Found::Noise(noise));
        }
    }

    /// The pending request got no reply.
    fn close_pending(&mut self) {
        if let Some(Pending { request, header, cands }) = self.pending.take() {
            self.found.push(Found::Pair { request, header, cands, reply: None, intact: true });
        }
    }

    /// Everything found, in input order.
    fn finish(mut self) -> Vec<Found<'c>> {
        self.end_noise();
        self.close_pending();
        let mut found = self.found;
        found.sort_by_key(|f| {
            let place = f.place();
            (place.offset, place.line)
        });
        found
    }

    /// A request at `p`: its length, header and the commands it fits. A
    /// well-formed request that no loaded command fits (a read of 8 bytes, a
    /// write whose byte count is twice its register count) has no candidates.
    fn request_at(&self, piece: &[u8], p: usize) -> Option<(usize, Header, Vec<Candidate<'c>>)> {
        let rest = piece.get(p..)?;
        if rest.len() < 8 {
            return None;
        }
        let header = Header {
            slave: byte(rest, 0).unwrap_or(0),
            function: byte(rest, 1).unwrap_or(0),
            address: word(rest, 2).unwrap_or(0),
            count: word(rest, 4).unwrap_or(0),
        };
        let cands: Vec<Candidate<'c>> = self
            .all
            .iter()
            .filter(|c| {
                let layout = c.command.layout();
                c.command.function.code() == header.function
                    && c.command.address == header.address
                    && c.command.count == header.count
                    && fits_slave(c.command, header.slave)
                    && rest.get(..layout.request_len()).is_some_and(|frame| layout.decode_request(frame).is_ok())
            })
            .copied()
            .collect();
        if let Some(first) = cands.first() {
            return Some((first.command.layout().request_len(), header, cands));
        }
        // A request no loaded command fits: framed by the runtime's
        // segmenter, if its header is one a probe could be sent.
        let plausible = match Function::from_code(header.function)? {
            Function::Read => (1..=125).contains(&header.count) && (1..=MAX_SLAVE).contains(&header.slave),
            Function::Write => {
                header.count <= 123
                    && header.slave <= MAX_SLAVE
                    && usize::from(byte(rest, REQUEST_BYTE_COUNT_AT)?) == 2 * usize::from(header.count)
            }
        };
        let span = segment::next_span_at_end(rest).filter(|_| plausible)?;
        matches!(span.kind, SpanKind::Request | SpanKind::RequestOrReply).then(|| (span.len(), header, Vec::new()))
    }

    /// The pending request's reply at `p`: its length, and whether it is
    /// intact. A reply with the right header but a wrong CRC or cut short is
    /// taken (not intact) where the piece ends after it or a frame follows
    /// it, unless a frame starts at `p` itself (the caller checks).
    fn reply_at(&self, piece: &[u8], p: usize, pending: &Pending<'c>) -> Option<(usize, bool)> {
        let rest = piece.get(p..)?;
        let (slave, function) = (*rest.first()?, *rest.get(1)?);
        let asked = pending.header;
        let slave_ok = if pending.cands.is_empty() {
            slave == asked.slave
        } else {
            pending.cands.iter().any(|c| c.command.layout().reply_slave(asked.slave) == slave)
        };
        if !slave_ok {
            return None;
        }
        let lens: Vec<usize> = if function == asked.function | EXCEPTION_BIT {
            vec![EXCEPTION_LEN]
        } else if function == asked.function {
            let mut lens: Vec<usize> = if pending.cands.is_empty() {
                let layout = match Function::from_code(function)? {
                    Function::Read => Layout::read(asked.address, asked.count),
                    Function::Write => Layout::write(asked.address, asked.count),
                };
                vec![layout.response_len()]
            } else {
                pending.cands.iter().flat_map(|c| reply_lens(c.command)).flatten().collect()
            };
            lens.sort_unstable_by(|a, b| b.cmp(a));
            lens.dedup();
            lens
        } else {
            return None;
        };
        if let Some(&len) = lens.iter().find(|&&len| rest.get(..len).is_some_and(crc_ok)) {
            return Some((len, true));
        }
        let full = lens.first().copied().unwrap_or(EXCEPTION_LEN);
        if rest.len() <= full {
            Some((rest.len(), false))
        } else if self.request_at(piece, p + full).is_some() || self.lone_reply_at(piece, p + full).is_some() {
            Some((full, false))
        } else {
            None
        }
    }

    /// A reply or exception at `p` with no request before it, to or from an
    /// address a probe may use, of a function the probes serve: framed by
    /// the runtime's segmenter (its CRC, and a length the byte count gives
    /// or, for the replies the manuals print with another count, the CRC).
    fn lone_reply_at(&self, piece: &[u8], p: usize) -> Option<usize> {
        let rest = piece.get(p..)?;
        let (slave, function) = (*rest.first()?, *rest.get(1)?);
        let fixed = self.all.iter().any(|c| c.command.fixed_slave == Some(slave));
        if !((1..=MAX_SLAVE).contains(&slave) || fixed) {
            return None;
        }
        Function::from_code(function & !EXCEPTION_BIT)?;
        let span = segment::next_span_at_end(rest)?;
        match span.kind {
            SpanKind::Reply | SpanKind::Exception | SpanKind::RequestOrReply => Some(span.len()),
            SpanKind::Request | SpanKind::Noise => None,
        }
    }
}

//! `yosemitech decode`: frames from a log or a bus capture, explained.
//!
//! One frame is decoded on its own: the command is found from the frame
//! ([`decode_one`]). Several frames (a request and its reply, a hex stream,
//! a `--capture` file) are split into frames by a [`Scanner`]: requests are
//! recognised by the commands' request layouts, replies by their CRC and the
//! length the pending request's command expects. Each reply is paired with
//! the request before it and decoded as the command(s) the request names;
//! decodings that fail are dropped and equal ones reported together.

use std::io::{Read as _, Write};
use std::path::Path;

use serde_json::{Value as Json, json};
use yosemitech_rtu::bytes::{byte, word};
use yosemitech_rtu::{ExceptionCode, Function, crc_ok, crc16};
use yosemitech_spec::interp::decode_fields;
use yosemitech_spec::{CommandSpec, Values};

use crate::catalog::{Catalog, Entry, closest};
use crate::cli::{DecodeArgs, DecodeCommandArgs};
use crate::error::{CliError, Kind as ErrorKind, Result};
use crate::format::{fields_json, hex, value_with_unit, values_json};

/// What a frame is, from its function code and length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    ReadRequest,
    ReadReply,
    WriteRequest,
    WriteReply,
    Exception,
    Unknown,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::ReadRequest => "read request",
            Kind::ReadReply => "read reply",
            Kind::WriteRequest => "write request",
            Kind::WriteReply => "write reply",
            Kind::Exception => "exception reply",
            Kind::Unknown => "unknown frame",
        }
    }

    fn json_name(self) -> &'static str {
        match self {
            Kind::ReadRequest => "read_request",
            Kind::ReadReply => "read_reply",
            Kind::WriteRequest => "write_request",
            Kind::WriteReply => "write_reply",
            Kind::Exception => "exception",
            Kind::Unknown => "unknown",
        }
    }

    fn is_request(self) -> bool {
        matches!(self, Kind::ReadRequest | Kind::WriteRequest)
    }

    /// Whether the frame carries field values (so the command must be known to decode it).
    fn has_values(self) -> bool {
        matches!(self, Kind::ReadReply | Kind::WriteRequest)
    }
}

/// A command that fits the frame, and the sensors that have it.
struct Candidate<'c> {
    sensors: Vec<&'c str>,
    command: &'c CommandSpec,
}

impl Candidate<'_> {
    fn label(&self) -> String {
        format!(
            "{} {} (0x{:04X}, {} register{})",
            self.sensors.join("/"),
            self.command.name,
            self.command.address,
            self.command.count,
            if self.command.count == 1 { "" } else { "s" }
        )
    }
}

/// The lengths a normal (non-exception) reply of `c` may have: the full
/// reply, and for a trigger read also the short form with byte count 0.
fn reply_lens(c: &CommandSpec) -> [Option<usize>; 2] {
    let layout = c.layout();
    [Some(layout.response_len()), layout.short_response_len()]
}

/// Whether a frame to or from `slave` may be of command `c`: a command with a
/// fixed slave address only ever uses it; any other uses 0..=247 (0 being a
/// broadcast, which only writes use).
fn fits_slave(c: &CommandSpec, slave: u8) -> bool {
    match c.fixed_slave {
        Some(fixed) => slave == fixed,
        None => slave <= 247 && (slave != 0 || !c.is_read()),
    }
}

/// The error as JSON: what `--json` prints instead of (and besides) the `error:` line.
fn error_json(e: &CliError) -> Json {
    json!({
        "message": e.message,
        "details": e.details,
        "hint": e.hint,
        "exit_code": match e.kind {
            ErrorKind::Usage => 2,
            ErrorKind::Device => 1,
            ErrorKind::Closed => 0,
        },
    })
}

fn pretty(doc: &Json) -> String {
    serde_json::to_string_pretty(doc).unwrap_or_default()
}

/// What `decode` is given: the frame arguments (all the library's
/// `decode_text` has), and on the command line possibly a capture file.
pub trait Invocation {
    /// The frames and options.
    fn frames(&self) -> &DecodeArgs;
    /// The capture file (`-`: stdin), if any.
    fn capture(&self) -> Option<&Path>;
}

impl Invocation for DecodeArgs {
    fn frames(&self) -> &DecodeArgs {
        self
    }

    fn capture(&self) -> Option<&Path> {
        None
    }
}

impl Invocation for DecodeCommandArgs {
    fn frames(&self) -> &DecodeArgs {
        &self.frames
    }

    fn capture(&self) -> Option<&Path> {
        self.capture.as_deref()
    }
}

/// Counts what is written, so that an error is printed as JSON only when no
/// JSON document went out before it.
struct Counted<'o> {
    inner: &'o mut dyn Write,
    written: usize,
}

impl Write for Counted<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.written += n;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// Runs `decode`.
pub fn run(catalog: &Catalog, args: &impl Invocation, out: &mut dyn Write) -> Result<()> {
    let frames = args.frames();
    let mut counted = Counted { inner: out, written: 0 };
    let result = dispatch(catalog, frames, args.capture(), &mut counted);
    if let Err(e) = &result
        && frames.json
        && counted.written == 0
        && e.kind != ErrorKind::Closed
    {
        writeln!(counted, "{}", pretty(&json!({ "error": error_json(e) })))?;
        counted.flush()?;
    }
    result
}

fn dispatch(catalog: &Catalog, args: &DecodeArgs, capture: Option<&Path>, out: &mut dyn Write) -> Result<()> {
    let input = match capture {
        Some(path) => Input::Capture(read_capture(path)?),
        None => Input::Bytes(parse_hex(&args.hex.join(" "))?),
    };
    let filter = Filter::new(catalog, args)?;
    let all: Vec<Cand<'_>> = catalog
        .entries()
        .iter()
        .flat_map(|e| e.sensor.commands.iter().map(|c| Cand { sensor: &e.sensor.name, command: c }))
        .collect();
    let scanner = Scanner::new(&all);
    match input {
        Input::Bytes(bytes) => {
            let found = scanner.scan_stream(&bytes);
            let frames: usize = found.iter().map(Found::frames).sum();
            let noise = found.iter().any(|f| matches!(f, Found::Noise(_)));
            let one_pair = matches!(found.as_slice(), [Found::Pair { reply: Some(_), .. }]);
            // One frame (or bytes with no frame in them) is decoded on its own, as ever.
            if !one_pair && (frames == 0 || (frames == 1 && !noise) || (bytes.len() >= 4 && crc_ok(&bytes))) {
                return decode_one(&filter, args.json, &bytes, out);
            }
            let reports: Vec<Report<'_>> = found.into_iter().map(|f| report(&filter, &all, f)).collect();
            match reports.as_slice() {
                [Report::Exchange(x)] if one_pair => print_pair(x, args.json, out),
                _ => print_reports(&reports, "stream", args.json, out),
            }
        }
        Input::Capture(text) => {
            let lines = read_lines(&text);
            if !lines.iter().any(|l| !l.readings.is_empty()) {
                let what = if lines.is_empty() {
                    "the capture holds no frames: it is empty".to_owned()
                } else {
                    format!("the capture holds no hex: {} line(s), none of them hex", lines.len())
                };
                return Err(CliError::usage(what)
                    .hint("a capture is hex text: one frame per line (`01 03 28 00 00 02 CD AB`), or one hex stream"));
            }
            // One frame per line, or one stream wrapped over lines: whichever
            // reading explains more bytes as frames (one line is a stream).
            let (found, mode) = if lines.iter().filter(|l| !l.readings.is_empty()).count() == 1 {
                (scanner.scan_joined(&lines), "stream")
            } else {
                let by_line = scanner.scan_lines(&lines);
                let as_stream = scanner.scan_joined(&lines);
                if frame_bytes(&as_stream) > frame_bytes(&by_line) { (as_stream, "stream") } else { (by_line, "lines") }
            };
            let reports: Vec<Report<'_>> = found.into_iter().map(|f| report(&filter, &all, f)).collect();
            print_reports(&reports, mode, args.json, out)
        }
    }
}

/// The bytes to decode.
enum Input {
    /// From the arguments.
    Bytes(Vec<u8>),
    /// A capture's text.
    Capture(String),
}

/// Reads a capture file, or stdin for `-`.
fn read_capture(path: &Path) -> Result<String> {
    let shown = path.display();
    let bytes = if path == Path::new("-") {
        let mut bytes = Vec::new();
        std::io::stdin().lock().read_to_end(&mut bytes).map(|_| bytes)
    } else {
        std::fs::read(path)
    }
    .map_err(|e| {
        CliError::usage(format!("cannot read the capture {shown}: {e}"))
            .hint("give a capture file (hex, one frame per line or one stream), or - to read stdin")
    })?;
    String::from_utf8(bytes).map_err(|e| {
        CliError::usage(format!("the capture {shown} is not text (byte {} is not UTF-8)", e.utf8_error().valid_up_to()))
            .hint("a capture is hex text; turn a binary capture into hex first, e.g. `xxd -p FILE`")
    })
}

/// Hex as people type it (spaces, `0x` prefixes, commas, colons, dashes or
/// semicolons between bytes), of any length: one frame or a whole stream.
fn parse_hex(text: &str) -> Result<Vec<u8>> {
    let shown: String = match text.trim() {
        t if t.chars().count() > 72 => format!("{}…", t.chars().take(72).collect::<String>()),
        t => t.to_owned(),
    };
    let bad = |why: String| {
        CliError::usage(format!("invalid frame `{shown}`: {why}"))
            .hint("give frames as hex bytes, e.g. `01 03 28 00 00 02 CD AB`, `010328000002CDAB` or `0x01 0x03 ...`")
    };
    let mut nibbles: Vec<u8> = Vec::new();
    for token in text.split(|c: char| c.is_whitespace() || matches!(c, ',' | ':' | '-' | ';')) {
        let token = token.strip_prefix("0x").or_else(|| token.strip_prefix("0X")).unwrap_or(token);
        for c in token.chars() {
            match c.to_digit(16).and_then(|d| u8::try_from(d).ok()) {
                Some(d) => nibbles.push(d),
                None => return Err(bad(format!("{c:?} is not a hex digit"))),
            }
        }
    }
    if nibbles.is_empty() {
        return Err(bad("the frame is empty".to_owned()));
    }
    if !nibbles.len().is_multiple_of(2) {
        return Err(bad(format!("{} hex digits is an odd number; each byte takes two", nibbles.len())));
    }
    Ok(nibbles.chunks(2).map(|pair| (byte(pair, 0).unwrap_or(0) << 4) | byte(pair, 1).unwrap_or(0)).collect())
}

/// Which commands `--sensor` and `--command` leave to decode as.
struct Filter<'c> {
    /// The sensors considered.
    entries: Vec<&'c Entry>,
    /// Only this command (`-` read as `_`).
    command: Option<String>,
}

impl<'c> Filter<'c> {
    fn new(catalog: &'c Catalog, args: &DecodeArgs) -> Result<Self> {
        let entries: Vec<&Entry> = match &args.sensor {
            Some(name) => vec![catalog.entry(name)?],
            None => catalog.entries().iter().collect(),
        };
        let command = args.command.as_ref().map(|n| n.replace('-', "_"));
        if let (Some(name), Some(wanted)) = (&args.command, &command)
            && !entries.iter().any(|e| e.sensor.command(wanted).is_some())
        {
            let names: Vec<&str> =
                entries.iter().flat_map(|e| e.sensor.commands.iter().map(|c| c.name.as_str())).collect();
            let e = CliError::usage(format!("no loaded sensor has a command `{name}`"));
            return Err(match closest(wanted, &names) {
                Some(best) => e.hint(format!("did you mean `{best}`? `yosemitech list` shows every command")),
                None => e.hint("`yosemitech list` shows every command"),
            });
        }
        Ok(Self { entries, command })
    }

    fn allows(&self, c: &Cand<'_>) -> bool {
        self.entries.iter().any(|e| e.sensor.name == c.sensor)
            && self.command.as_ref().is_none_or(|n| *n == c.command.name)
    }
}

/// A command a frame may be, with its sensor.
#[derive(Clone, Copy)]
struct Cand<'c> {
    sensor: &'c str,
    command: &'c CommandSpec,
}

/// What a request asks: its header.
#[derive(Debug, Clone, Copy)]
struct Header {
    slave: u8,
    function: u8,
    address: u16,
    count: u16,
}

/// Where bytes are: the capture line of the first byte (0 for arguments) and
/// its offset in all the bytes read.
#[derive(Debug, Clone, Copy, Default)]
struct Place {
    line: usize,
    offset: usize,
}

/// Bytes and where they were.
#[derive(Debug, Clone)]
struct Framed {
    bytes: Vec<u8>,
    place: Place,
}

/// A request waiting for its reply.
#[derive(Clone)]
struct Pending<'c> {
    request: Framed,
    header: Header,
    /// Every loaded command the request fits (before --sensor/--command).
    cands: Vec<Cand<'c>>,
}

/// What the scanner found, in input order.
enum Found<'c> {
    /// A request, with its reply if one followed (`intact` false: the reply
    /// is cut short or its CRC is wrong).
    Pair { request: Framed, header: Header, cands: Vec<Cand<'c>>, reply: Option<Framed>, intact: bool },
    /// A reply (or exception) with no request before it.
    Lone(Framed),
    /// Bytes that are no frame.
    Noise(Framed),
    /// A capture line that is not hex.
    Unreadable { place: Place, text: String, problem: String },
}

impl Found<'_> {
    fn place(&self) -> Place {
        match self {
            Found::Pair { request, .. } => request.place,
            Found::Lone(f) | Found::Noise(f) => f.place,
            Found::Unreadable { place, .. } => *place,
        }
    }

    /// Frames in it.
    fn frames(&self) -> usize {
        match self {
            Found::Pair { reply, .. } => 1 + usize::from(reply.is_some()),
            Found::Lone(_) => 1,
            _ => 0,
        }
    }

    /// Bytes in whole, CRC-valid frames.
    fn frame_bytes(&self) -> usize {
        match self {
            Found::Pair { request, reply, intact, .. } => {
                request.bytes.len() + reply.as_ref().filter(|_| *intact).map_or(0, |r| r.bytes.len())
            }
            Found::Lone(f) => f.bytes.len(),
            _ => 0,
        }
    }

    fn noise_bytes(&self) -> usize {
        match self {
            Found::Noise(f) => f.bytes.len(),
            Found::Pair { reply: Some(r), intact: false, .. } => r.bytes.len(),
            _ => 0,
        }
    }
}

fn frame_bytes(found: &[Found<'_>]) -> usize {
    found.iter().map(Found::frame_bytes).sum()
}

/// One capture line: its number, its text, and the byte strings it may hold
/// (with and without leading label words), best guess first.
struct Line<'t> {
    number: usize,
    text: &'t str,
    readings: Vec<Vec<u8>>,
    problem: Option<String>,
}

/// At most this many leading words are tried as a label.
const MAX_LABEL_WORDS: usize = 4;

/// Splits a capture into lines. Blank lines and `#` or `//` comments are
/// skipped. A label ending in a colon and a space (`12:00:01 TX: 01 03 ...`)
/// is dropped; leading words that are not hex may be a label too.
fn read_lines(text: &str) -> Vec<Line<'_>> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let trimmed = raw.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') || trimmed.starts_with("//") {
            continue;
        }
        // The hex after the last colon followed by white space; colons inside
        // hex (`01:03:28`) and times (`12:00:01`) have none after them.
        let label_end = trimmed
            .char_indices()
            .rev()
            .find(|&(at, c)| {
                c == ':' && trimmed.get(at + 1..).is_some_and(|rest| rest.starts_with(char::is_whitespace))
            })
            .map(|(at, _)| at + 1);
        let body = label_end.and_then(|at| trimmed.get(at..)).unwrap_or(trimmed).trim();
        let words: Vec<&str> = body.split_whitespace().collect();
        let mut readings: Vec<Vec<u8>> = Vec::new();
        let mut problem = None;
        // Leading words are tried as a label only where they could be one: a
        // line that is nothing but two-digit hex bytes has none.
        let plain = words.iter().all(|w| w.len() == 2 && w.chars().all(|c| c.is_ascii_hexdigit()));
        let tries = if plain { 0 } else { MAX_LABEL_WORDS.min(words.len().saturating_sub(1)) };
        for skip in 0..=tries {
            let rest = words.get(skip..).unwrap_or(&[]).join(" ");
            match parse_hex(&rest) {
                Ok(bytes) if !bytes.is_empty() => {
                    if !readings.contains(&bytes) {
                        readings.push(bytes);
                    }
                }
                Ok(_) => {}
                Err(e) => {
                    if problem.is_none() {
                        problem = Some(e.message);
                    }
                }
            }
        }
        // A line of hex with `: ` separators is hex too.
        if label_end.is_some()
            && let Ok(bytes) = parse_hex(trimmed)
            && !bytes.is_empty()
            && !readings.contains(&bytes)
        {
            readings.push(bytes);
        }
        lines.push(Line { number: i + 1, text: trimmed, readings, problem });
    }
    lines
}

/// Maps offsets in all the bytes to capture lines.
#[derive(Default)]
struct LineMap {
    /// (offset of the line's first byte, line number), by offset.
    starts: Vec<(usize, usize)>,
}

impl LineMap {
    fn line(&self, offset: usize) -> usize {
        let after = self.starts.partition_point(|&(start, _)| start <= offset);
        after.checked_sub(1).and_then(|i| self.starts.get(i)).map_or(0, |&(_, line)| line)
    }
}

/// Splits bytes into frames and pairs requests with replies.
struct Scanner<'a, 'c> {
    /// Every command of every loaded sensor: framing does not depend on --sensor/--command.
    all: &'a [Cand<'c>],
    pending: Option<Pending<'c>>,
    noise: Option<Framed>,
    found: Vec<Found<'c>>,
}

impl<'a, 'c> Scanner<'a, 'c> {
    fn new(all: &'a [Cand<'c>]) -> Self {
        Self { all, pending: None, noise: None, found: Vec::new() }
    }

    /// A fresh scanner that continues from this one's pending request.
    fn trial(&self) -> Self {
        Self { all: self.all, pending: self.pending.clone(), noise: None, found: Vec::new() }
    }

    /// All of `bytes`, as one stream.
    fn scan_stream(&self, bytes: &[u8]) -> Vec<Found<'c>> {
        let mut scanner = self.trial();
        scanner.feed(bytes, 0, &LineMap::default());
        scanner.finish()
    }

    /// A capture read one frame (or a few) per line: frames do not span lines.
    /// Of a line's readings, the one that is most frames wins.
    fn scan_lines(&self, lines: &[Line<'_>]) -> Vec<Found<'c>> {
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
    fn scan_joined(&self, lines: &[Line<'_>]) -> Vec<Found<'c>> {
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
    fn request_at(&self, piece: &[u8], p: usize) -> Option<(usize, Header, Vec<Cand<'c>>)> {
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
        let cands: Vec<Cand<'c>> = self
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
        let len = match header.function {
            0x03 if (1..=125).contains(&header.count) && (1..=247).contains(&header.slave) => 8,
            0x10 if header.count <= 123
                && header.slave <= 247
                && usize::from(byte(rest, 6).unwrap_or(0)) == 2 * usize::from(header.count) =>
            {
                9 + 2 * usize::from(header.count)
            }
            _ => return None,
        };
        rest.get(..len).filter(|frame| crc_ok(frame)).map(|_| (len, header, Vec::new()))
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
        let lens: Vec<usize> = if function == asked.function | 0x80 {
            vec![5]
        } else if function == asked.function {
            let mut lens: Vec<usize> = if pending.cands.is_empty() {
                vec![if function == 0x03 { 5 + 2 * usize::from(asked.count) } else { 8 }]
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
        let full = lens.first().copied().unwrap_or(5);
        if rest.len() <= full {
            Some((rest.len(), false))
        } else if self.request_at(piece, p + full).is_some() || self.lone_reply_at(piece, p + full).is_some() {
            Some((full, false))
        } else {
            None
        }
    }

    /// A reply or exception at `p` with no request before it: recognised by
    /// its CRC, its function, and a length some loaded command's reply has
    /// (or, for a read, its byte count gives).
    fn lone_reply_at(&self, piece: &[u8], p: usize) -> Option<usize> {
        let rest = piece.get(p..)?;
        let (slave, function) = (*rest.first()?, *rest.get(1)?);
        let fixed = self.all.iter().any(|c| c.command.fixed_slave == Some(slave));
        if !((1..=247).contains(&slave) || fixed) {
            return None;
        }
        let lens: Vec<usize> = match function {
            f if f & 0x80 != 0 && Function::from_code(f & 0x7F).is_some() => vec![5],
            0x03 => {
                let mut lens: Vec<usize> = self
                    .all
                    .iter()
                    .filter(|c| c.command.is_read())
                    .flat_map(|c| reply_lens(c.command))
                    .flatten()
                    .chain(rest.get(2).map(|&n| 5 + usize::from(n)))
                    .collect();
                lens.sort_unstable();
                lens.dedup();
                lens
            }
            0x10 => vec![8],
            _ => return None,
        };
        lens.into_iter().find(|&len| len >= 5 && rest.get(..len).is_some_and(crc_ok))
    }
}

/// How a transaction or a frame ended up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Status {
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
    fn name(self) -> &'static str {
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
    fn ok(self) -> bool {
        matches!(self, Status::Decoded | Status::Exception | Status::Broadcast)
    }
}

/// One way to read a transaction: the commands that read it so, and the values.
struct Decoding<'c> {
    cands: Vec<Cand<'c>>,
    values: Values,
}

impl<'c> Decoding<'c> {
    fn command(&self) -> Option<&'c CommandSpec> {
        self.cands.first().map(|c| c.command)
    }

    /// `get_sn of conductivity, ph_orp`.
    fn label(&self) -> String {
        label(&self.cands)
    }

    /// `ph = 7.6 pH, temperature_c = 25 °C`.
    fn values_text(&self) -> String {
        let command = self.command();
        self.values
            .iter()
            .map(|(n, v)| format!("{n} = {}", value_with_unit(v, command.and_then(|c| c.field(n)))))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The command's name, when every candidate has the same one.
    fn name(&self) -> Option<&str> {
        let first = self.command()?;
        self.cands.iter().all(|c| c.command.name == first.name).then_some(first.name.as_str())
    }

    fn json(&self) -> Json {
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

/// `get_sn of conductivity, ph_orp; get_x of y`: candidates by command name, in order.
fn label(cands: &[Cand<'_>]) -> String {
    let mut names: Vec<(&str, Vec<&str>)> = Vec::new();
    for c in cands {
        match names.iter_mut().find(|(n, _)| *n == c.command.name) {
            Some((_, sensors)) => sensors.push(c.sensor),
            None => names.push((&c.command.name, vec![c.sensor])),
        }
    }
    names.iter().map(|(n, sensors)| format!("{n} of {}", sensors.join(", "))).collect::<Vec<_>>().join("; ")
}

/// Candidates with their values, the equal ones together: same fields, same
/// values (bit for bit), same units.
fn group<'c>(decoded: impl IntoIterator<Item = (Cand<'c>, Values)>) -> Vec<Decoding<'c>> {
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
struct Exchange<'c> {
    request: Option<(Framed, Header)>,
    reply: Option<Framed>,
    status: Status,
    /// Every way to read it; one when decoded.
    decodings: Vec<Decoding<'c>>,
    exception: Option<ExceptionCode>,
    notes: Vec<String>,
    problems: Vec<String>,
}

impl<'c> Exchange<'c> {
    fn slave(&self) -> Option<u8> {
        match (&self.request, &self.reply) {
            (Some((_, header)), _) => Some(header.slave),
            (None, Some(reply)) => reply.bytes.first().copied(),
            (None, None) => None,
        }
    }

    /// The one decoding, when there is exactly one.
    fn chosen(&self) -> Option<&Decoding<'c>> {
        match self.decodings.as_slice() {
            [only] => Some(only),
            _ => None,
        }
    }
}

/// An entry of the output.
enum Report<'c> {
    Exchange(Exchange<'c>),
    Noise(Framed),
    Unreadable { place: Place, text: String, problem: String },
}

impl Report<'_> {
    fn status(&self) -> Status {
        match self {
            Report::Exchange(x) => x.status,
            Report::Noise(_) => Status::Noise,
            Report::Unreadable { .. } => Status::Unreadable,
        }
    }
}

/// `a read of 0x2800, 2 registers`.
fn describe(header: &Header) -> String {
    let registers =
        format!("0x{:04X}, {} register{}", header.address, header.count, if header.count == 1 { "" } else { "s" });
    match Function::from_code(header.function) {
        Some(Function::Read) => format!("a read of {registers}"),
        Some(Function::Write) => format!("a write of {registers}"),
        None => format!("function 0x{:02X} on {registers}", header.function),
    }
}

/// Decodes what the scanner found, with the commands --sensor/--command leave.
fn report<'c>(filter: &Filter<'_>, all: &[Cand<'c>], found: Found<'c>) -> Report<'c> {
    match found {
        Found::Noise(f) => Report::Noise(f),
        Found::Unreadable { place, text, problem } => Report::Unreadable { place, text, problem },
        Found::Pair { request, header, cands, reply, intact } => {
            Report::Exchange(transaction(filter, request, header, &cands, reply, intact))
        }
        Found::Lone(reply) => Report::Exchange(lone(filter, all, reply)),
    }
}

fn transaction<'c>(
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
            let expected = if byte(bytes, 1).unwrap_or(0) & 0x80 != 0 {
                5
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
        (Some(reply), true) if byte(&reply.bytes, 1).unwrap_or(0) & 0x80 != 0 => {
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
fn lone<'c>(filter: &Filter<'_>, all: &[Cand<'c>], reply: Framed) -> Exchange<'c> {
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
    if function & 0x80 != 0 {
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

/// A frame's bytes and place, as JSON.
fn framed_json(f: &Framed) -> Json {
    json!({
        "frame": hex(&f.bytes),
        "length": f.bytes.len(),
        "line": (f.place.line > 0).then_some(f.place.line),
        "offset": f.place.offset,
        "crc_ok": f.bytes.len() >= 4 && crc_ok(&f.bytes),
    })
}

fn exchange_json(x: &Exchange<'_>) -> Json {
    let header = x.request.as_ref().map(|(_, h)| *h);
    let function =
        header.map(|h| h.function).or_else(|| x.reply.as_ref().map(|r| byte(&r.bytes, 1).unwrap_or(0) & 0x7F));
    let function_name = function.and_then(Function::from_code).map(|f| match f {
        Function::Read => "read",
        Function::Write => "write",
    });
    let decodings: Vec<Json> = x.decodings.iter().map(Decoding::json).collect();
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
        "notes": x.notes,
        "problems": x.problems,
        "error": Json::Null,
    });
    if let (Json::Object(doc), Json::Object(chosen)) = (&mut doc, chosen) {
        doc.extend(chosen);
    }
    doc
}

fn report_json(r: &Report<'_>) -> Json {
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
fn exchange_error(x: &Exchange<'_>) -> Option<CliError> {
    let first = x.problems.first().cloned().unwrap_or_default();
    match x.status {
        Status::Decoded | Status::Exception | Status::Broadcast => None,
        Status::Ambiguous => {
            let what = x.request.as_ref().map_or_else(|| "the reply".to_owned(), |(_, h)| describe(h));
            let mut e = CliError::usage(format!(
                "the reply to {what} decodes {} ways, as different commands; say which one",
                x.decodings.len()
            ));
            for d in &x.decodings {
                e = e.detail(format!("{}: {}", d.label(), d.values_text()));
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
fn print_pair(x: &Exchange<'_>, json_out: bool, out: &mut dyn Write) -> Result<()> {
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
            writeln!(out, "{head:<12}{}{title}", d.label())?;
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
fn place_text(r: &Report<'_>) -> String {
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
fn hex_short(bytes: &[u8]) -> String {
    match bytes.get(..32) {
        Some(head) if bytes.len() > 32 => format!("{} …", hex(head)),
        _ => hex(bytes),
    }
}

/// An entry in one line of text.
fn report_text(r: &Report<'_>) -> String {
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
        let values = d.values_text();
        let written = match (d.command().is_some_and(CommandSpec::is_read), x.status) {
            (true, _) => "",
            (false, Status::Broadcast) => " (broadcast, not answered)",
            (false, _) => " (write acknowledged)",
        };
        if values.is_empty() { format!("{}{written}", d.label()) } else { format!("{}: {values}{written}", d.label()) }
    };
    let labels = x.decodings.iter().map(Decoding::label).collect::<Vec<_>>().join(" | ");
    let first = x.problems.first().map_or("", String::as_str);
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
fn print_reports(reports: &[Report<'_>], mode: &str, json_out: bool, out: &mut dyn Write) -> Result<()> {
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
    let how = if mode == "lines" { "frames by line" } else { "one hex stream" };
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

/// Decodes one frame on its own: the command is found from the frame alone.
fn decode_one(filter: &Filter<'_>, json_out: bool, frame: &[u8], out: &mut dyn Write) -> Result<()> {
    if frame.len() < 4 {
        return Err(CliError::usage(format!("{} byte(s) is too short for a frame", frame.len()))
            .hint("an RTU frame has at least an address, a function code and a 2-byte CRC"));
    }
    let entries = &filter.entries;
    let len = frame.len();
    let (slave, function) = (frame.first().copied().unwrap_or(0), frame.get(1).copied().unwrap_or(0));
    let body = frame.get(..len - 2).unwrap_or(&[]);
    let received = [frame.get(len - 2).copied().unwrap_or(0), frame.get(len - 1).copied().unwrap_or(0)];
    let expected = crc16(body).to_le_bytes();
    let crc_ok = received == expected;

    let kind = match function {
        f if f & 0x80 != 0 => Kind::Exception,
        0x03 if len == 8 => Kind::ReadRequest,
        0x03 => Kind::ReadReply,
        0x10 if len == 8 => Kind::WriteReply,
        0x10 => Kind::WriteRequest,
        _ => Kind::Unknown,
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
                Kind::Exception => c.function.code() == function & 0x7F,
                Kind::Unknown => false,
            }
    };
    let mut candidates: Vec<Candidate<'_>> = Vec::new();
    for entry in entries {
        for c in entry.sensor.commands.iter().filter(|c| fits(c)) {
            if wanted.as_ref().is_some_and(|w| *w != c.name) {
                continue;
            }
            // A command shared by every probe (yosemitech-common.yaml) is one candidate.
            let same = candidates.iter_mut().find(|k| {
                k.command.name == c.name
                    && k.command.shared_from.is_some()
                    && k.command.shared_from == c.shared_from
                    && k.command.layout() == c.layout()
            });
            match same {
                Some(k) => k.sensors.push(&entry.sensor.name),
                None => candidates.push(Candidate { sensors: vec![&entry.sensor.name], command: c }),
            }
        }
    }
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
            let n = frame.get(2).copied().unwrap_or(0);
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
            let n = frame.get(6).copied().unwrap_or(0);
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
            let code = ExceptionCode::from_u8(frame.get(2).copied().unwrap_or(0));
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

    let function_name = Function::from_code(function & 0x7F).map(|f| match f {
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
                format!("exception reply from address {slave} to function 0x{:02X}{fname}", function & 0x7F)
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

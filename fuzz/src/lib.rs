//! The bodies of the fuzz targets, as plain functions: the binaries in
//! `fuzz_targets/` hand libFuzzer's input to them, and anything else (a unit
//! test, a replay of a crash) can call them directly.
//!
//! A finding is a panic: an `assert!` below that fails, or a panic, overflow
//! or out-of-bounds access in the code under test (the targets are built with
//! debug assertions and overflow checks). Every target must also return
//! promptly (`-timeout`) and keep its memory bounded (`-rss_limit_mb`).
//!
//! | target | input | checks |
//! |---|---|---|
//! | [`decode_response`] | slave byte + frame | typed decoding of every command of every sensor agrees with the reference interpreter; anything accepted re-encodes to the same frame |
//! | [`frame_reader`] | header + stale bytes + reply stream, split into chunks | the client's reader never panics or hangs, returns a value only for a valid frame it was sent, and accepts a clean reply |
//! | [`spec_loader`] | two YAML files | the loader never panics; what it accepts generates code that parses |
//! | [`cli_decode`] | hex text | the CLI's `decode` path: hex parsing, classification and interpretation against every spec command |

use std::io;
use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::Duration;

use yosemitech::{conductivity, ph_orp};
use yosemitech_rtu::frame::{EXCEPTION_BIT, MAX_ADU};
use yosemitech_rtu::{
    Client, ClientConfig, EncodeError, Error, FieldValue, FrameError, Function, Hex, LineTiming, RetryPolicy,
    Transport, crc_ok,
};
use yosemitech_spec::interp::decode_fields;
use yosemitech_spec::sources::MemSources;
use yosemitech_spec::{Command, Spec, Values, load_with, parse_hex};

/// The real spec files, compiled in so that the targets need no files at run time.
pub const SPEC_FILES: [(&str, &str); 3] = [
    ("spec/ph-orp-optical.yaml", include_str!("../../spec/ph-orp-optical.yaml")),
    ("spec/conductivity.yaml", include_str!("../../spec/conductivity.yaml")),
    ("spec/yosemitech-common.yaml", include_str!("../../spec/yosemitech-common.yaml")),
];

/// The real spec, loaded once.
pub fn spec() -> &'static Spec {
    static SPEC: OnceLock<Spec> = OnceLock::new();
    SPEC.get_or_init(|| {
        let sources = SPEC_FILES.iter().fold(MemSources::default(), |s, (path, text)| s.with(*path, *text));
        match load_with(&sources, &[PathBuf::from("spec")]) {
            Ok(spec) => spec,
            Err(d) => panic!("the real spec does not load:\n{d}"),
        }
    })
}

/// The spec's command called `name` of sensor `sensor`.
fn spec_command(sensor: &str, name: &str) -> &'static Command {
    spec()
        .sensor(sensor)
        .and_then(|s| s.command(name))
        .unwrap_or_else(|| panic!("generated command {sensor}.{name} is not in the spec"))
}

// ---------------------------------------------------------------------------
// decode_response

/// Input: `[slave, frame...]`. Decodes the frame as a reply and as a request
/// of every command of every sensor through the generated dispatch
/// (`<sensor>::decode_response(id, slave, frame)`, `CommandId::decode_request`,
/// `identify_request`), and checks each result against the reference
/// interpreter (same verdict, same values) and against re-encoding (a
/// decoded value encodes back to the frame, apart from reserved bytes and a
/// byte count the spec lists as a firmware quirk).
pub fn decode_response(data: &[u8]) {
    let Some((&slave, frame)) = data.split_first() else { return };
    check_ph_orp(slave, frame);
    check_conductivity(slave, frame);
}

macro_rules! check_sensor {
    ($name:ident, $module:ident) => {
        fn $name(slave: u8, frame: &[u8]) {
            let sensor = stringify!($module);
            for id in $module::CommandId::ALL {
                let command = spec_command(sensor, id.name());
                assert_eq!(id.layout(), command.layout(), "{sensor}.{id}: generated and spec layouts differ");

                // As a reply.
                let typed = $module::decode_response(id, slave, frame);
                let interpreted = command.decode_response(slave, frame);
                match (&typed, &interpreted) {
                    (Ok(response), Ok(values)) => {
                        assert_eq!(response.command(), id);
                        same_values(sensor, id.name(), response.fields().map(|(info, v)| (info.name, v)), values);
                        let mut out = [0u8; MAX_ADU];
                        let n = response
                            .encode(slave, &mut out)
                            .unwrap_or_else(|e| panic!("{sensor}.{id}: a decoded reply does not encode: {e}"));
                        same_frame(command, Direction::Response, frame, out.get(..n).unwrap_or(&[]));
                    }
                    (Err(a), Err(b)) => {
                        assert_eq!(a, b, "{sensor}.{id}: typed and interpreted decoding reject differently")
                    }
                    (a, b) => panic!(
                        "{sensor}.{id}: typed decoding gives {:?}, the interpreter {:?} for reply {}",
                        a.as_ref().map(|_| "a value"),
                        b.as_ref().map(|_| "a value"),
                        Hex(frame)
                    ),
                }

                // As a request.
                let typed = id.decode_request(frame);
                let interpreted = command.decode_request(frame);
                match (&typed, &interpreted) {
                    (Ok((s, request)), Ok((t, values))) => {
                        assert_eq!(s, t);
                        assert_eq!(request.command(), id);
                        same_values(sensor, id.name(), request.fields().map(|(info, v)| (info.name, v)), values);
                        let mut out = [0u8; MAX_ADU];
                        match request.encode(*s, &mut out) {
                            Ok(n) => same_frame(command, Direction::Request, frame, out.get(..n).unwrap_or(&[])),
                            // Decoding takes what the wire carries; encoding refuses
                            // values outside the spec's ranges and unusable addresses.
                            Err(EncodeError::OutOfRange { .. } | EncodeError::InvalidSlave { .. }) => {}
                            Err(e) => panic!("{sensor}.{id}: a decoded request does not encode: {e}"),
                        }
                        let found = $module::identify_request(frame);
                        assert!(found.is_some(), "{sensor}.{id}: a valid request is not identified");
                    }
                    (Err(a), Err(b)) => {
                        assert_eq!(a, b, "{sensor}.{id}: typed and interpreted request decoding disagree")
                    }
                    _ => panic!("{sensor}.{id}: typed and interpreted request decoding disagree on {}", Hex(frame)),
                }
            }
            if let Some(id) = $module::identify_request(frame) {
                let layout = id.layout();
                assert_eq!(frame.get(1), Some(&layout.function.code()));
                assert_eq!(frame.get(2..4), Some(&layout.address.to_be_bytes()[..]));
                assert_eq!(frame.get(4..6), Some(&layout.count.to_be_bytes()[..]));
            }
        }
    };
}

check_sensor!(check_ph_orp, ph_orp);
check_sensor!(check_conductivity, conductivity);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Direction {
    Request,
    Response,
}

/// Typed field values equal the interpreter's, bit for bit.
fn same_values<'a>(
    sensor: &str,
    command: &str,
    typed: impl Iterator<Item = (&'a str, FieldValue<'a>)>,
    values: &Values,
) {
    let typed: Vec<(&str, FieldValue<'_>)> = typed.collect();
    assert_eq!(typed.len(), values.len(), "{sensor}.{command}: field counts differ");
    for ((name, t), (other, v)) in typed.iter().zip(values) {
        assert_eq!(name, other, "{sensor}.{command}: field order differs");
        let same = v.matches(t);
        assert!(same, "{sensor}.{command}.{name}: typed {t:?}, interpreted {v:?}");
    }
}

/// `encoded` is `original` again, except where the spec lets them differ:
/// reserved bytes (decoding ignores them, encoding writes their fill) and a
/// read reply's byte count when it is one the spec accepts as a quirk.
fn same_frame(command: &Command, direction: Direction, original: &[u8], encoded: &[u8]) {
    let name = &command.name;
    assert_eq!(original.len(), encoded.len(), "{name}: re-encoded length differs");
    let len = original.len();
    let mut free = vec![false; len];
    let data_at = match (direction, command.layout().function) {
        (Direction::Response, Function::Read) => Some(3),
        (Direction::Request, Function::Write) => Some(7),
        _ => None,
    };
    if let Some(at) = data_at {
        for f in command.fields.iter().filter(|f| f.is_reserved()) {
            for i in at + f.offset..at + f.offset + f.size() {
                if let Some(slot) = free.get_mut(i) {
                    *slot = true;
                }
            }
        }
    }
    if direction == Direction::Response
        && command.is_read()
        && original.get(2).is_some_and(|n| command.extra_byte_counts.contains(n))
        && let Some(slot) = free.get_mut(2)
    {
        *slot = true;
    }
    let body = len.saturating_sub(2);
    let mut free_differs = false;
    for i in 0..body {
        if original[i] != encoded[i] {
            assert!(
                free[i],
                "{name}: {direction:?} re-encodes differently at byte {i}: {} -> {}",
                Hex(original),
                Hex(encoded)
            );
            free_differs = true;
        }
    }
    if !free_differs {
        assert_eq!(original, encoded, "{name}: {direction:?} re-encodes with another CRC");
    }
}

// ---------------------------------------------------------------------------
// frame_reader

/// A transport that replays bytes: `stale` before the request (the client
/// drains and discards them), then `stream` after it, handed out in chunks
/// whose sizes come from `chunks` (0 = everything left). With the client's
/// timeout at zero, running out of bytes is the deadline.
struct Replay<'a> {
    stale: &'a [u8],
    stream: &'a [u8],
    chunks: &'a [u8],
    next_chunk: usize,
    written: bool,
    reads: usize,
}

impl Replay<'_> {
    fn chunk(&mut self) -> usize {
        let size = self.chunks.get(self.next_chunk % self.chunks.len().max(1)).copied().unwrap_or(0);
        self.next_chunk += 1;
        if size == 0 { usize::MAX } else { usize::from(size) }
    }
}

impl Transport for Replay<'_> {
    fn write_all(&mut self, _frame: &[u8]) -> io::Result<()> {
        assert!(!self.written, "one call with retries off sends one request");
        self.written = true;
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _timeout: Duration) -> io::Result<usize> {
        self.reads += 1;
        assert!(self.reads < 10_000, "the client keeps reading: it would hang on a real line");
        let n = buf.len().min(self.chunk());
        let source = if self.written { &mut self.stream } else { &mut self.stale };
        let n = n.min(source.len());
        let (head, rest) = source.split_at(n);
        buf[..n].copy_from_slice(head);
        *source = rest;
        Ok(n)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.stale = &[];
        Ok(())
    }

    fn line_timing(&self) -> Option<LineTiming> {
        None
    }
}

/// Input: `[command, slave, stale length, chunk count, chunks..., stale..., stream...]`.
///
/// Sends the request of a spec command (a write with zeroed data) through
/// [`Client::call_raw`] over a transport that replays the input, with the
/// timeout at zero and no retries, and checks the outcome:
///
/// - `Ok(frame)`: `frame` is a valid reply to the request (length, CRC,
///   slave, function, byte count or echo), it was sent after the request,
///   byte for byte, and the generated decoder accepts it;
/// - a clean reply at the very start of the stream is never rejected, and an
///   exception reply there is reported as that exception;
/// - a valid reply after up to 4 bytes of noise (which hold no frame of
///   their own) is found, whatever the noise looks like;
/// - errors are timeouts or frame errors, whose bytes were received.
pub fn frame_reader(data: &[u8]) {
    let [selector, slave_byte, stale_len, chunk_count, rest @ ..] = data else { return };
    let (chunks, rest) = rest.split_at(usize::from(*chunk_count % 16).min(rest.len()));
    let (stale, stream) = rest.split_at(usize::from(*stale_len).min(rest.len()));

    let commands: Vec<(&str, &Command)> =
        spec().sensors.iter().flat_map(|s| s.commands.iter().map(move |c| (s.name.as_str(), c))).collect();
    let (sensor, command) = commands[usize::from(*selector) % commands.len()];
    let layout = command.layout();
    let slave = layout.fixed_slave.unwrap_or(1 + slave_byte % 247);
    let mut request = [0u8; MAX_ADU];
    let data = vec![0u8; layout.request_data_len()];
    let n = layout.encode_request(slave, &data, &mut request).unwrap_or_else(|e| panic!("{}: {e}", command.name));
    let request = &request[..n];

    let replay = Replay { stale, stream, chunks, next_chunk: 0, written: false, reads: 0 };
    let config = ClientConfig {
        timeout: Duration::ZERO,
        retry: RetryPolicy::NONE,
        inter_frame_delay: Some(Duration::ZERO),
        broadcast_turnaround: Duration::ZERO,
        ..ClientConfig::default()
    };
    let mut client = Client::with_config(replay, config);
    let result = client.call_raw(request, &layout).map(<[u8]>::to_vec);

    let reply_len = layout.response_len();
    let clean = stream.get(..reply_len).filter(|head| layout.decode_response(slave, head).is_ok());
    // Line noise (up to 4 bytes that hold no frame of their own) and then
    // exactly one valid reply: the client must find the reply, whatever the
    // noise looks like (function codes, the slave's own address).
    let after_noise = (1..=4usize.min(stream.len())).find_map(|k| {
        let (noise, rest) = stream.split_at(k);
        (rest.len() == reply_len && layout.decode_response(slave, rest).is_ok() && !holds_frame(noise)).then_some(rest)
    });
    let exception = stream
        .get(..5)
        .filter(|head| head.get(1) == Some(&(layout.function.code() | EXCEPTION_BIT)) && crc_ok(head))
        .filter(|head| head.first() == Some(&layout.reply_slave(slave)));
    match result {
        Ok(frame) => {
            assert!(crc_ok(&frame), "a reply with a bad CRC was accepted: {}", Hex(&frame));
            if let Err(e) = layout.decode_response(slave, &frame) {
                panic!("an invalid reply was accepted ({e}): {}", Hex(&frame));
            }
            assert!(
                stream.windows(frame.len()).any(|w| w == frame),
                "the accepted reply {} is not in what arrived after the request: {}",
                Hex(&frame),
                Hex(stream)
            );
            if let Some(clean) = clean {
                assert_eq!(frame, clean, "a clean reply was replaced by another");
            }
            if let Some(reply) = after_noise {
                assert_eq!(frame, reply, "the reply after noise was not the one returned");
            }
            typed_accepts(sensor, &command.name, slave, &frame);
        }
        Err(error) => {
            if let Some(clean) = clean {
                panic!("a clean reply {} was rejected: {error}", Hex(clean));
            }
            if let Some(reply) = after_noise {
                panic!("the reply {} after noise was not found in {}: {error}", Hex(reply), Hex(stream));
            }
            match &error {
                Error::Timeout { received } => {
                    let received = received.as_bytes();
                    assert!(
                        received.is_empty() || stream.windows(received.len()).any(|w| w == received),
                        "a timeout reports bytes that did not arrive: {}",
                        Hex(received)
                    );
                }
                Error::Frame { error: FrameError::Exception { .. }, raw } => {
                    assert_eq!(raw.as_bytes().len(), 5);
                    assert!(crc_ok(raw.as_bytes()));
                }
                Error::Frame { raw, .. } => {
                    let raw = raw.as_bytes();
                    assert!(
                        stream.windows(raw.len().max(1)).any(|w| w == raw),
                        "a frame error reports bytes that did not arrive: {}",
                        Hex(raw)
                    );
                    if let Some(head) = exception {
                        panic!("the exception reply {} was reported as {error}", Hex(head));
                    }
                }
                other => panic!("unexpected error kind: {other}"),
            }
        }
    }
}

/// Whether `bytes` hold a whole frame: a run of at least 4 bytes ending in its own CRC.
fn holds_frame(bytes: &[u8]) -> bool {
    (0..bytes.len()).any(|from| (from + 4..=bytes.len()).any(|to| crc_ok(&bytes[from..to])))
}

/// The generated decoder of `sensor` accepts a frame the client accepted.
fn typed_accepts(sensor: &str, command: &str, slave: u8, frame: &[u8]) {
    let ok = match sensor {
        "ph_orp" => ph_orp::CommandId::from_name(command).map(|id| ph_orp::decode_response(id, slave, frame).is_ok()),
        "conductivity" => conductivity::CommandId::from_name(command)
            .map(|id| conductivity::decode_response(id, slave, frame).is_ok()),
        _ => None,
    };
    assert_eq!(ok, Some(true), "{sensor}.{command}: the generated decoder rejects {}", Hex(frame));
}

// ---------------------------------------------------------------------------
// spec_loader

/// Inputs up to this size that load also go through the generator.
pub const CODEGEN_MAX_INPUT: usize = 4096;

/// Input: two YAML files separated by the first NUL byte: `spec/sensor.yaml`
/// and `spec/yosemitech-common.yaml` (so `include: [yosemitech-common.yaml]`
/// resolves), both loaded as the directory `spec/` from memory. Invalid
/// UTF-8 is replaced (files on disk are checked for UTF-8 before parsing).
///
/// The loader must not panic; a rejection has at least one diagnostic with a
/// position; an accepted spec (up to [`CODEGEN_MAX_INPUT`] bytes) generates code (or reports a name collision or
/// an unsupported value), and the generated code always parses: text from
/// the spec never escapes its string literals.
pub fn spec_loader(data: &[u8]) {
    let (first, second) = match data.iter().position(|&b| b == 0) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &[][..]),
    };
    let sources = MemSources::default()
        .with("spec/sensor.yaml", String::from_utf8_lossy(first).into_owned())
        .with("spec/yosemitech-common.yaml", String::from_utf8_lossy(second).into_owned());
    match load_with(&sources, &[PathBuf::from("spec")]) {
        Ok(spec) => {
            let _ = spec.summary();
            // Generating (and formatting) a whole real spec takes ~100 ms:
            // the generator runs on small accepted specs, which is where
            // mutated names and texts end up anyway.
            if data.len() > CODEGEN_MAX_INPUT {
                return;
            }
            match yosemitech_codegen::Config::new().generate_spec(&spec) {
                Ok(generated) => {
                    for sensor in &generated.sensors {
                        assert!(sensor.source.starts_with("// @generated"));
                    }
                }
                Err(e @ yosemitech_codegen::Error::Internal { .. }) => {
                    panic!("an accepted spec generates code that does not parse: {e}")
                }
                Err(e) => {
                    let _ = e.to_string();
                }
            }
        }
        Err(diagnostics) => {
            assert!(!diagnostics.is_empty(), "a rejection without diagnostics");
            for d in &diagnostics.0 {
                assert!(!d.message.is_empty(), "an empty diagnostic");
            }
            let _ = diagnostics.to_string();
        }
    }
}

// ---------------------------------------------------------------------------
// cli_decode

/// Input: text, as typed after `yosemitech decode`. Runs the CLI's own
/// decode path ([`yosemitech_cli::decode_text`]: its hex parser, frame
/// classification, interpretation against every spec command and output, as
/// text and as JSON), then the generated decoders on the same frame
/// ([`decode_response`]) and the interpreter on every command.
pub fn cli_decode(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    // The spec's own parser on the raw text round-trips.
    if let Ok(bytes) = parse_hex(&text) {
        assert!(!bytes.is_empty() && bytes.len() <= MAX_ADU);
        assert_eq!(parse_hex(&Hex(&bytes).to_string()).as_deref(), Ok(&bytes[..]), "hex does not round-trip");
    }
    let mut shown = Vec::new();
    let outcome = yosemitech_cli::decode_text(&text, false, &mut shown);
    let mut json = Vec::new();
    let json_outcome = yosemitech_cli::decode_text(&text, true, &mut json);
    assert_eq!(outcome.is_ok(), json_outcome.is_ok(), "text and JSON output disagree on {text:?}");
    let Ok(frame) = yosemitech_cli::parse_frame(&text) else {
        assert!(outcome.is_err(), "decode accepted text its parser refuses: {text:?}");
        return;
    };
    assert!(!frame.is_empty() && frame.len() <= MAX_ADU);
    if frame.len() < 4 {
        return; // The CLI refuses these before looking at them.
    }
    for sensor in &spec().sensors {
        for c in &sensor.commands {
            // Data of any length decodes what fits and never panics.
            let partial = decode_fields(c, frame.get(3..).unwrap_or(&[]));
            assert!(partial.len() <= c.named_fields().count());
            if let Ok(values) = c.decode_response(frame[0], &frame) {
                let expected = if c.is_read() { c.named_fields().count() } else { 0 };
                assert_eq!(values.len(), expected, "{}: a valid reply decodes every field", c.name);
            }
            if let Ok((_, values)) = c.decode_request(&frame) {
                let expected = if c.is_read() { 0 } else { c.named_fields().count() };
                assert_eq!(values.len(), expected, "{}: a valid request decodes every field", c.name);
            }
        }
    }
    // The generated side must agree with the interpreter on this frame too.
    check_ph_orp(frame[0], &frame);
    check_conductivity(frame[0], &frame);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every example frame of the spec passes every target.
    #[test]
    fn spec_examples_pass_every_target() {
        for sensor in &spec().sensors {
            for c in &sensor.commands {
                for e in &c.examples {
                    let slave = e.slave();
                    let mut input = vec![slave];
                    input.extend_from_slice(e.true_response());
                    decode_response(&input);
                    cli_decode(Hex(e.true_response()).to_string().as_bytes());
                    cli_decode(Hex(e.true_request()).to_string().as_bytes());
                }
            }
        }
        for (_, text) in SPEC_FILES {
            spec_loader(text.as_bytes());
        }
        let joined = [SPEC_FILES[0].1.as_bytes(), &[0], SPEC_FILES[2].1.as_bytes()].concat();
        spec_loader(&joined);
    }
}

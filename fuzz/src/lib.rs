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
//! | [`cli_decode`] | hex text | the decode library's explanation (`yosemitech_explain`): segmenting, pairing, classification and interpretation against every spec command; its entries cover the bytes exactly, and so do the sniffer's (`explain::sniff`), the bytes heard in chunks and silences the data chooses |
//! | [`segmenter`] | chunk size + bytes | the frame segmenter's spans cover the bytes exactly, frames hold their CRC, and chunked reads find the same spans |

use std::io;
use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::Duration;

use yosemitech::SENSORS;
use yosemitech_rtu::frame::{EXCEPTION_BIT, MAX_ADU};
use yosemitech_rtu::{
    Client, ClientConfig, EncodeError, Error, FieldInfo, FieldValue, FrameError, Function, Hex, LineTiming,
    RetryPolicy, RoundTripError, SensorModule, Transport, crc_ok,
};
use yosemitech_spec::interp::decode_fields;
use yosemitech_spec::sources::MemSources;
use yosemitech_spec::{CommandSpec, Spec, Values, load_with, parse_hex};

/// Every `spec/*.yaml` of the workspace as `spec/<file name>` and text, in
/// name order, read once: a new spec file needs no change here.
pub fn spec_files() -> &'static [(String, &'static str)] {
    static FILES: OnceLock<Vec<(String, &'static str)>> = OnceLock::new();
    FILES.get_or_init(|| {
        let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../spec"));
        let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("cannot read {}: {e}", dir.display()))
            .filter_map(|entry| entry.ok().map(|e| e.path()))
            .filter(|path| path.extension().is_some_and(|e| e == "yaml"))
            .collect();
        paths.sort();
        paths
            .into_iter()
            .map(|path| {
                let text =
                    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
                let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                // Kept for the process's life, as the targets' inputs are.
                (format!("spec/{name}"), &*Box::leak(text.into_boxed_str()))
            })
            .collect()
    })
}

/// Whether a spec file describes a sensor (a top-level `sensor:` key) rather
/// than holding a fragment of shared commands.
pub fn is_sensor_file(text: &str) -> bool {
    text.lines().any(|line| line.starts_with("sensor:"))
}

/// The real spec, loaded once.
pub fn spec() -> &'static Spec {
    static SPEC: OnceLock<Spec> = OnceLock::new();
    SPEC.get_or_init(|| {
        let sources = spec_files().iter().fold(MemSources::default(), |s, (path, text)| s.with(path.as_str(), *text));
        match load_with(&sources, &[PathBuf::from("spec")]) {
            Ok(spec) => spec,
            Err(d) => panic!("the real spec does not load:\n{d}"),
        }
    })
}

/// The spec's command called `name` of sensor `sensor`.
fn spec_command(sensor: &str, name: &str) -> &'static CommandSpec {
    spec()
        .sensor(sensor)
        .and_then(|s| s.command(name))
        .unwrap_or_else(|| panic!("generated command {sensor}.{name} is not in the spec"))
}

/// The generated module of the spec sensor called `sensor`.
fn module(sensor: &str) -> &'static SensorModule {
    SENSORS
        .iter()
        .find(|m| m.info.name == sensor)
        .unwrap_or_else(|| panic!("spec sensor {sensor} has no generated module"))
}

// ---------------------------------------------------------------------------
// decode_response

/// Input: `[slave, frame...]`. Decodes the frame as a reply and as a request
/// of every command of every generated sensor module ([`yosemitech::SENSORS`],
/// through each module's [`SensorModule`] functions), and checks each result
/// against the reference interpreter (same verdict, same values) and against
/// re-encoding (a decoded value encodes back to the frame, apart from
/// reserved bytes and a byte count the spec lists as a firmware quirk; a
/// trigger read's reply, which may take several forms, re-encodes to the
/// manuals' form, which the interpreter accepts in turn).
pub fn decode_response(data: &[u8]) {
    let Some((&slave, frame)) = data.split_first() else { return };
    check_all_sensors(slave, frame);
}

/// The [`decode_response`] checks, for every command of every sensor.
fn check_all_sensors(slave: u8, frame: &[u8]) {
    for module in SENSORS {
        check_sensor(module, slave, frame);
    }
}

/// Compares the typed fields a [`SensorModule`] visitor hands out, one at a
/// time, with the interpreter's values (when the interpreter accepted the
/// frame), and counts them.
struct FieldCheck<'v> {
    sensor: &'static str,
    command: &'static str,
    expected: Option<&'v Values>,
    seen: usize,
}

impl FieldCheck<'_> {
    fn visit(&mut self, info: FieldInfo, typed: FieldValue<'_>) {
        let (sensor, command) = (self.sensor, self.command);
        if let Some(values) = self.expected {
            let Some((name, value)) = values.get(self.seen) else {
                panic!("{sensor}.{command}: typed decoding has more fields than the interpreter ({})", values.len())
            };
            assert_eq!(info.name, name, "{sensor}.{command}: field order differs");
            assert!(value.matches(&typed), "{sensor}.{command}.{name}: typed {typed:?}, interpreted {value:?}");
        }
        self.seen += 1;
    }

    fn finish(&self) {
        if let Some(values) = self.expected {
            assert_eq!(self.seen, values.len(), "{}.{}: field counts differ", self.sensor, self.command);
        }
    }
}

fn check_sensor(module: &SensorModule, slave: u8, frame: &[u8]) {
    let sensor = module.info.name;
    for name in module.commands.iter().map(|c| c.name) {
        let command = spec_command(sensor, name);
        let layout = module.layout(name).unwrap_or_else(|| panic!("{sensor}.{name}: listed but has no layout"));
        assert_eq!(layout, command.layout(), "{sensor}.{name}: generated and spec layouts differ");

        // As a reply.
        let interpreted = command.decode_response(slave, frame);
        let mut fields = FieldCheck { sensor, command: name, expected: interpreted.as_ref().ok(), seen: 0 };
        let typed = module
            .visit_response(name, slave, frame, &mut |info, value| fields.visit(info, value))
            .unwrap_or_else(|| panic!("{sensor}.{name}: listed but visit_response does not know it"));
        match (&typed, &interpreted) {
            (Ok(()), Ok(_)) => {
                fields.finish();
                let mut out = [0u8; MAX_ADU];
                let n = match module.reencode_response(name, slave, frame, &mut out) {
                    Some(Ok(n)) => n,
                    Some(Err(RoundTripError::Encode(e))) => {
                        panic!("{sensor}.{name}: a decoded reply does not encode: {e}")
                    }
                    Some(Err(RoundTripError::Frame(e))) => {
                        panic!("{sensor}.{name}: a reply decoded once is rejected on re-encoding: {e}")
                    }
                    None => panic!("{sensor}.{name}: listed but reencode_response does not know it"),
                };
                let encoded = out.get(..n).unwrap_or(&[]);
                if command.trigger && command.is_read() {
                    // Several reply forms are accepted; encoding writes the
                    // manuals' form, which must decode in turn.
                    if let Err(e) = command.decode_response(slave, encoded) {
                        panic!(
                            "{sensor}.{name}: reply {} re-encodes to {}, which the interpreter rejects: {e}",
                            Hex(frame),
                            Hex(encoded)
                        );
                    }
                } else {
                    same_frame(command, Direction::Response, frame, encoded);
                }
            }
            (Err(a), Err(b)) => assert_eq!(a, b, "{sensor}.{name}: typed and interpreted decoding reject differently"),
            (a, b) => panic!(
                "{sensor}.{name}: typed decoding gives {:?}, the interpreter {:?} for reply {}",
                a.as_ref().map(|_| "a value"),
                b.as_ref().map(|_| "a value"),
                Hex(frame)
            ),
        }

        // As a request.
        let interpreted = command.decode_request(frame);
        let mut fields =
            FieldCheck { sensor, command: name, expected: interpreted.as_ref().ok().map(|(_, v)| v), seen: 0 };
        let typed = module
            .visit_request(name, frame, &mut |info, value| fields.visit(info, value))
            .unwrap_or_else(|| panic!("{sensor}.{name}: listed but visit_request does not know it"));
        match (&typed, &interpreted) {
            (Ok(s), Ok((t, _))) => {
                assert_eq!(s, t, "{sensor}.{name}: typed and interpreted request slaves differ");
                fields.finish();
                let mut out = [0u8; MAX_ADU];
                match module.reencode_request(name, frame, &mut out) {
                    Some(Ok(n)) => same_frame(command, Direction::Request, frame, out.get(..n).unwrap_or(&[])),
                    // Decoding takes what the wire carries; encoding refuses
                    // values outside the spec's ranges and unusable addresses.
                    Some(Err(RoundTripError::Encode(
                        EncodeError::OutOfRange { .. } | EncodeError::InvalidSlave { .. },
                    ))) => {}
                    Some(Err(RoundTripError::Encode(e))) => {
                        panic!("{sensor}.{name}: a decoded request does not encode: {e}")
                    }
                    Some(Err(RoundTripError::Frame(e))) => {
                        panic!("{sensor}.{name}: a request decoded once is rejected on re-encoding: {e}")
                    }
                    None => panic!("{sensor}.{name}: listed but reencode_request does not know it"),
                }
                let found = module.identify_request(frame);
                assert!(found.is_some(), "{sensor}.{name}: a valid request is not identified");
            }
            (Err(a), Err(b)) => assert_eq!(a, b, "{sensor}.{name}: typed and interpreted request decoding disagree"),
            _ => panic!("{sensor}.{name}: typed and interpreted request decoding disagree on {}", Hex(frame)),
        }
    }
    if let Some(name) = module.identify_request(frame) {
        assert!(
            module.commands.iter().any(|c| c.name == name),
            "{sensor}: identify_request names an unlisted command {name}"
        );
        let layout = module.layout(name).unwrap_or_else(|| panic!("{sensor}.{name}: identified but has no layout"));
        assert_eq!(frame.get(1), Some(&layout.function.code()));
        assert_eq!(frame.get(2..4), Some(&layout.address.to_be_bytes()[..]));
        assert_eq!(frame.get(4..6), Some(&layout.count.to_be_bytes()[..]));
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Direction {
    Request,
    Response,
}

/// `encoded` is `original` again, except where the spec lets them differ:
/// reserved bytes (decoding ignores them, encoding writes their fill) and a
/// read reply's byte count when it is one the spec accepts as a quirk.
fn same_frame(command: &CommandSpec, direction: Direction, original: &[u8], encoded: &[u8]) {
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

    let commands: Vec<(&str, &CommandSpec)> =
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

    // The valid reply `bytes` start with: a trigger read's short form is
    // taken as soon as it checks, before the full-length form.
    let first_reply = |bytes: &'_ [u8]| -> Option<usize> {
        layout
            .short_response_len()
            .into_iter()
            .chain([layout.response_len()])
            .find(|&len| bytes.get(..len).is_some_and(|head| layout.decode_response(slave, head).is_ok()))
    };
    let clean = first_reply(stream).and_then(|len| stream.get(..len));
    // Line noise (up to 4 bytes that hold no frame of their own) and then
    // exactly one valid reply: the client must find the reply, whatever the
    // noise looks like (function codes, the slave's own address).
    let after_noise = (1..=4usize.min(stream.len())).find_map(|k| {
        let (noise, rest) = stream.split_at(k);
        (first_reply(rest) == Some(rest.len()) && !holds_frame(noise)).then_some(rest)
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
            // The client keeps the bytes of the last attempt; the error says what was wrong with them.
            let received = client.last_reply();
            match &error {
                Error::Timeout { received: count, .. } => {
                    assert_eq!(*count, received.len(), "a timeout counts the bytes the client kept");
                    assert!(
                        received.is_empty() || stream.windows(received.len()).any(|w| w == received),
                        "a timeout reports bytes that did not arrive: {}",
                        Hex(received)
                    );
                }
                Error::Frame { error: FrameError::Exception { .. } } => {
                    assert_eq!(received.len(), 5);
                    assert!(crc_ok(received));
                }
                Error::Frame { .. } => {
                    assert!(
                        stream.windows(received.len().max(1)).any(|w| w == received),
                        "a frame error reports bytes that did not arrive: {}",
                        Hex(received)
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
    let ok = module(sensor).visit_response(command, slave, frame, &mut |_, _| {});
    if let Some(Err(e)) = ok {
        panic!("{sensor}.{command}: the generated decoder rejects {} ({e})", Hex(frame));
    }
    assert_eq!(ok, Some(Ok(())), "{sensor}.{command}: the generated module does not know the command");
}

// ---------------------------------------------------------------------------
// spec_loader

/// Inputs up to this size that load also go through the generator.
pub const CODEGEN_MAX_INPUT: usize = 4096;

/// Where [`spec_loader`] puts the first of its two input files.
pub const SENSOR_FILE: &str = "spec/sensor.yaml";
/// Where [`spec_loader`] puts the second of its two input files: the
/// fragment every sensor file includes.
pub const COMMON_FRAGMENT: &str = "spec/yosemitech-common.yaml";

/// The fragments of the real spec (every embedded file without a top-level
/// `sensor:` key) but the common one, as fixed files of `spec/`.
fn fixed_fragments() -> &'static MemSources {
    static FRAGMENTS: OnceLock<MemSources> = OnceLock::new();
    FRAGMENTS.get_or_init(|| {
        spec_files()
            .iter()
            .filter(|(path, text)| path != COMMON_FRAGMENT && !is_sensor_file(text))
            .fold(MemSources::default(), |s, (path, text)| s.with(path.as_str(), *text))
    })
}

/// The directory `spec/` [`spec_loader`] loads for `data`: the real spec's
/// fragments, then the input's two files as [`SENSOR_FILE`] and
/// [`COMMON_FRAGMENT`] (replacing the real common fragment).
pub fn spec_loader_sources(data: &[u8]) -> MemSources {
    let (first, second) = match data.iter().position(|&b| b == 0) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &[][..]),
    };
    fixed_fragments()
        .clone()
        .with(SENSOR_FILE, String::from_utf8_lossy(first).into_owned())
        .with(COMMON_FRAGMENT, String::from_utf8_lossy(second).into_owned())
}

/// Input: two YAML files separated by the first NUL byte: [`SENSOR_FILE`]
/// and [`COMMON_FRAGMENT`] (so `include: [yosemitech-common.yaml]`
/// resolves), loaded as the directory `spec/` from memory together with the
/// real spec's other fragments (`yosemitech-optical.yaml`, ...: every
/// embedded file without a `sensor:` key), so that every real sensor file
/// loads as the first input. Invalid UTF-8 is replaced (files on disk are
/// checked for UTF-8 before parsing).
///
/// The loader must not panic; a rejection has at least one diagnostic with a
/// position; an accepted spec (up to [`CODEGEN_MAX_INPUT`] bytes) generates code (or reports a name collision or
/// an unsupported value), and the generated code always parses: text from
/// the spec never escapes its string literals.
pub fn spec_loader(data: &[u8]) {
    let sources = spec_loader_sources(data);
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

/// Input: text, as typed after `yosemitech decode`. Explains the bytes
/// with the decode library ([`yosemitech_explain`]: segmenting,
/// pairing, classification and interpretation against every spec command,
/// and a frame on its own) and checks that the explanation covers every
/// byte exactly once (and so does the sniffer's, `check_sniffer`), then
/// runs the generated decoders on the same frame
/// ([`decode_response`]) and the interpreter on every command.
pub fn cli_decode(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    // The spec's own parser on the raw text round-trips.
    if let Ok(bytes) = parse_hex(&text) {
        assert!(!bytes.is_empty() && bytes.len() <= MAX_ADU);
        assert_eq!(parse_hex(&Hex(&bytes).to_string()).as_deref(), Ok(&bytes[..]), "hex does not round-trip");
    }
    // Text the parser refuses is explained as its raw bytes.
    let parsed = yosemitech_explain::parse_frame(&text);
    check_explanation(parsed.as_deref().unwrap_or(data));
    check_sniffer(data);
    let Ok(frame) = parsed else { return };
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
    check_all_sensors(frame[0], &frame);
}

/// Explains `bytes` against every spec command and checks what the
/// explanation says about them: a frame on its own is all the bytes, and a
/// stream's entries cover every byte exactly once.
fn check_explanation(bytes: &[u8]) {
    use yosemitech_explain::{Commands, Explanation, Report, explain};
    let commands = Commands::new(&spec().sensors);
    match explain(&commands, bytes) {
        Explanation::TooShort(len) => assert!(len == bytes.len() && len < 4, "too short at {len} bytes"),
        Explanation::Frame(frame) => assert_eq!(frame.bytes, bytes, "a frame on its own is not the bytes"),
        Explanation::Exchange(x) => {
            let parts = x.request.iter().map(|(f, _)| f).chain(&x.reply);
            assert_eq!(
                parts.flat_map(|f| f.bytes.iter().copied()).collect::<Vec<u8>>(),
                bytes,
                "an exchange is not the bytes"
            );
        }
        Explanation::Stream(reports) => {
            let mut pieces: Vec<(usize, usize)> = Vec::new();
            for r in &reports {
                match r {
                    Report::Exchange(x) => pieces.extend(
                        x.request.iter().map(|(f, _)| f).chain(&x.reply).map(|f| (f.place.offset, f.bytes.len())),
                    ),
                    Report::Noise(f) => pieces.push((f.place.offset, f.bytes.len())),
                    Report::Unreadable { .. } => panic!("bytes read as an unreadable line"),
                }
            }
            pieces.sort_unstable();
            let mut at = 0;
            for (offset, len) in pieces {
                assert!(offset == at && len > 0, "entries leave a gap or overlap at byte {at} of {}", Hex(bytes));
                at += len;
            }
            assert_eq!(at, bytes.len(), "entries do not reach the end of {}", Hex(bytes));
        }
    }
}

/// Hears `data` as `yosemitech sniff` would, in chunks and at times the
/// data itself chooses (a byte's low bits: where a chunk ends; its high
/// bits: the silence after it), and checks that every byte is in exactly
/// one entry, in order.
fn check_sniffer(data: &[u8]) {
    use std::time::Duration;
    use yosemitech_explain::sniff::{Sniffer, Timing};
    use yosemitech_explain::{Commands, Report};
    use yosemitech_rtu::{CharFormat, LineTiming};
    let commands = Commands::new(&spec().sensors);
    let timing = Timing::of_line(LineTiming::new(9600, CharFormat::EIGHT_N_1), Duration::from_millis(300));
    let mut sniffer = Sniffer::new(&commands, timing);
    let (mut heard, mut at, mut start) = (Vec::new(), Duration::ZERO, 0);
    for (i, byte) in data.iter().enumerate() {
        if byte & 0x07 == 0 || i + 1 == data.len() {
            at += Duration::from_micros(u64::from(byte >> 3) * 1_000);
            heard.extend(sniffer.push(at, data.get(start..=i).unwrap_or(&[])));
            start = i + 1;
        }
    }
    heard.extend(sniffer.finish());
    let mut pieces: Vec<(usize, &[u8])> = Vec::new();
    for h in &heard {
        match &h.report {
            Report::Exchange(x) => {
                pieces.extend(x.request.iter().map(|(f, _)| f).chain(&x.reply).map(|f| (f.place.offset, &f.bytes[..])));
            }
            Report::Noise(f) => pieces.push((f.place.offset, &f.bytes[..])),
            Report::Unreadable { .. } => panic!("the sniffer heard an unreadable line"),
        }
    }
    pieces.sort_unstable();
    let joined: Vec<u8> = pieces.into_iter().flat_map(|(_, bytes)| bytes.iter().copied()).collect();
    assert_eq!(joined, data, "the sniffer's entries are not the bytes heard");
}

// ---------------------------------------------------------------------------
// segmenter

/// Input: `[chunk, bytes...]`. Splits the bytes into spans
/// ([`yosemitech_rtu::segment::spans`]) and checks that they follow each
/// other and cover the bytes exactly, that every frame span holds its CRC,
/// and that feeding the bytes `chunk + 1` at a time to
/// [`next_span`](yosemitech_rtu::segment::next_span), as a stream reader
/// does, finds the same spans. A server's
/// [`request_len`](yosemitech_rtu::segment::request_len) answers every head.
pub fn segmenter(data: &[u8]) {
    use yosemitech_rtu::segment::{Span, next_span, request_head_len, request_len, spans};
    let Some((&chunk, bytes)) = data.split_first() else { return };
    let whole: Vec<Span> = spans(bytes).collect();
    let mut at = 0;
    for span in &whole {
        assert_eq!(span.start, at, "spans leave a gap or overlap in {}", Hex(bytes));
        assert!(span.end > span.start, "an empty span in {}", Hex(bytes));
        assert!(!span.kind.is_frame() || crc_ok(span.bytes(bytes)), "a frame span without its CRC: {span:?}");
        at = span.end;
    }
    assert_eq!(at, bytes.len(), "spans do not reach the end of {}", Hex(bytes));
    let step = usize::from(chunk) + 1;
    let (mut have, mut done) = (0, 0);
    let mut streamed = Vec::new();
    while have < bytes.len() {
        have = (have + step).min(bytes.len());
        while let Ok(span) = next_span(bytes.get(done..have).unwrap_or(&[])) {
            streamed.push(Span { start: span.start + done, end: span.end + done, ..span });
            done += span.end;
        }
    }
    let rest = bytes.get(done..).unwrap_or(&[]);
    streamed.extend(spans(rest).map(|span| Span { start: span.start + done, end: span.end + done, ..span }));
    assert_eq!(streamed, whole, "chunks of {step} find other spans in {}", Hex(bytes));
    for head in 0..bytes.len().min(8) {
        let head = bytes.get(..head).unwrap_or(&[]);
        if let (Some(need), Some(len)) = (request_head_len(head), request_len(head)) {
            assert!(need <= head.len() && len >= need, "head {} gives length {len}", Hex(head));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The generated modules are the spec's sensors, with the spec's commands in spec order.
    #[test]
    fn generated_modules_match_the_spec() {
        let mut modules: Vec<&str> = SENSORS.iter().map(|m| m.info.name).collect();
        let mut sensors: Vec<&str> = spec().sensors.iter().map(|s| s.name.as_str()).collect();
        modules.sort_unstable();
        sensors.sort_unstable();
        assert_eq!(modules, sensors);
        for sensor in &spec().sensors {
            let names: Vec<&str> = sensor.commands.iter().map(|c| c.name.as_str()).collect();
            let listed: Vec<&str> = module(&sensor.name).commands.iter().map(|c| c.name).collect();
            assert_eq!(listed, names, "{}", sensor.name);
        }
    }

    /// Every example frame of the spec passes every target.
    #[test]
    fn spec_examples_pass_every_target() {
        for sensor in &spec().sensors {
            for c in &sensor.commands {
                for e in &c.examples {
                    let slave = e.slave();
                    for frame in [e.true_request(), e.true_response()].into_iter().flatten() {
                        decode_response(&[&[slave], frame].concat());
                        cli_decode(Hex(frame).to_string().as_bytes());
                    }
                }
            }
        }
    }

    /// Every spec file passes the loader target, and every sensor file,
    /// followed by the common fragment (the seeds of `cargo xtask fuzz`),
    /// loads as the target loads it.
    #[test]
    fn spec_files_pass_the_loader_target() {
        let common = spec_files().iter().find(|(path, _)| path == COMMON_FRAGMENT).map(|(_, text)| *text);
        let common = common.expect("the spec has the common fragment");
        let mut sensor_files = 0;
        for (path, text) in spec_files() {
            spec_loader(text.as_bytes());
            if !is_sensor_file(text) {
                continue;
            }
            sensor_files += 1;
            let joined = [text.as_bytes(), &[0], common.as_bytes()].concat();
            spec_loader(&joined);
            if let Err(d) = load_with(&spec_loader_sources(&joined), &[PathBuf::from("spec")]) {
                panic!("{path} does not load as the spec_loader target's input:\n{d}");
            }
        }
        assert_eq!(sensor_files, spec().sensors.len());
    }
}

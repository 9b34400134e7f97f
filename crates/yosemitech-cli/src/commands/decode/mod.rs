//! `yosemitech decode`: frames from a log or a bus capture, explained.
//!
//! One frame is decoded on its own: the command is found from the frame
//! ([`single::decode_one`]). Several frames (a request and its reply, a hex stream,
//! a `--capture` file) are split into frames by a [`scan::Scanner`]: requests are
//! recognised by the commands' request layouts, replies by their CRC and the
//! length the pending request's command expects; what no loaded command
//! frames (a request of an unknown command, a reply with no request before
//! it) is framed by the runtime's segmenter ([`yosemitech_rtu::segment`]),
//! on the same length rules. Each reply is paired with the request before
//! it and decoded as the command(s) the request names; decodings that fail
//! are dropped and equal ones reported together.
//!
//! The modules: [`input`] reads hex and captures, [`scan`] splits and
//! pairs, [`report`] decodes what was found into values, [`print`] and
//! [`single`] (one frame on its own) write them out; [`candidates`] is what
//! a frame may be.

mod candidates;
mod input;
mod print;
mod report;
mod scan;
mod single;

use std::io::Write;
use std::path::Path;

use serde_json::{Value as Json, json};
use yosemitech_rtu::crc_ok;

use crate::catalog::Catalog;
use crate::cli::{DecodeArgs, DecodeCommandArgs};
use crate::error::{CliError, Kind as ErrorKind, Result};

use self::candidates::{Cand, Filter};
use self::input::{Input, parse_hex, read_capture, read_lines};
use self::print::{print_pair, print_reports};
use self::report::{Report, report};
use self::scan::{Found, Scanner, frame_bytes};
use self::single::decode_one;

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

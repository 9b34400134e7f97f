//! `yosemitech decode`: frames from a log or a bus capture, explained.
//!
//! The explanation is the library's ([`crate::explain`]): this module
//! reads the input ([`input`]), chooses the commands `--sensor` and
//! `--command` leave ([`filter`]), and renders the explanation: a frame on
//! its own as a block ([`single`]), a request with its reply as a block and
//! several entries one line each ([`print`]), or JSON.

mod filter;
mod input;
mod print;
mod single;

use std::io::Write;
use std::path::Path;

use serde_json::{Value as Json, json};

use crate::catalog::Catalog;
use crate::error::{CliError, Kind as ErrorKind, Result};

use crate::explain::{CaptureMode, Explanation, explain, explain_capture};

use self::filter::commands;
use self::input::{Input, parse_hex, read_capture, read_lines};
use self::print::{print_pair, print_reports};
use self::single::print_frame;
use clap::Args;
use std::path::PathBuf;

/// `decode`: the frames and how to read them.
#[derive(Args, Debug)]
pub struct DecodeArgs {
    /// Frames in hex: one frame, a request and its reply, or a stream (arguments are joined).
    #[arg(value_name = "HEX", required_unless_present = "capture", conflicts_with = "capture", num_args = 1..)]
    pub hex: Vec<String>,
    /// Only consider this sensor's commands.
    #[arg(long, value_name = "SENSOR")]
    pub sensor: Option<String>,
    /// Decode as this command.
    #[arg(long, value_name = "COMMAND")]
    pub command: Option<String>,
    /// Print JSON (one document; JSON lines for several transactions and captures).
    #[arg(long)]
    pub json: bool,
}

/// `decode` on the command line: [`DecodeArgs`] and a capture file.
#[derive(Args, Debug)]
pub struct DecodeCommandArgs {
    /// The frames and options.
    #[command(flatten)]
    pub frames: DecodeArgs,
    /// Read a capture from FILE (`-`: stdin): one frame per line, or a hex stream.
    #[arg(long, value_name = "FILE")]
    pub capture: Option<PathBuf>,
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
    let commands = commands(catalog, args)?;
    match input {
        Input::Bytes(bytes) => match explain(&commands, &bytes) {
            Explanation::TooShort(len) => Err(CliError::usage(format!("{len} byte(s) is too short for a frame"))
                .hint("an RTU frame has at least an address, a function code and a 2-byte CRC")),
            Explanation::Frame(frame) => print_frame(&frame, args.json, out),
            Explanation::Exchange(x) => print_pair(&x, args.json, out),
            Explanation::Stream(reports) => print_reports(&reports, CaptureMode::Stream, args.json, out),
        },
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
            let (reports, mode) = explain_capture(&commands, &lines);
            print_reports(&reports, mode, args.json, out)
        }
    }
}

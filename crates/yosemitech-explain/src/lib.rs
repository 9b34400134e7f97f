//! Frames explained: bytes (a frame, a request and its reply, a stream, a
//! capture's lines) in, a value out that says what each frame is, which
//! commands it fits, how requests pair with replies and which decodings
//! agree. The `decode` and `sniff` subcommands render it; the fuzzer
//! drives it. A library of its own, so that the fuzz targets build it
//! without the CLI's dependencies.
//!
//! It works on the spec's model ([`yosemitech_spec::Sensor`]) rather than
//! the generated tables, because the tool also explains frames of spec
//! files loaded at run time, and it decodes through the interpreter.
//!
//! Bytes are split into frames by a [`scan::Scanner`]: requests are
//! recognised by the commands' request layouts, replies by their CRC and the
//! length the pending request's command expects; what no loaded command
//! frames (a request of an unknown command, a reply with no request before
//! it) is framed by the runtime's segmenter ([`yosemitech_rtu::segment`]),
//! on the same length rules. Each reply is paired with the request before
//! it and decoded as the command(s) the request names ([`exchange`]);
//! decodings that fail are dropped and equal ones grouped. Where the bytes
//! are one frame (or hold none), that frame is explained on its own
//! ([`frame`]): its kind, the commands it fits, and its checks, even with a
//! wrong CRC or a function no probe serves.
//!
//! The modules: [`candidates`] is what a frame may be, [`scan`] splits and
//! pairs, [`exchange`] decodes what was found, [`frame`] explains a frame
//! on its own.

#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod candidates;
pub mod exchange;
pub mod finding;
pub mod frame;
pub mod scan;
pub mod sniff;

use yosemitech_rtu::crc_ok;

/// A frame typed by a person: hex with or without spaces, `0x` prefixes,
/// commas, colons, semicolons or dashes between bytes.
pub fn parse_frame(text: &str) -> Result<Vec<u8>, String> {
    let mut compact = String::new();
    for token in text.split(|c: char| c.is_whitespace() || matches!(c, ',' | ':' | '-' | ';')) {
        let token = token.strip_prefix("0x").or_else(|| token.strip_prefix("0X")).unwrap_or(token);
        compact.push_str(token);
    }
    yosemitech_spec::parse_hex(&compact)
}

pub use self::candidates::{Candidate, Commands, Decoding};
pub use self::exchange::{Exchange, Report, Status};
pub use self::finding::Finding;
pub use self::frame::{Frame, FrameStatus, Kind};
pub use self::scan::{Found, Line, Scanner};

/// What bytes are.
pub enum Explanation<'c> {
    /// Fewer bytes than the shortest frame.
    TooShort(usize),
    /// One frame (or bytes no frame is found in), on its own.
    Frame(Frame<'c>),
    /// One request and its reply.
    Exchange(Exchange<'c>),
    /// Several entries, in input order.
    Stream(Vec<Report<'c>>),
}

/// How a capture was read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureMode {
    /// As one hex stream, wrapped over lines.
    Stream,
    /// One frame (or a few) per line.
    Lines,
}

/// Explains `bytes` given as one stream.
pub fn explain<'c>(commands: &Commands<'c>, bytes: &[u8]) -> Explanation<'c> {
    let found = Scanner::new(&commands.all).scan_stream(bytes);
    let frames: usize = found.iter().map(Found::frames).sum();
    let noise = found.iter().any(|f| matches!(f, Found::Noise(_)));
    let one_pair = matches!(found.as_slice(), [Found::Pair { reply: Some(_), .. }]);
    // One frame is explained on its own, so is a frame the scanner cannot
    // frame (a wrong CRC, a function no probe serves), and so are bytes
    // whose CRC holds over all of them.
    if !one_pair && (frames == 0 || (frames == 1 && !noise) || (bytes.len() >= 4 && crc_ok(bytes))) {
        return explain_frame(commands, bytes);
    }
    let mut reports: Vec<Report<'c>> = found.into_iter().map(|f| exchange::report(commands, f)).collect();
    match (one_pair, reports.len()) {
        (true, 1) => match reports.pop() {
            Some(Report::Exchange(x)) => Explanation::Exchange(x),
            Some(other) => Explanation::Stream(vec![other]),
            None => Explanation::Stream(reports),
        },
        _ => Explanation::Stream(reports),
    }
}

/// Explains `frame` on its own, whatever the scanner would make of it.
pub fn explain_frame<'c>(commands: &Commands<'c>, frame: &[u8]) -> Explanation<'c> {
    frame::explain_frame(commands, frame).map_or(Explanation::TooShort(frame.len()), Explanation::Frame)
}

/// Explains a capture's lines: one frame per line, or one stream wrapped
/// over lines, whichever explains more bytes as frames (one line is a stream).
pub fn explain_capture<'c>(commands: &Commands<'c>, lines: &[Line<'_>]) -> (Vec<Report<'c>>, CaptureMode) {
    let scanner = Scanner::new(&commands.all);
    let (found, mode) = if lines.iter().filter(|l| !l.readings.is_empty()).count() == 1 {
        (scanner.scan_joined(lines), CaptureMode::Stream)
    } else {
        let by_line = scanner.scan_lines(lines);
        let as_stream = scanner.scan_joined(lines);
        if scan::frame_bytes(&as_stream) > scan::frame_bytes(&by_line) {
            (as_stream, CaptureMode::Stream)
        } else {
            (by_line, CaptureMode::Lines)
        }
    };
    (found.into_iter().map(|f| exchange::report(commands, f)).collect(), mode)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where each piece of an explanation lies: (offset, length).
    fn pieces(explanation: &Explanation<'_>, len: usize) -> Vec<(usize, usize)> {
        let mut pieces: Vec<(usize, usize)> = match explanation {
            Explanation::TooShort(_) | Explanation::Frame(_) => {
                vec![(0, len)].into_iter().filter(|&(_, n)| n > 0).collect()
            }
            Explanation::Exchange(x) => {
                x.request.iter().map(|(f, _)| f).chain(&x.reply).map(|f| (f.place.offset, f.bytes.len())).collect()
            }
            Explanation::Stream(reports) => reports
                .iter()
                .flat_map(|r| match r {
                    Report::Exchange(x) => x.request.iter().map(|(f, _)| f).chain(&x.reply).collect::<Vec<_>>(),
                    Report::Noise(f) => vec![f],
                    Report::Unreadable { .. } => Vec::new(),
                })
                .map(|f| (f.place.offset, f.bytes.len()))
                .collect(),
        };
        pieces.sort_unstable();
        pieces
    }

    /// Every sensor's printed frames in one stream, with a byte of noise
    /// after each: the entries cover every byte exactly once, and each
    /// frame is an entry's request or reply.
    #[test]
    fn a_stream_of_every_printed_frame_is_covered_exactly() {
        let spec = yosemitech_tests::spec();
        let commands = Commands::new(&spec.sensors);
        for sensor in &spec.sensors {
            let mut bytes = Vec::new();
            let mut starts = Vec::new();
            for c in &sensor.commands {
                for e in &c.examples {
                    for frame in [e.true_request(), e.true_response()].into_iter().flatten() {
                        starts.push(bytes.len());
                        bytes.extend_from_slice(frame);
                        bytes.push(0xEE);
                    }
                }
            }
            let explanation = explain(&commands, &bytes);
            let mut at = 0;
            for (offset, len) in pieces(&explanation, bytes.len()) {
                assert_eq!((offset, len > 0), (at, true), "{}: a gap or an overlap at byte {at}", sensor.name);
                at += len;
            }
            assert_eq!(at, bytes.len(), "{}: the entries stop short", sensor.name);
            if let Explanation::Stream(_) = explanation {
                let framed: Vec<usize> = pieces(&explanation, bytes.len()).iter().map(|&(offset, _)| offset).collect();
                for start in &starts {
                    assert!(framed.contains(start), "{}: no entry starts at the frame at {start}", sensor.name);
                }
            }
        }
    }
}

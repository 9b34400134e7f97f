//! What `decode` reads: hex as people type it, and a capture file's lines
//! (labels, comments, one frame per line or one stream wrapped over lines).

use std::io::Read as _;
use std::path::Path;

use yosemitech_rtu::bytes::byte;

use crate::error::{CliError, Result};
use crate::explain::Line;

/// The bytes to decode.
pub(super) enum Input {
    /// From the arguments.
    Bytes(Vec<u8>),
    /// A capture's text.
    Capture(String),
}

/// Reads a capture file, or stdin for `-`.
pub(super) fn read_capture(path: &Path) -> Result<String> {
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
pub(super) fn parse_hex(text: &str) -> Result<Vec<u8>> {
    // `-` is how other tools say "stdin": here that is `--capture -`.
    if text.trim() == "-" {
        return Err(CliError::usage("`-` is not a frame: to read frames from stdin, use `--capture -`")
            .hint("`decode --capture -` reads a capture (one frame a line, or a hex stream) from stdin"));
    }
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

/// At most this many leading words are tried as a label.
pub(super) const MAX_LABEL_WORDS: usize = 4;

/// Splits a capture into lines. Blank lines and `#` or `//` comments are
/// skipped. A label ending in a colon and a space (`12:00:01 TX: 01 03 ...`)
/// is dropped; leading words that are not hex may be a label too.
pub(super) fn read_lines(text: &str) -> Vec<Line<'_>> {
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

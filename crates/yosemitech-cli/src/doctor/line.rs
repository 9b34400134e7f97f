//! The raw line the doctor talks on: bytes out, every byte back with when
//! it came, and what those bytes are (an echo, a frame, garbage).
//!
//! The client of `yosemitech_rtu` hides exactly what a diagnosis needs to
//! see (it skips noise, swallows echoes, retries), so the doctor writes a
//! request and reads whatever the line carries until a deadline.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use yosemitech_rtu::{FrameError, LineSettings, SerialConfig, SerialTransport, Transport};
use yosemitech_spec::CommandSpec;

/// A serial line whose settings the doctor can change.
pub trait Line {
    /// Sets the line's serial settings.
    fn configure(&mut self, settings: LineSettings) -> io::Result<()>;
    /// Sends `frame`.
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()>;
    /// Reads what has arrived, waiting up to `timeout` for a first byte; 0 when none came.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    /// Drops what has arrived unread.
    fn discard_input(&mut self) -> io::Result<()>;
}

/// A serial port, reopened at each change of settings (some adapters
/// apply parity and stop bits only on open).
pub struct SerialLine {
    path: String,
    port: Option<(LineSettings, SerialTransport)>,
}

impl SerialLine {
    /// The port at `path`, opened by the first [`Line::configure`].
    pub fn new(path: impl Into<String>) -> Self {
        Self { path: path.into(), port: None }
    }

    fn port(&mut self) -> io::Result<&mut SerialTransport> {
        self.port
            .as_mut()
            .map(|(_, port)| port)
            .ok_or_else(|| io::Error::new(io::ErrorKind::NotConnected, "the line is not configured"))
    }
}

impl Line for SerialLine {
    fn configure(&mut self, settings: LineSettings) -> io::Result<()> {
        if self.port.as_ref().is_some_and(|(now, _)| *now == settings) {
            return Ok(());
        }
        // Closed before it is opened again.
        self.port = None;
        let port = SerialTransport::open(&SerialConfig::with_settings(self.path.clone(), settings))?;
        self.port = Some((settings, port));
        Ok(())
    }

    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        self.port()?.write_all(frame)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.port()?.read(buf, timeout)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.port()?.discard_input()
    }
}

/// One request and everything the line carried back.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Exchange {
    /// The request as sent.
    pub sent: Vec<u8>,
    /// Every byte that came back, in order.
    pub received: Vec<u8>,
    /// When each run of bytes came, after the request was sent: (time, bytes so far).
    arrivals: Vec<(Duration, usize)>,
}

impl Exchange {
    /// True when the line carried the request back (an adapter that
    /// hears its own transmitter): the reply starts with the whole request.
    pub fn echoed(&self) -> bool {
        !self.sent.is_empty() && self.received.starts_with(&self.sent)
    }

    /// The bytes after the echo, if any: what the far end sent.
    pub fn answer(&self) -> &[u8] {
        if self.echoed() { self.received.get(self.sent.len()..).unwrap_or(&[]) } else { &self.received }
    }

    /// Time from the end of the request to the answer's first byte.
    pub fn turnaround(&self) -> Option<Duration> {
        let skip = self.received.len() - self.answer().len();
        self.arrivals.iter().find(|(_, upto)| *upto > skip).map(|(at, _)| *at)
    }
}

/// How long the line stays quiet after an answer before it is taken as complete.
const QUIET: Duration = Duration::from_millis(60);

/// Sends `request` and reads until `wait` passes, or until the answer
/// (what follows an echo) has started and the line has been quiet for a
/// while, or until `stop` is set.
pub fn exchange(line: &mut dyn Line, request: &[u8], wait: Duration, stop: &AtomicBool) -> io::Result<Exchange> {
    const SLICE: Duration = Duration::from_millis(20);
    line.discard_input()?;
    line.write_all(request)?;
    let sent_at = Instant::now();
    let deadline = sent_at + wait;
    let mut out = Exchange { sent: request.to_vec(), received: Vec::new(), arrivals: Vec::new() };
    let mut last_byte = sent_at;
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::SeqCst) {
        let now = Instant::now();
        if now >= deadline {
            break;
        }
        let n = line.read(&mut buf, (deadline - now).min(SLICE))?.min(buf.len());
        if n > 0 {
            out.received.extend_from_slice(buf.get(..n).unwrap_or(&[]));
            out.arrivals.push((sent_at.elapsed(), out.received.len()));
            last_byte = Instant::now();
        } else if !out.answer().is_empty() && !out.sent.starts_with(&out.received) && last_byte.elapsed() >= QUIET {
            break;
        }
    }
    Ok(out)
}

/// What an answer is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Heard {
    /// No byte.
    Nothing,
    /// The reply the command expects, from the address asked; its register data.
    Reply(Vec<u8>),
    /// An exception reply with this code.
    Exception(u8),
    /// A well-formed reply (its CRC holds) from another address.
    OtherAddress(u8),
    /// A frame from the address asked, for the command asked, that does
    /// not hold together (CRC, length, byte count): a reply damaged on the way.
    Damaged,
    /// Bytes that are not a reply to the request at all.
    Garbage,
}

/// What `answer` is, as the answer to `command` sent to `slave`.
pub fn hear(command: &CommandSpec, slave: u8, answer: &[u8]) -> Heard {
    if answer.is_empty() {
        return Heard::Nothing;
    }
    let layout = command.layout();
    let expected_slave = command.fixed_slave.unwrap_or(slave);
    let function = layout.function.code();
    match layout.decode_response(slave, answer) {
        Ok(data) => Heard::Reply(data.to_vec()),
        Err(FrameError::Exception { .. }) => Heard::Exception(answer.get(2).copied().unwrap_or(0)),
        Err(FrameError::WrongSlave { actual, .. }) => Heard::OtherAddress(actual),
        Err(_) => match answer {
            [a, f, ..] if *a == expected_slave && (*f == function || *f == function | 0x80) => Heard::Damaged,
            _ => Heard::Garbage,
        },
    }
}

/// Bytes as `01 03 00 ...`, the form every report shows.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exchange_of(sent: &[u8], received: &[u8]) -> Exchange {
        Exchange { sent: sent.to_vec(), received: received.to_vec(), arrivals: vec![(Duration::from_millis(5), 8)] }
    }

    #[test]
    fn an_echo_is_the_whole_request_read_back() {
        let request = [1, 3, 0x09, 0, 0, 7, 0x04, 0x08];
        let echo = exchange_of(&request, &[&request[..], &[1, 3, 2][..]].concat());
        assert!(echo.echoed());
        assert_eq!(echo.answer(), [1, 3, 2]);
        // A reply that starts as the request does (address, function) is no echo.
        let reply = exchange_of(&request, &[1, 3, 0x0E, 0, 0]);
        assert!(!reply.echoed());
        assert_eq!(reply.answer(), [1, 3, 0x0E, 0, 0]);
    }
}

//! A serial port (RS-485 adapter) over the `serialport` crate.

use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use serialport::{ClearBuffer, SerialPort};

use super::{MAX_WAIT, Transport, is_no_data};
use crate::Hex;
use crate::frame::MAX_ADU;
use crate::timing::{CharFormat, DataBits, LineSettings, LineTiming, Parity, StopBits};

/// Time allowed beyond the frame's own line time for a write to drain.
const WRITE_SLACK: Duration = Duration::from_secs(1);

/// Time allowed beyond the frame's own line time for its echo to come back
/// (USB adapters buffer for up to 16 ms before passing bytes on).
const ECHO_SLACK: Duration = Duration::from_millis(100);

/// How to open a serial port. [`SerialConfig::new`] gives 9600 baud 8N1, the
/// setting of Yosemitech probes, without echo suppression.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct SerialConfig {
    /// The device: `/dev/ttyUSB0`, `COM3`.
    pub path: String,
    /// Bits per second (9600 for Yosemitech probes).
    pub baud: u32,
    /// Data bits per character.
    pub data_bits: DataBits,
    /// Whether a parity bit follows the data bits, and which.
    pub parity: Parity,
    /// Stop bits ending each character: 1 or 2.
    pub stop_bits: StopBits,
    /// Read back and drop the bytes of each sent frame: for RS-485 adapters
    /// that receive their own transmission. A read-back that differs from
    /// what was sent (a collision) is an [`io::ErrorKind::InvalidData`] error.
    pub echo_suppression: bool,
}

impl SerialConfig {
    /// The port at `path`, 9600 baud 8N1, no echo suppression.
    pub fn new(path: impl Into<String>) -> Self {
        let format = CharFormat::EIGHT_N_1;
        Self {
            path: path.into(),
            baud: 9600,
            data_bits: format.data_bits,
            parity: format.parity,
            stop_bits: format.stop_bits,
            echo_suppression: false,
        }
    }

    /// The port at `path` with a line's baud rate and character format (a
    /// sensor's spec settings), no echo suppression.
    pub fn with_settings(path: impl Into<String>, settings: LineSettings) -> Self {
        Self {
            baud: settings.baud,
            data_bits: settings.format.data_bits,
            parity: settings.format.parity,
            stop_bits: settings.format.stop_bits,
            ..Self::new(path)
        }
    }

    /// The character format of `data_bits`, `parity` and `stop_bits` (`8N1`).
    pub fn char_format(&self) -> CharFormat {
        CharFormat { data_bits: self.data_bits, parity: self.parity, stop_bits: self.stop_bits }
    }

    /// The line timing of this baud rate and format.
    pub fn line_timing(&self) -> LineTiming {
        LineTiming::new(self.baud, self.char_format())
    }
}

/// RTU frames over a serial port.
///
/// Ports open exclusively (the `serialport` default). Each write waits until
/// the bytes have left the UART (`tcdrain`), so the client's t3.5 is counted
/// from the real end of the frame. Reads use `serialport`'s per-call timeout.
pub struct SerialTransport {
    port: Box<dyn SerialPort>,
    timing: LineTiming,
    echo_suppression: bool,
    /// The timeout last given to the port, to skip redundant calls.
    timeout: Option<Duration>,
}

impl SerialTransport {
    /// Opens and configures the port described by `config`. The error
    /// names the port and the settings attempted, and keeps the cause's kind
    /// (`NotFound`, `PermissionDenied`, ...).
    pub fn open(config: &SerialConfig) -> io::Result<Self> {
        let port = serialport::new(config.path.as_str(), config.baud)
            .data_bits(match config.data_bits {
                DataBits::Seven => serialport::DataBits::Seven,
                DataBits::Eight => serialport::DataBits::Eight,
            })
            .parity(match config.parity {
                Parity::None => serialport::Parity::None,
                Parity::Even => serialport::Parity::Even,
                Parity::Odd => serialport::Parity::Odd,
            })
            .stop_bits(match config.stop_bits {
                StopBits::One => serialport::StopBits::One,
                StopBits::Two => serialport::StopBits::Two,
            })
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::ZERO)
            .open()
            .map_err(|e| {
                let e = io::Error::from(e);
                io::Error::new(
                    e.kind(),
                    format!("cannot open serial port {} at {} baud: {e}", config.path, config.baud),
                )
            })?;
        Ok(Self::from_port(port, config))
    }

    /// Wraps a port that is already open, leaving its settings as they are.
    /// `config` supplies the line timing and echo suppression; its path is
    /// not used.
    pub fn from_port(port: Box<dyn SerialPort>, config: &SerialConfig) -> Self {
        Self { port, timing: config.line_timing(), echo_suppression: config.echo_suppression, timeout: None }
    }

    /// Wraps a native Unix port, such as one end of `TTYPort::pair()`; see
    /// [`SerialTransport::from_port`].
    #[cfg(unix)]
    pub fn from_tty(port: serialport::TTYPort, config: &SerialConfig) -> Self {
        Self::from_port(Box::new(port), config)
    }

    /// The port, for settings this transport does not cover (RTS, DTR, break).
    pub fn port(&self) -> &dyn SerialPort {
        self.port.as_ref()
    }

    /// The port, mutably.
    pub fn port_mut(&mut self) -> &mut dyn SerialPort {
        self.port.as_mut()
    }

    fn set_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        let timeout = timeout.min(MAX_WAIT);
        // Windows timeouts are whole milliseconds, and 0 does not mean "return at once"
        // with the COMMTIMEOUTS `serialport` uses.
        #[cfg(windows)]
        let timeout = timeout.max(Duration::from_millis(1));
        if self.timeout != Some(timeout) {
            self.port.set_timeout(timeout)?;
            self.timeout = Some(timeout);
        }
        Ok(())
    }

    /// Reads back the echo of `frame` and checks it.
    fn swallow_echo(&mut self, frame: &[u8]) -> io::Result<()> {
        let allowed = self.timing.frame_time(frame.len()).saturating_add(ECHO_SLACK);
        let deadline = Instant::now().checked_add(allowed.min(MAX_WAIT));
        let mut echo = [0u8; MAX_ADU];
        for sent in frame.chunks(MAX_ADU) {
            let echo = echo.get_mut(..sent.len()).unwrap_or_default();
            let mut got = 0;
            while let Some(rest) = echo.get_mut(got..).filter(|rest| !rest.is_empty()) {
                let remaining = deadline.map_or(Duration::ZERO, |d| d.saturating_duration_since(Instant::now()));
                if remaining.is_zero() {
                    return Err(io::Error::new(
                        io::ErrorKind::TimedOut,
                        format!("RS-485 echo incomplete: read back {got} of {} bytes", sent.len()),
                    ));
                }
                got += self.read(rest, remaining)?.min(rest.len());
            }
            if echo != sent {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!("RS-485 echo differs (collision?): sent {}, read back {}", Hex(sent), Hex(echo)),
                ));
            }
        }
        Ok(())
    }
}

impl Transport for SerialTransport {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        self.set_timeout(self.timing.frame_time(frame.len()).saturating_add(WRITE_SLACK))?;
        self.port.write_all(frame)?;
        self.port.flush()?;
        if self.echo_suppression {
            self.swallow_echo(frame)?;
        }
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        self.set_timeout(timeout)?;
        match self.port.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if is_no_data(&e) => Ok(0),
            Err(e) => Err(e),
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.port.clear(ClearBuffer::Input).map_err(io::Error::from)
    }

    fn line_timing(&self) -> Option<LineTiming> {
        Some(self.timing)
    }
}

impl core::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SerialTransport")
            .field("port", &self.port.name())
            .field("timing", &self.timing)
            .field("echo_suppression", &self.echo_suppression)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_port_is_named_in_the_error() {
        let path = "/nonexistent/yosemitech-test-port";
        let Err(e) = SerialTransport::open(&SerialConfig::new(path)) else { panic!("{path} opened") };
        assert_eq!(e.kind(), io::ErrorKind::NotFound, "{e}");
        let text = e.to_string();
        assert!(text.contains(path) && text.contains("9600 baud"), "{text}");
    }
}

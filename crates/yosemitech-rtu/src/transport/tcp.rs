//! RTU-over-TCP: raw RTU frames (with CRC) over a TCP stream, as serial
//! device servers and RS-485 gateways in "transparent" mode carry them.
//! Not Modbus TCP (no MBAP header).

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use super::{Transport, is_no_data};
use crate::timing::LineTiming;

/// The shortest read timeout the socket accepts (zero means "block forever").
const MIN_SOCKET_TIMEOUT: Duration = Duration::from_micros(1);

/// Most bytes [`Transport::discard_input`] reads and drops in one call.
const DISCARD_LIMIT: usize = 64 * 1024;

/// RTU frames over a TCP connection to a serial gateway.
///
/// The gateway owns the serial line and its timing, so
/// [`Transport::line_timing`] is `None` and the client adds no t3.5 wait.
/// A connection closed by the gateway is [`io::ErrorKind::UnexpectedEof`].
#[derive(Debug)]
pub struct TcpTransport {
    stream: TcpStream,
    read_timeout: Option<Duration>,
}

impl TcpTransport {
    /// Connects to `addr`, trying each address it resolves to, each within
    /// `timeout`. `timeout` also bounds each write.
    pub fn connect<A: ToSocketAddrs>(addr: A, timeout: Duration) -> io::Result<Self> {
        let mut last_error = None;
        for addr in addr.to_socket_addrs()? {
            match TcpStream::connect_timeout(&addr, timeout) {
                Ok(stream) => {
                    stream.set_write_timeout(Some(timeout.max(MIN_SOCKET_TIMEOUT)))?;
                    return Self::from_stream(stream);
                }
                Err(error) => last_error = Some(error),
            }
        }
        Err(last_error.unwrap_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "address resolved to nothing")))
    }

    /// Wraps a connected stream; turns Nagle's algorithm off so each frame
    /// leaves at once.
    pub fn from_stream(stream: TcpStream) -> io::Result<Self> {
        stream.set_nodelay(true)?;
        Ok(Self { stream, read_timeout: None })
    }

    /// The underlying stream (for its addresses and socket options).
    pub fn get_ref(&self) -> &TcpStream {
        &self.stream
    }

    /// The stream, dropping the transport.
    pub fn into_inner(self) -> TcpStream {
        self.stream
    }

    fn drain(&mut self) -> io::Result<()> {
        let mut scratch = [0u8; 512];
        let mut dropped = 0;
        while dropped < DISCARD_LIMIT {
            match self.stream.read(&mut scratch) {
                Ok(0) => return Err(closed()),
                Ok(n) => dropped += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(()),
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

fn closed() -> io::Error {
    io::Error::new(io::ErrorKind::UnexpectedEof, "connection closed by the gateway")
}

impl Transport for TcpTransport {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        self.stream.write_all(frame)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let timeout = Some(timeout.max(MIN_SOCKET_TIMEOUT));
        if self.read_timeout != timeout {
            self.stream.set_read_timeout(timeout)?;
            self.read_timeout = timeout;
        }
        match self.stream.read(buf) {
            Ok(0) => Err(closed()),
            Ok(n) => Ok(n),
            Err(e) if is_no_data(&e) => Ok(0),
            Err(e) => Err(e),
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.stream.set_nonblocking(true)?;
        let result = self.drain();
        self.stream.set_nonblocking(false)?;
        result
    }

    fn line_timing(&self) -> Option<LineTiming> {
        None
    }
}

//! Links under the tokio [`AsyncClient`](crate::AsyncClient) (feature
//! `tokio`): RTU frames on any tokio stream ([`RtuStream`]: TCP to a
//! transparent gateway, a pipe), a serial port ([`AsyncSerial`], feature
//! `tokio-serial`), and Modbus TCP to an Ethernet gateway ([`MbapLink`]).
//!
//! A link moves bytes; it knows no Modbus timing, framing or retries (the
//! [`ClientCore`](crate::client::ClientCore) does). Every read is
//! cancel-safe: a read future dropped before it completes loses no byte,
//! which is what lets a dropped transaction leave the bus usable.

use std::future::Future;
use std::io;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

use crate::frame::MAX_ADU;
use crate::mbap::{self, HEADER_LEN, Header, MAX_MBAP_ADU};
use crate::timing::LineTiming;

/// A byte link to one or more Modbus devices, for the [`AsyncClient`](crate::AsyncClient).
///
/// The futures carry no `Send` bound here; those of the links in this
/// module are `Send` when their stream is, so a client on them can be moved
/// into a spawned task.
pub trait AsyncLink {
    /// Sends one whole RTU frame. A write interrupted by dropping its future
    /// is finished before the next one (links that can tell), so the far end
    /// never sees half a frame followed by another.
    fn write_frame(&mut self, frame: &[u8]) -> impl Future<Output = io::Result<()>>;

    /// Reads what has arrived into `buf` (not empty), waiting for at least
    /// one byte; the client bounds the wait. A closed link is an error, not
    /// 0. Cancel-safe.
    fn read(&mut self, buf: &mut [u8]) -> impl Future<Output = io::Result<usize>>;

    /// Drops input held below the link's reads (an OS or adapter buffer)
    /// where the platform allows. The client first reads pending bytes (to
    /// log and time them), then calls this. Default: nothing to drop.
    fn discard_input(&mut self) -> io::Result<()> {
        Ok(())
    }

    /// Baud rate and character format of a serial line (t3.5 and the
    /// request's time on the line follow from it); `None` (the default) for
    /// links without line timing of their own.
    fn line_timing(&self) -> Option<LineTiming> {
        None
    }
}

/// RTU frames (with CRC) on a tokio byte stream: a `TcpStream` to a serial
/// gateway in transparent mode, a pipe, a pty opened some other way.
#[derive(Debug)]
pub struct RtuStream<S> {
    stream: S,
    line_timing: Option<LineTiming>,
}

impl<S> RtuStream<S> {
    /// Frames on `stream`, without line timing (the far end owns the line).
    pub fn new(stream: S) -> Self {
        Self { stream, line_timing: None }
    }

    /// Builder: the stream is (or stands for) a serial line of this timing.
    #[must_use]
    pub fn with_line_timing(mut self, line_timing: Option<LineTiming>) -> Self {
        self.line_timing = line_timing;
        self
    }

    /// The stream.
    pub fn get_ref(&self) -> &S {
        &self.stream
    }

    /// The stream, mutably (bytes moved through it bypass the client).
    pub fn get_mut(&mut self) -> &mut S {
        &mut self.stream
    }

    /// The stream, dropping the link.
    pub fn into_inner(self) -> S {
        self.stream
    }
}

impl<S: AsyncRead + AsyncWrite + Unpin> AsyncLink for RtuStream<S> {
    async fn write_frame(&mut self, frame: &[u8]) -> io::Result<()> {
        self.stream.write_all(frame).await?;
        self.stream.flush().await
    }

    async fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        read_some(&mut self.stream, buf).await
    }

    fn line_timing(&self) -> Option<LineTiming> {
        self.line_timing
    }
}

/// Reads at least one byte; end of stream is an error.
async fn read_some<S: AsyncRead + Unpin>(stream: &mut S, buf: &mut [u8]) -> io::Result<usize> {
    if buf.is_empty() {
        return Ok(0);
    }
    match stream.read(buf).await? {
        0 => Err(io::Error::new(io::ErrorKind::UnexpectedEof, "the link was closed")),
        n => Ok(n),
    }
}

/// A serial port (RS-485 adapter) through tokio-serial (feature `tokio-serial`).
#[cfg(feature = "tokio-serial")]
#[derive(Debug)]
pub struct AsyncSerial {
    port: tokio_serial::SerialStream,
    line_timing: LineTiming,
}

#[cfg(feature = "tokio-serial")]
impl AsyncSerial {
    /// Opens the port `config` describes (baud rate, format; echo
    /// suppression is not supported here and is ignored).
    pub fn open(config: &super::SerialConfig) -> io::Result<Self> {
        use crate::timing::{DataBits, Parity, StopBits};
        let builder = tokio_serial::new(config.path.as_str(), config.baud)
            .data_bits(match config.data_bits {
                DataBits::Seven => tokio_serial::DataBits::Seven,
                DataBits::Eight => tokio_serial::DataBits::Eight,
            })
            .parity(match config.parity {
                Parity::None => tokio_serial::Parity::None,
                Parity::Even => tokio_serial::Parity::Even,
                Parity::Odd => tokio_serial::Parity::Odd,
            })
            .stop_bits(match config.stop_bits {
                StopBits::One => tokio_serial::StopBits::One,
                StopBits::Two => tokio_serial::StopBits::Two,
            })
            .flow_control(tokio_serial::FlowControl::None);
        let port = tokio_serial::SerialStream::open(&builder)?;
        Ok(Self { port, line_timing: config.line_timing() })
    }

    /// The port.
    pub fn port(&self) -> &tokio_serial::SerialStream {
        &self.port
    }
}

#[cfg(feature = "tokio-serial")]
impl AsyncLink for AsyncSerial {
    async fn write_frame(&mut self, frame: &[u8]) -> io::Result<()> {
        self.port.write_all(frame).await?;
        self.port.flush().await
    }

    async fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        read_some(&mut self.port, buf).await
    }

    fn discard_input(&mut self) -> io::Result<()> {
        use tokio_serial::SerialPort;
        self.port.clear(tokio_serial::ClearBuffer::Input).map_err(io::Error::from)
    }

    fn line_timing(&self) -> Option<LineTiming> {
        Some(self.line_timing)
    }
}

/// Modbus TCP (MBAP) to an Ethernet gateway, presented to the client as
/// RTU frames: each frame written leaves as an MBAP ADU with the next
/// transaction id (unit id = slave address, CRC dropped); each ADU read
/// comes back as the RTU frame carrying its PDU, with its CRC computed
/// ([`mbap::adu_to_rtu`]).
///
/// Replies whose transaction id is not the last request's (late replies of
/// an abandoned request) are dropped here, so the client never sees them.
/// Progress is kept in the link, not in futures: a dropped read or write is
/// resumed by the next call.
#[derive(Debug)]
pub struct MbapLink<S> {
    stream: S,
    transaction: u16,
    /// The ADU being written: `out[written..out_len]` is still to go.
    out: [u8; MAX_MBAP_ADU],
    out_len: usize,
    written: usize,
    /// The ADU being read: `adu[..adu_filled]`.
    adu: [u8; MAX_MBAP_ADU],
    adu_filled: usize,
    /// The RTU frame of the last matching ADU: `rtu[rtu_read..rtu_len]` not yet read.
    rtu: [u8; MAX_ADU],
    rtu_len: usize,
    rtu_read: usize,
}

impl<S> MbapLink<S> {
    /// Modbus TCP on `stream` (a connected `TcpStream`).
    pub fn new(stream: S) -> Self {
        Self {
            stream,
            transaction: 0,
            out: [0; MAX_MBAP_ADU],
            out_len: 0,
            written: 0,
            adu: [0; MAX_MBAP_ADU],
            adu_filled: 0,
            rtu: [0; MAX_ADU],
            rtu_len: 0,
            rtu_read: 0,
        }
    }

    /// The transaction id of the last request sent.
    pub fn transaction(&self) -> u16 {
        self.transaction
    }

    /// The stream.
    pub fn get_ref(&self) -> &S {
        &self.stream
    }

    /// The stream, dropping the link.
    pub fn into_inner(self) -> S {
        self.stream
    }
}

impl<S: AsyncRead + AsyncWrite + Unpin> MbapLink<S> {
    /// Writes what is left of the current ADU.
    async fn finish_write(&mut self) -> io::Result<()> {
        while self.written < self.out_len {
            let pending = self.out.get(self.written..self.out_len).unwrap_or(&[]);
            let n = self.stream.write(pending).await?;
            if n == 0 {
                return Err(io::Error::new(io::ErrorKind::WriteZero, "the gateway stopped reading"));
            }
            self.written += n;
        }
        self.stream.flush().await
    }

    /// Reads ADUs until one answers the last request; leaves its RTU frame in `rtu`.
    async fn next_reply(&mut self) -> io::Result<()> {
        loop {
            let want = match Header::parse(self.adu.get(..self.adu_filled).unwrap_or(&[])) {
                Ok(header) => header.adu_len(),
                Err(mbap::MbapError::Truncated { .. }) => HEADER_LEN,
                Err(error) => return Err(io::Error::new(io::ErrorKind::InvalidData, error)),
            };
            if self.adu_filled < want {
                let buf = self.adu.get_mut(self.adu_filled..want).unwrap_or_default();
                self.adu_filled += read_some(&mut self.stream, buf).await?;
                continue;
            }
            let adu = self.adu.get(..want).unwrap_or(&[]);
            self.adu_filled = 0;
            let (header, len) =
                mbap::adu_to_rtu(adu, &mut self.rtu).map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))?;
            if header.transaction == self.transaction {
                self.rtu_len = len;
                self.rtu_read = 0;
                return Ok(());
            }
            log!(
                debug,
                transaction = header.transaction,
                expected = self.transaction,
                "dropping a late Modbus TCP reply"
            );
        }
    }
}

impl<S: AsyncRead + AsyncWrite + Unpin> AsyncLink for MbapLink<S> {
    async fn write_frame(&mut self, frame: &[u8]) -> io::Result<()> {
        self.finish_write().await?;
        let transaction = self.transaction.wrapping_add(1);
        let len = mbap::rtu_to_adu(frame, transaction, &mut self.out)
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        self.transaction = transaction;
        // A reply converted but not read belongs to the previous request.
        self.rtu_len = 0;
        self.rtu_read = 0;
        self.out_len = len;
        self.written = 0;
        self.finish_write().await
    }

    async fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        if self.rtu_read >= self.rtu_len {
            self.next_reply().await?;
        }
        let pending = self.rtu.get(self.rtu_read..self.rtu_len).unwrap_or(&[]);
        let n = pending.len().min(buf.len());
        if let (Some(to), Some(from)) = (buf.get_mut(..n), pending.get(..n)) {
            to.copy_from_slice(from);
        }
        self.rtu_read += n;
        Ok(n)
    }
}

/// An in-process responder as an async link: each frame written is answered
/// at once, in the caller's task; a read with nothing queued waits forever
/// (nothing can arrive before the next write), so the client's reply
/// timeout ends it. The in-memory link of tests and benchmarks, on the same
/// [`ResponderTransport`](super::ResponderTransport) the blocking client uses.
impl<R: super::Responder> AsyncLink for super::ResponderTransport<R> {
    async fn write_frame(&mut self, frame: &[u8]) -> io::Result<()> {
        super::Transport::write_all(self, frame)
    }

    async fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        match super::Transport::read(self, buf, std::time::Duration::ZERO)? {
            0 => std::future::pending().await,
            n => Ok(n),
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        super::Transport::discard_input(self)
    }

    fn line_timing(&self) -> Option<LineTiming> {
        super::Transport::line_timing(self)
    }
}

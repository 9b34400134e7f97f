//! Byte transports under the [`Client`](crate::Client): serial port,
//! RTU-over-TCP and in-memory.
//!
//! A transport moves raw RTU frames; it knows nothing about Modbus. Framing,
//! timing, retries and checks live in the client, once, for every transport.

use std::io;
use std::time::Duration;

use crate::timing::LineTiming;

#[cfg(feature = "tokio")]
mod asynchronous;
mod memory;
#[cfg(feature = "serial")]
mod serial;
mod tcp;

#[cfg(feature = "tokio-serial")]
pub use asynchronous::AsyncSerial;
#[cfg(feature = "tokio")]
pub use asynchronous::{AsyncLink, MbapLink, RtuStream};
pub use memory::{MemoryTransport, Responder, ResponderTransport};
#[cfg(feature = "serial")]
pub use serial::{SerialConfig, SerialTransport};
pub use tcp::TcpTransport;

/// A byte link to one or more Modbus devices.
///
/// Object-safe: `Client<Box<dyn Transport + Send>>` works.
pub trait Transport {
    /// Sends one whole frame. Returns once the bytes have been handed to the
    /// line (for a serial port: transmitted, and their echo swallowed when
    /// echo suppression is on).
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()>;

    /// Reads what has arrived into `buf`, waiting at most `timeout` for the
    /// first byte. Returns the number of bytes read, and 0 when nothing
    /// arrived in time. Never blocks past `timeout` (give or take the
    /// scheduler); a zero `timeout` only takes what is already there.
    ///
    /// May return 0 before `timeout` has passed (an interrupted wait):
    /// callers keep their own deadline. A closed link is an error, not 0.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;

    /// Drops input that has arrived but not been read, down to driver and
    /// adapter buffers where the platform allows. The client first reads
    /// pending bytes with a zero timeout (to log them), then calls this.
    fn discard_input(&mut self) -> io::Result<()>;

    /// Baud rate and character format of a serial line, from which the
    /// client derives the t3.5 silence between frames. `None` for links
    /// without line timing of their own (TCP, in-memory).
    fn line_timing(&self) -> Option<LineTiming>;
}

/// A transport behind a pointer (`&mut T`, `Box<T>`) is a transport: every
/// method goes to the pointee.
macro_rules! forward_transport {
    ($($pointer:ty),+) => {$(
        impl<T: Transport + ?Sized> Transport for $pointer {
            fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
                (**self).write_all(frame)
            }

            fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
                (**self).read(buf, timeout)
            }

            fn discard_input(&mut self) -> io::Result<()> {
                (**self).discard_input()
            }

            fn line_timing(&self) -> Option<LineTiming> {
                (**self).line_timing()
            }
        }
    )+};
}

forward_transport!(&mut T, Box<T>);

/// True for read errors that mean "nothing arrived yet" rather than a broken link.
fn is_no_data(error: &io::Error) -> bool {
    matches!(error.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted)
}

/// Longest duration handed to the OS in one wait; longer waits are split by callers' loops.
pub(crate) const MAX_WAIT: Duration = Duration::from_secs(24 * 60 * 60);

//! The client's error type, [`ClientError`], generic over the link's I/O error.

use core::convert::Infallible;
use core::fmt;

use crate::error::{EncodeError, ExceptionCode, FrameError};

/// Why a request failed. `E` is the link's I/O error: `std::io::Error` for
/// the blocking `Client` (whose `Error` is
/// this type), the `embedded-io` error of the firmware driver, and
/// [`Infallible`] for the sans-IO [`ClientCore`](super::ClientCore), which
/// does no I/O.
///
/// Small (a few words): the bytes received are not carried here but kept by
/// the client until the next request (`last_reply()` of every driver and of
/// the core), so a report can show what the device sent. `Display` gives the
/// cause and the number of bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ClientError<E> {
    /// No complete reply before the deadline. `received` counts the bytes
    /// that did arrive (0 when the device was silent), garbage included;
    /// `last_reply()` holds them.
    Timeout {
        /// How many bytes arrived before the deadline.
        received: usize,
        /// The request that went unanswered, so the error says which probe
        /// was silent to what.
        sent: Sent,
    },
    /// A reply of the expected length failed a check: CRC, slave address,
    /// function, byte count, write echo, or a Modbus exception.
    /// `last_reply()` holds the frame.
    Frame {
        /// What is wrong with it.
        error: FrameError,
    },
    /// The request could not be encoded (invalid slave address, value out of range).
    Encode(EncodeError),
    /// A raw request frame given to `call_raw` or `broadcast_raw` does not match its layout.
    Request(FrameError),
    /// The link failed (port gone, connection closed, RS-485 echo mismatch).
    Io(E),
}

/// What a request asked of which slave: the part of it an error names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Sent {
    /// The slave address the request went to.
    pub slave: u8,
    /// Its Modbus function code.
    pub function: u8,
    /// The first register it reads or writes.
    pub register: u16,
    /// The command's spec name, when it was sent as a typed command.
    pub command: Option<&'static str>,
}

impl fmt::Display for Sent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "slave {} ", self.slave)?;
        match self.command {
            Some(name) => write!(f, "to {name}"),
            None => write!(f, "to function 0x{:02X} at register 0x{:04X}", self.function, self.register),
        }
    }
}

impl<E> ClientError<E> {
    /// True for [`ClientError::Timeout`].
    pub fn is_timeout(&self) -> bool {
        matches!(self, Self::Timeout { .. })
    }

    /// True when the device answered with a Modbus exception.
    pub fn is_exception(&self) -> bool {
        self.exception().is_some()
    }

    /// The Modbus exception code, if the device answered with one.
    pub fn exception(&self) -> Option<ExceptionCode> {
        match self {
            Self::Frame { error: FrameError::Exception { code, .. } } => Some(*code),
            _ => None,
        }
    }

    /// The frame check that failed, for [`ClientError::Frame`].
    pub fn frame_error(&self) -> Option<FrameError> {
        match self {
            Self::Frame { error } => Some(*error),
            _ => None,
        }
    }

    /// The same error with its I/O error mapped by `f`.
    pub fn map_io<F>(self, f: impl FnOnce(E) -> F) -> ClientError<F> {
        match self {
            Self::Timeout { received, sent } => ClientError::Timeout { received, sent },
            Self::Frame { error } => ClientError::Frame { error },
            Self::Encode(error) => ClientError::Encode(error),
            Self::Request(error) => ClientError::Request(error),
            Self::Io(error) => ClientError::Io(f(error)),
        }
    }
}

impl ClientError<Infallible> {
    /// The core's error (which never holds an I/O error) as a driver's.
    pub fn with_io<F>(self) -> ClientError<F> {
        self.map_io(|never| match never {})
    }
}

impl<E: fmt::Display> fmt::Display for ClientError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Timeout { received: 0, sent } => write!(f, "no reply from {sent} before the timeout"),
            Self::Timeout { received, sent } => {
                write!(f, "incomplete reply from {sent} before the timeout: {received} bytes received")
            }
            Self::Frame { error } => write!(f, "bad reply: {error}"),
            Self::Encode(error) => write!(f, "cannot encode the request: {error}"),
            Self::Request(error) => write!(f, "invalid request frame: {error}"),
            Self::Io(error) => write!(f, "transport error: {error}"),
        }
    }
}

#[cfg(feature = "std")]
impl<E: fmt::Debug + fmt::Display> std::error::Error for ClientError<E> {}

#[cfg(feature = "std")]
impl From<std::io::Error> for ClientError<std::io::Error> {
    fn from(error: std::io::Error) -> Self {
        Self::Io(error)
    }
}

impl<E> From<EncodeError> for ClientError<E> {
    fn from(error: EncodeError) -> Self {
        Self::Encode(error)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displays_the_cause_and_stays_small() {
        let sent = Sent { slave: 7, function: 3, register: 0x2601, command: Some("read_thing") };
        let e = ClientError::<Infallible>::Timeout { received: 2, sent };
        assert_eq!(e.to_string(), "incomplete reply from slave 7 to read_thing before the timeout: 2 bytes received");
        let silent = ClientError::<Infallible>::Timeout { received: 0, sent };
        assert_eq!(silent.to_string(), "no reply from slave 7 to read_thing before the timeout");
        let raw = ClientError::<Infallible>::Timeout { received: 0, sent: Sent { command: None, ..sent } };
        assert_eq!(raw.to_string(), "no reply from slave 7 to function 0x03 at register 0x2601 before the timeout");
        let exc = ClientError::<Infallible>::Frame {
            error: FrameError::Exception { function: 3, code: ExceptionCode::IllegalDataAddress },
        };
        assert!(exc.is_exception());
        assert_eq!(exc.exception(), Some(ExceptionCode::IllegalDataAddress));
        assert!(exc.to_string().contains("illegal data address"), "{exc}");
        // Well under clippy's threshold for large error types (128 bytes).
        assert!(core::mem::size_of::<ClientError<std::io::Error>>() <= 48);
    }
}

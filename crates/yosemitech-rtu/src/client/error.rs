//! The client's error type.

use std::fmt;
use std::io;

use crate::error::{EncodeError, ExceptionCode, FrameError};
use crate::raw::RawBytes;

/// Why a request failed.
///
/// Reply errors carry the bytes received ([`Error::raw`]), inline, so a
/// report shows what the device sent. `Display` includes the cause and the
/// bytes; [`std::error::Error::source`] is `None` (nothing is hidden there).
///
/// Holding the bytes inline makes the type about 300 bytes, above the
/// threshold of `clippy::result_large_err`: crates whose functions return it
/// allow that lint (as this one does) or box the error.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// No complete reply before the deadline. `received` holds the bytes that
    /// did arrive (empty when the device was silent), garbage included.
    Timeout {
        /// The bytes received before the deadline.
        received: RawBytes,
    },
    /// A reply of the expected length failed a check: CRC, slave address,
    /// function, byte count, write echo, or a Modbus exception.
    Frame {
        /// What is wrong with it.
        error: FrameError,
        /// The reply frame.
        raw: RawBytes,
    },
    /// The request could not be encoded (invalid slave address, value out of range).
    Encode(EncodeError),
    /// A raw request frame given to [`Client::call_raw`](crate::Client::call_raw)
    /// or [`Client::broadcast_raw`](crate::Client::broadcast_raw) does not match its layout.
    Request(FrameError),
    /// The transport failed (port gone, connection closed, RS-485 echo mismatch).
    Io(io::Error),
}

impl Error {
    /// True for [`Error::Timeout`].
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
            Self::Frame { error: FrameError::Exception { code, .. }, .. } => Some(*code),
            _ => None,
        }
    }

    /// The frame check that failed, for [`Error::Frame`].
    pub fn frame_error(&self) -> Option<FrameError> {
        match self {
            Self::Frame { error, .. } => Some(*error),
            _ => None,
        }
    }

    /// The bytes received, for [`Error::Timeout`] and [`Error::Frame`].
    pub fn raw(&self) -> Option<&[u8]> {
        match self {
            Self::Timeout { received } => Some(received.as_bytes()),
            Self::Frame { raw, .. } => Some(raw.as_bytes()),
            _ => None,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Timeout { received } if received.is_empty() => f.write_str("no reply before the timeout"),
            Self::Timeout { received } => {
                write!(f, "incomplete reply before the timeout: {} bytes received: {received}", received.len())
            }
            Self::Frame { error, raw } => write!(f, "bad reply: {error}; reply: {raw}"),
            Self::Encode(error) => write!(f, "cannot encode the request: {error}"),
            Self::Request(error) => write!(f, "invalid request frame: {error}"),
            Self::Io(error) => write!(f, "transport error: {error}"),
        }
    }
}

impl std::error::Error for Error {}

impl From<io::Error> for Error {
    fn from(error: io::Error) -> Self {
        Self::Io(error)
    }
}

impl From<EncodeError> for Error {
    fn from(error: EncodeError) -> Self {
        Self::Encode(error)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displays_cause_and_bytes() {
        let e = Error::Timeout { received: RawBytes::new(&[0x01, 0x03]) };
        assert_eq!(e.to_string(), "incomplete reply before the timeout: 2 bytes received: 01 03");
        assert_eq!(Error::Timeout { received: RawBytes::EMPTY }.to_string(), "no reply before the timeout");
        let exc = Error::Frame {
            error: FrameError::Exception { function: 3, code: ExceptionCode::IllegalDataAddress },
            raw: RawBytes::new(&[0x01, 0x83, 0x02, 0xC0, 0xF1]),
        };
        assert!(exc.is_exception());
        assert_eq!(exc.exception(), Some(ExceptionCode::IllegalDataAddress));
        assert_eq!(exc.raw(), Some(&[0x01, 0x83, 0x02, 0xC0, 0xF1][..]));
        assert!(exc.to_string().ends_with("reply: 01 83 02 C0 F1"), "{exc}");
        let io = Error::from(io::Error::new(io::ErrorKind::BrokenPipe, "gone"));
        assert!(!io.is_exception() && !io.is_timeout() && io.raw().is_none());
    }
}

//! Generated commands over an existing tokio-modbus connection (feature
//! `tokio-modbus`).
//!
//! For code that already holds a [`tokio_modbus::client::Context`] (RTU or
//! TCP) and wants typed Yosemitech values from it. tokio-modbus does the
//! framing, timing and I/O; this module only translates:
//!
//! 1. the command's request frame ([`Command::encode_request`], with every
//!    range and slave check) becomes the tokio-modbus request with the same
//!    PDU: read holding registers (0x03) or write multiple registers (0x10)
//!    at [`Layout::address`] and [`Layout::count`];
//! 2. what tokio-modbus returns (registers, a write echo, or an exception
//!    code) is written back as the RTU reply frame that carries it;
//! 3. that frame goes through the command's own generated decoder
//!    ([`Command::decode_response`]), the one every other client uses. A
//!    Modbus exception comes out as [`FrameError::Exception`] in
//!    [`Error::Frame`], exactly as from the blocking [`Client`](crate::Client).
//!
//! # What tokio-modbus cannot carry
//!
//! * **Trigger reads** (a read with [`Layout::trigger`]): the manuals' reply
//!   is byte count 0 followed by `2 * count` bytes, which tokio-modbus's RTU
//!   codec frames by the byte count, leaving bytes on the line. They are
//!   refused before anything is sent: [`Error::Unsupported`] with
//!   [`Unsupported::TriggerRead`]. Trigger *writes* (zero registers) work.
//! * **Broadcasts** (slave 0): tokio-modbus waits for a reply that never
//!   comes. Refused with [`Unsupported::Broadcast`].
//! * **Byte-count quirks** ([`Layout::extra_byte_counts`]): tokio-modbus
//!   frames and counts registers by the byte count, so such a reply fails in
//!   tokio-modbus ([`Error::Modbus`]) or in the decoder ([`Error::Frame`]).
//!
//! Commands with a fixed slave address (get slave id: 0xFF) work: call them
//! with that address, as with every client. Each call sets the context's
//! slave (`SlaveContext::set_slave`) to its own.
//!
//! ```no_run
//! # async fn example<C: yosemitech_rtu::Command>(command: C) -> Result<(), Box<dyn std::error::Error>>
//! # where C::Response: std::fmt::Debug {
//! use tokio_modbus::client::tcp;
//!
//! // An Ethernet gateway; the probe is slave 1 on its RS-485 line.
//! let mut ctx = tcp::connect("192.168.0.10:502".parse()?).await?;
//! let response = yosemitech_rtu::tokio_modbus::call(&mut ctx, 1, &command).await?;
//! println!("{response:?}");
//! # Ok(()) }
//! ```

use std::borrow::Cow;
use std::fmt;

use ::tokio_modbus::client::Client as ModbusClient;
use ::tokio_modbus::{Request, Response, Slave};

use crate::bytes::word;
use crate::command::Command;
use crate::crc::crc16;
use crate::error::{EncodeError, FrameError};
use crate::frame::{BROADCAST, Frame, Function, Layout, MAX_ADU, encode_exception};

/// A command tokio-modbus cannot carry; see the [module docs](self).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Unsupported {
    /// A trigger read, whose reply tokio-modbus cannot frame.
    TriggerRead,
    /// A broadcast (slave 0), for which tokio-modbus would wait for a reply.
    Broadcast,
}

/// Why a command over tokio-modbus failed.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The request could not be encoded (slave address, value out of range).
    Encode(EncodeError),
    /// A raw request given to [`call_raw`] does not match its layout.
    Request(FrameError),
    /// The reply tokio-modbus returned fails the command's checks, or is a
    /// Modbus exception ([`FrameError::Exception`]).
    Frame(FrameError),
    /// tokio-modbus failed: I/O, a connection closed, a reply it could not
    /// frame or that does not match the request.
    Modbus(::tokio_modbus::Error),
    /// The command cannot go through tokio-modbus; nothing was sent.
    Unsupported(Unsupported),
    /// tokio-modbus returned a response to another function (it checks
    /// function codes, so this means a tokio-modbus bug).
    UnexpectedResponse {
        /// The function code of the response.
        function: u8,
    },
}

impl Error {
    /// The Modbus exception code, if the device answered with one.
    pub fn exception(&self) -> Option<crate::ExceptionCode> {
        match self {
            Self::Frame(FrameError::Exception { code, .. }) => Some(*code),
            _ => None,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Encode(error) => write!(f, "cannot encode the request: {error}"),
            Self::Request(error) => write!(f, "invalid request frame: {error}"),
            Self::Frame(error) => write!(f, "bad reply: {error}"),
            Self::Modbus(error) => write!(f, "tokio-modbus: {error}"),
            Self::Unsupported(Unsupported::TriggerRead) => {
                f.write_str("trigger reads cannot go through tokio-modbus (it cannot frame their reply)")
            }
            Self::Unsupported(Unsupported::Broadcast) => {
                f.write_str("broadcasts cannot go through tokio-modbus (it waits for a reply)")
            }
            Self::UnexpectedResponse { function } => {
                write!(f, "tokio-modbus returned a response to function 0x{function:02X}")
            }
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Modbus(error) => Some(error),
            _ => None,
        }
    }
}

impl From<EncodeError> for Error {
    fn from(error: EncodeError) -> Self {
        Self::Encode(error)
    }
}

/// Sends `command` to `slave` through `ctx` and decodes the reply with the
/// command's generated decoder. See the [module docs](self) for what
/// cannot be sent; those fail before anything goes out.
pub async fn call<C, M>(ctx: &mut M, slave: u8, command: &C) -> Result<C::Response, Error>
where
    C: Command,
    M: ModbusClient + ?Sized,
{
    let request = command.request_frame(slave)?;
    let reply = exchange(ctx, &request, &C::LAYOUT).await?;
    C::decode_response(slave, &reply).map_err(Error::Frame)
}

/// Sends a request frame built elsewhere (the spec interpreter, a
/// `SensorModule`'s layout) through `ctx` and returns the RTU reply frame
/// that carries what tokio-modbus received, checked against `layout`
/// ([`Layout::decode_response`]). The slave is the request's first byte.
pub async fn call_raw<M>(ctx: &mut M, request: &[u8], layout: &Layout<'_>) -> Result<Frame, Error>
where
    M: ModbusClient + ?Sized,
{
    let reply = exchange(ctx, request, layout).await?;
    let slave = request.first().copied().unwrap_or(BROADCAST);
    layout.decode_response(slave, &reply).map_err(Error::Frame)?;
    Ok(reply)
}

/// The tokio-modbus round trip of one request frame: the reply frame, unchecked.
async fn exchange<M>(ctx: &mut M, request: &[u8], layout: &Layout<'_>) -> Result<Frame, Error>
where
    M: ModbusClient + ?Sized,
{
    let (slave, data) = layout.decode_request(request).map_err(Error::Request)?;
    layout.check_slave(slave)?;
    if slave == BROADCAST {
        return Err(Error::Unsupported(Unsupported::Broadcast));
    }
    if layout.function == Function::Read && layout.trigger {
        return Err(Error::Unsupported(Unsupported::TriggerRead));
    }
    let modbus_request = match layout.function {
        Function::Read => Request::ReadHoldingRegisters(layout.address, layout.count),
        Function::Write => {
            let words = data.chunks_exact(2).map(|w| word(w, 0).unwrap_or(0)).collect();
            Request::WriteMultipleRegisters(layout.address, Cow::Owned(words))
        }
    };
    ctx.set_slave(Slave(slave));
    let reply_slave = layout.reply_slave(slave);
    let response = ctx.call(modbus_request).await.map_err(Error::Modbus)?;
    let frame = match response {
        Ok(Response::ReadHoldingRegisters(words)) => Frame::fill(|out| read_reply(reply_slave, &words, out)),
        Ok(Response::WriteMultipleRegisters(address, count)) => {
            Frame::fill(|out| write_reply(reply_slave, address, count, out))
        }
        Ok(other) => return Err(Error::UnexpectedResponse { function: other.function_code().value() }),
        Err(code) => Frame::fill(|out| encode_exception(reply_slave, layout.function.code(), u8::from(code), out)),
    };
    Ok(frame?)
}

/// Writes the read reply carrying `words`: slave, 0x03, byte count, data, CRC.
fn read_reply(slave: u8, words: &[u16], out: &mut [u8]) -> Result<usize, EncodeError> {
    let data_len = 2 * words.len();
    let len = 5 + data_len;
    let byte_count = u8::try_from(data_len).map_err(|_| EncodeError::BufferTooSmall { needed: len })?;
    let out = out.get_mut(..len).filter(|_| len <= MAX_ADU).ok_or(EncodeError::BufferTooSmall { needed: len })?;
    let (body, crc) = out.split_at_mut(len - 2);
    let mut bytes =
        [slave, Function::Read.code(), byte_count].into_iter().chain(words.iter().flat_map(|w| w.to_be_bytes()));
    for slot in body.iter_mut() {
        *slot = bytes.next().unwrap_or(0);
    }
    crc.copy_from_slice(&crc16(body).to_le_bytes());
    Ok(len)
}

/// Writes the write reply echoing `address` and `count`: slave, 0x10, address, count, CRC.
fn write_reply(slave: u8, address: u16, count: u16, out: &mut [u8]) -> Result<usize, EncodeError> {
    const LEN: usize = 8;
    let out = out.get_mut(..LEN).ok_or(EncodeError::BufferTooSmall { needed: LEN })?;
    let [a0, a1] = address.to_be_bytes();
    let [c0, c1] = count.to_be_bytes();
    let body = [slave, Function::Write.code(), a0, a1, c0, c1];
    let [crc0, crc1] = crc16(&body).to_le_bytes();
    out.copy_from_slice(&[slave, Function::Write.code(), a0, a1, c0, c1, crc0, crc1]);
    Ok(LEN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rebuilt_replies_are_rtu_frames() {
        let mut out = [0u8; MAX_ADU];
        let n = read_reply(1, &[0x3333, 0xF340], &mut out).unwrap();
        // The pH manual's get_ph reply (Fig 24).
        assert_eq!(out[..n], [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78]);
        let n = write_reply(1, 0x1C00, 0, &mut out).unwrap();
        // Conductivity manual: start measurement's reply.
        assert_eq!(out[..n], [0x01, 0x10, 0x1C, 0x00, 0x00, 0x00, 0xC7, 0x99]);
        assert!(read_reply(1, &[0; 200], &mut out).is_err(), "more registers than a frame holds");
    }
}

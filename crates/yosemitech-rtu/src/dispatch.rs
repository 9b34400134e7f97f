//! [`Command`]'s frame methods for code that dispatches over many commands.
//!
//! `Command`'s provided methods are inlined, so that a call for one known
//! command folds its layout into the frame checks: the client's typed
//! transaction is as short as a hand-written one. A `match` over every
//! command of a sensor (the generated `CommandId::decode_request`,
//! `Request::encode` and their kin) would then hold one copy of the framing
//! per command, in every build of the generated crate. These functions do the
//! same checks and return the same errors, with the framing compiled once
//! here: each command adds only its message's conversion.

use crate::command::Command;
use crate::error::{EncodeError, FrameError};
use crate::frame::Layout;
use crate::message::Message;

/// [`Command::decode_request`] with the framing out of line.
pub fn decode_request<C: Command>(frame: &[u8]) -> Result<(u8, C), FrameError> {
    let (slave, data) = request_data(&C::LAYOUT, frame)?;
    Ok((slave, from_data(data, C::REQUEST_LEN, frame)?))
}

/// [`Command::decode_response`] with the framing out of line.
pub fn decode_response<C: Command>(slave: u8, frame: &[u8]) -> Result<C::Response, FrameError> {
    let data = response_data(&C::LAYOUT, slave, frame)?;
    from_data(data, C::RESPONSE_LEN, frame)
}

/// [`Command::encode_request`] with the framing out of line.
pub fn encode_request<C: Command>(request: &C, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
    request.validate()?;
    write_request(&C::LAYOUT, slave, request.to_data().as_ref(), out)
}

/// [`Command::encode_response`] with the framing out of line.
pub fn encode_response<C: Command>(response: &C::Response, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
    write_response(&C::LAYOUT, slave, response.to_data().as_ref(), out)
}

/// A message from the register data its layout framed. The layout frames
/// exactly the message's length, so the error is for a command whose layout
/// and types disagree: it is reported as a frame of the wrong length.
fn from_data<M: Message>(data: &[u8], frame_len: usize, frame: &[u8]) -> Result<M, FrameError> {
    // A `match`, not `map_err`: a closure would be one more function per message type.
    match M::Data::try_from(data) {
        Ok(data) => Ok(M::from_data(&data)),
        Err(_) => Err(FrameError::Truncated { expected: frame_len, actual: frame.len() }),
    }
}

// The four below are the one copy of the framing: never inlined, or each
// caller above would carry it again.

/// [`Layout::decode_request`], compiled once.
#[inline(never)]
pub(crate) fn request_data<'f>(layout: &Layout<'_>, frame: &'f [u8]) -> Result<(u8, &'f [u8]), FrameError> {
    layout.decode_request(frame)
}

/// [`Layout::decode_response`], compiled once.
#[inline(never)]
pub(crate) fn response_data<'f>(layout: &Layout<'_>, slave: u8, frame: &'f [u8]) -> Result<&'f [u8], FrameError> {
    layout.decode_response(slave, frame)
}

/// [`Layout::encode_request`], compiled once.
#[inline(never)]
pub(crate) fn write_request(layout: &Layout<'_>, slave: u8, data: &[u8], out: &mut [u8]) -> Result<usize, EncodeError> {
    layout.encode_request(slave, data, out)
}

/// [`Layout::encode_response`], compiled once.
#[inline(never)]
pub(crate) fn write_response(
    layout: &Layout<'_>,
    slave: u8,
    data: &[u8],
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    layout.encode_response(slave, data, out)
}

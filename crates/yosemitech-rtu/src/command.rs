//! The contract between generated command types and the runtime.

use crate::error::{EncodeError, FrameError};
use crate::frame::{Frame, Function, Layout};

/// One Modbus command of a sensor: a typed request that knows its reply.
///
/// Generated for every command in the spec. `Self` is the request (a unit
/// struct for reads, the written values for writes); [`Command::Response`] the
/// decoded reply. All methods are allocation-free and never panic.
pub trait Command: Sized {
    /// The decoded reply: `()` for triggers and writes without data.
    type Response;

    /// The command's name in the spec.
    const NAME: &'static str;

    /// Function, start address, register count and addressing quirks.
    const LAYOUT: Layout<'static>;

    /// The function code of the layout: 0x03 or 0x10.
    const FUNCTION: Function = Self::LAYOUT.function;
    /// The first register, as sent on the wire.
    const ADDRESS: u16 = Self::LAYOUT.address;
    /// The number of registers.
    const COUNT: u16 = Self::LAYOUT.count;
    /// Bytes in the request frame.
    const REQUEST_LEN: usize = Self::LAYOUT.request_len();
    /// Bytes in a normal reply frame.
    const RESPONSE_LEN: usize = Self::LAYOUT.response_len();

    /// Writes the request frame for `slave` into `out` and returns its length.
    fn encode_request(&self, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError>;

    /// Checks a request frame and returns its slave address and the request.
    fn decode_request(frame: &[u8]) -> Result<(u8, Self), FrameError>;

    /// Writes the reply `response` from `slave` into `out` and returns its length.
    fn encode_response(response: &Self::Response, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError>;

    /// Checks a reply to a request sent to `slave` and decodes it.
    fn decode_response(slave: u8, frame: &[u8]) -> Result<Self::Response, FrameError>;

    /// The request frame for `slave`, on the stack.
    fn request_frame(&self, slave: u8) -> Result<Frame, EncodeError> {
        Frame::fill(|out| self.encode_request(slave, out))
    }
}

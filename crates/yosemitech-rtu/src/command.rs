//! The contract between generated command types and the runtime.

use crate::error::{EncodeError, FrameError};
use crate::frame::{Frame, Function, Layout};
use crate::message::Message;

/// One Modbus command of a sensor: a typed request that knows its reply.
///
/// Generated for every command in the spec, as declarations only: the
/// command's name and layout, and its request and reply as [`Message`]s.
/// `Self` is the request (a unit struct for reads, the written values for
/// writes); [`Command::Response`] the decoded reply. The framing is the
/// runtime's: every method is provided, allocation-free and never panics.
pub trait Command: Message {
    /// The decoded reply: `()` for writes, which carry no data back.
    type Response: Message;

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

    /// Writes the request frame for `slave` into `out` and returns its
    /// length. A write's values are checked against their ranges first.
    #[inline]
    fn encode_request(&self, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
        self.validate()?;
        Self::LAYOUT.encode_request(slave, self.to_data().as_ref(), out)
    }

    /// Checks a request frame and returns its slave address and the request.
    #[inline]
    fn decode_request(frame: &[u8]) -> Result<(u8, Self), FrameError> {
        let (slave, data) = Self::LAYOUT.decode_request(frame)?;
        let data = Self::Data::try_from(data)
            .map_err(|_| FrameError::Truncated { expected: Self::REQUEST_LEN, actual: frame.len() })?;
        Ok((slave, Self::from_data(&data)))
    }

    /// Writes the reply `response` from `slave` into `out` and returns its
    /// length. A reply is not range-checked: a probe may report values
    /// outside its measuring range.
    #[inline]
    fn encode_response(response: &Self::Response, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
        Self::LAYOUT.encode_response(slave, response.to_data().as_ref(), out)
    }

    /// Checks a reply to a request sent to `slave` and decodes it.
    #[inline]
    fn decode_response(slave: u8, frame: &[u8]) -> Result<Self::Response, FrameError> {
        // A trigger's reply is an acknowledgement: the layout returns none of
        // the registers it may carry, which mean nothing.
        let data = Self::LAYOUT.decode_response(slave, frame)?;
        let data = <Self::Response as Message>::Data::try_from(data)
            .map_err(|_| FrameError::Truncated { expected: Self::RESPONSE_LEN, actual: frame.len() })?;
        Ok(Self::Response::from_data(&data))
    }

    /// The request frame for `slave`, on the stack.
    fn request_frame(&self, slave: u8) -> Result<Frame, EncodeError> {
        Frame::fill(|out| self.encode_request(slave, out))
    }
}

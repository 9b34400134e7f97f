//! Hand-written [`Command`]s and a simulated probe for the runtime's own
//! tests (`yosemitech-rtu`): commands and frames of the manuals, written
//! without the generator, so the runtime is tested on its own.

use yosemitech_rtu::codec::{ByteOrder4, f32_from_wire, f32_to_wire};
use yosemitech_rtu::frame::encode_exception;
use yosemitech_rtu::{Command, EncodeError, FrameError, Layout};

/// The pH manual's get_ph request (Fig 23): [`ReadFloat`] to slave 1.
pub const READ_FLOAT_REQUEST: [u8; 8] = [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB];
/// Its reply (Fig 25): 7.6 as a little-endian f32 image.
pub const READ_FLOAT_REPLY: [u8; 9] = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];

/// get_ph: read 2 registers at 0x2800, one f32 (DCBA).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadFloat;

impl Command for ReadFloat {
    type Response = f32;
    const NAME: &'static str = "read_float";
    const LAYOUT: Layout<'static> = Layout::read(0x2800, 2);

    fn encode_request(&self, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
        Self::LAYOUT.encode_request(slave, &[], out)
    }

    fn decode_request(frame: &[u8]) -> Result<(u8, Self), FrameError> {
        Self::LAYOUT.decode_request(frame).map(|(slave, _)| (slave, ReadFloat))
    }

    fn encode_response(response: &f32, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
        Self::LAYOUT.encode_response(slave, &f32_to_wire(ByteOrder4::Dcba, *response), out)
    }

    fn decode_response(slave: u8, frame: &[u8]) -> Result<f32, FrameError> {
        let data = Self::LAYOUT.decode_response(slave, frame)?;
        let bytes: [u8; 4] = data.try_into().map_err(|_| FrameError::Truncated { expected: 4, actual: data.len() })?;
        Ok(f32_from_wire(ByteOrder4::Dcba, bytes))
    }
}

/// Conductivity start_measurement: a write of zero registers at 0x1C00.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartMeasurement;

impl Command for StartMeasurement {
    type Response = ();
    const NAME: &'static str = "start_measurement";
    const LAYOUT: Layout<'static> = Layout { trigger: true, ..Layout::write(0x1C00, 0) };

    fn encode_request(&self, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
        Self::LAYOUT.encode_request(slave, &[], out)
    }

    fn decode_request(frame: &[u8]) -> Result<(u8, Self), FrameError> {
        Self::LAYOUT.decode_request(frame).map(|(slave, _)| (slave, StartMeasurement))
    }

    fn encode_response(_: &(), slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
        Self::LAYOUT.encode_response(slave, &[], out)
    }

    fn decode_response(slave: u8, frame: &[u8]) -> Result<(), FrameError> {
        Self::LAYOUT.decode_response(slave, frame).map(drop)
    }
}

/// get_slave_id with the fixed address 0xFF: read 1 register at 0x3000, the address in the first byte.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadAtFixedSlave;

impl Command for ReadAtFixedSlave {
    type Response = u8;
    const NAME: &'static str = "read_at_fixed_slave";
    const LAYOUT: Layout<'static> = Layout { fixed_slave: Some(0xFF), ..Layout::read(0x3000, 1) };

    fn encode_request(&self, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
        Self::LAYOUT.encode_request(slave, &[], out)
    }

    fn decode_request(frame: &[u8]) -> Result<(u8, Self), FrameError> {
        Self::LAYOUT.decode_request(frame).map(|(slave, _)| (slave, ReadAtFixedSlave))
    }

    fn encode_response(response: &u8, slave: u8, out: &mut [u8]) -> Result<usize, EncodeError> {
        Self::LAYOUT.encode_response(slave, &[*response, 0x00], out)
    }

    fn decode_response(slave: u8, frame: &[u8]) -> Result<u8, FrameError> {
        let data = Self::LAYOUT.decode_response(slave, frame)?;
        data.first().copied().ok_or(FrameError::Truncated { expected: 2, actual: 0 })
    }
}

/// A pH probe at `address` reading `ph`: answers get_ph and get_slave_id,
/// acknowledges start_measurement, answers any other request to it with
/// exception 0x02 (illegal data address), and ignores other slaves and broadcasts.
pub fn float_probe(address: u8, ph: f32, request: &[u8], reply: &mut Vec<u8>) {
    let mut out = [0u8; 256];
    let len = if let Ok((slave, ReadFloat)) = ReadFloat::decode_request(request) {
        if slave != address {
            return;
        }
        ReadFloat::encode_response(&ph, slave, &mut out)
    } else if let Ok((slave, ReadAtFixedSlave)) = ReadAtFixedSlave::decode_request(request) {
        ReadAtFixedSlave::encode_response(&address, slave, &mut out)
    } else if let Ok((slave, StartMeasurement)) = StartMeasurement::decode_request(request) {
        if slave != address {
            return;
        }
        StartMeasurement::encode_response(&(), slave, &mut out)
    } else {
        match request {
            [slave, function, ..] if *slave == address => encode_exception(address, *function, 0x02, &mut out),
            _ => return,
        }
    };
    reply.extend_from_slice(&out[..len.unwrap()]);
}

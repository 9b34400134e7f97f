//! Hand-written [`Command`]s and a simulated probe for the runtime's own
//! tests (`yosemitech-rtu`): commands and frames of the manuals, written
//! without the generator, so the runtime is tested on its own.

use yosemitech_rtu::codec::{ByteOrder4, f32_from_wire, f32_to_wire};
use yosemitech_rtu::frame::encode_exception;
use yosemitech_rtu::{Command, EncodeError, FieldInfo, FieldValue, Layout, Message, NoData};

/// The pH manual's get_ph request (Fig 23): [`ReadFloat`] to slave 1.
pub const READ_FLOAT_REQUEST: [u8; 8] = [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB];
/// Its reply (Fig 25): 7.6 as a little-endian f32 image.
pub const READ_FLOAT_REPLY: [u8; 9] = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];

/// get_ph: read 2 registers at 0x2800, one f32 (DCBA).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReadFloat;

impl NoData for ReadFloat {}

impl Command for ReadFloat {
    type Response = Ph;
    const NAME: &'static str = "read_float";
    const LAYOUT: Layout<'static> = Layout::read(0x2800, 2);
}

/// [`ReadFloat`]'s reply: the pH.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ph(pub f32);

impl PartialEq<f32> for Ph {
    fn eq(&self, other: &f32) -> bool {
        self.0 == *other
    }
}

impl Message for Ph {
    type Data = [u8; 4];
    const FIELDS: &'static [FieldInfo] = &[FieldInfo::new("ph", Some("pH"))];

    fn from_data(data: &[u8; 4]) -> Self {
        Self(f32_from_wire(ByteOrder4::Dcba, *data))
    }

    fn to_data(&self) -> [u8; 4] {
        f32_to_wire(ByteOrder4::Dcba, self.0)
    }

    fn field(&self, index: usize) -> Option<FieldValue<'_>> {
        (index == 0).then_some(FieldValue::F32(self.0))
    }
}

/// Conductivity start_measurement: a write of zero registers at 0x1C00.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StartMeasurement;

impl NoData for StartMeasurement {}

impl Command for StartMeasurement {
    type Response = ();
    const NAME: &'static str = "start_measurement";
    const LAYOUT: Layout<'static> = Layout { trigger: true, ..Layout::write(0x1C00, 0) };
}

/// get_slave_id with the fixed address 0xFF: read 1 register at 0x3000, the address in the first byte.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReadAtFixedSlave;

impl NoData for ReadAtFixedSlave {}

impl Command for ReadAtFixedSlave {
    type Response = SlaveAddress;
    const NAME: &'static str = "read_at_fixed_slave";
    const LAYOUT: Layout<'static> = Layout { fixed_slave: Some(0xFF), ..Layout::read(0x3000, 1) };
}

/// [`ReadAtFixedSlave`]'s reply: the address, its second byte reserved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlaveAddress(pub u8);

impl PartialEq<u8> for SlaveAddress {
    fn eq(&self, other: &u8) -> bool {
        self.0 == *other
    }
}

impl Message for SlaveAddress {
    type Data = [u8; 2];
    const FIELDS: &'static [FieldInfo] = &[FieldInfo::new("slave_address", None)];

    fn from_data(data: &[u8; 2]) -> Self {
        Self(data[0])
    }

    fn to_data(&self) -> [u8; 2] {
        [self.0, 0x00]
    }

    fn field(&self, index: usize) -> Option<FieldValue<'_>> {
        (index == 0).then_some(FieldValue::Int(i64::from(self.0)))
    }
}

/// A write with data: 1 register at 0x1100, a big-endian word the probe
/// takes only up to 1000 (an averaging time, in seconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WriteWord(pub u16);

impl Message for WriteWord {
    type Data = [u8; 2];
    const FIELDS: &'static [FieldInfo] = &[FieldInfo::new("averaging", Some("s"))];

    fn from_data(data: &[u8; 2]) -> Self {
        Self(u16::from_be_bytes(*data))
    }

    fn to_data(&self) -> [u8; 2] {
        self.0.to_be_bytes()
    }

    fn field(&self, index: usize) -> Option<FieldValue<'_>> {
        (index == 0).then_some(FieldValue::Int(i64::from(self.0)))
    }

    fn validate(&self) -> Result<(), EncodeError> {
        if self.0 <= 1000 { Ok(()) } else { Err(EncodeError::OutOfRange { field: "averaging" }) }
    }
}

impl Command for WriteWord {
    type Response = ();
    const NAME: &'static str = "write_word";
    const LAYOUT: Layout<'static> = Layout::write(0x1100, 1);
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
        ReadFloat::encode_response(&Ph(ph), slave, &mut out)
    } else if let Ok((slave, ReadAtFixedSlave)) = ReadAtFixedSlave::decode_request(request) {
        ReadAtFixedSlave::encode_response(&SlaveAddress(address), slave, &mut out)
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

/// A client configuration for a device in memory or behind a socket, where
/// no line timing applies: no inter-frame wait, no retries, `timeout` for a
/// reply (a silence costs only that).
pub fn unpaced_config(timeout: std::time::Duration) -> yosemitech_rtu::ClientConfig {
    yosemitech_rtu::ClientConfig {
        timeout,
        retry: yosemitech_rtu::RetryPolicy::NONE,
        inter_frame_delay: Some(std::time::Duration::ZERO),
        ..yosemitech_rtu::ClientConfig::default()
    }
}

//! Benchmarks of the Yosemitech Modbus runtime: shared fixtures,
//! the reference implementations it is compared with, and the wire-limit
//! arithmetic of the bus-efficiency run.
//!
//! The benchmarks themselves are in `benches/` (`cargo bench -p
//! yosemitech-bench`), the zero-allocation tests in `tests/zero_alloc*.rs`
//! (allocations counted by the test kit's `counting_alloc`), and the
//! results with the command that produced them in `BENCHMARKS.md` at the
//! workspace root. This crate is not published: it holds criterion and the
//! comparison crates so the product crates stay lean.

use std::path::PathBuf;
use std::time::Duration;

use yosemitech_rtu::LineTiming;
#[cfg(feature = "harness")]
use yosemitech_sim::Simulator;
#[cfg(feature = "harness")]
use yosemitech_spec::Sensor;

/// The pH manual's get_ph request (Fig 23): slave 1, read 2 registers at 0x2800.
pub const GET_PH_REQUEST: [u8; 8] = [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB];

/// The pH manual's get_ph reply (Fig 24): pH 7.6 as a little-endian f32 image.
pub const GET_PH_REPLY: [u8; 9] = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];

/// The value [`GET_PH_REPLY`] carries.
pub const GET_PH_VALUE: f32 = 7.6;

/// The conductivity manual's temperature-and-conductivity reply (Fig 28): 5
/// registers, 17.625 °C, 17.625 mS/cm, range status 0.
pub const CONDUCTIVITY_REPLY: [u8; 15] =
    [0x01, 0x03, 0x0A, 0x00, 0x00, 0x8D, 0x41, 0x00, 0x00, 0x8D, 0x41, 0x00, 0x00, 0xC7, 0x33];

/// The values [`CONDUCTIVITY_REPLY`] carries: temperature, conductivity.
pub const CONDUCTIVITY_VALUES: (f32, f32) = (17.625, 17.625);

/// The workspace's `spec/` directory.
pub fn spec_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec"))
}

/// Where criterion writes its results, found as criterion finds it:
/// `$CRITERION_HOME`, else `$CARGO_TARGET_DIR/criterion`, else the
/// workspace's `target/criterion`. The bus-efficiency run writes
/// `bus_efficiency/results.json` there, and `bench-report` reads it all.
pub fn criterion_dir() -> PathBuf {
    if let Some(home) = std::env::var_os("CRITERION_HOME") {
        PathBuf::from(home)
    } else if let Some(target) = std::env::var_os("CARGO_TARGET_DIR") {
        PathBuf::from(target).join("criterion")
    } else {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../target/criterion"))
    }
}

/// The sensor `name` of the workspace's spec.
#[cfg(feature = "harness")]
pub fn sensor(name: &str) -> Result<Sensor, String> {
    let spec = yosemitech_spec::load_paths(&[spec_dir()]).map_err(|e| format!("the spec does not load: {e}"))?;
    spec.sensor(name).cloned().ok_or_else(|| format!("the spec has no sensor {name}"))
}

/// A simulated pH probe at its factory address (1), registers as the
/// manual's examples show them (get_ph answers 7.6): the sensor whose
/// printed exchange is [`GET_PH_REQUEST`] and [`GET_PH_REPLY`], found by its
/// frames rather than named.
#[cfg(feature = "harness")]
pub fn ph_simulator() -> Result<Simulator, String> {
    let spec = yosemitech_spec::load_paths(&[spec_dir()]).map_err(|e| format!("the spec does not load: {e}"))?;
    let prints_get_ph =
        |sensor: &&Sensor| {
            sensor.commands.iter().flat_map(|c| &c.examples).any(|e| {
                e.true_pair().is_some_and(|(request, reply)| request == GET_PH_REQUEST && reply == GET_PH_REPLY)
            })
        };
    let sensor = spec.sensors.iter().find(prints_get_ph).ok_or("no sensor of the spec prints the get_ph exchange")?;
    Ok(Simulator::new(sensor.clone()))
}

/// A responder that answers [`GET_PH_REQUEST`] with [`GET_PH_REPLY`] and
/// anything else with silence, without allocating (it appends to a buffer
/// the transport preallocated): for measuring the client on its own.
pub fn fixed_get_ph_responder() -> impl FnMut(&[u8], &mut Vec<u8>) {
    |request: &[u8], reply: &mut Vec<u8>| {
        if request == GET_PH_REQUEST {
            reply.extend_from_slice(&GET_PH_REPLY);
        }
    }
}

/// The client configuration of the measurements, where no serial line
/// timing applies (a device in memory or behind a socket): no inter-frame
/// wait, no retries, `timeout` for a reply.
pub fn unpaced_config(timeout: Duration) -> yosemitech_rtu::ClientConfig {
    yosemitech_rtu::ClientConfig {
        timeout,
        retry: yosemitech_rtu::RetryPolicy::NONE,
        inter_frame_delay: Some(Duration::ZERO),
        ..yosemitech_rtu::ClientConfig::default()
    }
}

/// The typed command of the one-float-read measurements (callgrind
/// harness): the pH manual's get_ph, chosen here, once, because
/// [`GET_PH_REQUEST`] and [`GET_PH_REPLY`] are its manual's frames.
pub type FloatRead = yosemitech::ph_orp::GetPh;

/// The request of [`FloatRead`] to slave 1 ([`GET_PH_REQUEST`]).
pub const FLOAT_READ_REQUEST: [u8; 8] = GET_PH_REQUEST;

/// The value the reply of [`fixed_float_read_responder`] carries.
pub const FLOAT_READ_VALUE: f32 = GET_PH_VALUE;

/// The float a decoded [`FloatRead`] reply carries.
#[inline]
pub fn float_read_value(response: &<FloatRead as yosemitech::Command>::Response) -> f32 {
    response.ph
}

/// [`fixed_get_ph_responder`]: answers [`FLOAT_READ_REQUEST`] with the
/// manual's reply carrying [`FLOAT_READ_VALUE`].
pub fn fixed_float_read_responder() -> impl FnMut(&[u8], &mut Vec<u8>) {
    fixed_get_ph_responder()
}

/// The CRC-16/MODBUS implementations of the `crc` crate.
pub mod crc_ref {
    /// The `crc` crate's default implementation: one 256-entry table, a byte at a time.
    pub static TABLE_1: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_MODBUS);

    /// The `crc` crate's slice-by-16 implementation: 16 tables of 256 entries.
    pub static TABLE_16: crc::Crc<u16, crc::Table<16>> = crc::Crc::<u16, crc::Table<16>>::new(&crc::CRC_16_MODBUS);
}

/// The same decoding done with `rmodbus` (0.13) as a Modbus RTU client:
/// frame checks by [`rmodbus::client::ModbusRequest::parse_slice`], then the
/// register data turned into typed values in the probes' byte order
/// (little-endian f32 images: `33 33 F3 40` is 7.6).
pub mod rmodbus_ref {
    use rmodbus::client::ModbusRequest;
    use rmodbus::{ErrorKind, ModbusProto};

    /// A conductivity reading, as the generated
    /// `GetTemperatureAndConductivityResponse` holds it (status as its raw byte).
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct Conductivity {
        /// Temperature, °C.
        pub temperature_c: f32,
        /// Conductivity, mS/cm.
        pub conductivity_ms_cm: f32,
        /// Range-switching status byte (the first byte of register 5).
        pub range_status: u8,
    }

    /// A request generator for slave 1, read `count` holding registers at
    /// `address`, with the request frame it generated (the state
    /// `parse_slice` checks replies against).
    pub fn read_request(address: u16, count: u16) -> Result<(ModbusRequest, Vec<u8>), ErrorKind> {
        let mut request = ModbusRequest::new(1, ModbusProto::Rtu);
        let mut frame = Vec::with_capacity(256);
        request.generate_get_holdings(address, count, &mut frame)?;
        Ok((request, frame))
    }

    /// Generates the get_ph request into `frame` (cleared first; it
    /// allocates only if `frame` has no capacity).
    pub fn encode_get_ph(request: &mut ModbusRequest, frame: &mut Vec<u8>) -> Result<(), ErrorKind> {
        request.generate_get_holdings(0x2800, 2, frame)
    }

    /// [`encode_get_ph`]: the [`FloatRead`](super::FloatRead) request.
    pub fn encode_float_read(request: &mut ModbusRequest, frame: &mut Vec<u8>) -> Result<(), ErrorKind> {
        encode_get_ph(request, frame)
    }

    /// [`decode_get_ph`]: the [`FloatRead`](super::FloatRead) reply's float.
    pub fn decode_float_read(request: &ModbusRequest, frame: &[u8]) -> Result<f32, ErrorKind> {
        decode_get_ph(request, frame)
    }

    /// The register data of a checked reply, exactly `2 * count` bytes.
    /// `parse_slice` checks the CRC, slave, function and (loosely) the byte
    /// count; the exact data length is checked here, as the generated
    /// codecs do.
    fn data<'a>(request: &'a ModbusRequest, frame: &'a [u8]) -> Result<&'a [u8], ErrorKind> {
        let data = request.parse_slice(frame)?;
        if data.len() == 2 * usize::from(request.count) { Ok(data) } else { Err(ErrorKind::FrameBroken) }
    }

    fn f32_le(data: &[u8], at: usize) -> Result<f32, ErrorKind> {
        let bytes = data.get(at..at + 4).and_then(|b| <[u8; 4]>::try_from(b).ok()).ok_or(ErrorKind::FrameBroken)?;
        Ok(f32::from_le_bytes(bytes))
    }

    /// Checks a get_ph reply and decodes the pH.
    pub fn decode_get_ph(request: &ModbusRequest, frame: &[u8]) -> Result<f32, ErrorKind> {
        f32_le(data(request, frame)?, 0)
    }

    /// Checks a temperature-and-conductivity reply and decodes it.
    pub fn decode_conductivity(request: &ModbusRequest, frame: &[u8]) -> Result<Conductivity, ErrorKind> {
        let data = data(request, frame)?;
        Ok(Conductivity {
            temperature_c: f32_le(data, 0)?,
            conductivity_ms_cm: f32_le(data, 4)?,
            range_status: data.get(8).copied().ok_or(ErrorKind::FrameBroken)?,
        })
    }
}

/// The fastest a master can repeat one transaction on a line: the request
/// and the reply back to back (`request_len + reply_len` characters), the
/// slave's turnaround of t3.5 after the request, and the master's gap of
/// `master_gap` after the reply.
///
/// With `master_gap` = t3.5 this is the wire limit of the Modbus spec; at
/// 9600 baud 8N1 a get_ph (8 + 9 bytes) takes 25.0 ms, 40 a second.
pub fn transaction_limit(line: LineTiming, request_len: usize, reply_len: usize, master_gap: Duration) -> Duration {
    line.frame_time(request_len + reply_len) + line.t3_5() + master_gap
}

#[cfg(test)]
mod tests {
    use super::*;
    use yosemitech_rtu::CharFormat;

    #[test]
    fn wire_limit_at_9600_is_40_per_second() {
        let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
        let limit = transaction_limit(line, 8, 9, line.t3_5());
        assert!((limit.as_secs_f64() * 1e3 - 25.0).abs() < 0.01, "{limit:?}");
    }

    #[test]
    fn references_agree_with_the_manual() {
        assert_eq!(yosemitech_rtu::crc16(&GET_PH_REQUEST[..6]), crc_ref::TABLE_1.checksum(&GET_PH_REQUEST[..6]));
        assert_eq!(crc_ref::TABLE_16.checksum(&GET_PH_REQUEST[..6]).to_le_bytes(), [0xCD, 0xAB]);
        let (mut ph, mut frame) = rmodbus_ref::read_request(0x2800, 2).unwrap();
        assert_eq!(frame, GET_PH_REQUEST);
        rmodbus_ref::encode_get_ph(&mut ph, &mut frame).unwrap();
        assert_eq!(frame, GET_PH_REQUEST);
        assert_eq!(rmodbus_ref::decode_get_ph(&ph, &GET_PH_REPLY), Ok(GET_PH_VALUE));
        let mut bad = GET_PH_REPLY;
        bad[4] ^= 1;
        assert!(rmodbus_ref::decode_get_ph(&ph, &bad).is_err());
        let (cond, _) = rmodbus_ref::read_request(0x2600, 5).unwrap();
        let reading = rmodbus_ref::decode_conductivity(&cond, &CONDUCTIVITY_REPLY).unwrap();
        assert_eq!((reading.temperature_c, reading.conductivity_ms_cm), CONDUCTIVITY_VALUES);
        assert_eq!(reading.range_status, 0);
        assert!(rmodbus_ref::decode_get_ph(&ph, &CONDUCTIVITY_REPLY).is_err());
    }
}

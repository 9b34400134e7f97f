//! [`SensorInfo`]: what generated sensor modules say about their sensor.

use crate::error::{EncodeError, FrameError};
use crate::frame::Layout;
use crate::timing::{CharFormat, LineTiming};
use crate::value::{FieldInfo, FieldValue};

/// Static facts about one sensor model, from its spec: generated code
/// declares one `SENSOR` constant of this type per sensor module.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SensorInfo {
    /// The spec's snake_case name (the Rust module name).
    pub name: &'static str,
    /// Human title of the probe (one line).
    pub title: &'static str,
    /// Title of the vendor manual the spec transcribes; `None` for a model
    /// no Modbus manual covers.
    pub manual: Option<&'static str>,
    /// Hardware and firmware revisions the manual covers.
    pub revision: Option<&'static str>,
    /// Where the facts come from when no manual covers the model
    /// (`no manual: from <source>`).
    pub provenance: Option<&'static str>,
    /// Factory baud rate (300..=1000000, validated by the spec).
    pub baud: u32,
    /// Factory character format (8N1 for every Yosemitech probe).
    pub format: CharFormat,
    /// Lowest valid slave address.
    pub min_address: u8,
    /// Highest valid slave address.
    pub max_address: u8,
    /// Factory slave address, within `min_address..=max_address`.
    pub default_address: u8,
}

impl SensorInfo {
    /// The timing of a line at the factory serial settings.
    pub const fn line_timing(&self) -> LineTiming {
        LineTiming::new(self.baud, self.format)
    }

    /// True when `address` is a valid slave address for this sensor.
    pub const fn is_valid_address(&self, address: u8) -> bool {
        address >= self.min_address && address <= self.max_address
    }
}

/// Why a frame could not be decoded and encoded again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoundTripError {
    /// The frame was rejected by the command's decoder.
    Frame(FrameError),
    /// The decoded message could not be encoded.
    Encode(EncodeError),
}

impl core::fmt::Display for RoundTripError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Frame(e) => write!(f, "{e}"),
            Self::Encode(e) => write!(f, "{e}"),
        }
    }
}

/// A visitor of decoded fields: each field's name and unit, and its value.
pub type FieldVisitor<'v> = &'v mut dyn FnMut(FieldInfo, FieldValue<'_>);

/// `(command name, frame, visitor)`: decodes a request and visits its fields.
pub type VisitRequestFn = fn(&str, &[u8], FieldVisitor<'_>) -> Option<Result<u8, FrameError>>;

/// `(command name, slave, frame, visitor)`: decodes a reply and visits its fields.
pub type VisitResponseFn = fn(&str, u8, &[u8], FieldVisitor<'_>) -> Option<Result<(), FrameError>>;

/// `(command name, frame, out)`: decodes a request and encodes it again.
pub type ReencodeRequestFn = fn(&str, &[u8], &mut [u8]) -> Option<Result<usize, RoundTripError>>;

/// `(command name, slave, frame, out)`: decodes a reply and encodes it again.
pub type ReencodeResponseFn = fn(&str, u8, &[u8], &mut [u8]) -> Option<Result<usize, RoundTripError>>;

/// A generated sensor module as data: what code that serves every sensor
/// (loggers, tests, the CLI) needs without naming one. Each generated module
/// declares one `MODULE`; the generated crate lists them in `SENSORS`. Every
/// function goes through the module's typed codecs, never allocates, and
/// returns `None` for a command name the sensor does not have.
#[derive(Clone, Copy)]
pub struct SensorModule {
    /// The sensor's facts: name, manual, serial settings, address range.
    pub info: SensorInfo,
    /// Every command's spec name, in spec order.
    pub commands: &'static [&'static str],
    /// The wire layout of the named command.
    pub layout: fn(&str) -> Option<Layout<'static>>,
    /// The command a request frame is for, by function, start address and count.
    pub identify_request: fn(&[u8]) -> Option<&'static str>,
    /// Decodes a request to the named command, passes each field of a
    /// write's data (in wire order) to the visitor, and returns the slave
    /// address the request is for.
    pub visit_request: VisitRequestFn,
    /// Decodes a request to the named command and encodes the typed request
    /// again into `out`: the length written.
    pub reencode_request: ReencodeRequestFn,
    /// Decodes a reply (from a request sent to the slave given) to the named
    /// command and encodes the typed reply again into `out`.
    pub reencode_response: ReencodeResponseFn,
    /// Decodes a reply to the named command and passes each field, in wire
    /// order, to the visitor.
    pub visit_response: VisitResponseFn,
    /// The derived quantities the spec declares (`DERIVED` of the module):
    /// each with its inputs and its generated function.
    pub derived: &'static [crate::derived::DerivedInfo],
}

impl core::fmt::Debug for SensorModule {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SensorModule")
            .field("info", &self.info)
            .field("commands", &self.commands)
            .field("derived", &self.derived)
            .finish_non_exhaustive()
    }
}

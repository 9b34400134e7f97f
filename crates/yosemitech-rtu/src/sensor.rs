//! [`SensorInfo`]: what generated sensor modules say about their sensor.

use crate::bytes::copy_in_pieces;
use crate::command::Command;
use crate::dispatch::{request_data, response_data, write_request, write_response};
use crate::error::{EncodeError, FrameError};
use crate::frame::{Function, Layout, MAX_ADU};
use crate::message::Message;
use crate::timing::{CharFormat, LineSettings, LineTiming};
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
    /// The factory serial settings: baud rate and character format.
    pub const fn line_settings(&self) -> LineSettings {
        LineSettings { baud: self.baud, format: self.format }
    }

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

/// One command of a sensor as data: a row of the generated `COMMANDS` table.
/// [`CommandEntry::of`] builds it from the typed command, so its codecs
/// are the typed ones; code that picks commands at run time (the CLI, the
/// simulator, tests, fuzzing) goes through it without naming a type.
#[derive(Clone, Copy)]
pub struct CommandEntry {
    /// The command's snake_case name in the spec.
    pub name: &'static str,
    /// The command's title in the manual.
    pub title: &'static str,
    /// Function, start address, register count and addressing quirks.
    pub layout: Layout<'static>,
    /// Name and unit of each field of the request (empty for reads).
    pub request_fields: &'static [FieldInfo],
    /// Name and unit of each field of the reply (empty for writes).
    pub response_fields: &'static [FieldInfo],
    // One function per message type, generic over the type alone: the
    // framing and the field names are the entry's own (non-generic) code and
    // data, so messages of one shape (every read's empty request, a reading
    // of one `f32` in one byte order) compile to one function.
    request_codec: MessageCodec,
    response_codec: MessageCodec,
    // A flag, not the read's name: the read is the one of the same registers
    // (the spec's own pairing), and a name would add eight bytes to every
    // row of every table in firmware.
    restores_coefficients: bool,
}

/// What a message's codec does with the message it decodes from register data.
enum Pass<'p, 'v> {
    /// Passes each field, named by the entry's `fields`, to the visitor.
    Visit(&'static [FieldInfo], FieldVisitor<'v>),
    /// Encodes the message's register data again into `out` (checking its
    /// ranges first when `validate`): the length written.
    Reencode { out: &'p mut [u8], validate: bool },
}

/// Why a message's codec stopped.
enum CodecError {
    /// The register data is not the message's length (the layout frames
    /// exactly that length, so this is a table whose layout and type disagree).
    DataLength,
    /// The message failed its range check or does not fit `out`.
    Encode(EncodeError),
}

/// A decoded message's value of each field, by index in its `FIELDS`.
type FieldValues<'m> = &'m dyn Fn(usize) -> Option<FieldValue<'m>>;

/// Decodes one message type from its register data and does the [`Pass`] asked.
type MessageCodec = fn(&[u8], Pass<'_, '_>) -> Result<usize, CodecError>;

// `let else` and `if let` rather than `map_err` and `?`: each closure would
// be one more function per message type.
fn message_codec<M: Message>(data: &[u8], pass: Pass<'_, '_>) -> Result<usize, CodecError> {
    let Ok(data) = M::Data::try_from(data) else {
        return Err(CodecError::DataLength);
    };
    let message = M::from_data(&data);
    match pass {
        Pass::Visit(fields, visit) => {
            visit_fields(fields, &|index| message.field(index), visit);
            Ok(0)
        }
        Pass::Reencode { out, validate } => {
            if validate && let Err(error) = message.validate() {
                return Err(CodecError::Encode(error));
            }
            copy_data(message.to_data().as_ref(), out)
        }
    }
}

/// Copies re-encoded register data to the start of `out`: its length.
fn copy_data(data: &[u8], out: &mut [u8]) -> Result<usize, CodecError> {
    if copy_in_pieces(out, data) {
        Ok(data.len())
    } else {
        Err(CodecError::Encode(EncodeError::FrameTooLong { len: data.len() }))
    }
}

/// Passes each field that has a value to the visitor, in wire order: one
/// loop for every message type, which brings only its `field` (an
/// iterator chain here would be compiled again for each of them).
#[inline(never)]
fn visit_fields(fields: &[FieldInfo], value: FieldValues<'_>, visit: FieldVisitor<'_>) {
    for (index, info) in fields.iter().enumerate() {
        if let Some(v) = value(index) {
            visit(*info, v);
        }
    }
}

impl CommandEntry {
    /// The entry of command `C`, titled as the manual titles it.
    pub const fn of<C: Command>(title: &'static str) -> Self {
        Self {
            name: C::NAME,
            title,
            layout: C::LAYOUT,
            request_fields: C::FIELDS,
            response_fields: <C::Response as Message>::FIELDS,
            request_codec: message_codec::<C>,
            response_codec: message_codec::<C::Response>,
            restores_coefficients: false,
        }
    }

    /// This entry, marked as a write of calibration coefficients: one of
    /// the spec's coefficient blocks, which a read of the same registers
    /// reads back (see [`SensorModule::coefficient_blocks`]).
    pub const fn restoring_coefficients(self) -> Self {
        Self { restores_coefficients: true, ..self }
    }

    /// Whether this is a write of calibration coefficients (see
    /// [`SensorModule::coefficient_blocks`]).
    pub const fn restores_coefficients(&self) -> bool {
        self.restores_coefficients
    }

    /// Decodes a request, passes each field of a write's data (in wire
    /// order) to the visitor, and returns the slave address it is for.
    pub fn visit_request(&self, frame: &[u8], visit: FieldVisitor<'_>) -> Result<u8, FrameError> {
        let (slave, data) = request_data(&self.layout, frame)?;
        match (self.request_codec)(data, Pass::Visit(self.request_fields, visit)) {
            Ok(_) => Ok(slave),
            Err(_) => Err(truncated(self.layout.request_len(), frame)),
        }
    }

    /// Decodes a reply to a request sent to `slave` and passes each field,
    /// in wire order, to the visitor.
    pub fn visit_response(&self, slave: u8, frame: &[u8], visit: FieldVisitor<'_>) -> Result<(), FrameError> {
        let data = response_data(&self.layout, slave, frame)?;
        match (self.response_codec)(data, Pass::Visit(self.response_fields, visit)) {
            Ok(_) => Ok(()),
            Err(_) => Err(truncated(self.layout.response_len(), frame)),
        }
    }

    /// Decodes a request and encodes the typed request again into `out`:
    /// the length written.
    pub fn reencode_request(&self, frame: &[u8], out: &mut [u8]) -> Result<usize, RoundTripError> {
        let (slave, data) = request_data(&self.layout, frame).map_err(RoundTripError::Frame)?;
        let mut again = [0; MAX_ADU];
        let len = (self.request_codec)(data, Pass::Reencode { out: &mut again, validate: true })
            .map_err(|error| self.codec_error(error, self.layout.request_len(), frame))?;
        write_request(&self.layout, slave, again.get(..len).unwrap_or(&[]), out).map_err(RoundTripError::Encode)
    }

    /// Decodes a reply (to a request sent to `slave`) and encodes the typed
    /// reply again into `out`: the length written.
    pub fn reencode_response(&self, slave: u8, frame: &[u8], out: &mut [u8]) -> Result<usize, RoundTripError> {
        let data = response_data(&self.layout, slave, frame).map_err(RoundTripError::Frame)?;
        let mut again = [0; MAX_ADU];
        // A reply is not range-checked: a probe may report values outside its measuring range.
        let len = (self.response_codec)(data, Pass::Reencode { out: &mut again, validate: false })
            .map_err(|error| self.codec_error(error, self.layout.response_len(), frame))?;
        write_response(&self.layout, slave, again.get(..len).unwrap_or(&[]), out).map_err(RoundTripError::Encode)
    }

    fn codec_error(&self, error: CodecError, frame_len: usize, frame: &[u8]) -> RoundTripError {
        match error {
            CodecError::DataLength => RoundTripError::Frame(truncated(frame_len, frame)),
            CodecError::Encode(error) => RoundTripError::Encode(error),
        }
    }
}

impl core::fmt::Debug for CommandEntry {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("CommandEntry").field("name", &self.name).field("layout", &self.layout).finish_non_exhaustive()
    }
}

/// `a == b`, byte by byte: `==` on text is a call to `memcmp`, 116 bytes
/// of firmware flash to compare command names of a dozen bytes.
fn same_text(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).all(|(x, y)| x == y)
}

/// The error of a frame whose register data is not its message's length.
fn truncated(expected: usize, frame: &[u8]) -> FrameError {
    FrameError::Truncated { expected, actual: frame.len() }
}

/// A generated sensor module as data: what code that serves every sensor
/// (loggers, tests, the CLI) needs without naming one. Each generated module
/// declares one `MODULE`; the generated crate lists them in `SENSORS`. Every
/// method goes through the module's typed codecs, never allocates, and
/// returns `None` for a command name the sensor does not have.
#[derive(Debug, Clone, Copy)]
pub struct SensorModule {
    /// The sensor's facts: name, manual, serial settings, address range.
    pub info: SensorInfo,
    /// Every command, in spec order.
    pub commands: &'static [CommandEntry],
    /// The derived quantities the spec declares (`DERIVED` of the module):
    /// each with its inputs and its generated function.
    pub derived: &'static [crate::derived::DerivedInfo],
}

impl SensorModule {
    /// The command called `name` in the spec.
    // Out of line: firmware that looks commands up by name in several
    // places keeps one copy of the search.
    #[inline(never)]
    pub fn command(&self, name: &str) -> Option<&'static CommandEntry> {
        self.commands.iter().find(|c| same_text(c.name, name))
    }

    /// The calibration-coefficient blocks of the sensor, in spec order: each
    /// write the spec marks as one (every field an `f32` coefficient) with
    /// the first read of the same registers, which reads them back. A
    /// backup reads every block; a restore writes each and reads it back.
    pub fn coefficient_blocks(&self) -> impl Iterator<Item = CoefficientBlock> + use<> {
        let commands = self.commands;
        commands.iter().filter(|w| w.restores_coefficients).filter_map(move |write| {
            let read = commands.iter().find(|r| {
                r.layout.function == Function::Read
                    && r.layout.address == write.layout.address
                    && r.layout.count == write.layout.count
            })?;
            Some(CoefficientBlock { write, read })
        })
    }

    /// Every command's spec name, in spec order.
    pub fn command_names(&self) -> impl Iterator<Item = &'static str> + use<> {
        self.commands.iter().map(|c| c.name)
    }

    /// The wire layout of the named command.
    pub fn layout(&self, name: &str) -> Option<Layout<'static>> {
        self.command(name).map(|c| c.layout)
    }

    /// The command a request frame is for, by its function, start address
    /// and register count (the first in spec order if several match). Does
    /// not check the frame.
    pub fn identify_request(&self, frame: &[u8]) -> Option<&'static str> {
        let index = identify_request(self.commands, frame)?;
        self.commands.get(index).map(|c| c.name)
    }

    /// Decodes a request to the named command, passes each field of a
    /// write's data (in wire order) to the visitor, and returns the slave
    /// address the request is for.
    pub fn visit_request(&self, name: &str, frame: &[u8], visit: FieldVisitor<'_>) -> Option<Result<u8, FrameError>> {
        Some(self.command(name)?.visit_request(frame, visit))
    }

    /// Decodes a reply (from a request sent to `slave`) to the named command
    /// and passes each field, in wire order, to the visitor.
    pub fn visit_response(
        &self,
        name: &str,
        slave: u8,
        frame: &[u8],
        visit: FieldVisitor<'_>,
    ) -> Option<Result<(), FrameError>> {
        Some(self.command(name)?.visit_response(slave, frame, visit))
    }

    /// Decodes a request to the named command and encodes the typed request
    /// again into `out`: the length written.
    pub fn reencode_request(&self, name: &str, frame: &[u8], out: &mut [u8]) -> Option<Result<usize, RoundTripError>> {
        Some(self.command(name)?.reencode_request(frame, out))
    }

    /// Decodes a reply (from a request sent to `slave`) to the named command
    /// and encodes the typed reply again into `out`.
    pub fn reencode_response(
        &self,
        name: &str,
        slave: u8,
        frame: &[u8],
        out: &mut [u8],
    ) -> Option<Result<usize, RoundTripError>> {
        Some(self.command(name)?.reencode_response(slave, frame, out))
    }
}

/// A block of calibration coefficients: the write that sets it and the read
/// of the same registers (see [`SensorModule::coefficient_blocks`]).
#[derive(Debug, Clone, Copy)]
pub struct CoefficientBlock {
    /// The write of the coefficients.
    pub write: &'static CommandEntry,
    /// The read of the same registers.
    pub read: &'static CommandEntry,
}

/// The index of the first command of `commands` whose function, start
/// address and register count a request frame carries. Does not check the
/// frame.
pub fn identify_request(commands: &[CommandEntry], frame: &[u8]) -> Option<usize> {
    let [_, function, address_hi, address_lo, count_hi, count_lo] = *frame.first_chunk::<6>()?;
    let address = u16::from_be_bytes([address_hi, address_lo]);
    let count = u16::from_be_bytes([count_hi, count_lo]);
    commands
        .iter()
        .position(|c| c.layout.function.code() == function && c.layout.address == address && c.layout.count == count)
}

//! Every calibration coefficient of any sensor, read as one backup and
//! restored with read-back, through the module as data
//! ([`SensorModule::coefficient_blocks`]): a new spec's coefficient blocks
//! are backed up without a line of Rust.
//!
//! ```
//! use yosemitech::procedures::backup::{backup, restore};
//! use yosemitech::{Client, SENSORS, Transport};
//!
//! # fn run<T: Transport>(client: &mut Client<T>) -> Result<(), yosemitech::procedures::ProcedureError> {
//! for module in SENSORS.iter().filter(|m| m.coefficient_blocks().next().is_some()) {
//!     let saved = backup(client, module, module.info.default_address)?;
//!     for (block, field, value) in saved.values(module) {
//!         println!("{} {block}.{}: {value}", module.info.name, field.name);
//!     }
//!     // ... a calibration writes new coefficients ...
//!     let replaced = restore(client, module, module.info.default_address, &saved)?;
//!     assert_eq!(replaced.sensor, module.info.name);
//! }
//! # Ok(())
//! # }
//! ```

use std::fmt;
use std::str::FromStr;

use yosemitech_rtu::frame::MAX_ADU;
use yosemitech_rtu::{CoefficientBlock, CommandEntry, FieldInfo, FieldValue, FrameError, RoundTripError, SensorModule};

use super::ProcedureError;
use crate::{Client, Transport};

/// Every coefficient of one probe, as its reads returned them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CoefficientBackup {
    /// The sensor's spec name ([`SensorModule`]'s `info.name`).
    pub sensor: String,
    /// One entry per coefficient block, in spec order.
    pub blocks: Vec<BlockBackup>,
}

/// One coefficient block: the register data its read returned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BlockBackup {
    /// The spec name of the write that restores the block.
    pub write: String,
    /// The register data, two bytes per register, as on the wire.
    pub data: Vec<u8>,
}

impl CoefficientBackup {
    /// The block restored by the write called `write`.
    pub fn block(&self, write: &str) -> Option<&BlockBackup> {
        self.blocks.iter().find(|b| b.write == write)
    }

    /// Every coefficient, as `module`'s reads decode it: the block's write
    /// name, the field's name and unit, and its value. Blocks `module` does
    /// not have, or whose data is not their length, are left out.
    pub fn values(&self, module: &SensorModule) -> Vec<(&str, FieldInfo, f32)> {
        let mut values = Vec::new();
        for saved in &self.blocks {
            let Some(block) = module.coefficient_blocks().find(|b| b.write.name == saved.write) else { continue };
            let mut frame = [0; MAX_ADU];
            let Ok(len) = block.read.layout.encode_response(1, &saved.data, &mut frame) else { continue };
            let _ = block.read.visit_response(1, frame.get(..len).unwrap_or_default(), &mut |info, value| {
                if let FieldValue::F32(v) = value {
                    values.push((saved.write.as_str(), info, v));
                }
            });
        }
        values
    }
}

/// The text of a backup: `sensor: write [HHHH HHHH] write [HHHH ...]`, each
/// block's register data in hex, a register (two bytes) per group. It reads
/// back with [`str::parse`], so a backup can be kept in a file before a
/// calibration and restored after a power cut.
///
/// ```
/// use yosemitech::procedures::backup::{BlockBackup, CoefficientBackup};
///
/// let saved = CoefficientBackup {
///     sensor: "probe".into(),
///     blocks: vec![BlockBackup { write: "set_calibration".into(), data: vec![0x3F, 0x80, 0, 0] }],
/// };
/// let text = saved.to_string();
/// assert_eq!(text, "probe: set_calibration [3F80 0000]");
/// assert_eq!(text.parse::<CoefficientBackup>(), Ok(saved));
/// ```
impl fmt::Display for CoefficientBackup {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:", self.sensor)?;
        for block in &self.blocks {
            write!(f, " {} [", block.write)?;
            for (i, byte) in block.data.iter().enumerate() {
                let gap = if i > 0 && i % 2 == 0 { " " } else { "" };
                write!(f, "{gap}{byte:02X}")?;
            }
            f.write_str("]")?;
        }
        Ok(())
    }
}

/// Reads a backup's text (its [`Display`](fmt::Display) form). Only the
/// text is checked here; whether the backup fits a probe is
/// [`restore`]'s to check, before it writes anything.
impl FromStr for CoefficientBackup {
    type Err = ParseBackupError;

    fn from_str(text: &str) -> Result<Self, ParseBackupError> {
        // Every `rest` below is a suffix of `body`, a prefix of `text`: the
        // offset where reading stopped is what `rest` lacks.
        let body = text.trim_end();
        let error = |rest: &str, reason| ParseBackupError { at: body.len() - rest.len(), reason };
        let (sensor, mut rest) = body.split_once(':').ok_or_else(|| error(body, "no `:` after the sensor"))?;
        let sensor = name(sensor).ok_or_else(|| error(body, "the sensor's name is not one word"))?;
        let mut blocks = Vec::new();
        loop {
            rest = rest.trim_start();
            if rest.is_empty() {
                return Ok(Self { sensor: sensor.to_owned(), blocks });
            }
            let (write, after) = rest.split_once('[').ok_or_else(|| error(rest, "a block without `[`"))?;
            let write = name(write).ok_or_else(|| error(rest, "a block's name is not one word"))?;
            let (hex, after) = after.split_once(']').ok_or_else(|| error(rest, "a block without `]`"))?;
            let data = hex_bytes(hex).ok_or_else(|| error(rest, "a block's data is not pairs of hex digits"))?;
            blocks.push(BlockBackup { write: write.to_owned(), data });
            rest = after;
        }
    }
}

/// Why a backup's text did not read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParseBackupError {
    /// The byte offset in the text of the part that did not read: the
    /// start of the block at fault, or 0 when the sensor's name is.
    pub at: usize,
    /// What was wrong there.
    pub reason: &'static str,
}

impl fmt::Display for ParseBackupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "not a coefficient backup: {} (at byte {})", self.reason, self.at)
    }
}

impl std::error::Error for ParseBackupError {}

/// `text` trimmed, if it is one word without the text form's separators.
fn name(text: &str) -> Option<&str> {
    let word = text.trim();
    let separator = |c: char| c.is_whitespace() || matches!(c, ':' | '[' | ']');
    (!word.is_empty() && !word.contains(separator)).then_some(word)
}

/// The bytes written in hex as `text`: groups of whole bytes (two digits
/// each), separated by whitespace.
fn hex_bytes(text: &str) -> Option<Vec<u8>> {
    let mut bytes = Vec::new();
    for group in text.split_whitespace() {
        let digits = group.as_bytes();
        // `from_str_radix` alone would take a sign (`+F`).
        if digits.len() % 2 != 0 || !digits.iter().all(u8::is_ascii_hexdigit) {
            return None;
        }
        for pair in digits.chunks_exact(2) {
            bytes.push(u8::from_str_radix(std::str::from_utf8(pair).ok()?, 16).ok()?);
        }
    }
    Some(bytes)
}

/// Reads every coefficient block of the probe at `slave`.
pub fn backup<T: Transport>(
    client: &mut Client<T>,
    module: &SensorModule,
    slave: u8,
) -> Result<CoefficientBackup, ProcedureError> {
    let mut blocks = Vec::new();
    for block in module.coefficient_blocks() {
        blocks.push(BlockBackup { write: block.write.name.to_owned(), data: read_data(client, block.read, slave)? });
    }
    Ok(CoefficientBackup { sensor: module.info.name.to_owned(), blocks })
}

/// Writes every block of `backup` to the probe at `slave` and reads each
/// back, comparing every field bit for bit. Returns what the probe held
/// before.
///
/// The whole backup is checked first (this sensor's, every block present
/// and of its length, every value finite and in the spec's range), and
/// nothing is written unless all of it passes. The probe's coefficients are
/// read before the first write: if a write or a read-back then fails, the
/// error ([`ProcedureError::RestoreInterrupted`]) carries them.
pub fn restore<T: Transport>(
    client: &mut Client<T>,
    module: &SensorModule,
    slave: u8,
    backup: &CoefficientBackup,
) -> Result<CoefficientBackup, ProcedureError> {
    let plan = plan(module, slave, backup)?;
    let replaced = self::backup(client, module, slave)?;
    for (block, request) in &plan {
        if let Err(cause) = write_block(client, *block, slave, request) {
            return Err(ProcedureError::RestoreInterrupted { replaced: Box::new(replaced), cause: Box::new(cause) });
        }
    }
    Ok(replaced)
}

/// A write request ready to send: the frame and its length.
type Request = ([u8; MAX_ADU], usize);

/// Every block's write request, once the whole backup is checked.
fn plan(
    module: &SensorModule,
    slave: u8,
    backup: &CoefficientBackup,
) -> Result<Vec<(CoefficientBlock, Request)>, ProcedureError> {
    let unfit = |block: Option<&str>, reason: &'static str| ProcedureError::BackupDoesNotFit {
        sensor: module.info.name,
        block: block.map(str::to_owned),
        reason,
    };
    if backup.sensor != module.info.name {
        return Err(unfit(None, "it is another sensor's backup"));
    }
    let blocks: Vec<CoefficientBlock> = module.coefficient_blocks().collect();
    if let Some(stray) = backup.blocks.iter().find(|b| !blocks.iter().any(|block| block.write.name == b.write)) {
        return Err(unfit(Some(&stray.write), "the sensor has no such coefficient block"));
    }
    let mut plan = Vec::new();
    for block in blocks {
        let name = block.write.name;
        let saved = backup.block(name).ok_or_else(|| unfit(Some(name), "the backup lacks this block"))?;
        let mut frame = [0; MAX_ADU];
        let len = block
            .write
            .layout
            .encode_request(slave, &saved.data, &mut frame)
            .map_err(|_| unfit(Some(name), "its data is not the block's length"))?;
        let request = frame.get(..len).unwrap_or_default();
        if !fields_of_request(block.write, request)?.iter().all(Bits::is_finite) {
            return Err(ProcedureError::NotFinite { what: name });
        }
        let mut again = [0; MAX_ADU];
        match block.write.reencode_request(request, &mut again) {
            Ok(_) => {}
            Err(RoundTripError::Encode(_)) => return Err(unfit(Some(name), "a value is outside the spec's range")),
            Err(RoundTripError::Frame(error)) => return Err(frame_error(error)),
        }
        plan.push((block, (frame, len)));
    }
    Ok(plan)
}

/// Writes one block and reads it back, comparing every field bit for bit.
fn write_block<T: Transport>(
    client: &mut Client<T>,
    block: CoefficientBlock,
    slave: u8,
    (frame, len): &Request,
) -> Result<(), ProcedureError> {
    let request = frame.get(..*len).unwrap_or_default();
    let written = fields_of_request(block.write, request)?;
    client.call_raw(request, &block.write.layout)?;
    let back = read_data(client, block.read, slave)?;
    if fields_of_data(block.read, slave, &back)? != written {
        return Err(ProcedureError::ReadBackMismatch { what: block.write.name });
    }
    Ok(())
}

/// The register data the read `read` returns from the probe at `slave`.
fn read_data<T: Transport>(client: &mut Client<T>, read: &CommandEntry, slave: u8) -> Result<Vec<u8>, ProcedureError> {
    let mut frame = [0; MAX_ADU];
    let len = read.layout.encode_request(slave, &[], &mut frame).map_err(crate::Error::from)?;
    let reply = client.call_raw(frame.get(..len).unwrap_or_default(), &read.layout)?;
    let data = read.layout.decode_response(slave, reply).map_err(frame_error)?;
    Ok(data.to_vec())
}

/// A field's value, floats by their bits (so that a read-back compares bit
/// for bit, NaN payloads included).
#[derive(Debug, Clone, PartialEq, Eq)]
enum Bits {
    F32(u32),
    Other(String),
}

impl Bits {
    fn of(value: FieldValue<'_>) -> Self {
        match value {
            FieldValue::F32(v) => Self::F32(v.to_bits()),
            other => Self::Other(format!("{other:?}")),
        }
    }

    fn is_finite(&self) -> bool {
        match self {
            Self::F32(bits) => f32::from_bits(*bits).is_finite(),
            Self::Other(_) => true,
        }
    }
}

/// Every field of a write request.
fn fields_of_request(write: &CommandEntry, request: &[u8]) -> Result<Vec<Bits>, ProcedureError> {
    let mut fields = Vec::new();
    write.visit_request(request, &mut |_, value| fields.push(Bits::of(value))).map_err(frame_error)?;
    Ok(fields)
}

/// Every field of a read's register data.
fn fields_of_data(read: &CommandEntry, slave: u8, data: &[u8]) -> Result<Vec<Bits>, ProcedureError> {
    let mut frame = [0; MAX_ADU];
    let len = read.layout.encode_response(slave, data, &mut frame).map_err(crate::Error::from)?;
    let mut fields = Vec::new();
    read.visit_response(slave, frame.get(..len).unwrap_or_default(), &mut |_, value| fields.push(Bits::of(value)))
        .map_err(frame_error)?;
    Ok(fields)
}

/// A frame this procedure built or the client already checked, rejected by
/// a decoder: reported as the device error it would be on the wire.
fn frame_error(error: FrameError) -> ProcedureError {
    ProcedureError::Device(crate::Error::Frame { error })
}

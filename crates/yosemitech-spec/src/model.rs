//! The validated spec: what the generator, interpreter, simulator and CLI read.
//!
//! Every value here has passed [`crate::load_paths`]: names are valid
//! identifiers, fields fill the registers exactly, every example frame has
//! been replayed through the interpreter.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Serialize;
use yosemitech_rtu::{ByteOrder2, ByteOrder4, Function, Layout};

/// All sensors of a spec directory.
#[derive(Debug, Clone, Serialize)]
pub struct Spec {
    /// Sensors, in file-name order.
    pub sensors: Vec<Sensor>,
}

impl Spec {
    /// The sensor called `name`.
    pub fn sensor(&self, name: &str) -> Option<&Sensor> {
        self.sensors.iter().find(|s| s.name == name)
    }

    /// Every file the spec was read from, included fragments once each.
    pub fn files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = self.sensors.iter().flat_map(|s| s.files.iter().cloned()).collect();
        files.sort();
        files.dedup();
        files
    }
}

/// One sensor: one vendor manual.
#[derive(Debug, Clone, Serialize)]
pub struct Sensor {
    /// snake_case name (the Rust module).
    pub name: String,
    /// Human title.
    pub title: String,
    /// What it measures.
    pub doc: String,
    /// The manual.
    pub manual: Manual,
    /// Serial settings.
    pub serial: Serial,
    /// Lowest valid slave address.
    pub min_address: u8,
    /// Highest valid slave address.
    pub max_address: u8,
    /// Factory slave address.
    pub default_address: u8,
    /// Commands, in spec order (included ones where they are included).
    pub commands: Vec<Command>,
    /// Numbers the procedures use.
    pub constants: Vec<Constant>,
    /// Manual-wide errata.
    pub errata: Vec<Erratum>,
    /// The sensor's file.
    pub file: PathBuf,
    /// The sensor's file and every file it includes.
    pub files: Vec<PathBuf>,
}

impl Sensor {
    /// The command called `name`.
    pub fn command(&self, name: &str) -> Option<&Command> {
        self.commands.iter().find(|c| c.name == name)
    }

    /// The constant called `name`.
    pub fn constant(&self, name: &str) -> Option<&Constant> {
        self.constants.iter().find(|c| c.name == name)
    }

    /// Every example frame of every command.
    pub fn example_count(&self) -> usize {
        self.commands.iter().map(|c| c.examples.len()).sum()
    }
}

/// The manual a sensor's spec transcribes.
#[derive(Debug, Clone, Serialize)]
pub struct Manual {
    /// Title.
    pub title: String,
    /// Revisions covered.
    pub revision: String,
    /// The text extraction used.
    pub file: Option<String>,
}

/// Serial line settings.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
pub struct Serial {
    /// Bits per second.
    pub baud: u32,
    /// Data bits.
    pub data_bits: u8,
    /// Parity.
    pub parity: Parity,
    /// Stop bits.
    pub stop_bits: u8,
}

impl Serial {
    /// Bits on the line per character: start, data, parity, stop.
    pub fn bits_per_char(&self) -> u32 {
        1 + u32::from(self.data_bits) + u32::from(self.parity != Parity::None) + u32::from(self.stop_bits)
    }
}

/// Parity.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Parity {
    /// None.
    None,
    /// Even.
    Even,
    /// Odd.
    Odd,
}

/// Where the manual documents something.
#[derive(Debug, Clone, Serialize, PartialEq, Eq, Default)]
pub struct Source {
    /// Section, e.g. "2.2.3".
    pub section: String,
    /// Figures.
    pub figures: Vec<u32>,
}

/// One command.
#[derive(Debug, Clone, Serialize)]
pub struct Command {
    /// snake_case name.
    pub name: String,
    /// Title from the manual.
    pub title: String,
    /// What it does.
    pub doc: String,
    /// Where this sensor's manual documents it.
    pub source: Source,
    /// Read or write.
    #[serde(serialize_with = "ser_function")]
    pub function: Function,
    /// First register on the wire.
    pub address: u16,
    /// Registers.
    pub count: u16,
    /// A write of zero registers that triggers an action.
    pub trigger: bool,
    /// Slave address forced on request and reply.
    pub fixed_slave: Option<u8>,
    /// Extra byte counts a read reply may carry.
    pub extra_byte_counts: Vec<u8>,
    /// Register data fields in wire order (reply of a read, request of a write).
    pub fields: Vec<Field>,
    /// Frames printed in the manual.
    pub examples: Vec<Example>,
    /// Table contradictions.
    pub errata: Vec<CommandErratum>,
    /// The fragment this command was included from.
    pub shared_from: Option<String>,
}

fn ser_function<S: serde::Serializer>(f: &Function, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(match f {
        Function::Read => "read",
        Function::Write => "write",
    })
}

impl Command {
    /// The wire layout, for framing.
    pub fn layout(&self) -> Layout<'_> {
        Layout {
            function: self.function,
            address: self.address,
            count: self.count,
            fixed_slave: self.fixed_slave,
            extra_byte_counts: &self.extra_byte_counts,
        }
    }

    /// True for reads.
    pub fn is_read(&self) -> bool {
        self.function == Function::Read
    }

    /// Named (non-reserved) fields.
    pub fn named_fields(&self) -> impl Iterator<Item = &Field> {
        self.fields.iter().filter(|f| !f.is_reserved())
    }

    /// The field called `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name.as_deref() == Some(name))
    }
}

/// A table contradiction for one command.
#[derive(Debug, Clone, Serialize)]
pub struct CommandErratum {
    /// Identifier (E1, …).
    pub id: String,
    /// The figure with the wrong table.
    pub figure: u32,
    /// The start address the table prints, if wrong.
    pub table_address: Option<u16>,
    /// The register count the table prints, if wrong.
    pub table_count: Option<u16>,
    /// The function the table prints, if wrong.
    #[serde(serialize_with = "ser_opt_function")]
    pub table_function: Option<Function>,
    /// Why the spec's value is the truth.
    pub note: String,
}

fn ser_opt_function<S: serde::Serializer>(f: &Option<Function>, s: S) -> Result<S::Ok, S::Error> {
    match f {
        Some(f) => ser_function(f, s),
        None => s.serialize_none(),
    }
}

impl CommandErratum {
    /// What the table prints, e.g. `["address 0x1100"]`.
    pub fn table_says(&self) -> Vec<String> {
        let mut said = Vec::new();
        if let Some(a) = self.table_address {
            said.push(format!("address 0x{a:04X}"));
        }
        if let Some(n) = self.table_count {
            said.push(format!("count {n}"));
        }
        if let Some(f) = self.table_function {
            said.push(format!("function 0x{:02X}", f.code()));
        }
        said
    }
}

/// A manual-wide erratum.
#[derive(Debug, Clone, Serialize)]
pub struct Erratum {
    /// Identifier.
    pub id: String,
    /// Figures concerned.
    pub figures: Vec<u32>,
    /// Sections concerned.
    pub sections: Vec<String>,
    /// Explanation.
    pub note: String,
}

/// One field of register data.
#[derive(Debug, Clone, Serialize)]
pub struct Field {
    /// snake_case name; `None` only for reserved bytes.
    pub name: Option<String>,
    /// Type and encoding.
    pub kind: FieldKind,
    /// Byte offset in the register data.
    pub offset: usize,
    /// Unit.
    pub unit: Option<String>,
    /// Meaning.
    pub doc: Option<String>,
    /// Values a write may send (inclusive).
    pub range: Option<(f64, f64)>,
}

impl Field {
    /// Bytes on the wire.
    pub fn size(&self) -> usize {
        self.kind.size()
    }

    /// True for reserved bytes.
    pub fn is_reserved(&self) -> bool {
        matches!(self.kind, FieldKind::Reserved { .. })
    }

    /// The field's name, or `reserved`.
    pub fn display_name(&self) -> &str {
        self.name.as_deref().unwrap_or("reserved")
    }
}

/// Wire order of a 2-byte value.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Order2 {
    /// Big-endian.
    Ab,
    /// Little-endian.
    Ba,
}

impl Order2 {
    /// The runtime's byte order.
    pub fn rtu(self) -> ByteOrder2 {
        match self {
            Self::Ab => ByteOrder2::Ab,
            Self::Ba => ByteOrder2::Ba,
        }
    }
}

/// Wire order of a 4-byte value.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Order4 {
    /// Big-endian.
    Abcd,
    /// Little-endian memory image.
    Dcba,
    /// Word-swapped.
    Cdab,
    /// Byte-swapped.
    Badc,
}

impl Order4 {
    /// The runtime's byte order.
    pub fn rtu(self) -> ByteOrder4 {
        match self {
            Self::Abcd => ByteOrder4::Abcd,
            Self::Dcba => ByteOrder4::Dcba,
            Self::Cdab => ByteOrder4::Cdab,
            Self::Badc => ByteOrder4::Badc,
        }
    }
}

/// The size of an enum code.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum EnumRepr {
    /// One byte.
    U8,
    /// Two bytes in the given order.
    U16(Order2),
}

/// A named enum code.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Variant {
    /// snake_case name.
    pub name: String,
    /// Wire value.
    pub value: u16,
    /// Meaning.
    pub doc: Option<String>,
}

/// Type and encoding of a field.
#[derive(Debug, Clone, Serialize, PartialEq)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum FieldKind {
    /// IEEE 754 single.
    F32 {
        /// Byte order.
        order: Order4,
    },
    /// Unsigned byte.
    U8,
    /// Signed byte.
    I8,
    /// Unsigned 16-bit.
    U16 {
        /// Byte order.
        order: Order2,
    },
    /// Signed 16-bit.
    I16 {
        /// Byte order.
        order: Order2,
    },
    /// Unsigned 32-bit.
    U32 {
        /// Byte order.
        order: Order4,
    },
    /// Signed 32-bit.
    I32 {
        /// Byte order.
        order: Order4,
    },
    /// Fixed-length text.
    Ascii {
        /// Bytes.
        len: usize,
        /// Padding byte.
        padding: u8,
    },
    /// Major, minor.
    Version,
    /// Named codes.
    Enum {
        /// Code size.
        repr: EnumRepr,
        /// Known codes.
        variants: Vec<Variant>,
    },
    /// Ignored bytes.
    Reserved {
        /// Bytes.
        len: usize,
        /// Byte written.
        fill: u8,
    },
}

impl FieldKind {
    /// Bytes on the wire.
    pub fn size(&self) -> usize {
        match self {
            Self::U8 | Self::I8 => 1,
            Self::U16 { .. } | Self::I16 { .. } | Self::Version => 2,
            Self::F32 { .. } | Self::U32 { .. } | Self::I32 { .. } => 4,
            Self::Ascii { len, .. } | Self::Reserved { len, .. } => *len,
            Self::Enum { repr: EnumRepr::U8, .. } => 1,
            Self::Enum { repr: EnumRepr::U16(_), .. } => 2,
        }
    }

    /// The spec's name of the type.
    pub fn type_name(&self) -> &'static str {
        match self {
            Self::F32 { .. } => "f32",
            Self::U8 => "u8",
            Self::I8 => "i8",
            Self::U16 { .. } => "u16",
            Self::I16 { .. } => "i16",
            Self::U32 { .. } => "u32",
            Self::I32 { .. } => "i32",
            Self::Ascii { .. } => "ascii",
            Self::Version => "version",
            Self::Enum { .. } => "enum",
            Self::Reserved { .. } => "reserved",
        }
    }
}

/// A frame pair printed in the manual.
#[derive(Debug, Clone, Serialize)]
pub struct Example {
    /// Figures.
    pub figures: Vec<u32>,
    /// Request as printed.
    pub request: Vec<u8>,
    /// Reply as printed.
    pub response: Vec<u8>,
    /// Values the manual states, by field name.
    pub values: BTreeMap<String, crate::Value>,
    /// Remarks.
    pub doc: Option<String>,
    /// Where the printed frame is wrong.
    pub erratum: Option<ExampleErratum>,
}

impl Example {
    /// The true request: the correction if the printed one is wrong.
    pub fn true_request(&self) -> &[u8] {
        self.erratum.as_ref().and_then(|e| e.corrected_request.as_deref()).unwrap_or(&self.request)
    }

    /// The true reply: the correction if the printed one is wrong.
    pub fn true_response(&self) -> &[u8] {
        self.erratum.as_ref().and_then(|e| e.corrected_response.as_deref()).unwrap_or(&self.response)
    }

    /// The slave address the request is sent to.
    pub fn slave(&self) -> u8 {
        self.true_request().first().copied().unwrap_or(0)
    }

    /// Frames printed in this example: request and reply.
    pub const FRAMES: usize = 2;
}

/// A printed frame that is wrong.
#[derive(Debug, Clone, Serialize)]
pub struct ExampleErratum {
    /// Identifier.
    pub id: String,
    /// The figure.
    pub figure: u32,
    /// What is wrong.
    pub printed: String,
    /// True request.
    pub corrected_request: Option<Vec<u8>>,
    /// True reply.
    pub corrected_response: Option<Vec<u8>>,
    /// Whether our decoder accepts the printed frame.
    pub printed_decodes: bool,
}

/// A number a procedure uses.
#[derive(Debug, Clone, Serialize)]
pub struct Constant {
    /// snake_case name.
    pub name: String,
    /// Rust type.
    pub ty: ConstantType,
    /// The values; one for a scalar.
    pub values: Vec<f64>,
    /// True when declared with `values:` (an array).
    pub is_list: bool,
    /// Unit.
    pub unit: Option<String>,
    /// Meaning.
    pub doc: String,
    /// Source in the manual.
    pub source: Option<Source>,
}

/// Rust type of a constant.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ConstantType {
    /// f32.
    F32,
    /// u8.
    U8,
    /// u16.
    U16,
    /// u32.
    U32,
}

//! Register data: a field's type, its encoding on the wire and its named
//! codes and bits.

use serde::Serialize;
use yosemitech_rtu::{ByteOrder2, ByteOrder4};

use super::Figure;

/// One field of register data.
#[derive(Debug, Clone, Serialize)]
pub struct Field {
    /// snake_case name; `None` only for reserved bytes.
    pub name: Option<String>,
    /// The field's type and wire encoding; its size is `kind.size()` bytes.
    pub kind: FieldKind,
    /// Byte offset in the register data.
    pub offset: usize,
    /// Unit of the value (`mS/cm`, `degC`) as the manual gives it; `None` for unitless values.
    pub unit: Option<String>,
    /// What the value means, in prose.
    pub doc: Option<String>,
    /// Values a write may send (inclusive); on a read, the measuring range.
    pub range: Option<(f64, f64)>,
    /// The value of natural water the simulator centres a reading on.
    pub typical: Option<f64>,
    /// The value read where a sub-probe is not fitted.
    pub absent: Option<f64>,
    /// Values with their bytes, printed outside a frame; each verified both ways.
    pub examples: Vec<FieldExample>,
}

/// A field's value and its bytes, as a manual prints them outside a frame.
#[derive(Debug, Clone, Serialize)]
pub struct FieldExample {
    /// The bytes as printed, `field.size()` of them.
    pub bytes: Vec<u8>,
    /// The value they decode to.
    pub value: crate::Value,
    /// Where the manual prints it.
    pub figures: Vec<Figure>,
}

/// A named bit of a flags field.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Flag {
    /// snake_case identifier, unique within the field.
    pub name: String,
    /// The mask: exactly one bit set, within the field's size.
    pub mask: u16,
    /// What the bit means when set.
    pub doc: Option<String>,
}

impl Field {
    /// Bytes on the wire: `kind.size()`.
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

fn ser_order2<S: serde::Serializer>(o: &ByteOrder2, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(o.name())
}

fn ser_order4<S: serde::Serializer>(o: &ByteOrder4, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(o.name())
}

/// The size of an enum code.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum EnumRepr {
    /// One byte, no byte order.
    U8,
    /// Two bytes in the given order.
    U16(#[serde(serialize_with = "ser_order2")] ByteOrder2),
}

/// A named enum code: a value the field may carry, with its meaning.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Variant {
    /// snake_case identifier, unique within the field, also as a Rust name.
    pub name: String,
    /// The code on the wire; fits the enum's size (0..=255 for one byte).
    pub value: u16,
    /// What the code means.
    pub doc: Option<String>,
}

/// Type and encoding of a field.
#[derive(Debug, Clone, Serialize, PartialEq)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum FieldKind {
    /// IEEE 754 single, 4 bytes, decoded bit for bit (NaN payloads kept).
    F32 {
        /// The order of its 4 bytes on the wire.
        #[serde(serialize_with = "ser_order4")]
        order: ByteOrder4,
    },
    /// Unsigned byte.
    U8,
    /// Signed byte (two's complement).
    I8,
    /// Unsigned 16-bit integer, 2 bytes.
    U16 {
        /// The order of its 2 bytes on the wire.
        #[serde(serialize_with = "ser_order2")]
        order: ByteOrder2,
    },
    /// Signed 16-bit integer, 2 bytes (two's complement).
    I16 {
        /// The order of its 2 bytes on the wire.
        #[serde(serialize_with = "ser_order2")]
        order: ByteOrder2,
    },
    /// Unsigned 32-bit integer, 4 bytes.
    U32 {
        /// The order of its 4 bytes on the wire.
        #[serde(serialize_with = "ser_order4")]
        order: ByteOrder4,
    },
    /// Signed 32-bit integer, 4 bytes (two's complement).
    I32 {
        /// The order of its 4 bytes on the wire.
        #[serde(serialize_with = "ser_order4")]
        order: ByteOrder4,
    },
    /// Fixed-length text: `len` bytes, printable ASCII, padded at the end.
    Ascii {
        /// Bytes on the wire, padding included (1 or more).
        len: usize,
        /// The byte that fills the text to `len` (0x00 or a space).
        padding: u8,
    },
    /// Major, minor.
    Version,
    /// Named codes: an enum of one or two bytes; unknown codes decode as raw values.
    Enum {
        /// The size of the code, and its byte order when two bytes.
        repr: EnumRepr,
        /// The codes the manual names, unique by value and by name.
        variants: Vec<Variant>,
    },
    /// Bytes the device sends and ignores; written as `fill`.
    Reserved {
        /// Bytes on the wire (1 or more).
        len: usize,
        /// The byte an encoder writes in each reserved byte.
        fill: u8,
    },
    /// One byte, two decimal digits.
    Bcd,
    /// Independent named bits of one or two bytes; unnamed bits are kept as read.
    Flags {
        /// Size and order of the bit field.
        repr: EnumRepr,
        /// The named bits: each mask has exactly one bit, unique within the field.
        flags: Vec<Flag>,
    },
}

impl FieldKind {
    /// A plain number (float or integer): what a range, a derived
    /// quantity's input or a unit applies to.
    pub fn is_number(&self) -> bool {
        matches!(
            self,
            Self::F32 { .. }
                | Self::U8
                | Self::I8
                | Self::U16 { .. }
                | Self::I16 { .. }
                | Self::U32 { .. }
                | Self::I32 { .. }
        )
    }

    /// Bytes on the wire: 1, 2, 4, or a text's or reserved run's length.
    pub fn size(&self) -> usize {
        match self {
            Self::U8 | Self::I8 | Self::Bcd => 1,
            Self::Flags { repr: EnumRepr::U8, .. } => 1,
            Self::Flags { repr: EnumRepr::U16(_), .. } => 2,
            Self::U16 { .. } | Self::I16 { .. } | Self::Version => 2,
            Self::F32 { .. } | Self::U32 { .. } | Self::I32 { .. } => 4,
            Self::Ascii { len, .. } | Self::Reserved { len, .. } => *len,
            Self::Enum { repr: EnumRepr::U8, .. } => 1,
            Self::Enum { repr: EnumRepr::U16(_), .. } => 2,
        }
    }

    /// The spec's name (`dcba`, `ab`) of the byte order of a multi-byte
    /// number, enum or flags field; `None` for a field of one byte, text, a
    /// version or reserved bytes, which have no byte order.
    pub fn byte_order_name(&self) -> Option<&'static str> {
        match self {
            Self::F32 { order } | Self::U32 { order } | Self::I32 { order } => Some(order.name()),
            Self::U16 { order }
            | Self::I16 { order }
            | Self::Enum { repr: EnumRepr::U16(order), .. }
            | Self::Flags { repr: EnumRepr::U16(order), .. } => Some(order.name()),
            _ => None,
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
            Self::Bcd => "bcd",
            Self::Flags { .. } => "flags",
        }
    }
}

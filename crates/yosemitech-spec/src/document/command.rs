//! A spec file's commands: function, registers, fields and their wire
//! encodings, ranges and the manual's printed examples.

use super::*;

/// Read or write.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum FunctionDoc {
    /// 0x03, read holding registers.
    Read,
    /// 0x10, write multiple registers.
    Write,
}

/// A command: a full definition (`name`), or `use` of an included one.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
#[cfg_attr(feature = "schema", schemars(extend("oneOf" = [{"required": ["name"]}, {"required": ["use"]}])))]
pub struct CommandDoc {
    /// snake_case name of a new command.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<Spanned<String>>,
    /// Name of an included command this entry adds `source`, `examples` and `errata` to.
    #[serde(rename = "use")]
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uses: Option<Spanned<String>>,
    /// Human title, as in the manual's section heading.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub title: Option<Spanned<String>>,
    /// The software revision that introduced the command (a manual's `software`).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub since: Option<Spanned<String>>,
    /// What the command is for, where the simulator or the CLI must know.
    #[cfg_attr(feature = "schema", schemars(with = "Option<RoleDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub role: Option<Spanned<RoleDoc>>,
    /// Of a user calibration block: the field it calibrates, where the manual says it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibrates: Option<CalibratesDoc>,
    /// In a `use` entry: the unit this manual states for a field.
    #[cfg_attr(feature = "schema", schemars(with = "Option<BTreeMap<String, String>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<Spanned<BTreeMap<String, Spanned<String>>>>,
    /// What the command does; becomes the rustdoc.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Where the manual documents it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceDoc>,
    /// Where its facts come from when no manual states them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub provenance: Option<ProvenanceDoc>,
    /// `read` (0x03) or `write` (0x10).
    #[cfg_attr(feature = "schema", schemars(with = "Option<FunctionDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub function: Option<Spanned<FunctionDoc>>,
    /// First register, as sent on the wire.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub address: Option<Spanned<u32>>,
    /// Number of registers.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<Spanned<u32>>,
    /// A command that carries no value: a write of zero registers, or a read whose reply is ignored.
    #[cfg_attr(feature = "schema", schemars(with = "Option<bool>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trigger: Option<Spanned<bool>>,
    /// A slave address the request and the reply always use (e.g. 0xFF).
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fixed_slave: Option<Spanned<u32>>,
    /// Byte counts a read reply may carry besides `2 * count`, for firmware quirks.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[cfg_attr(feature = "schema", schemars(with = "Vec<u32>"))]
    pub extra_byte_counts: Vec<Spanned<u32>>,
    /// The register data, in wire order: the reply of a read, the request of a write.
    #[cfg_attr(feature = "schema", schemars(with = "Option<Vec<FieldDoc>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fields: Option<Spanned<Vec<FieldDoc>>>,
    /// Frames printed in the manual.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub examples: Vec<ExampleDoc>,
    /// Places where the manual's command table contradicts its examples.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub errata: Vec<CommandErratumDoc>,
}

/// The type of a field.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum FieldTypeDoc {
    /// IEEE 754 single, 4 bytes, needs `byte_order`.
    F32,
    /// One byte, unsigned.
    U8,
    /// One byte, signed.
    I8,
    /// Two bytes, unsigned, needs `byte_order`.
    U16,
    /// Two bytes, signed, needs `byte_order`.
    I16,
    /// Four bytes, unsigned, needs `byte_order`.
    U32,
    /// Four bytes, signed, needs `byte_order`.
    I32,
    /// Fixed-length text of `size` bytes, padded with `padding`.
    Ascii,
    /// Two bytes: major, minor.
    Version,
    /// A code with named `variants`; `size` 1 or 2 bytes.
    Enum,
    /// `size` bytes the device ignores or fills with `fill`.
    Reserved,
    /// One byte of two decimal digits (`0x59` = 59).
    Bcd,
    /// Independent bits with names; `size` 1 or 2 bytes.
    Flags,
}

/// Byte order of a multi-byte value, as wire letters (A = most significant).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum ByteOrderDoc {
    /// Two bytes, big-endian.
    Ab,
    /// Two bytes, little-endian.
    Ba,
    /// Four bytes, big-endian.
    Abcd,
    /// Four bytes, little-endian memory image.
    Dcba,
    /// Four bytes, word-swapped.
    Cdab,
    /// Four bytes, byte-swapped.
    Badc,
}

impl ByteOrderDoc {
    /// The two-byte runtime order this spelling names; `None` for a four-byte one.
    pub fn two(self) -> Option<ByteOrder2> {
        match self {
            Self::Ab => Some(ByteOrder2::Ab),
            Self::Ba => Some(ByteOrder2::Ba),
            Self::Abcd | Self::Dcba | Self::Cdab | Self::Badc => None,
        }
    }

    /// The four-byte runtime order this spelling names; `None` for a two-byte one.
    pub fn four(self) -> Option<ByteOrder4> {
        match self {
            Self::Abcd => Some(ByteOrder4::Abcd),
            Self::Dcba => Some(ByteOrder4::Dcba),
            Self::Cdab => Some(ByteOrder4::Cdab),
            Self::Badc => Some(ByteOrder4::Badc),
            Self::Ab | Self::Ba => None,
        }
    }

    /// The spelling, as the runtime names the order (`ab`, `dcba`).
    pub fn name(self) -> &'static str {
        match (self.two(), self.four()) {
            (Some(two), _) => two.name(),
            (None, Some(four)) => four.name(),
            (None, None) => "",
        }
    }
}

/// Text padding byte.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum PaddingDoc {
    /// 0x00.
    Nul,
    /// 0x20.
    Space,
}

/// An inclusive range of valid values.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct RangeDoc {
    /// Lowest valid value.
    pub min: f64,
    /// Highest valid value.
    pub max: f64,
}

/// One field of register data.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct FieldDoc {
    /// snake_case name; optional for `reserved`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<Spanned<String>>,
    /// The value's type.
    #[serde(rename = "type")]
    #[cfg_attr(feature = "schema", schemars(with = "FieldTypeDoc"))]
    pub ty: Spanned<FieldTypeDoc>,
    /// Byte offset in the register data; defaults to right after the previous field.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offset: Option<Spanned<u32>>,
    /// Wire byte order, for 2- and 4-byte numbers.
    #[cfg_attr(feature = "schema", schemars(with = "Option<ByteOrderDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub byte_order: Option<Spanned<ByteOrderDoc>>,
    /// Bytes, for `ascii`, `enum` and `reserved`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub size: Option<Spanned<u32>>,
    /// Padding of `ascii` text.
    #[cfg_attr(feature = "schema", schemars(with = "Option<PaddingDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub padding: Option<Spanned<PaddingDoc>>,
    /// Byte written into `reserved` bytes (default 0).
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fill: Option<Spanned<u32>>,
    /// Physical unit (pH, mV, degC, mS/cm).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<Spanned<String>>,
    /// What the value means.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Values a write may send.
    #[cfg_attr(feature = "schema", schemars(with = "Option<RangeDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<Spanned<RangeDoc>>,
    /// The value of natural water the simulator centres a reading on
    /// (default: the middle of `range`). Not a fact of the probe.
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub typical: Option<Spanned<f64>>,
    /// Named codes of an `enum`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<Vec<VariantDoc>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variants: Option<Spanned<Vec<VariantDoc>>>,
    /// Named bits of a `flags` field.
    #[cfg_attr(feature = "schema", schemars(with = "Option<Vec<FlagDoc>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flags: Option<Spanned<Vec<FlagDoc>>>,
    /// The value read where a sub-probe is not fitted.
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub absent: Option<Spanned<f64>>,
    /// Values with their bytes, as the manual prints them outside a frame.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub examples: Vec<FieldExampleDoc>,
}

/// A named bit of a flags field.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct FlagDoc {
    /// snake_case name.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// The bit, as a mask with one bit set (`0x04`).
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub mask: Spanned<u32>,
    /// What the bit means.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
}

/// A field's value and its bytes, printed outside a frame.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct FieldExampleDoc {
    /// The bytes, hex separated by spaces.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub bytes: Spanned<String>,
    /// The value the manual states.
    #[cfg_attr(feature = "schema", schemars(with = "StatedValue"))]
    pub value: Spanned<StatedValue>,
    /// Where the manual prints it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub figures: Vec<FigureDoc>,
}

/// A named code of an enum field.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct VariantDoc {
    /// snake_case name; becomes a CamelCase variant.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// The code on the wire.
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub value: Spanned<u32>,
    /// What the code means.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
}

/// A value stated by the manual for an example frame.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(untagged)]
pub enum StatedValue {
    /// A number.
    Number(f64),
    /// Text, a version ("1.1") or an enum variant name.
    Text(String),
}

/// A whole number is written without a fraction (`20`, not `20.0`), as a
/// manual prints an address or a count; it reads back as the same number.
#[cfg(feature = "serialize")]
impl serde::Serialize for StatedValue {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // Past 2^53 an f64 no longer holds every integer: keep its own spelling.
        const EXACT: f64 = 9_007_199_254_740_992.0;
        match self {
            Self::Number(n) if n.fract() == 0.0 && n.abs() < EXACT => s.serialize_i64(*n as i64),
            Self::Number(n) => s.serialize_f64(*n),
            Self::Text(t) => s.serialize_str(t),
        }
    }
}

/// Whether the manual prints a frame's CRC.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum CrcDoc {
    /// The CRC is printed (the default).
    Printed,
    /// The CRC cells are empty: the text holds the bytes before the CRC.
    Missing,
}

/// A frame pair printed in the manual.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ExampleDoc {
    /// The figures that print the frames (and their register tables).
    pub figures: Vec<FigureDoc>,
    /// The manual (its `software` revision) when not the file's `manual`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manual: Option<Spanned<String>>,
    /// The request as printed, hex bytes separated by spaces; `??` for a
    /// placeholder byte, a final `...` for bytes of unknown number.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request: Option<Spanned<String>>,
    /// Whether the request's CRC is printed.
    #[cfg_attr(feature = "schema", schemars(with = "Option<CrcDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request_crc: Option<Spanned<CrcDoc>>,
    /// The reply as printed, like `request`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub response: Option<Spanned<String>>,
    /// Whether the reply's CRC is printed.
    #[cfg_attr(feature = "schema", schemars(with = "Option<CrcDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub response_crc: Option<Spanned<CrcDoc>>,
    /// The values the manual states, by field name (none for an example
    /// whose frames carry no values).
    #[cfg_attr(feature = "schema", schemars(with = "Option<BTreeMap<String, StatedValue>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub values: Option<Spanned<BTreeMap<String, Spanned<StatedValue>>>>,
    /// Remarks on the example.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Where a printed frame contradicts the truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub erratum: Option<ExampleErratumDoc>,
    /// Other manuals that print the same frames, byte for byte: cited with
    /// their own figure numbers instead of copied.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub also_in: Vec<CitationDoc>,
}

/// Another manual's figures that print an example's frames identically.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct CitationDoc {
    /// The manual (its `software` revision).
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub manual: Spanned<String>,
    /// Its figures and tables that print the frames.
    pub figures: Vec<FigureDoc>,
}

/// A printed frame that is wrong, and its correction.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ExampleErratumDoc {
    /// Identifier in datasheet-notes.md (E4, E5, …).
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub id: Spanned<String>,
    /// The figure that prints the wrong frame.
    #[cfg_attr(feature = "schema", schemars(with = "FigureDoc"))]
    pub figure: Spanned<FigureDoc>,
    /// What is wrong with the printed frame.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub printed: Spanned<String>,
    /// The true request, when the printed request is wrong.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corrected_request: Option<Spanned<String>>,
    /// The true reply, when the printed reply is wrong.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corrected_response: Option<Spanned<String>>,
    /// Whether our decoder accepts the printed frame as it is.
    #[cfg_attr(feature = "schema", schemars(with = "bool"))]
    pub printed_decodes: Spanned<bool>,
}

/// What a manual's command table says where it contradicts the examples.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct TableSaysDoc {
    /// The start address the table prints.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub address: Option<Spanned<u32>>,
    /// The register count the table prints.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<Spanned<u32>>,
    /// The function the table prints.
    #[cfg_attr(feature = "schema", schemars(with = "Option<FunctionDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub function: Option<Spanned<FunctionDoc>>,
}

/// A command table that contradicts the command's examples.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct CommandErratumDoc {
    /// Identifier in datasheet-notes.md (E1, E2, …).
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub id: Spanned<String>,
    /// The figure or table with the wrong table; none for a table the manual does not number.
    #[cfg_attr(feature = "schema", schemars(with = "Option<FigureDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub figure: Option<Spanned<FigureDoc>>,
    /// The manual (its `software` revision) when not the file's `manual`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manual: Option<Spanned<String>>,
    /// What the table prints instead of the truth.
    pub table: TableSaysDoc,
    /// Why the spec's value is the truth.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub note: Spanned<String>,
}

/// A contradiction in the manual that no command carries.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ErratumDoc {
    /// Identifier in datasheet-notes.md.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub id: Spanned<String>,
    /// Figures or tables concerned.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub figures: Vec<FigureDoc>,
    /// The manual (its `software` revision) when not the file's `manual`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manual: Option<Spanned<String>>,
    /// Manual sections concerned.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sections: Vec<String>,
    /// What the manual says and what the spec takes as the truth.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub note: Spanned<String>,
}

/// The Rust type of a constant.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum ConstantTypeDoc {
    /// f32.
    F32,
    /// u8.
    U8,
    /// u16.
    U16,
    /// u32.
    U32,
}

/// A number a procedure uses.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ConstantDoc {
    /// snake_case name; becomes an UPPER_CASE constant.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// The Rust type.
    #[serde(rename = "type")]
    #[cfg_attr(feature = "schema", schemars(with = "ConstantTypeDoc"))]
    pub ty: Spanned<ConstantTypeDoc>,
    /// A single value (exactly one of `value` and `values`).
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<Spanned<f64>>,
    /// A list of values, in order.
    #[cfg_attr(feature = "schema", schemars(with = "Option<Vec<f64>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub values: Option<Spanned<Vec<f64>>>,
    /// Unit.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<Spanned<String>>,
    /// What it is for.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub doc: Spanned<String>,
    /// Where the manual states it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceDoc>,
}

/// A derived quantity: a formula over fields, constants and station inputs.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct DerivedDoc {
    /// snake_case name; becomes the generated function's name.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// Human title.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub title: Spanned<String>,
    /// The result's unit, checked against the formula's.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<Spanned<String>>,
    /// What the quantity is.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub doc: Spanned<String>,
    /// Where the manual gives the formula.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceDoc>,
    /// The formula's inputs, in parameter order.
    #[cfg_attr(feature = "schema", schemars(with = "Vec<DerivedInputDoc>"))]
    pub inputs: Spanned<Vec<DerivedInputDoc>>,
    /// The formula: numbers, inputs and constants by name, `+ - * / ^`,
    /// parentheses, `exp()`, `ln()`, comparisons and `if(c, a, b)`.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub expr: Spanned<String>,
    /// Values computed independently, each with its source.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub examples: Vec<DerivedExampleDoc>,
}

/// One input of a derived quantity: a field of a read, or a station value.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
#[cfg_attr(feature = "schema", schemars(extend("oneOf" = [{"required": ["field"]}, {"required": ["station"]}])))]
pub struct DerivedInputDoc {
    /// snake_case name the formula uses; the generated function's parameter.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// `command.field` of a read of the sensor.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub field: Option<Spanned<String>>,
    /// The station input's name (`salinity`, `barometric_pressure`).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub station: Option<Spanned<String>>,
    /// The unit of a station input (a field input has its field's).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<Spanned<String>>,
    /// The value used when a station gives none.
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub default: Option<Spanned<f64>>,
    /// The values the formula takes; others make the quantity not computable.
    #[cfg_attr(feature = "schema", schemars(with = "Option<RangeDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<Spanned<RangeDoc>>,
}

/// A value of a derived quantity computed independently of the formula.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct DerivedExampleDoc {
    /// The inputs by name (station inputs left out take their `default`).
    #[cfg_attr(feature = "schema", schemars(with = "BTreeMap<String, f64>"))]
    pub inputs: Spanned<BTreeMap<String, Spanned<f64>>>,
    /// The value the source gives.
    #[cfg_attr(feature = "schema", schemars(with = "f64"))]
    pub value: Spanned<f64>,
    /// How far the formula's value may be from `value`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<Spanned<f64>>,
    /// Where the value comes from.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub doc: Spanned<String>,
}

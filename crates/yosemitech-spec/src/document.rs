//! The YAML shape of a spec file, exactly as written, with source positions.
//!
//! Nothing here is validated beyond YAML types: [`crate::load_paths`] turns these
//! documents into the checked [`crate::model`]. Positions are kept with
//! `Spanned` on every value a semantic error may point at; the model avoids
//! `untagged` and `flatten`, which would lose them.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::Deserialize;
use serde_saphyr::Spanned;

/// One spec file: a sensor (one vendor manual) or a fragment of shared commands.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "Yosemitech Modbus sensor spec")]
#[schemars(extend("oneOf" = [{"required": ["sensor"]}, {"required": ["fragment"]}]))]
pub struct SpecFile {
    /// The sensor this file describes. A file has `sensor` or `fragment`, not both.
    pub sensor: Option<SensorDoc>,
    /// A file of commands shared by several sensors, included by sensor files.
    pub fragment: Option<FragmentDoc>,
    /// Fragment files whose commands this file includes, relative to this file.
    #[serde(default)]
    #[schemars(with = "Vec<String>")]
    pub include: Vec<Spanned<String>>,
    /// The commands: full definitions, or `use:` entries that add this
    /// manual's source and examples to an included command.
    #[serde(default)]
    pub commands: Vec<CommandDoc>,
    /// Numbers the manual's procedures use.
    #[serde(default)]
    pub constants: Vec<ConstantDoc>,
    /// Contradictions in the manual that no single command or frame carries.
    #[serde(default)]
    pub errata: Vec<ErratumDoc>,
}

/// The sensor a manual describes.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SensorDoc {
    /// snake_case name; becomes the Rust module name.
    #[schemars(with = "String")]
    pub name: Spanned<String>,
    /// Human title.
    #[schemars(with = "String")]
    pub title: Spanned<String>,
    /// What the sensor measures.
    #[schemars(with = "String")]
    pub doc: Spanned<String>,
    /// The manual this file transcribes.
    pub manual: ManualDoc,
    /// Serial line settings.
    pub serial: SerialDoc,
    /// Valid slave addresses.
    pub addresses: AddressRangeDoc,
    /// The factory slave address.
    #[schemars(with = "u32")]
    pub default_address: Spanned<u32>,
}

/// The manual a spec transcribes.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ManualDoc {
    /// The manual's title.
    #[schemars(with = "String")]
    pub title: Spanned<String>,
    /// Hardware and software revisions the manual covers.
    #[schemars(with = "String")]
    pub revision: Spanned<String>,
    /// The text extraction the spec was written from.
    #[schemars(with = "Option<String>")]
    pub file: Option<Spanned<String>>,
}

/// Serial line settings.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SerialDoc {
    /// Bits per second.
    #[schemars(with = "u32")]
    pub baud: Spanned<u32>,
    /// Data bits per character (7 or 8).
    #[schemars(with = "u32")]
    pub data_bits: Spanned<u32>,
    /// Parity.
    pub parity: ParityDoc,
    /// Stop bits (1 or 2).
    #[schemars(with = "u32")]
    pub stop_bits: Spanned<u32>,
}

/// Parity bit.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ParityDoc {
    /// No parity bit.
    None,
    /// Even parity.
    Even,
    /// Odd parity.
    Odd,
}

/// An inclusive range of slave addresses.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AddressRangeDoc {
    /// Lowest address.
    #[schemars(with = "u32")]
    pub min: Spanned<u32>,
    /// Highest address.
    #[schemars(with = "u32")]
    pub max: Spanned<u32>,
}

/// A file of shared commands.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FragmentDoc {
    /// snake_case name.
    #[schemars(with = "String")]
    pub name: Spanned<String>,
    /// What the fragment holds.
    #[schemars(with = "String")]
    pub doc: Spanned<String>,
}

/// Where in the manual something is documented.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SourceDoc {
    /// Section number, e.g. "2.2.3".
    #[schemars(with = "String")]
    pub section: Spanned<String>,
    /// Figure numbers.
    #[serde(default)]
    pub figures: Vec<u32>,
}

/// Read or write.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FunctionDoc {
    /// 0x03, read holding registers.
    Read,
    /// 0x10, write multiple registers.
    Write,
}

/// A command: a full definition (`name`), or `use` of an included one.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(extend("oneOf" = [{"required": ["name"]}, {"required": ["use"]}]))]
pub struct CommandDoc {
    /// snake_case name of a new command.
    #[schemars(with = "Option<String>")]
    pub name: Option<Spanned<String>>,
    /// Name of an included command this entry adds `source`, `examples` and `errata` to.
    #[serde(rename = "use")]
    #[schemars(with = "Option<String>")]
    pub uses: Option<Spanned<String>>,
    /// Human title, as in the manual's section heading.
    #[schemars(with = "Option<String>")]
    pub title: Option<Spanned<String>>,
    /// What the command does; becomes the rustdoc.
    #[schemars(with = "Option<String>")]
    pub doc: Option<Spanned<String>>,
    /// Where the manual documents it.
    pub source: Option<SourceDoc>,
    /// `read` (0x03) or `write` (0x10).
    #[schemars(with = "Option<FunctionDoc>")]
    pub function: Option<Spanned<FunctionDoc>>,
    /// First register, as sent on the wire.
    #[schemars(with = "Option<u32>")]
    pub address: Option<Spanned<u32>>,
    /// Number of registers.
    #[schemars(with = "Option<u32>")]
    pub count: Option<Spanned<u32>>,
    /// A write of zero registers that triggers an action (allows `count: 0`).
    #[schemars(with = "Option<bool>")]
    pub trigger: Option<Spanned<bool>>,
    /// A slave address the request and the reply always use (e.g. 0xFF).
    #[schemars(with = "Option<u32>")]
    pub fixed_slave: Option<Spanned<u32>>,
    /// Byte counts a read reply may carry besides `2 * count`, for firmware quirks.
    #[serde(default)]
    #[schemars(with = "Vec<u32>")]
    pub extra_byte_counts: Vec<Spanned<u32>>,
    /// The register data, in wire order: the reply of a read, the request of a write.
    #[schemars(with = "Option<Vec<FieldDoc>>")]
    pub fields: Option<Spanned<Vec<FieldDoc>>>,
    /// Frames printed in the manual.
    #[serde(default)]
    pub examples: Vec<ExampleDoc>,
    /// Places where the manual's command table contradicts its examples.
    #[serde(default)]
    pub errata: Vec<CommandErratumDoc>,
}

/// The type of a field.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema, PartialEq, Eq)]
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
}

/// Byte order of a multi-byte value, as wire letters (A = most significant).
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema, PartialEq, Eq)]
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

/// Text padding byte.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum PaddingDoc {
    /// 0x00.
    Nul,
    /// 0x20.
    Space,
}

/// An inclusive range of valid values.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RangeDoc {
    /// Lowest valid value.
    pub min: f64,
    /// Highest valid value.
    pub max: f64,
}

/// One field of register data.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FieldDoc {
    /// snake_case name; optional for `reserved`.
    #[schemars(with = "Option<String>")]
    pub name: Option<Spanned<String>>,
    /// The value's type.
    #[serde(rename = "type")]
    #[schemars(with = "FieldTypeDoc")]
    pub ty: Spanned<FieldTypeDoc>,
    /// Byte offset in the register data; defaults to right after the previous field.
    #[schemars(with = "Option<u32>")]
    pub offset: Option<Spanned<u32>>,
    /// Wire byte order, for 2- and 4-byte numbers.
    #[schemars(with = "Option<ByteOrderDoc>")]
    pub byte_order: Option<Spanned<ByteOrderDoc>>,
    /// Bytes, for `ascii`, `enum` and `reserved`.
    #[schemars(with = "Option<u32>")]
    pub size: Option<Spanned<u32>>,
    /// Padding of `ascii` text.
    #[schemars(with = "Option<PaddingDoc>")]
    pub padding: Option<Spanned<PaddingDoc>>,
    /// Byte written into `reserved` bytes (default 0).
    #[schemars(with = "Option<u32>")]
    pub fill: Option<Spanned<u32>>,
    /// Physical unit (pH, mV, degC, mS/cm).
    #[schemars(with = "Option<String>")]
    pub unit: Option<Spanned<String>>,
    /// What the value means.
    #[schemars(with = "Option<String>")]
    pub doc: Option<Spanned<String>>,
    /// Values a write may send.
    #[schemars(with = "Option<RangeDoc>")]
    pub range: Option<Spanned<RangeDoc>>,
    /// Named codes of an `enum`.
    #[schemars(with = "Option<Vec<VariantDoc>>")]
    pub variants: Option<Spanned<Vec<VariantDoc>>>,
}

/// A named code of an enum field.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VariantDoc {
    /// snake_case name; becomes a CamelCase variant.
    #[schemars(with = "String")]
    pub name: Spanned<String>,
    /// The code on the wire.
    #[schemars(with = "u32")]
    pub value: Spanned<u32>,
    /// What the code means.
    #[schemars(with = "Option<String>")]
    pub doc: Option<Spanned<String>>,
}

/// A value stated by the manual for an example frame.
#[derive(Debug, Clone, Deserialize, JsonSchema, PartialEq)]
#[serde(untagged)]
pub enum StatedValue {
    /// A number.
    Number(f64),
    /// Text, a version ("1.1") or an enum variant name.
    Text(String),
}

/// A frame pair printed in the manual.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExampleDoc {
    /// The figures that print the frames (and their register tables).
    pub figures: Vec<u32>,
    /// The request as printed, hex bytes separated by spaces.
    #[schemars(with = "String")]
    pub request: Spanned<String>,
    /// The reply as printed, hex bytes separated by spaces.
    #[schemars(with = "String")]
    pub response: Spanned<String>,
    /// The values the manual states, by field name.
    #[schemars(with = "BTreeMap<String, StatedValue>")]
    pub values: Spanned<BTreeMap<String, Spanned<StatedValue>>>,
    /// Remarks on the example.
    #[schemars(with = "Option<String>")]
    pub doc: Option<Spanned<String>>,
    /// Where a printed frame contradicts the truth.
    pub erratum: Option<ExampleErratumDoc>,
}

/// A printed frame that is wrong, and its correction.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExampleErratumDoc {
    /// Identifier in datasheet-notes.md (E4, E5, …).
    #[schemars(with = "String")]
    pub id: Spanned<String>,
    /// The figure that prints the wrong frame.
    #[schemars(with = "u32")]
    pub figure: Spanned<u32>,
    /// What is wrong with the printed frame.
    #[schemars(with = "String")]
    pub printed: Spanned<String>,
    /// The true request, when the printed request is wrong.
    #[schemars(with = "Option<String>")]
    pub corrected_request: Option<Spanned<String>>,
    /// The true reply, when the printed reply is wrong.
    #[schemars(with = "Option<String>")]
    pub corrected_response: Option<Spanned<String>>,
    /// Whether our decoder accepts the printed frame as it is.
    #[schemars(with = "bool")]
    pub printed_decodes: Spanned<bool>,
}

/// What a manual's command table says where it contradicts the examples.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TableSaysDoc {
    /// The start address the table prints.
    #[schemars(with = "Option<u32>")]
    pub address: Option<Spanned<u32>>,
    /// The register count the table prints.
    #[schemars(with = "Option<u32>")]
    pub count: Option<Spanned<u32>>,
    /// The function the table prints.
    #[schemars(with = "Option<FunctionDoc>")]
    pub function: Option<Spanned<FunctionDoc>>,
}

/// A command table that contradicts the command's examples.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CommandErratumDoc {
    /// Identifier in datasheet-notes.md (E1, E2, …).
    #[schemars(with = "String")]
    pub id: Spanned<String>,
    /// The figure with the wrong table.
    #[schemars(with = "u32")]
    pub figure: Spanned<u32>,
    /// What the table prints instead of the truth.
    pub table: TableSaysDoc,
    /// Why the spec's value is the truth.
    #[schemars(with = "String")]
    pub note: Spanned<String>,
}

/// A contradiction in the manual that no command carries.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ErratumDoc {
    /// Identifier in datasheet-notes.md.
    #[schemars(with = "String")]
    pub id: Spanned<String>,
    /// Figures or sections concerned.
    #[serde(default)]
    pub figures: Vec<u32>,
    /// Manual sections concerned.
    #[serde(default)]
    pub sections: Vec<String>,
    /// What the manual says and what the spec takes as the truth.
    #[schemars(with = "String")]
    pub note: Spanned<String>,
}

/// The Rust type of a constant.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema, PartialEq, Eq)]
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
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ConstantDoc {
    /// snake_case name; becomes an UPPER_CASE constant.
    #[schemars(with = "String")]
    pub name: Spanned<String>,
    /// The Rust type.
    #[serde(rename = "type")]
    #[schemars(with = "ConstantTypeDoc")]
    pub ty: Spanned<ConstantTypeDoc>,
    /// A single value (exactly one of `value` and `values`).
    #[schemars(with = "Option<f64>")]
    pub value: Option<Spanned<f64>>,
    /// A list of values, in order.
    #[schemars(with = "Option<Vec<f64>>")]
    pub values: Option<Spanned<Vec<f64>>>,
    /// Unit.
    #[schemars(with = "Option<String>")]
    pub unit: Option<Spanned<String>>,
    /// What it is for.
    #[schemars(with = "String")]
    pub doc: Spanned<String>,
    /// Where the manual states it.
    pub source: Option<SourceDoc>,
}

//! A borrowed, allocation-free view of one decoded field, for generic code.

use core::fmt;

use crate::codec::{Bcd, Version};

/// One field of a decoded message, as generic code (CLI tables, differential
/// tests, loggers) sees it. Generated message types list theirs with a
/// `fields()` method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FieldValue<'a> {
    /// An f32 field, bit for bit as decoded (NaN payloads kept).
    F32(f32),
    /// Any integer field, sign-extended to i64.
    Int(i64),
    /// A text field without its padding (raw bytes; may be non-ASCII if the device sent that).
    Text(&'a [u8]),
    /// A version field: major and minor byte.
    Version(Version),
    /// A two-digit BCD field, raw.
    Bcd(Bcd),
    /// An enum field: the raw code and the variant's spec name when known.
    Enum {
        /// The code on the wire.
        raw: u16,
        /// The variant's snake_case name; `None` for an unknown code.
        name: Option<&'static str>,
    },
}

impl FieldValue<'_> {
    /// Bit-exact equality (floats by bits).
    pub fn same_as(&self, other: &FieldValue<'_>) -> bool {
        match (self, other) {
            (FieldValue::F32(a), FieldValue::F32(b)) => a.to_bits() == b.to_bits(),
            (a, b) => a == b,
        }
    }
}

impl fmt::Display for FieldValue<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FieldValue::F32(v) => write!(f, "{v}"),
            FieldValue::Int(v) => write!(f, "{v}"),
            FieldValue::Text(bytes) => {
                for &b in *bytes {
                    if b.is_ascii_graphic() || b == b' ' {
                        write!(f, "{}", char::from(b))?;
                    } else {
                        write!(f, "\\x{b:02x}")?;
                    }
                }
                Ok(())
            }
            FieldValue::Version(v) => write!(f, "{v}"),
            FieldValue::Bcd(v) => write!(f, "{v}"),
            FieldValue::Enum { raw, name: Some(name) } => write!(f, "{name} ({raw})"),
            FieldValue::Enum { raw, name: None } => write!(f, "unknown ({raw})"),
        }
    }
}

/// Static description of one field of a generated message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FieldInfo {
    /// The spec's snake_case name.
    pub name: &'static str,
    /// Unit, if any.
    pub unit: Option<&'static str>,
}

impl FieldInfo {
    /// The field called `name`, measured in `unit`.
    pub const fn new(name: &'static str, unit: Option<&'static str>) -> Self {
        Self { name, unit }
    }
}

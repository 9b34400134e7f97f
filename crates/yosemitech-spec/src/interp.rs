//! The reference interpreter: encodes and decodes frames by walking the spec.
//!
//! It is deliberately plain (allocating, no generated code) so that it can
//! check the spec's own examples, drive the simulator and the CLI's `--spec`
//! mode, and serve as the independent side of the differential test against
//! the generated codecs. Framing is shared with them through
//! [`yosemitech_rtu::Layout`]; only the field walking is its own.

use std::collections::BTreeMap;
use std::fmt;

use serde::Serialize;
use yosemitech_rtu::{Bcd, FrameError, Version, codec};

use crate::model::{CommandSpec, EnumRepr, Field, FieldKind, Variant};

/// A decoded or stated field value.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Value {
    /// f32 fields.
    Float(f32),
    /// Integer fields.
    Int(i64),
    /// Text fields.
    Text(String),
    /// Version fields.
    #[serde(serialize_with = "ser_version")]
    Version(Version),
    /// BCD fields: the raw byte (its digits may be invalid).
    #[serde(serialize_with = "ser_bcd")]
    Bcd(Bcd),
    /// Enum fields: the raw code and its name when known.
    Enum {
        /// The code on the wire.
        raw: u16,
        /// The variant name, `None` for an unknown code.
        name: Option<String>,
    },
}

fn ser_version<S: serde::Serializer>(v: &Version, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(v)
}

fn ser_bcd<S: serde::Serializer>(v: &Bcd, s: S) -> Result<S::Ok, S::Error> {
    match v.value() {
        Some(n) => s.serialize_u8(n),
        None => s.serialize_none(),
    }
}

/// An `f32` as the `f64` of its shortest decimal: the probe's 15.8 is 15.8,
/// not 15.800000190734863 (`f64::from` keeps the f32's binary error, which
/// stores, exports and JSON would then print).
pub fn f32_decimal(v: f32) -> f64 {
    // Display writes the shortest decimal that reads back as the same f32.
    v.to_string().parse().unwrap_or(f64::NAN)
}

impl Value {
    /// The value as a number, for stores, means and JSON: a float as its
    /// shortest decimal ([`f32_decimal`]), an integer, a BCD byte's digits;
    /// `None` for text, versions, enums and a BCD byte of invalid digits.
    pub fn number(&self) -> Option<f64> {
        match self {
            Value::Float(v) => Some(f32_decimal(*v)),
            Value::Int(v) => Some(*v as f64),
            Value::Bcd(v) => v.value().map(f64::from),
            Value::Text(_) | Value::Version(_) | Value::Enum { .. } => None,
        }
    }

    /// Bit-exact equality (floats compared by bits, so NaN payloads and -0.0 count).
    pub fn same_as(&self, other: &Value) -> bool {
        match (self, other) {
            (Value::Float(a), Value::Float(b)) => a.to_bits() == b.to_bits(),
            (a, b) => a == b,
        }
    }

    /// Bit-exact equality with a field as generated code decodes it: the
    /// one comparison the differential tests and the fuzzer share. Text is
    /// compared byte for byte (the interpreter keeps each byte as a char).
    pub fn matches(&self, typed: &yosemitech_rtu::FieldValue<'_>) -> bool {
        use yosemitech_rtu::FieldValue;
        match (typed, self) {
            (FieldValue::F32(a), Value::Float(b)) => a.to_bits() == b.to_bits(),
            (FieldValue::Int(a), Value::Int(b)) => a == b,
            (FieldValue::Text(a), Value::Text(b)) => a.iter().map(|&c| char::from(c)).eq(b.chars()),
            (FieldValue::Version(a), Value::Version(b)) => a == b,
            (FieldValue::Bcd(a), Value::Bcd(b)) => a == b,
            (FieldValue::Enum { raw, name }, Value::Enum { raw: r, name: n }) => raw == r && *name == n.as_deref(),
            _ => false,
        }
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Float(v) => write!(f, "{v}"),
            Value::Int(v) => write!(f, "{v}"),
            Value::Text(v) => write!(f, "{v:?}"),
            Value::Version(v) => write!(f, "{v}"),
            Value::Bcd(v) => write!(f, "{v}"),
            Value::Enum { raw, name: Some(name) } => write!(f, "{name} ({raw})"),
            Value::Enum { raw, name: None } => write!(f, "unknown ({raw})"),
        }
    }
}

/// Field values in wire order, by name.
pub type Values = Vec<(String, Value)>;

/// Why values could not be encoded.
#[derive(Debug, Clone, PartialEq)]
pub enum EncodeValuesError {
    /// A field has no value.
    Missing(String),
    /// A value names no field.
    Unknown(String),
    /// A value has the wrong type for its field.
    WrongType {
        /// Field.
        field: String,
        /// The field's type.
        expected: &'static str,
    },
    /// A value is outside the field's range or type.
    OutOfRange {
        /// Field.
        field: String,
        /// Explanation.
        detail: String,
    },
    /// The frame could not be built.
    Frame(yosemitech_rtu::EncodeError),
}

impl fmt::Display for EncodeValuesError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Missing(name) => write!(f, "no value for field `{name}`"),
            Self::Unknown(name) => write!(f, "no field called `{name}`"),
            Self::WrongType { field, expected } => write!(f, "field `{field}` takes a {expected} value"),
            Self::OutOfRange { field, detail } => write!(f, "field `{field}`: {detail}"),
            Self::Frame(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for EncodeValuesError {}

/// Decodes register data into values (reserved bytes skipped).
///
/// `data` must be the command's full register data; shorter data decodes
/// the fields that fit and stops (it never panics).
pub fn decode_fields(command: &CommandSpec, data: &[u8]) -> Values {
    let mut out = Vec::new();
    for field in &command.fields {
        let Some(name) = &field.name else { continue };
        let Some(bytes) = data.get(field.offset..field.offset + field.size()) else { break };
        out.push((name.clone(), decode_field(field, bytes)));
    }
    out
}

fn arr<const N: usize>(bytes: &[u8]) -> [u8; N] {
    let mut a = [0u8; N];
    for (slot, b) in a.iter_mut().zip(bytes) {
        *slot = *b;
    }
    a
}

fn variant_name(variants: &[Variant], raw: u16) -> Option<String> {
    variants.iter().find(|v| v.value == raw).map(|v| v.name.clone())
}

/// Decodes one field from exactly its bytes.
pub fn decode_field(field: &Field, bytes: &[u8]) -> Value {
    match &field.kind {
        FieldKind::F32 { order } => Value::Float(codec::f32_from_wire(*order, arr(bytes))),
        FieldKind::U8 => Value::Int(i64::from(arr::<1>(bytes)[0])),
        FieldKind::I8 => Value::Int(i64::from(arr::<1>(bytes)[0] as i8)),
        FieldKind::U16 { order } => Value::Int(i64::from(codec::u16_from_wire(*order, arr(bytes)))),
        FieldKind::I16 { order } => Value::Int(i64::from(codec::u16_from_wire(*order, arr(bytes)) as i16)),
        FieldKind::U32 { order } => Value::Int(i64::from(codec::u32_from_wire(*order, arr(bytes)))),
        FieldKind::I32 { order } => Value::Int(i64::from(codec::u32_from_wire(*order, arr(bytes)) as i32)),
        FieldKind::Ascii { padding, .. } => {
            let end = bytes.iter().rposition(|b| b != padding).map_or(0, |i| i + 1);
            let text: String = bytes.iter().take(end).map(|&b| char::from(b)).collect();
            Value::Text(text)
        }
        FieldKind::Version => Value::Version(Version::from_wire(arr(bytes))),
        FieldKind::Enum { repr, variants } => {
            let raw = match repr {
                EnumRepr::U8 => u16::from(arr::<1>(bytes)[0]),
                EnumRepr::U16(order) => codec::u16_from_wire(*order, arr(bytes)),
            };
            Value::Enum { raw, name: variant_name(variants, raw) }
        }
        FieldKind::Reserved { .. } => Value::Int(0),
        FieldKind::Bcd => Value::Bcd(Bcd(arr::<1>(bytes)[0])),
        FieldKind::Flags { repr, .. } => Value::Int(i64::from(match repr {
            EnumRepr::U8 => u16::from(arr::<1>(bytes)[0]),
            EnumRepr::U16(order) => codec::u16_from_wire(*order, arr(bytes)),
        })),
    }
}

/// Encodes values into register data. Every named field needs a value;
/// reserved bytes get their fill. Ranges are checked for a write's data; on
/// a read a range is the measuring range, which a probe may leave.
pub fn encode_fields(command: &CommandSpec, values: &BTreeMap<String, Value>) -> Result<Vec<u8>, EncodeValuesError> {
    if let Some(unknown) = values.keys().find(|k| command.field(k).is_none()) {
        return Err(EncodeValuesError::Unknown(unknown.clone()));
    }
    let mut data = vec![0u8; 2 * usize::from(command.count)];
    for field in &command.fields {
        let bytes = match &field.name {
            None => encode_reserved(field),
            Some(name) => {
                let value = values.get(name).ok_or_else(|| EncodeValuesError::Missing(name.clone()))?;
                encode_command_field(command, field, value)?
            }
        };
        if let Some(slot) = data.get_mut(field.offset..field.offset + bytes.len()) {
            slot.copy_from_slice(&bytes);
        }
    }
    Ok(data)
}

fn encode_reserved(field: &Field) -> Vec<u8> {
    match field.kind {
        FieldKind::Reserved { len, fill } => vec![fill; len],
        _ => vec![0; field.size()],
    }
}

fn out_of_range(field: &Field, detail: String) -> EncodeValuesError {
    EncodeValuesError::OutOfRange { field: field.display_name().to_owned(), detail }
}

fn int_in(field: &Field, value: &Value, min: i64, max: i64) -> Result<i64, EncodeValuesError> {
    let v = match value {
        Value::Int(v) => *v,
        Value::Float(f) if f.fract() == 0.0 && f.is_finite() => *f as i64,
        _ => {
            return Err(EncodeValuesError::WrongType {
                field: field.display_name().to_owned(),
                expected: field.kind.type_name(),
            });
        }
    };
    if v < min || v > max {
        return Err(out_of_range(field, format!("{v} is outside {min} to {max}")));
    }
    Ok(v)
}

/// Checks a value against the field's declared `range`.
fn check_range(ranges: bool, field: &Field, v: f64) -> Result<(), EncodeValuesError> {
    match field.range {
        _ if !ranges => Ok(()),
        Some((min, max)) if !(min..=max).contains(&v) => {
            Err(out_of_range(field, format!("{v} is outside the valid range {min} to {max}")))
        }
        _ => Ok(()),
    }
}

/// Encodes one field of `command` by the command's rule: a write's values
/// must be in their field's `range`; a read's range is the measuring range,
/// which a probe may leave, so it is not enforced.
pub fn encode_command_field(command: &CommandSpec, field: &Field, value: &Value) -> Result<Vec<u8>, EncodeValuesError> {
    encode_field_checked(field, value, !command.is_read())
}

/// Encodes one field, checking its `range`.
pub fn encode_field(field: &Field, value: &Value) -> Result<Vec<u8>, EncodeValuesError> {
    encode_field_checked(field, value, true)
}

/// Encodes one field, checking its range only when `ranges` is true.
fn encode_field_checked(field: &Field, value: &Value, ranges: bool) -> Result<Vec<u8>, EncodeValuesError> {
    let wrong =
        || EncodeValuesError::WrongType { field: field.display_name().to_owned(), expected: field.kind.type_name() };
    Ok(match &field.kind {
        FieldKind::F32 { order } => {
            let v = match value {
                Value::Float(v) => *v,
                Value::Int(v) => *v as f32,
                _ => return Err(wrong()),
            };
            if !v.is_nan() {
                check_range(ranges, field, f64::from(v))?;
            }
            codec::f32_to_wire(*order, v).to_vec()
        }
        FieldKind::U8 => {
            let v = int_in(field, value, 0, 255)?;
            check_range(ranges, field, v as f64)?;
            vec![v as u8]
        }
        FieldKind::I8 => {
            let v = int_in(field, value, -128, 127)?;
            check_range(ranges, field, v as f64)?;
            vec![v as i8 as u8]
        }
        FieldKind::U16 { order } => {
            let v = int_in(field, value, 0, 0xFFFF)?;
            check_range(ranges, field, v as f64)?;
            codec::u16_to_wire(*order, v as u16).to_vec()
        }
        FieldKind::I16 { order } => {
            let v = int_in(field, value, -0x8000, 0x7FFF)?;
            check_range(ranges, field, v as f64)?;
            codec::u16_to_wire(*order, v as i16 as u16).to_vec()
        }
        FieldKind::U32 { order } => {
            let v = int_in(field, value, 0, 0xFFFF_FFFF)?;
            check_range(ranges, field, v as f64)?;
            codec::u32_to_wire(*order, v as u32).to_vec()
        }
        FieldKind::I32 { order } => {
            let v = int_in(field, value, i64::from(i32::MIN), i64::from(i32::MAX))?;
            check_range(ranges, field, v as f64)?;
            codec::u32_to_wire(*order, v as i32 as u32).to_vec()
        }
        FieldKind::Ascii { len, padding } => {
            let Value::Text(text) = value else { return Err(wrong()) };
            if text.len() > *len || !text.is_ascii() {
                return Err(out_of_range(field, format!("text must be at most {len} ASCII characters")));
            }
            let mut bytes = vec![*padding; *len];
            for (slot, b) in bytes.iter_mut().zip(text.bytes()) {
                *slot = b;
            }
            bytes
        }
        FieldKind::Version => match value {
            Value::Version(v) => v.to_wire().to_vec(),
            Value::Text(t) => parse_version(t).ok_or_else(wrong)?.to_wire().to_vec(),
            _ => return Err(wrong()),
        },
        FieldKind::Enum { repr, variants } => {
            let raw = match value {
                Value::Enum { raw, .. } => *raw,
                Value::Text(name) => variants
                    .iter()
                    .find(|v| &v.name == name)
                    .map(|v| v.value)
                    .ok_or_else(|| out_of_range(field, format!("`{name}` is not a variant")))?,
                Value::Int(v) => u16::try_from(*v).map_err(|_| out_of_range(field, format!("{v} is not a code")))?,
                _ => return Err(wrong()),
            };
            match repr {
                EnumRepr::U8 => vec![u8::try_from(raw).map_err(|_| out_of_range(field, format!("{raw} > 255")))?],
                EnumRepr::U16(order) => codec::u16_to_wire(*order, raw).to_vec(),
            }
        }
        FieldKind::Reserved { .. } => encode_reserved(field),
        FieldKind::Bcd => {
            let raw = match value {
                Value::Bcd(b) => *b,
                other => {
                    let v = int_in(field, other, 0, 99)?;
                    Bcd::from_value(v as u8).ok_or_else(|| out_of_range(field, format!("{v} > 99")))?
                }
            };
            match raw.value() {
                Some(v) => check_range(ranges, field, f64::from(v))?,
                // A write never sends a byte that is not two digits.
                None if ranges => {
                    return Err(out_of_range(field, format!("0x{:02X} is not two decimal digits", raw.0)));
                }
                None => {}
            }
            vec![raw.0]
        }
        FieldKind::Flags { repr, .. } => {
            // Bits no flag names are kept, as a device may set them (like an enum's unknown codes).
            let max = if matches!(repr, EnumRepr::U8) { 0xFF } else { 0xFFFF };
            let raw = int_in(field, value, 0, max)?;
            match repr {
                EnumRepr::U8 => vec![raw as u8],
                EnumRepr::U16(order) => codec::u16_to_wire(*order, raw as u16).to_vec(),
            }
        }
    })
}

/// What a serial-number reply carries: the serial number and the model
/// code, which real probes send in two places (the byte before the text
/// when it is not 0, `0x09` for "09"; and the text's characters 3-4,
/// `YL09...`). Which of the two to believe depends on the sensors loaded:
/// see [`SerialNumberReply::model_code`].
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SerialNumberReply {
    /// The serial number, as the command's text field reads it.
    pub text: Option<String>,
    /// The model code in the reserved byte before the text.
    pub code_before: Option<String>,
    /// The model code as the text's characters 3-4.
    pub code_in_text: Option<String>,
}

impl SerialNumberReply {
    /// Reads `data` (the register data of `command`'s reply) as a
    /// serial-number reply; a command without a text field carries none.
    pub fn read(command: &CommandSpec, data: &[u8]) -> Self {
        let Some(field) = command.named_fields().find(|f| matches!(f.kind, FieldKind::Ascii { .. })) else {
            return Self::default();
        };
        let text = match data.get(field.offset..field.offset + field.size()).map(|b| decode_field(field, b)) {
            Some(Value::Text(t)) => Some(t),
            _ => None,
        };
        let code_before = field
            .offset
            .checked_sub(1)
            .filter(|&at| command.fields.iter().any(|f| f.is_reserved() && f.offset <= at && at < f.offset + f.size()))
            .and_then(|at| data.get(at).copied())
            .filter(|&b| b != 0)
            .map(|b| format!("{b:02X}"));
        let code_in_text = text.as_deref().and_then(|t| {
            let code: String = t.chars().skip(2).take(2).collect();
            (code.chars().count() == 2 && code.chars().all(|c| c.is_ascii_alphanumeric())).then_some(code)
        });
        Self { text, code_before, code_in_text }
    }

    /// The model code to believe, `declared` saying whether a loaded
    /// sensor declares a code: the byte before the text first, unless it
    /// names no sensor and the text does.
    pub fn model_code(&self, declared: impl Fn(&str) -> bool) -> Option<&str> {
        let before = self.code_before.as_deref();
        let in_text = self.code_in_text.as_deref();
        if before.is_some() && (before.is_some_and(&declared) || !in_text.is_some_and(&declared)) {
            before
        } else {
            in_text
        }
    }
}

/// Parses `major.minor` with each part 0..=255.
pub fn parse_version(text: &str) -> Option<Version> {
    let (major, minor) = text.split_once('.')?;
    Some(Version::new(major.trim().parse().ok()?, minor.trim().parse().ok()?))
}

impl CommandSpec {
    /// Encodes a request to `slave`: `values` are the write's fields (none for a read).
    pub fn encode_request(&self, slave: u8, values: &BTreeMap<String, Value>) -> Result<Vec<u8>, EncodeValuesError> {
        let data = if self.is_read() {
            if let Some(k) = values.keys().next() {
                return Err(EncodeValuesError::Unknown(k.clone()));
            }
            Vec::new()
        } else {
            encode_fields(self, values)?
        };
        let mut out = vec![0u8; self.layout().request_len()];
        let n = self.layout().encode_request(slave, &data, &mut out).map_err(EncodeValuesError::Frame)?;
        out.truncate(n);
        Ok(out)
    }

    /// Encodes a reply from `slave`: `values` are a read's fields (none for a write).
    pub fn encode_response(&self, slave: u8, values: &BTreeMap<String, Value>) -> Result<Vec<u8>, EncodeValuesError> {
        // A trigger read's reply carries no value (the runtime writes its filler).
        let data = if self.is_read() && !self.trigger { encode_fields(self, values)? } else { Vec::new() };
        let mut out = vec![0u8; self.layout().response_len()];
        let n = self.layout().encode_response(slave, &data, &mut out).map_err(EncodeValuesError::Frame)?;
        out.truncate(n);
        Ok(out)
    }

    /// Decodes a request frame: its slave and the write's values.
    pub fn decode_request(&self, frame: &[u8]) -> Result<(u8, Values), FrameError> {
        let (slave, data) = self.layout().decode_request(frame)?;
        Ok((slave, decode_fields(self, data)))
    }

    /// Decodes a reply to a request sent to `slave`: a read's values.
    pub fn decode_response(&self, slave: u8, frame: &[u8]) -> Result<Values, FrameError> {
        let data = self.layout().decode_response(slave, frame)?;
        Ok(decode_fields(self, data))
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn the_model_code_is_the_byte_before_the_text_unless_only_the_text_names_a_sensor() {
        use super::SerialNumberReply;
        let reply = |before: Option<&str>, in_text: Option<&str>| SerialNumberReply {
            text: None,
            code_before: before.map(str::to_owned),
            code_in_text: in_text.map(str::to_owned),
        };
        let declared = |c: &str| c == "43";
        assert_eq!(reply(Some("43"), Some("09")).model_code(declared), Some("43"));
        assert_eq!(reply(Some("09"), Some("43")).model_code(declared), Some("43"));
        assert_eq!(reply(Some("09"), Some("10")).model_code(declared), Some("09"));
        assert_eq!(reply(Some("09"), None).model_code(declared), Some("09"));
        assert_eq!(reply(None, Some("10")).model_code(declared), Some("10"));
        assert_eq!(reply(None, None).model_code(declared), None);
    }
    #[test]
    fn an_f32_is_its_shortest_decimal_as_f64() {
        assert_eq!(super::f32_decimal(15.8).to_string(), "15.8");
        assert_eq!(super::f32_decimal(-6.56).to_string(), "-6.56");
        // Whatever the f32, the f64 reads back as it and prints as it does.
        for bits in (0..u32::MAX).step_by(7_654_321) {
            let v = f32::from_bits(bits);
            let d = super::f32_decimal(v);
            if v.is_nan() {
                assert!(d.is_nan());
                continue;
            }
            assert_eq!((d as f32).to_bits(), v.to_bits(), "{v}");
            assert_eq!(d.to_string(), v.to_string(), "{v}");
        }
    }

    use yosemitech_rtu::FieldValue;

    use super::Value;

    #[test]
    fn matches_is_bit_exact_and_typed() {
        assert!(Value::Float(7.6).matches(&FieldValue::F32(7.6)));
        assert!(!Value::Float(0.0).matches(&FieldValue::F32(-0.0)), "-0.0 is not 0.0");
        let nan = f32::from_bits(0x7FC0_0001);
        assert!(Value::Float(nan).matches(&FieldValue::F32(nan)));
        assert!(!Value::Int(1).matches(&FieldValue::F32(1.0)), "types must agree");
        assert!(Value::Text("YL".into()).matches(&FieldValue::Text(b"YL")));
        assert!(!Value::Text("YL".into()).matches(&FieldValue::Text(b"YL\0")));
        let known = Value::Enum { raw: 0, name: Some("ok".into()) };
        assert!(known.matches(&FieldValue::Enum { raw: 0, name: Some("ok") }));
        assert!(!known.matches(&FieldValue::Enum { raw: 0, name: None }));
    }
}

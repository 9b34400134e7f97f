//! Frames: the bytes of a reply, its exceptions and the manuals' quirks.

use yosemitech_rtu::frame::encode_exception;
use yosemitech_rtu::{EncodeError, ExceptionCode, codec, crc16};
use yosemitech_spec::interp::decode_field;
use yosemitech_spec::{CommandSpec, EnumRepr, Field, FieldKind, Value};

/// The bytes of an address in a `slave_address` field.
pub(super) fn address_bytes(field: &Field, address: u8) -> Option<Vec<u8>> {
    match &field.kind {
        FieldKind::U8 | FieldKind::I8 | FieldKind::Enum { repr: EnumRepr::U8, .. } => Some(vec![address]),
        FieldKind::U16 { order } | FieldKind::I16 { order } => {
            Some(codec::u16_to_wire(*order, u16::from(address)).to_vec())
        }
        FieldKind::Enum { repr: EnumRepr::U16(order), .. } => {
            Some(codec::u16_to_wire(*order, u16::from(address)).to_vec())
        }
        FieldKind::U32 { order } | FieldKind::I32 { order } => {
            Some(codec::u32_to_wire(*order, u32::from(address)).to_vec())
        }
        _ => None,
    }
}

/// Refuses write data with a value outside its field's `range` (or NaN).
pub(super) fn check_ranges(command: &CommandSpec, data: &[u8]) -> Result<(), ExceptionCode> {
    for field in command.fields.iter().filter(|f| f.range.is_some()) {
        let Some((min, max)) = field.range else { continue };
        let bytes = data.get(field.offset..field.offset + field.size()).ok_or(ExceptionCode::IllegalDataValue)?;
        let value = match decode_field(field, bytes) {
            Value::Float(v) => f64::from(v),
            Value::Int(v) => v as f64,
            Value::Enum { raw, .. } => f64::from(raw),
            _ => continue,
        };
        if !(min..=max).contains(&value) {
            return Err(ExceptionCode::IllegalDataValue);
        }
    }
    Ok(())
}

/// Appends a frame of at most `len` bytes written by `encode`.
pub(super) fn push_frame(
    out: &mut Vec<u8>,
    len: usize,
    encode: impl FnOnce(&mut [u8]) -> Result<usize, EncodeError>,
) -> Result<(), ExceptionCode> {
    let start = out.len();
    out.resize(start + len, 0);
    match out.get_mut(start..).map(encode) {
        Some(Ok(n)) => {
            out.truncate(start + n);
            Ok(())
        }
        _ => {
            out.truncate(start);
            Err(ExceptionCode::ServerDeviceFailure)
        }
    }
}

pub(super) fn push_exception(out: &mut Vec<u8>, slave: u8, function: u8, code: ExceptionCode) {
    let mut frame = [0u8; yosemitech_rtu::frame::EXCEPTION_LEN];
    if let Ok(n) = encode_exception(slave, function, code.to_u8(), &mut frame) {
        out.extend_from_slice(frame.get(..n).unwrap_or(&[]));
    }
}

/// Replaces the byte count of the read reply in `out` and fixes its CRC.
pub(super) fn requirk(out: &mut Vec<u8>, byte_count: u8) {
    if out.len() < 5 {
        return;
    }
    if let Some(b) = out.get_mut(2) {
        *b = byte_count;
    }
    out.truncate(out.len() - 2);
    let crc = crc16(out);
    out.extend_from_slice(&crc.to_le_bytes());
}

/// Whether a manual prints `command`'s reply, complete with its CRC, as
/// the short form of a trigger read: slave, function, byte count 0.
pub(super) fn prints_empty_reply(command: &CommandSpec) -> bool {
    command.examples.iter().filter_map(|e| e.true_response()).any(|reply| reply.len() == 5)
}

/// Cuts a read reply down to its header with byte count 0, and a new CRC.
pub(super) fn shorten_to_empty(out: &mut Vec<u8>) {
    if out.len() < 5 {
        return;
    }
    out.truncate(3);
    if let Some(b) = out.get_mut(2) {
        *b = 0;
    }
    let crc = crc16(out);
    out.extend_from_slice(&crc.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use yosemitech_tests::with_crc;

    use super::*;

    #[test]
    fn address_bytes_follow_the_field_type() {
        let field = |kind| Field {
            name: Some("slave_address".into()),
            kind,
            offset: 0,
            unit: None,
            doc: None,
            range: None,
            typical: None,
            absent: None,
            examples: Vec::new(),
        };
        assert_eq!(address_bytes(&field(FieldKind::U8), 7), Some(vec![7]));
        let be = FieldKind::U16 { order: yosemitech_rtu::ByteOrder2::Ab };
        assert_eq!(address_bytes(&field(be), 7), Some(vec![0, 7]));
        let le = FieldKind::U16 { order: yosemitech_rtu::ByteOrder2::Ba };
        assert_eq!(address_bytes(&field(le), 7), Some(vec![7, 0]));
        assert_eq!(address_bytes(&field(FieldKind::Version), 7), None);
    }

    #[test]
    fn requirk_rewrites_count_and_crc() {
        let mut reply = with_crc(&[1, 3, 4, 1, 2, 3, 4]);
        requirk(&mut reply, 2);
        assert_eq!(reply, with_crc(&[1, 3, 2, 1, 2, 3, 4]));
        let mut short = vec![1, 2];
        requirk(&mut short, 9);
        assert_eq!(short, [1, 2]);
    }
}

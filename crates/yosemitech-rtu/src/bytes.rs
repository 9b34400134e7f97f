//! Reading a byte or a big-endian word at an index of a frame, without a
//! panic: every decoder of the workspace reads frames it has not yet
//! checked the length of, so a read past the end is an answer (`None`),
//! never an index out of bounds.

/// The byte at `at`, if `bytes` has one there.
#[inline]
pub fn byte(bytes: &[u8], at: usize) -> Option<u8> {
    bytes.get(at).copied()
}

/// The big-endian word (Modbus register order) at `at..at + 2`, if both
/// bytes are there.
#[inline]
pub fn word(bytes: &[u8], at: usize) -> Option<u16> {
    match bytes.get(at..at.checked_add(2)?) {
        Some(&[high, low]) => Some(u16::from_be_bytes([high, low])),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_inside_and_refuses_past_the_end() {
        let bytes = [0x01, 0x03, 0x28, 0x00];
        assert_eq!(byte(&bytes, 0), Some(0x01));
        assert_eq!(byte(&bytes, 3), Some(0x00));
        assert_eq!(byte(&bytes, 4), None);
        assert_eq!(word(&bytes, 1), Some(0x0328));
        assert_eq!(word(&bytes, 2), Some(0x2800));
        assert_eq!(word(&bytes, 3), None, "one byte is no word");
        assert_eq!(word(&bytes, usize::MAX), None);
        assert_eq!(byte(&[], 0), None);
    }
}

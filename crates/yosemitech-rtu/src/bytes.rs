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

/// Copies `from` to the start of `to`, if `to` is long enough (else copies
/// nothing and says so). In pieces of at most eight bytes: a message's data
/// has a constant length, so after inlining each piece is two word moves,
/// where a copy of more than eight bytes at once is a call to `memcpy` in a
/// build for size (730 bytes of firmware flash, for a serial number's twelve).
#[inline]
pub fn copy_in_pieces(to: &mut [u8], from: &[u8]) -> bool {
    let Some(to) = to.get_mut(..from.len()) else {
        return false;
    };
    let mut at = 0;
    while let (Some(to), Some(from)) = (to.get_mut(at..at + 8), from.get(at..at + 8)) {
        to.copy_from_slice(from);
        at += 8;
    }
    if let (Some(to), Some(from)) = (to.get_mut(at..), from.get(at..)) {
        to.copy_from_slice(from);
    }
    true
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

    #[test]
    fn copies_in_pieces_or_not_at_all() {
        let from: [u8; 21] = core::array::from_fn(|i| i as u8 + 1);
        for len in 0..=from.len() {
            let mut to = [0u8; 24];
            assert!(copy_in_pieces(&mut to, &from[..len]));
            assert_eq!(&to[..len], &from[..len], "{len} bytes");
            assert!(to[len..].iter().all(|&b| b == 0), "nothing past {len} bytes");
        }
        let mut short = [0u8; 3];
        assert!(!copy_in_pieces(&mut short, &from[..4]));
        assert_eq!(short, [0; 3]);
    }
}

//! [`RawBytes`]: bytes received from a device, kept inline for error reports.

use core::fmt;

use crate::frame::MAX_ADU;

/// Up to [`MAX_ADU`] bytes as received from a device, stored inline (no heap).
///
/// Errors carry these so a report shows what the device actually sent.
/// Longer input is cut to its first [`MAX_ADU`] bytes ([`RawBytes::was_cut`]).
/// Displays as space-separated hex.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct RawBytes {
    bytes: [u8; MAX_ADU],
    len: u16,
    cut: bool,
}

impl RawBytes {
    /// No bytes (length zero).
    pub const EMPTY: Self = Self { bytes: [0; MAX_ADU], len: 0, cut: false };

    /// A copy of the first [`MAX_ADU`] bytes of `bytes`.
    pub fn new(bytes: &[u8]) -> Self {
        let mut raw = Self::EMPTY;
        let n = bytes.len().min(MAX_ADU);
        for (slot, byte) in raw.bytes.iter_mut().zip(bytes) {
            *slot = *byte;
        }
        // n <= MAX_ADU = 256 fits in u16.
        raw.len = n as u16;
        raw.cut = bytes.len() > MAX_ADU;
        raw
    }

    /// The bytes held, at most `MAX_ADU`.
    pub fn as_bytes(&self) -> &[u8] {
        self.bytes.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// The number of bytes kept.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// True when no bytes were received.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// True when more than [`MAX_ADU`] bytes were given and only the first were kept.
    pub fn was_cut(&self) -> bool {
        self.cut
    }
}

impl Default for RawBytes {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl AsRef<[u8]> for RawBytes {
    fn as_ref(&self) -> &[u8] {
        self.as_bytes()
    }
}

impl fmt::Display for RawBytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&crate::Hex(self.as_bytes()), f)?;
        if self.cut { f.write_str(" ...") } else { Ok(()) }
    }
}

impl fmt::Debug for RawBytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "RawBytes({self})")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_and_shows_bytes() {
        let raw = RawBytes::new(&[0x01, 0x83, 0x02]);
        assert_eq!(raw.as_bytes(), [0x01, 0x83, 0x02]);
        assert_eq!(raw.len(), 3);
        assert!(!raw.was_cut());
        assert_eq!(format!("{raw}"), "01 83 02");
        assert!(RawBytes::new(&[]).is_empty());
        assert_eq!(format!("{}", RawBytes::EMPTY), "");
    }

    #[test]
    fn cuts_long_input() {
        let long = [0xAAu8; 300];
        let raw = RawBytes::new(&long);
        assert_eq!(raw.len(), MAX_ADU);
        assert!(raw.was_cut());
        assert!(format!("{raw}").ends_with("AA ..."));
    }
}

//! Register-data value codecs: byte orders, versions and fixed-length ASCII.
//!
//! Modbus says a register is big-endian, but vendors place multi-register
//! values in any of four byte orders. The letters name the bytes of the value
//! from most to least significant as they appear on the wire: `ABCD` is plain
//! big-endian, `DCBA` a little-endian memory image (Yosemitech's floats).

use core::fmt;

/// Wire order of a two-byte value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ByteOrder2 {
    /// Most significant byte first (Modbus standard).
    Ab,
    /// Least significant byte first.
    Ba,
}

/// Wire order of a four-byte value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ByteOrder4 {
    /// Big-endian: most significant byte first.
    Abcd,
    /// Little-endian memory image (byte- and word-swapped); Yosemitech floats.
    Dcba,
    /// Big-endian registers, least significant register first (word swap).
    Cdab,
    /// Little-endian registers, most significant register first (byte swap).
    Badc,
}

impl ByteOrder2 {
    /// Both orders.
    pub const ALL: [Self; 2] = [Self::Ab, Self::Ba];

    /// The order's wire letters in lower case, as the spec language writes
    /// them: `ab` or `ba`. The one name table of two-byte orders.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Ab => "ab",
            Self::Ba => "ba",
        }
    }

    /// What the order is in words: `big-endian` or `little-endian`.
    pub const fn meaning(self) -> &'static str {
        match self {
            Self::Ab => "big-endian",
            Self::Ba => "little-endian",
        }
    }
}

impl ByteOrder4 {
    /// The four orders.
    pub const ALL: [Self; 4] = [Self::Abcd, Self::Dcba, Self::Cdab, Self::Badc];

    /// The order's wire letters in lower case, as the spec language writes
    /// them: `abcd`, `dcba`, `cdab` or `badc`. The one name table of
    /// four-byte orders.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Abcd => "abcd",
            Self::Dcba => "dcba",
            Self::Cdab => "cdab",
            Self::Badc => "badc",
        }
    }

    /// What the order is in words: `big-endian`, `little-endian image`,
    /// `word-swapped` or `byte-swapped`.
    pub const fn meaning(self) -> &'static str {
        match self {
            Self::Abcd => "big-endian",
            Self::Dcba => "little-endian image",
            Self::Cdab => "word-swapped",
            Self::Badc => "byte-swapped",
        }
    }
}

/// Decodes a two-byte value from wire bytes.
#[inline]
pub const fn u16_from_wire(order: ByteOrder2, b: [u8; 2]) -> u16 {
    match order {
        ByteOrder2::Ab => u16::from_be_bytes(b),
        ByteOrder2::Ba => u16::from_le_bytes(b),
    }
}

/// Encodes a two-byte value to wire bytes.
#[inline]
pub const fn u16_to_wire(order: ByteOrder2, v: u16) -> [u8; 2] {
    match order {
        ByteOrder2::Ab => v.to_be_bytes(),
        ByteOrder2::Ba => v.to_le_bytes(),
    }
}

/// Decodes a four-byte value from wire bytes.
#[inline]
pub const fn u32_from_wire(order: ByteOrder4, b: [u8; 4]) -> u32 {
    let [w, x, y, z] = b;
    match order {
        ByteOrder4::Abcd => u32::from_be_bytes([w, x, y, z]),
        ByteOrder4::Dcba => u32::from_be_bytes([z, y, x, w]),
        ByteOrder4::Cdab => u32::from_be_bytes([y, z, w, x]),
        ByteOrder4::Badc => u32::from_be_bytes([x, w, z, y]),
    }
}

/// Encodes a four-byte value to wire bytes.
#[inline]
pub const fn u32_to_wire(order: ByteOrder4, v: u32) -> [u8; 4] {
    let [a, b, c, d] = v.to_be_bytes();
    match order {
        ByteOrder4::Abcd => [a, b, c, d],
        ByteOrder4::Dcba => [d, c, b, a],
        ByteOrder4::Cdab => [c, d, a, b],
        ByteOrder4::Badc => [b, a, d, c],
    }
}

/// Decodes an IEEE 754 single from wire bytes, bit-exactly (NaN payloads kept).
#[inline]
pub const fn f32_from_wire(order: ByteOrder4, b: [u8; 4]) -> f32 {
    f32::from_bits(u32_from_wire(order, b))
}

/// Encodes an IEEE 754 single to wire bytes, bit-exactly.
#[inline]
pub const fn f32_to_wire(order: ByteOrder4, v: f32) -> [u8; 4] {
    u32_to_wire(order, v.to_bits())
}

/// A firmware or hardware revision sent as two bytes, major then minor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Version {
    /// The first wire byte (major revision).
    pub major: u8,
    /// The second wire byte (minor revision).
    pub minor: u8,
}

impl Version {
    /// A version from its two bytes.
    pub const fn new(major: u8, minor: u8) -> Self {
        Self { major, minor }
    }

    /// The two wire bytes: major, then minor.
    pub const fn to_wire(self) -> [u8; 2] {
        [self.major, self.minor]
    }

    /// From the two wire bytes.
    pub const fn from_wire(b: [u8; 2]) -> Self {
        Self { major: b[0], minor: b[1] }
    }
}

impl fmt::Display for Version {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.major, self.minor)
    }
}

/// One byte of two decimal digits (`0x59` is 59), as clocks send them.
///
/// The raw byte is kept as received: a byte with a digit above 9 is not a
/// number, and [`Bcd::value`] says so instead of guessing one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Bcd(pub u8);

impl Bcd {
    /// The byte for `value`, `None` above 99.
    pub const fn from_value(value: u8) -> Option<Self> {
        if value > 99 { None } else { Some(Self((value / 10) << 4 | (value % 10))) }
    }

    /// The two digits as a number, `None` when a digit is above 9.
    pub const fn value(self) -> Option<u8> {
        let (high, low) = (self.0 >> 4, self.0 & 0x0F);
        if high > 9 || low > 9 { None } else { Some(high * 10 + low) }
    }
}

impl fmt::Display for Bcd {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.value() {
            Some(v) => write!(f, "{v:02}"),
            None => write!(f, "invalid BCD (0x{:02X})", self.0),
        }
    }
}

/// A fixed-length text field of `N` bytes, padded with `pad` bytes at the end.
///
/// The raw bytes are kept as received: a device that sends bytes outside ASCII
/// is shown, not trusted ([`Ascii::as_str`] returns `None`).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Ascii<const N: usize> {
    bytes: [u8; N],
    pad: u8,
}

impl<const N: usize> Ascii<N> {
    /// The field as received, padding included.
    pub const fn from_wire(bytes: [u8; N], pad: u8) -> Self {
        Self { bytes, pad }
    }

    /// The field at `at..at + N` of a message's register data, as received
    /// (`pad` bytes if the data ends before, which a message's own data,
    /// of the length its layout frames, never does).
    #[inline]
    pub fn read(data: &[u8], at: usize, pad: u8) -> Self {
        let mut bytes = [pad; N];
        if let Some(from) = data.get(at..at.saturating_add(N)) {
            crate::bytes::copy_in_pieces(&mut bytes, from);
        }
        Self { bytes, pad }
    }

    /// The field from text: at most `N` ASCII bytes, padded with `pad`.
    /// Returns `None` when `text` is too long or not ASCII.
    pub fn from_text(text: &str, pad: u8) -> Option<Self> {
        if text.len() > N || !text.is_ascii() {
            return None;
        }
        let mut bytes = [pad; N];
        for (slot, byte) in bytes.iter_mut().zip(text.bytes()) {
            *slot = byte;
        }
        Some(Self { bytes, pad })
    }

    /// The raw wire bytes, padding included, as received or encoded.
    pub const fn to_wire(&self) -> [u8; N] {
        self.bytes
    }

    /// The raw bytes, padding included.
    pub const fn as_bytes(&self) -> &[u8; N] {
        &self.bytes
    }

    /// The raw bytes without trailing padding (whatever the device sent).
    pub fn trimmed(&self) -> &[u8] {
        let end = self.bytes.iter().rposition(|&b| b != self.pad).map_or(0, |i| i + 1);
        self.bytes.get(..end).unwrap_or(&[])
    }

    /// The byte that pads the text to `N` bytes.
    pub const fn pad(&self) -> u8 {
        self.pad
    }

    /// The text without trailing padding, if it is printable ASCII.
    pub fn as_str(&self) -> Option<&str> {
        let end = self.bytes.iter().rposition(|&b| b != self.pad).map_or(0, |i| i + 1);
        let text = self.bytes.get(..end)?;
        if text.iter().all(|b| b.is_ascii_graphic() || *b == b' ') { core::str::from_utf8(text).ok() } else { None }
    }
}

impl<const N: usize> fmt::Debug for Ascii<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.as_str() {
            Some(s) => write!(f, "{s:?}"),
            None => write!(f, "Ascii({:02x?})", self.bytes),
        }
    }
}

impl<const N: usize> fmt::Display for Ascii<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.as_str() {
            Some(s) => f.write_str(s),
            None => {
                for b in self.bytes {
                    if b.is_ascii_graphic() || b == b' ' {
                        write!(f, "{}", char::from(b))?;
                    } else {
                        write!(f, "\\x{b:02x}")?;
                    }
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yosemitech_float_is_little_endian_image() {
        // pH manual Fig 25: 7.6 = 33 33 F3 40.
        assert_eq!(f32_from_wire(ByteOrder4::Dcba, [0x33, 0x33, 0xF3, 0x40]), 7.6);
        assert_eq!(f32_to_wire(ByteOrder4::Abcd, 17.625), [0x41, 0x8D, 0x00, 0x00]);
        assert_eq!(f32_to_wire(ByteOrder4::Cdab, 17.625), [0x00, 0x00, 0x41, 0x8D]);
        assert_eq!(f32_to_wire(ByteOrder4::Badc, 17.625), [0x8D, 0x41, 0x00, 0x00]);
    }

    #[test]
    fn all_orders_round_trip() {
        for order in ByteOrder4::ALL {
            for v in [0u32, 1, 0x0102_0304, u32::MAX, 0x8000_0001] {
                assert_eq!(u32_from_wire(order, u32_to_wire(order, v)), v);
            }
        }
        for order in ByteOrder2::ALL {
            assert_eq!(u16_from_wire(order, u16_to_wire(order, 0x1234)), 0x1234);
        }
        assert_eq!(u16_to_wire(ByteOrder2::Ab, 0x1234), [0x12, 0x34]);
    }

    #[test]
    fn ascii_trims_padding_and_rejects_binary() {
        let sn = Ascii::<4>::from_wire(*b"YL\0\0", 0);
        assert_eq!(sn.as_str(), Some("YL"));
        assert_eq!(Ascii::<2>::from_wire([0x59, 0x07], 0).as_str(), None);
        assert_eq!(Ascii::<2>::from_text("YLX", 0), None);
        assert_eq!(Ascii::<3>::from_text("YL", b' ').map(|a| a.to_wire()), Some(*b"YL "));
    }
}

#[cfg(test)]
mod bcd_tests {
    use super::Bcd;

    #[test]
    fn bcd_round_trips_every_two_digit_number_and_refuses_the_rest() {
        for v in 0..=99u8 {
            let b = Bcd::from_value(v).unwrap();
            assert_eq!(b.value(), Some(v));
        }
        assert_eq!(Bcd(0x59).value(), Some(59));
        assert_eq!(Bcd::from_value(100), None);
        let invalid = (0..=255u8).filter(|&raw| Bcd(raw).value().is_none()).count();
        assert_eq!(invalid, 256 - 100, "exactly the 100 two-digit bytes are numbers");
    }
}

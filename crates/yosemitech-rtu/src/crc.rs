//! CRC-16/MODBUS (poly 0x8005 reflected as 0xA001, init 0xFFFF), sent low byte first.

/// The 256-entry lookup table, computed at compile time.
static TABLE: [u16; 256] = build_table();

// Runs only in const evaluation, where an out-of-bounds index is a compile
// error rather than a panic; `get_mut` is not usable in a `const fn` loop.
#[allow(clippy::indexing_slicing)]
const fn build_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = i as u16;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xA001 } else { crc >> 1 };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// Continues a CRC-16/MODBUS computation over `data`, starting from `crc`.
///
/// Start from [`CRC_INIT`]; the result of one call can be passed to the next,
/// so a frame can be checked as it arrives in pieces.
#[inline]
pub fn crc16_update(mut crc: u16, data: &[u8]) -> u16 {
    for &byte in data {
        let index = usize::from((crc ^ u16::from(byte)) & 0xFF);
        // `index` is at most 0xFF, so the lookup cannot fail; `get` keeps the
        // no-panic guarantee visible to clippy.
        crc = (crc >> 8) ^ TABLE.get(index).copied().unwrap_or(0);
    }
    crc
}

/// The initial value of a CRC-16/MODBUS computation.
pub const CRC_INIT: u16 = 0xFFFF;

/// CRC-16/MODBUS of `data`. On the wire the low byte goes first.
///
/// ```
/// assert_eq!(yosemitech_rtu::crc16(b"123456789"), 0x4B37);
/// ```
#[inline]
pub fn crc16(data: &[u8]) -> u16 {
    crc16_update(CRC_INIT, data)
}

/// True when the last two bytes of `frame` are the CRC of the bytes before them.
pub fn crc_ok(frame: &[u8]) -> bool {
    match frame.len().checked_sub(2).map(|n| frame.split_at(n)) {
        Some((body, [lo, hi])) => crc16(body) == u16::from_le_bytes([*lo, *hi]),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bit-by-bit implementation, independent of the table.
    fn crc16_bitwise(data: &[u8]) -> u16 {
        let mut crc = 0xFFFFu16;
        for &b in data {
            crc ^= u16::from(b);
            for _ in 0..8 {
                crc = if crc & 1 != 0 { (crc >> 1) ^ 0xA001 } else { crc >> 1 };
            }
        }
        crc
    }

    #[test]
    fn check_value() {
        assert_eq!(crc16(b"123456789"), 0x4B37);
    }

    #[test]
    fn manual_get_ph_request() {
        // pH manual, Fig 23: 01 03 28 00 00 02 CD AB.
        assert_eq!(crc16(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02]).to_le_bytes(), [0xCD, 0xAB]);
        assert!(crc_ok(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB]));
        assert!(!crc_ok(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xAB, 0xCD]));
        assert!(!crc_ok(&[0x01]));
    }

    proptest::proptest! {
        #[test]
        fn table_matches_bitwise(data in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
            proptest::prop_assert_eq!(crc16(&data), crc16_bitwise(&data));
        }

        #[test]
        fn incremental_matches_whole(data in proptest::collection::vec(proptest::num::u8::ANY, 0..300), cut in 0usize..300) {
            let cut = cut.min(data.len());
            let (a, b) = data.split_at(cut);
            proptest::prop_assert_eq!(crc16_update(crc16_update(CRC_INIT, a), b), crc16(&data));
        }
    }
}

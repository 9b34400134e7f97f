//! CRC-16/MODBUS (poly 0x8005 reflected as 0xA001, init 0xFFFF), sent low byte first.

/// One step of the bit-serial CRC: the register shifted right by one bit.
const fn shift_bit(crc: u16) -> u16 {
    if crc & 1 != 0 { (crc >> 1) ^ 0xA001 } else { crc >> 1 }
}

/// Bytes per step of the main loop of [`crc16_update`] with the `fast-crc`
/// feature: 16 tables of 256 entries, 8 KiB. Without it the runtime looks up
/// half a byte at a time in [`NIBBLES`] (32 bytes: for firmware, where flash
/// counts more than nanoseconds).
#[cfg(feature = "fast-crc")]
const LANES: usize = 16;

/// `TABLES[k][b]`: the CRC register after byte `b` followed by `k` zero
/// bytes, from a zero register (16 × 256 entries, computed at compile time).
/// `TABLES[0]` is the classic byte-at-a-time table.
#[cfg(feature = "fast-crc")]
static TABLES: [[u16; 256]; LANES] = build_tables();

// Runs only in const evaluation, where an out-of-bounds index is a compile
// error rather than a panic; `get_mut` is not usable in a `const fn` loop.
#[cfg(feature = "fast-crc")]
#[allow(clippy::indexing_slicing)]
const fn build_tables() -> [[u16; 256]; LANES] {
    let mut tables = [[0u16; 256]; LANES];
    let mut i = 0;
    while i < 256 {
        let mut crc = i as u16;
        let mut bit = 0;
        while bit < 8 {
            crc = shift_bit(crc);
            bit += 1;
        }
        tables[0][i] = crc;
        i += 1;
    }
    let mut k = 1;
    while k < LANES {
        let mut i = 0;
        while i < 256 {
            let previous = tables[k - 1][i];
            tables[k][i] = (previous >> 8) ^ tables[0][(previous & 0xFF) as usize];
            i += 1;
        }
        k += 1;
    }
    tables
}

/// `TABLES[lane][byte]`. A byte cannot be out of range and every caller
/// passes a constant lane below [`LANES`], so the check compiles away; `get`
/// keeps the no-panic guarantee visible to clippy.
#[cfg(feature = "fast-crc")]
#[inline(always)]
fn lookup(lane: usize, byte: u8) -> u16 {
    TABLES.get(lane).and_then(|table| table.get(usize::from(byte))).copied().unwrap_or(0)
}

/// `NIBBLES[n]`: the CRC register after the four bits `n`, from a zero
/// register (computed at compile time).
#[cfg_attr(all(feature = "fast-crc", not(test)), allow(dead_code))]
static NIBBLES: [u16; 16] = build_nibbles();

#[allow(clippy::indexing_slicing)] // const evaluation only, as `build_tables`
#[cfg_attr(all(feature = "fast-crc", not(test)), allow(dead_code))]
const fn build_nibbles() -> [u16; 16] {
    let mut table = [0u16; 16];
    let mut n = 0;
    while n < 16 {
        let mut crc = n as u16;
        let mut bit = 0;
        while bit < 4 {
            crc = shift_bit(crc);
            bit += 1;
        }
        table[n] = crc;
        n += 1;
    }
    table
}

/// The register after its low four bits: the masked index is always in
/// range, so the check compiles away.
#[inline(always)]
#[cfg_attr(all(feature = "fast-crc", not(test)), allow(dead_code))]
fn shift_nibble(crc: u16) -> u16 {
    (crc >> 4) ^ NIBBLES.get(usize::from(crc & 0x0F)).copied().unwrap_or(0)
}

/// [`crc16_update`] half a byte at a time: the build without `fast-crc`
/// (and the reference its tests hold the fast one to).
// Out of line: the firmware checks CRCs in several places and keeps one loop.
#[inline(never)]
#[cfg_attr(all(feature = "fast-crc", not(test)), allow(dead_code))]
fn crc16_update_by_nibbles(mut crc: u16, data: &[u8]) -> u16 {
    for &byte in data {
        crc = shift_nibble(shift_nibble(crc ^ u16::from(byte)));
    }
    crc
}

/// Defines `fn $name(crc, &[u8; N]) -> u16`: the register after a block of
/// `N` bytes. The register is folded into the block's first two bytes and
/// every byte is looked up in its own table, so a block costs one dependent
/// lookup instead of `N` (slicing-by-N).
#[cfg(feature = "fast-crc")]
macro_rules! block_fn {
    ($name:ident, $n:literal, [$($byte:ident: $lane:literal),*]) => {
        #[inline(always)]
        fn $name(crc: u16, block: &[u8; $n]) -> u16 {
            let [low, high] = crc.to_le_bytes();
            let [first, second, $($byte),*] = *block;
            // The bytes the register does not touch first: their lookups
            // do not wait for the previous block.
            let independent = 0 $(^ lookup($lane, $byte))*;
            independent ^ lookup($n - 2, second ^ high) ^ lookup($n - 1, first ^ low)
        }
    };
}

#[cfg(feature = "fast-crc")]
block_fn!(block16, 16, [
    b2: 13, b3: 12, b4: 11, b5: 10, b6: 9, b7: 8, b8: 7, b9: 6,
    b10: 5, b11: 4, b12: 3, b13: 2, b14: 1, b15: 0
]);
#[cfg(feature = "fast-crc")]
block_fn!(block8, 8, [b2: 5, b3: 4, b4: 3, b5: 2, b6: 1, b7: 0]);
#[cfg(feature = "fast-crc")]
block_fn!(block4, 4, [b2: 1, b3: 0]);
#[cfg(feature = "fast-crc")]
block_fn!(block2, 2, []);

/// Continues a CRC-16/MODBUS computation over `data`, starting from `crc`.
///
/// Start from [`CRC_INIT`]; the result of one call can be passed to the next,
/// so a frame can be checked as it arrives in pieces.
///
/// Blocks of 16 bytes, then one block each of the remaining 8, 4 and 2
/// bytes and a last single byte: a 7-byte reply body takes 3 dependent
/// steps, 256 bytes 16.
#[inline]
#[cfg(feature = "fast-crc")]
pub fn crc16_update(mut crc: u16, data: &[u8]) -> u16 {
    let (blocks, mut rest) = data.as_chunks::<LANES>();
    for block in blocks {
        crc = block16(crc, block);
    }
    if let Some((block, after)) = rest.split_first_chunk::<8>() {
        crc = block8(crc, block);
        rest = after;
    }
    if let Some((block, after)) = rest.split_first_chunk::<4>() {
        crc = block4(crc, block);
        rest = after;
    }
    if let Some((block, after)) = rest.split_first_chunk::<2>() {
        crc = block2(crc, block);
        rest = after;
    }
    if let Some(&byte) = rest.first() {
        crc = (crc >> 8) ^ lookup(0, (crc as u8) ^ byte);
    }
    crc
}

/// Continues a CRC-16/MODBUS computation over `data`, starting from `crc`
/// (half a byte at a time: the build without `fast-crc`).
#[inline]
#[cfg(not(feature = "fast-crc"))]
pub fn crc16_update(crc: u16, data: &[u8]) -> u16 {
    crc16_update_by_nibbles(crc, data)
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
#[inline]
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
    fn crc16_bitwise(mut crc: u16, data: &[u8]) -> u16 {
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
    fn manual_float_read_request() {
        // pH manual, Fig 23: 01 03 28 00 00 02 CD AB.
        assert_eq!(crc16(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02]).to_le_bytes(), [0xCD, 0xAB]);
        assert!(crc_ok(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB]));
        assert!(!crc_ok(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xAB, 0xCD]));
        assert!(!crc_ok(&[0x01]));
    }

    proptest::proptest! {
        #[test]
        fn table_matches_bitwise(data in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
            proptest::prop_assert_eq!(crc16(&data), crc16_bitwise(CRC_INIT, &data));
        }

        #[test]
        fn nibbles_match_bitwise(data in proptest::collection::vec(proptest::num::u8::ANY, 0..300), init: u16) {
            proptest::prop_assert_eq!(crc16_update_by_nibbles(init, &data), crc16_bitwise(init, &data));
        }

        #[test]
        fn incremental_matches_whole(data in proptest::collection::vec(proptest::num::u8::ANY, 0..300), cut in 0usize..300) {
            let cut = cut.min(data.len());
            let (a, b) = data.split_at(cut);
            proptest::prop_assert_eq!(crc16_update(crc16_update(CRC_INIT, a), b), crc16(&data));
        }
    }
}

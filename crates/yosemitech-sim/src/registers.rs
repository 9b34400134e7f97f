//! The register file: a sparse map from register address to its two wire bytes.

use std::collections::BTreeMap;
use std::fmt;

use yosemitech_rtu::Hex;

/// The simulated device's holding registers, sparse.
///
/// Each register holds the two bytes it carries on the wire, in wire order
/// (not a `u16` in any byte order: Yosemitech values are little-endian
/// images spread over registers, so bytes are the only honest unit).
/// Registers never written read as `00 00`.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct RegisterMap {
    words: BTreeMap<u16, [u8; 2]>,
}

impl RegisterMap {
    /// An empty map: every register reads `00 00`.
    pub fn new() -> Self {
        Self::default()
    }

    /// The bytes of register `address`, if it was ever written.
    pub fn get(&self, address: u16) -> Option<[u8; 2]> {
        self.words.get(&address).copied()
    }

    /// Appends the bytes of `count` registers from `address` to `out`
    /// (`2 * count` bytes; unset registers read `00 00`). Addresses past
    /// 0xFFFF wrap, as the 16-bit register space does.
    pub fn read_into(&self, address: u16, count: u16, out: &mut Vec<u8>) {
        for i in 0..count {
            out.extend_from_slice(&self.get(address.wrapping_add(i)).unwrap_or([0, 0]));
        }
    }

    /// The bytes of `count` registers from `address`.
    pub fn read(&self, address: u16, count: u16) -> Vec<u8> {
        let mut out = Vec::with_capacity(2 * usize::from(count));
        self.read_into(address, count, &mut out);
        out
    }

    /// Stores `data` (register data in wire order) from register `address`
    /// on. An odd trailing byte goes to the first byte of its register, the
    /// second is kept.
    pub fn write(&mut self, address: u16, data: &[u8]) {
        self.write_bytes(address, 0, data);
    }

    /// Stores `bytes` at byte `offset` of the register data that starts at
    /// register `address` (byte `offset` is byte `offset % 2` of register
    /// `address + offset / 2`): one field of a command.
    pub fn write_bytes(&mut self, address: u16, offset: usize, bytes: &[u8]) {
        for (i, &b) in bytes.iter().enumerate() {
            let at = offset + i;
            // Register addresses are 16 bits: wrap like the address space.
            let register = address.wrapping_add((at / 2) as u16);
            let word = self.words.entry(register).or_insert([0, 0]);
            if let Some(slot) = word.get_mut(at % 2) {
                *slot = b;
            }
        }
    }

    /// Registers ever written, in address order.
    pub fn iter(&self) -> impl Iterator<Item = (u16, [u8; 2])> + '_ {
        self.words.iter().map(|(&a, &w)| (a, w))
    }

    /// Number of registers ever written.
    pub fn len(&self) -> usize {
        self.words.len()
    }

    /// True when no register was ever written.
    pub fn is_empty(&self) -> bool {
        self.words.is_empty()
    }
}

impl fmt::Debug for RegisterMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut map = f.debug_map();
        for (address, word) in self.iter() {
            map.entry(&format_args!("0x{address:04X}"), &Hex(&word));
        }
        map.finish()
    }
}

/// Which reads keep registers of their own (by command index).
///
/// Two reads that cover a register share it when their fields there are the
/// same fields (a block read and a read of its first value). Where a field
/// of one straddles a field of the other, the addresses cannot be register
/// offsets (the Y4000's newer hardware numbers its parameters at 0x26NN, one
/// float each), so each read answers from its own registers: writing one
/// value would otherwise corrupt its neighbours.
pub fn reads_of_their_own(sensor: &yosemitech_spec::Sensor) -> Vec<bool> {
    // A field's bytes on the register line: register address * 2 + offset.
    let spans = |c: &yosemitech_spec::CommandSpec| -> Vec<(u32, u32)> {
        c.fields
            .iter()
            .map(|f| {
                let start = u32::from(c.address) * 2 + f.offset as u32;
                (start, start + f.size() as u32)
            })
            .collect()
    };
    let reads: Vec<(usize, Vec<(u32, u32)>)> = sensor
        .commands
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_read() && c.count > 0 && !c.trigger)
        .map(|(i, c)| (i, spans(c)))
        .collect();
    let mut own = vec![false; sensor.commands.len()];
    for (a, (ia, fa)) in reads.iter().enumerate() {
        for (ib, fb) in reads.iter().skip(a + 1) {
            let straddle = fa.iter().any(|x| fb.iter().any(|y| x.0 < y.1 && y.0 < x.1 && x != y));
            if straddle {
                for i in [*ia, *ib] {
                    if let Some(o) = own.get_mut(i) {
                        *o = true;
                    }
                }
            }
        }
    }
    own
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_back_writes_and_zeros() {
        let mut r = RegisterMap::new();
        r.write(0x2800, &[0x33, 0x33, 0xF3, 0x40]);
        assert_eq!(r.read(0x2800, 2), [0x33, 0x33, 0xF3, 0x40]);
        assert_eq!(r.read(0x27FF, 4), [0, 0, 0x33, 0x33, 0xF3, 0x40, 0, 0]);
        r.write_bytes(0x3000, 0, &[0x14]);
        assert_eq!(r.get(0x3000), Some([0x14, 0]));
        r.write_bytes(0x2600, 3, &[0xAA, 0xBB]);
        assert_eq!(r.read(0x2600, 3), [0, 0, 0, 0xAA, 0xBB, 0]);
        r.write(0xFFFF, &[1, 2, 3, 4]);
        assert_eq!(r.get(0x0000), Some([3, 4]), "wraps");
        assert_eq!(r.len(), 7);
        assert!(format!("{r:?}").contains("0x2800: 33 33"));
    }
}

//! Modbus TCP framing: the MBAP header, and conversion between an MBAP ADU
//! and the RTU frame every codec of this crate reads and writes.
//!
//! An MBAP ADU is `transaction id (2), protocol id (2, always 0), length (2),
//! unit id (1), PDU`; the length counts the unit id and the PDU. An RTU frame
//! is `slave (1), PDU, CRC (2)`. The PDU is the same in both, and the unit id
//! of a gateway is the slave address on its serial line, so converting is
//! moving the PDU and adding or checking the CRC:
//!
//! ```text
//! RTU:             [slave] [function ... data] [crc lo] [crc hi]
//! MBAP: [tid] [0] [len] [unit ] [function ... data]
//! ```
//!
//! Everything here is `no_std`, allocation-free and total: any input gives a
//! value or an [`MbapError`], never a panic. Multi-byte fields are big-endian.

use core::fmt;

use crate::bytes::{byte, word};
use crate::crc::{crc_ok, crc16};
use crate::error::FrameError;
use crate::frame::MAX_ADU;

/// Bytes of the MBAP header, unit id included.
pub const HEADER_LEN: usize = 7;

/// The protocol id of Modbus: the only one defined.
pub const PROTOCOL_MODBUS: u16 = 0;

/// The largest PDU: what fits in an RTU frame besides address and CRC.
pub const MAX_PDU: usize = MAX_ADU - RTU_OVERHEAD;

/// The largest MBAP ADU (260 bytes).
pub const MAX_MBAP_ADU: usize = HEADER_LEN + MAX_PDU;

/// Bytes an RTU frame has around its PDU: the slave address and the CRC.
pub const RTU_OVERHEAD: usize = 3;

/// The least length field: the unit id and a function code.
const MIN_LENGTH: u16 = 2;

/// The greatest length field: the unit id and the largest PDU.
const MAX_LENGTH: u16 = 1 + MAX_PDU as u16;

/// Byte ranges of the header.
mod field {
    use core::ops::Range;

    pub const TRANSACTION: Range<usize> = 0..2;
    pub const PROTOCOL: Range<usize> = 2..4;
    pub const LENGTH: Range<usize> = 4..6;
    pub const UNIT: usize = 6;
}

/// Why an MBAP header or ADU, or the RTU frame to convert, was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum MbapError {
    /// Fewer bytes than the header or its length field announce.
    Truncated {
        /// Bytes needed.
        expected: usize,
        /// Bytes present.
        actual: usize,
    },
    /// More bytes than the length field announces.
    TooLong {
        /// Bytes announced.
        expected: usize,
        /// Bytes present.
        actual: usize,
    },
    /// The protocol id is not 0 (Modbus).
    Protocol {
        /// The protocol id in the header.
        actual: u16,
    },
    /// The length field is below 2 (no function code) or above 254 (a PDU
    /// longer than an RTU frame can carry).
    Length {
        /// The length field in the header.
        actual: u16,
    },
    /// The RTU frame to convert is not one: too short, too long or a CRC mismatch.
    Rtu(FrameError),
    /// The output buffer is smaller than the converted frame.
    BufferTooSmall {
        /// Bytes the frame needs.
        needed: usize,
    },
}

impl fmt::Display for MbapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Truncated { expected, actual } => {
                write!(f, "truncated MBAP frame: {actual} bytes, expected {expected}")
            }
            Self::TooLong { expected, actual } => write!(f, "MBAP frame too long: {actual} bytes, expected {expected}"),
            Self::Protocol { actual } => write!(f, "MBAP protocol id {actual}, expected 0 (Modbus)"),
            Self::Length { actual } => {
                write!(f, "MBAP length field {actual} outside {MIN_LENGTH}..={MAX_LENGTH}")
            }
            Self::Rtu(error) => write!(f, "not an RTU frame: {error}"),
            Self::BufferTooSmall { needed } => write!(f, "output buffer too small: {needed} bytes needed"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for MbapError {}

/// A checked MBAP header: protocol 0, a length that fits an RTU frame.
///
/// Invariant: `2 <= length <= 254`, so [`Header::pdu_len`] is at least 1 and
/// the PDU fits an RTU frame of at most [`MAX_ADU`] bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Header {
    /// Pairs a reply with its request; the server echoes it.
    pub transaction: u16,
    /// The addressed device: the slave address behind a gateway.
    pub unit: u8,
    length: u16,
}

impl Header {
    /// The header of an ADU carrying a `pdu_len`-byte PDU.
    pub const fn new(transaction: u16, unit: u8, pdu_len: usize) -> Result<Self, MbapError> {
        if pdu_len == 0 || pdu_len > MAX_PDU {
            let actual = if pdu_len >= u16::MAX as usize { u16::MAX } else { pdu_len as u16 + 1 };
            return Err(MbapError::Length { actual });
        }
        Ok(Self { transaction, unit, length: pdu_len as u16 + 1 })
    }

    /// Reads and checks the header at the start of `bytes` (which may hold
    /// the rest of the ADU, or not yet).
    pub fn parse(bytes: &[u8]) -> Result<Self, MbapError> {
        let Some(header) = bytes.get(..HEADER_LEN) else {
            return Err(MbapError::Truncated { expected: HEADER_LEN, actual: bytes.len() });
        };
        let protocol = word(header, field::PROTOCOL.start).unwrap_or(0);
        if protocol != PROTOCOL_MODBUS {
            return Err(MbapError::Protocol { actual: protocol });
        }
        let length = word(header, field::LENGTH.start).unwrap_or(0);
        if !(MIN_LENGTH..=MAX_LENGTH).contains(&length) {
            return Err(MbapError::Length { actual: length });
        }
        let unit = header.get(field::UNIT).copied().unwrap_or(0);
        Ok(Self { transaction: word(header, field::TRANSACTION.start).unwrap_or(0), unit, length })
    }

    /// Writes the header to `out[..HEADER_LEN]`.
    pub fn emit(&self, out: &mut [u8]) -> Result<(), MbapError> {
        let out = out.get_mut(..HEADER_LEN).ok_or(MbapError::BufferTooSmall { needed: HEADER_LEN })?;
        let [t0, t1] = self.transaction.to_be_bytes();
        let [p0, p1] = PROTOCOL_MODBUS.to_be_bytes();
        let [l0, l1] = self.length.to_be_bytes();
        out.copy_from_slice(&[t0, t1, p0, p1, l0, l1, self.unit]);
        Ok(())
    }

    /// The length field: unit id and PDU bytes.
    pub const fn length(&self) -> u16 {
        self.length
    }

    /// Bytes of the PDU (function code and data), at least 1.
    pub const fn pdu_len(&self) -> usize {
        self.length as usize - 1
    }

    /// Bytes of the whole ADU, header included.
    pub const fn adu_len(&self) -> usize {
        HEADER_LEN + self.pdu_len()
    }

    /// Bytes of the RTU frame carrying the same PDU.
    pub const fn rtu_len(&self) -> usize {
        self.pdu_len() + RTU_OVERHEAD
    }
}

/// Checks a whole MBAP ADU and returns its header and PDU.
pub fn parse_adu(adu: &[u8]) -> Result<(Header, &[u8]), MbapError> {
    let header = Header::parse(adu)?;
    let expected = header.adu_len();
    if adu.len() > expected {
        return Err(MbapError::TooLong { expected, actual: adu.len() });
    }
    let pdu = adu.get(HEADER_LEN..expected).ok_or(MbapError::Truncated { expected, actual: adu.len() })?;
    Ok((header, pdu))
}

/// Converts the RTU frame `rtu` (checked: length and CRC) into an MBAP ADU
/// with `transaction` in `out`, the slave address becoming the unit id.
/// Returns the ADU's length (the RTU frame's plus 4).
pub fn rtu_to_adu(rtu: &[u8], transaction: u16, out: &mut [u8]) -> Result<usize, MbapError> {
    const MIN_RTU: usize = RTU_OVERHEAD + 1;
    if rtu.len() < MIN_RTU {
        return Err(MbapError::Rtu(FrameError::Truncated { expected: MIN_RTU, actual: rtu.len() }));
    }
    if rtu.len() > MAX_ADU {
        return Err(MbapError::Rtu(FrameError::TooLong { expected: MAX_ADU, actual: rtu.len() }));
    }
    if !crc_ok(rtu) {
        let n = rtu.len() - 2;
        let received = word(rtu, n).map_or(0, u16::swap_bytes);
        let computed = crc16(rtu.get(..n).unwrap_or(&[]));
        return Err(MbapError::Rtu(FrameError::Crc { received, computed }));
    }
    let pdu = rtu.get(1..rtu.len() - 2).unwrap_or(&[]);
    let header = Header::new(transaction, byte(rtu, 0).unwrap_or(0), pdu.len())?;
    let len = header.adu_len();
    let out = out.get_mut(..len).ok_or(MbapError::BufferTooSmall { needed: len })?;
    header.emit(out)?;
    if let Some(slot) = out.get_mut(HEADER_LEN..) {
        slot.copy_from_slice(pdu);
    }
    Ok(len)
}

/// Converts the MBAP ADU `adu` (checked: [`parse_adu`]) into the RTU frame
/// carrying the same PDU, addressed to its unit id, with its CRC, in `out`.
/// Returns the header (for its transaction id) and the frame's length.
pub fn adu_to_rtu(adu: &[u8], out: &mut [u8]) -> Result<(Header, usize), MbapError> {
    let (header, pdu) = parse_adu(adu)?;
    let len = header.rtu_len();
    let out = out.get_mut(..len).ok_or(MbapError::BufferTooSmall { needed: len })?;
    let (body, crc) = out.split_at_mut(len - 2);
    if let Some((unit, rest)) = body.split_first_mut() {
        *unit = header.unit;
        rest.copy_from_slice(pdu);
    }
    crc.copy_from_slice(&crc16(body).to_le_bytes());
    Ok((header, len))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// get_ph from the pH manual, as RTU and as Modbus TCP (transaction 0x1234).
    const RTU_REQUEST: [u8; 8] = [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB];
    const MBAP_REQUEST: [u8; 12] = [0x12, 0x34, 0x00, 0x00, 0x00, 0x06, 0x01, 0x03, 0x28, 0x00, 0x00, 0x02];

    #[test]
    fn converts_the_manual_request_both_ways() {
        let mut adu = [0u8; MAX_MBAP_ADU];
        let n = rtu_to_adu(&RTU_REQUEST, 0x1234, &mut adu).unwrap();
        assert_eq!(&adu[..n], MBAP_REQUEST);
        let mut rtu = [0u8; MAX_ADU];
        let (header, n) = adu_to_rtu(&MBAP_REQUEST, &mut rtu).unwrap();
        assert_eq!(&rtu[..n], RTU_REQUEST);
        assert_eq!((header.transaction, header.unit, header.length(), header.pdu_len()), (0x1234, 1, 6, 5));
    }

    #[test]
    fn rejects_bad_headers_and_lengths() {
        let mut bad = MBAP_REQUEST;
        bad[3] = 1;
        assert_eq!(Header::parse(&bad), Err(MbapError::Protocol { actual: 1 }));
        for (length, ok) in [(0u16, false), (1, false), (2, true), (254, true), (255, false)] {
            let mut h = MBAP_REQUEST;
            h[4..6].copy_from_slice(&length.to_be_bytes());
            assert_eq!(Header::parse(&h).is_ok(), ok, "length {length}");
        }
        assert_eq!(Header::parse(&MBAP_REQUEST[..6]), Err(MbapError::Truncated { expected: 7, actual: 6 }));
        assert_eq!(parse_adu(&MBAP_REQUEST[..11]), Err(MbapError::Truncated { expected: 12, actual: 11 }));
        let mut long = [0u8; 13];
        long[..12].copy_from_slice(&MBAP_REQUEST);
        assert_eq!(parse_adu(&long), Err(MbapError::TooLong { expected: 12, actual: 13 }));
        let mut corrupt = RTU_REQUEST;
        corrupt[7] ^= 1;
        assert!(matches!(rtu_to_adu(&corrupt, 0, &mut [0; 64]), Err(MbapError::Rtu(FrameError::Crc { .. }))));
        assert!(matches!(rtu_to_adu(&RTU_REQUEST[..3], 0, &mut [0; 64]), Err(MbapError::Rtu(_))));
        assert_eq!(rtu_to_adu(&RTU_REQUEST, 0, &mut [0; 11]), Err(MbapError::BufferTooSmall { needed: 12 }));
        assert_eq!(adu_to_rtu(&MBAP_REQUEST, &mut [0; 7]), Err(MbapError::BufferTooSmall { needed: 8 }));
        assert!(Header::new(0, 1, 0).is_err());
        assert!(Header::new(0, 1, MAX_PDU + 1).is_err());
        assert_eq!(Header::new(0, 1, MAX_PDU).unwrap().rtu_len(), MAX_ADU);
    }

    proptest::proptest! {
        #[test]
        fn rtu_frames_round_trip(
            unit in proptest::num::u8::ANY,
            transaction in proptest::num::u16::ANY,
            pdu in proptest::collection::vec(proptest::num::u8::ANY, 1..=MAX_PDU),
        ) {
            let mut rtu = [0u8; MAX_ADU];
            rtu[0] = unit;
            rtu[1..=pdu.len()].copy_from_slice(&pdu);
            let crc = crc16(&rtu[..=pdu.len()]).to_le_bytes();
            rtu[pdu.len() + 1..pdu.len() + 3].copy_from_slice(&crc);
            let rtu = &rtu[..pdu.len() + 3];
            let mut adu = [0u8; MAX_MBAP_ADU];
            let n = rtu_to_adu(rtu, transaction, &mut adu).unwrap();
            proptest::prop_assert_eq!(n, rtu.len() + 4);
            let (header, body) = parse_adu(&adu[..n]).unwrap();
            proptest::prop_assert_eq!((header.transaction, header.unit), (transaction, unit));
            proptest::prop_assert_eq!(body, &pdu[..]);
            let mut back = [0u8; MAX_ADU];
            let (_, m) = adu_to_rtu(&adu[..n], &mut back).unwrap();
            proptest::prop_assert_eq!(&back[..m], rtu);
        }

        #[test]
        fn headers_round_trip(transaction in proptest::num::u16::ANY, unit in proptest::num::u8::ANY, pdu_len in 1..=MAX_PDU) {
            let header = Header::new(transaction, unit, pdu_len).unwrap();
            let mut bytes = [0u8; HEADER_LEN];
            header.emit(&mut bytes).unwrap();
            proptest::prop_assert_eq!(Header::parse(&bytes), Ok(header));
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..300), out_len in 0usize..300) {
            let mut out = [0u8; 300];
            let _ = Header::parse(&bytes);
            let _ = parse_adu(&bytes);
            if let Ok((header, n)) = adu_to_rtu(&bytes, &mut out[..out_len]) {
                proptest::prop_assert!(crc_ok(&out[..n]));
                proptest::prop_assert_eq!(n, header.rtu_len());
            }
            let _ = rtu_to_adu(&bytes, 7, &mut out[..out_len]);
        }
    }
}

//! `rtu::dispatch` against `Command`'s provided methods: the same frames
//! accepted, the same values decoded, the same errors and the same bytes
//! written, for reads, writes with data, triggers and fixed addresses.

use proptest::prelude::*;
use yosemitech_rtu::{Command, EncodeError, Layout, Message, NoData, dispatch};
use yosemitech_tests::rtu::{Ph, ReadAtFixedSlave, ReadFloat, SlaveAddress, StartMeasurement, WriteWord};
use yosemitech_tests::with_crc;

/// A trigger read: a read of one register whose reply only acknowledges
/// (whatever the register holds means nothing).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct TriggerRead;

impl NoData for TriggerRead {}

impl Command for TriggerRead {
    type Response = ();
    const NAME: &'static str = "trigger_read";
    const LAYOUT: Layout<'static> = Layout { trigger: true, ..Layout::read(0x2500, 1) };
}

/// Results compared by their `Debug` text: a NaN decodes alike on both paths
/// but is not equal to itself.
fn same<T: std::fmt::Debug>(a: &T, b: &T) -> bool {
    format!("{a:?}") == format!("{b:?}")
}

/// Both decoders of `C` on `frame`, as a request and as a reply from `slave`.
fn assert_decoders_agree<C: Command + std::fmt::Debug>(slave: u8, frame: &[u8])
where
    C::Response: std::fmt::Debug,
{
    let (inline, shared) = (C::decode_request(frame), dispatch::decode_request::<C>(frame));
    assert!(same(&inline, &shared), "{} request {frame:02X?}: {inline:?} against {shared:?}", C::NAME);
    let (inline, shared) = (C::decode_response(slave, frame), dispatch::decode_response::<C>(slave, frame));
    assert!(same(&inline, &shared), "{} reply {frame:02X?}: {inline:?} against {shared:?}", C::NAME);
}

/// Both encoders of `C`, into buffers of `room` bytes.
fn assert_encoders_agree<C: Command + std::fmt::Debug>(request: &C, response: &C::Response, slave: u8, room: usize) {
    let (mut inline, mut shared) = (vec![0; room], vec![0; room]);
    let (a, b) = (request.encode_request(slave, &mut inline), dispatch::encode_request(request, slave, &mut shared));
    assert_eq!(a, b, "{} request to {slave} in {room} bytes", C::NAME);
    assert_eq!(inline, shared, "{} request to {slave} in {room} bytes", C::NAME);
    let (mut inline, mut shared) = (vec![0; room], vec![0; room]);
    let (a, b) = (
        C::encode_response(response, slave, &mut inline),
        dispatch::encode_response::<C>(response, slave, &mut shared),
    );
    assert_eq!(a, b, "{} reply from {slave} in {room} bytes", C::NAME);
    assert_eq!(inline, shared, "{} reply from {slave} in {room} bytes", C::NAME);
}

/// Every decoder on `frame`, whichever command it was made for.
fn assert_all_decoders_agree(slave: u8, frame: &[u8]) {
    assert_decoders_agree::<ReadFloat>(slave, frame);
    assert_decoders_agree::<StartMeasurement>(slave, frame);
    assert_decoders_agree::<ReadAtFixedSlave>(slave, frame);
    assert_decoders_agree::<WriteWord>(slave, frame);
    assert_decoders_agree::<TriggerRead>(slave, frame);
}

/// The frame `encode` writes, if it writes one.
fn encoded(encode: impl FnOnce(&mut [u8]) -> Result<usize, EncodeError>) -> Option<Vec<u8>> {
    let mut out = [0u8; 256];
    let len = encode(&mut out).ok()?;
    out.get(..len).map(<[u8]>::to_vec)
}

/// A frame close to a real one: the frame `C` writes, with one byte changed
/// or the frame cut, and its CRC made right again when `fix_crc`.
fn near_frames(frame: &[u8], at: usize, byte: u8, cut: usize, fix_crc: bool) -> [Vec<u8>; 2] {
    let mut changed = frame.to_vec();
    if let Some(b) = changed.get_mut(at % frame.len().max(1)) {
        *b = byte;
    }
    let cut = frame.get(..cut.min(frame.len())).unwrap_or(frame).to_vec();
    [changed, cut].map(|f| if fix_crc && f.len() > 2 { with_crc(&f[..f.len() - 2]) } else { f })
}

proptest! {
    #[test]
    fn decoders_agree_on_any_bytes(slave: u8, frame in prop::collection::vec(any::<u8>(), 0..24)) {
        assert_all_decoders_agree(slave, &frame);
    }

    #[test]
    fn decoders_agree_near_real_frames(
        slave in 0u8..=255,
        value: f32,
        word: u16,
        at: usize,
        byte: u8,
        cut in 0usize..16,
        fix_crc: bool,
    ) {
        // Encoding may refuse (slave 0, a value out of range): then there is no frame to vary.
        let frames = [
            encoded(|out| ReadFloat.encode_request(slave, out)),
            encoded(|out| ReadFloat::encode_response(&Ph(value), slave, out)),
            encoded(|out| StartMeasurement.encode_request(slave, out)),
            encoded(|out| StartMeasurement::encode_response(&(), slave, out)),
            encoded(|out| ReadAtFixedSlave.encode_request(0xFF, out)),
            encoded(|out| ReadAtFixedSlave::encode_response(&SlaveAddress(slave), 0xFF, out)),
            encoded(|out| WriteWord(word).encode_request(slave, out)),
            encoded(|out| WriteWord::encode_response(&(), slave, out)),
            encoded(|out| TriggerRead.encode_request(slave, out)),
            encoded(|out| TriggerRead::encode_response(&(), slave, out)),
        ];
        for frame in frames.into_iter().flatten() {
            assert_all_decoders_agree(slave, &frame);
            for near in near_frames(&frame, at, byte, cut, fix_crc) {
                assert_all_decoders_agree(slave, &near);
            }
        }
    }

    #[test]
    fn encoders_agree(slave: u8, value: f32, word: u16, room in 0usize..16) {
        assert_encoders_agree(&ReadFloat, &Ph(value), slave, room);
        assert_encoders_agree(&StartMeasurement, &(), slave, room);
        assert_encoders_agree(&ReadAtFixedSlave, &SlaveAddress(slave), slave, room);
        assert_encoders_agree(&WriteWord(word), &(), slave, room);
        assert_encoders_agree(&TriggerRead, &(), slave, room);
    }
}

#[test]
fn a_write_out_of_range_is_refused_on_both_paths() {
    let mut out = [0u8; 32];
    let refused = WriteWord(1001);
    assert!(refused.validate().is_err());
    assert_eq!(refused.encode_request(1, &mut out), dispatch::encode_request(&refused, 1, &mut out));
    assert!(dispatch::encode_request(&refused, 1, &mut out).is_err());
}

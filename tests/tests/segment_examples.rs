//! The frame segmenter (`yosemitech_rtu::segment`) against the manuals:
//! every whole frame an example prints (or its correction) is found as one
//! span of its kind, alone, behind noise and between the frames of its
//! exchange; bytes fed in chunks of any size give the spans of the whole;
//! and any bytes at all are covered exactly, without a panic.
//!
//! The frames come from the spec at test time: no sensor, command or number
//! of examples is named here.

use proptest::prelude::*;
use yosemitech_rtu::Hex;
use yosemitech_rtu::segment::{Span, SpanKind, next_span, spans};
use yosemitech_tests::spec;

/// Noise put in front of and between frames: no function code the
/// segmenter knows at any of its positions.
const NOISE: [u8; 3] = [0xAA, 0x55, 0x00];

/// A frame a manual prints, what it is called in a failure, and whether it
/// is a request.
struct Printed {
    what: String,
    bytes: Vec<u8>,
    request: bool,
}

/// The kinds a whole `frame` may be found as: a request or a reply as it
/// is, or an exception by its function code; a read of 8 bytes whose third
/// byte is 3 is both a request and a reply, as the segmenter says.
fn expected(frame: &[u8], request: bool) -> SpanKind {
    match frame.get(1) {
        Some(f) if f & 0x80 != 0 => SpanKind::Exception,
        Some(0x03) if frame.len() == 8 && frame.get(2) == Some(&3) => SpanKind::RequestOrReply,
        _ if request => SpanKind::Request,
        _ => SpanKind::Reply,
    }
}

/// Every whole frame of every example of every command: the true frames,
/// and printed ones whose CRC holds (an erratum's printed frame the decoder
/// accepts).
fn printed_frames() -> Vec<Printed> {
    let mut frames = Vec::new();
    for sensor in &spec().sensors {
        for command in &sensor.commands {
            for (i, example) in command.examples.iter().enumerate() {
                let what = |side: &str| format!("{}.{} example {} {side}", sensor.name, command.name, i + 1);
                let printed = |f: &Option<yosemitech_spec::PrintedFrame>| {
                    f.as_ref().and_then(|f| f.complete.clone()).filter(|b| yosemitech_rtu::crc_ok(b))
                };
                let sides = [
                    (what("request"), example.true_request().map(<[u8]>::to_vec), true),
                    (what("reply"), example.true_response().map(<[u8]>::to_vec), false),
                    (what("printed request"), printed(&example.request), true),
                    (what("printed reply"), printed(&example.response), false),
                ];
                for (what, bytes, request) in sides {
                    let Some(bytes) = bytes else { continue };
                    if !frames.iter().any(|p: &Printed| p.bytes == bytes && p.request == request) {
                        frames.push(Printed { what, bytes, request });
                    }
                }
            }
        }
    }
    assert!(!frames.is_empty(), "the spec prints no whole frame");
    frames
}

/// Every exchange whose request and reply the manual gives whole.
fn exchanges() -> Vec<(String, Vec<u8>, Vec<u8>)> {
    let mut pairs = Vec::new();
    for sensor in &spec().sensors {
        for command in &sensor.commands {
            for (i, example) in command.examples.iter().enumerate() {
                if let Some((request, reply)) = example.true_pair() {
                    let what = format!("{}.{} example {}", sensor.name, command.name, i + 1);
                    pairs.push((what, request.to_vec(), reply.to_vec()));
                }
            }
        }
    }
    assert!(!pairs.is_empty(), "the spec gives no whole exchange");
    pairs
}

/// (kind, start, end) of every span of a whole input.
fn whole(bytes: &[u8]) -> Vec<(SpanKind, usize, usize)> {
    spans(bytes).map(|s| (s.kind, s.start, s.end)).collect()
}

/// The spans a streaming reader finds when the bytes arrive in pieces
/// ending at `cuts` (increasing; the last piece ends with the bytes), then
/// the input ends.
fn streamed(bytes: &[u8], cuts: &[usize]) -> Vec<(SpanKind, usize, usize)> {
    let mut found = Vec::new();
    let mut done = 0;
    for &have in cuts.iter().chain([&bytes.len()]) {
        let have = have.min(bytes.len()).max(done);
        while let Ok(span) = next_span(&bytes[done..have]) {
            assert!(!span.is_empty(), "an empty span at {done}");
            found.push((span.kind, done + span.start, done + span.end));
            done += span.end;
        }
    }
    found.extend(spans(&bytes[done..]).map(|s: Span| (s.kind, done + s.start, done + s.end)));
    found
}

#[test]
fn every_printed_frame_is_one_span_of_its_kind() {
    for p in printed_frames() {
        let kind = expected(&p.bytes, p.request);
        assert_eq!(whole(&p.bytes), [(kind, 0, p.bytes.len())], "{}: {}", p.what, Hex(&p.bytes));
        // A reader that has the whole frame takes it at once.
        assert_eq!(
            next_span(&p.bytes).map(|s| (s.kind, s.end)),
            Ok((kind, p.bytes.len())),
            "{}: {}",
            p.what,
            Hex(&p.bytes)
        );
    }
}

#[test]
fn noise_before_a_printed_frame_is_one_noise_span() {
    for p in printed_frames() {
        let kind = expected(&p.bytes, p.request);
        for lead in 1..=NOISE.len() {
            let bytes = [&NOISE[..lead], &p.bytes].concat();
            assert_eq!(
                whole(&bytes),
                [(SpanKind::Noise, 0, lead), (kind, lead, bytes.len())],
                "{} behind {lead} noise byte(s): {}",
                p.what,
                Hex(&bytes)
            );
        }
    }
}

#[test]
fn an_exchange_with_noise_around_is_its_two_frames_and_the_noise() {
    for (what, request, reply) in exchanges() {
        let bytes = [&NOISE[..], &request, &NOISE, &reply, &NOISE].concat();
        let (a, b) = (NOISE.len(), NOISE.len() + request.len());
        let (c, d) = (b + NOISE.len(), b + NOISE.len() + reply.len());
        let want = [
            (SpanKind::Noise, 0, a),
            (expected(&request, true), a, b),
            (SpanKind::Noise, b, c),
            (expected(&reply, false), c, d),
            (SpanKind::Noise, d, bytes.len()),
        ];
        assert_eq!(whole(&bytes), want, "{what}: {}", Hex(&bytes));
        // Without noise, back to back.
        let bytes = [&request[..], &reply].concat();
        let want =
            [(expected(&request, true), 0, request.len()), (expected(&reply, false), request.len(), bytes.len())];
        assert_eq!(whole(&bytes), want, "{what}: {}", Hex(&bytes));
    }
}

#[test]
fn chunks_of_every_size_give_the_spans_of_the_whole() {
    for (what, request, reply) in exchanges() {
        let bytes = [&NOISE[..], &request, &reply, &NOISE[..2], &request[..5]].concat();
        let all = whole(&bytes);
        assert!(all.len() >= 4, "{what}: {all:?}");
        for size in 1..=bytes.len() {
            let cuts: Vec<usize> = (size..bytes.len()).step_by(size).collect();
            assert_eq!(streamed(&bytes, &cuts), all, "{what}, chunks of {size}: {}", Hex(&bytes));
        }
    }
}

#[test]
fn a_frame_cut_short_waits_for_its_bytes() {
    for p in printed_frames() {
        for cut in 1..p.bytes.len() {
            assert!(next_span(&p.bytes[..cut]).is_err(), "{}: {cut} of {} bytes taken", p.what, p.bytes.len());
        }
    }
}

/// Every exchange of the spec, back to back with noise between: one stream.
fn all_exchanges() -> Vec<u8> {
    exchanges().into_iter().flat_map(|(_, request, reply)| [&request[..], &reply, &NOISE].concat()).collect()
}

proptest! {
    #[test]
    fn random_chunks_of_the_manuals_exchanges_give_the_spans_of_the_whole(
        cuts in proptest::collection::vec(0usize..4096, 0..64)
    ) {
        let bytes = all_exchanges();
        let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c % bytes.len()).collect();
        cuts.sort_unstable();
        prop_assert_eq!(streamed(&bytes, &cuts), whole(&bytes));
    }

    #[test]
    fn any_bytes_are_covered_exactly_and_alike_in_chunks(
        bytes in proptest::collection::vec(any::<u8>(), 0..700),
        cuts in proptest::collection::vec(0usize..700, 0..16),
    ) {
        let all = whole(&bytes);
        let mut at = 0;
        for &(kind, start, end) in &all {
            prop_assert_eq!(start, at);
            prop_assert!(end > start);
            if kind.is_frame() {
                prop_assert!(yosemitech_rtu::crc_ok(&bytes[start..end]), "{:?} {}", kind, Hex(&bytes[start..end]));
            }
            at = end;
        }
        prop_assert_eq!(at, bytes.len());
        let mut cuts = cuts;
        cuts.sort_unstable();
        prop_assert_eq!(streamed(&bytes, &cuts), all);
    }

    #[test]
    fn frames_in_any_bytes_are_found(
        lead in proptest::collection::vec(any::<u8>(), 0..40),
        pick in any::<proptest::sample::Index>(),
    ) {
        // A frame of the manuals behind arbitrary bytes: found whole at its
        // place, unless the bytes before it make a frame that runs into it.
        let frames = printed_frames();
        let p = pick.get(&frames);
        let bytes = [&lead[..], &p.bytes].concat();
        let all = whole(&bytes);
        let overlapping = all.iter().any(|&(kind, start, end)| kind.is_frame() && start < lead.len() && end > lead.len());
        if !overlapping {
            let kind = expected(&p.bytes, p.request);
            prop_assert!(all.contains(&(kind, lead.len(), bytes.len())), "{}: {:?} in {}", p.what, all, Hex(&bytes));
        }
    }
}

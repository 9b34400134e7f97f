//! Golden tests: every frame the manuals print (and the fixture spec's
//! frames), replayed through the generated codecs.
//!
//! The frames and the values the manuals state come from the spec at test
//! time; each command is reached through its module's generated dispatch
//! (`CommandId::from_name`, `decode_request`, `decode_response`, `encode`),
//! so no command is listed here. For every example:
//!
//! - the request decodes to the stated values (writes) and the generated
//!   code encodes those values back to exactly the printed bytes, CRC
//!   included;
//! - the reply decodes to the stated values and encodes back to the true
//!   reply;
//! - errata are checked both ways: a printed frame the spec marks as
//!   decodable (E4, byte count 0x0C) decodes, one it marks as wrong (E5, no
//!   CRC) is rejected with a typed error, and every corrected frame decodes.

use yosemitech_tests::codec as codec_common;

use codec_common::{Decoded, sensors};
use yosemitech_rtu::FrameError;

fn hex(bytes: &[u8]) -> String {
    yosemitech_rtu::Hex(bytes).to_string()
}

fn check_values(what: &str, decoded: &Decoded, stated: &std::collections::BTreeMap<String, yosemitech_spec::Value>) {
    let names: Vec<&str> = decoded.values.iter().map(|(n, _)| *n).collect();
    let stated_names: Vec<&str> = stated.keys().map(String::as_str).collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(sorted, stated_names, "{what}: decoded fields vs the manual's stated values");
    for (name, value) in &decoded.values {
        let want = &stated[*name];
        assert!(value.same_as(want), "{what}: `{name}` decodes to {value:?}, the manual states {want}");
    }
}

/// What a partial printed frame states: each known byte of its header
/// (slave, function, then address and count, or the byte count) is what the
/// command sends.
fn check_partial_header(what: &str, frame: &yosemitech_spec::PrintedFrame, head: &[u8]) {
    for (i, want) in head.iter().enumerate() {
        if let Some(got) = frame.byte(i) {
            assert_eq!(got, *want, "{what}: byte {i} of the printed frame");
        }
    }
}

#[test]
fn every_printed_frame_replays() {
    let mut frames = 0usize;
    let mut partial = 0usize;
    let mut examples = 0usize;
    let mut commands = 0usize;
    let mut errata = Vec::new();
    let sensors = sensors();
    let mut fixture_frames = 0usize;
    for (api, sensor) in &sensors {
        let before = frames;
        for spec_cmd in &sensor.commands {
            let cmd = api.commands.iter().find(|c| c.name == spec_cmd.name).expect("checked by sensors()");
            commands += 1;
            for (i, ex) in spec_cmd.examples.iter().enumerate() {
                examples += 1;
                let what = format!("{}.{} example {} (figures {:?})", sensor.name, spec_cmd.name, i + 1, ex.figures);
                let no_values = std::collections::BTreeMap::new();
                let request_values = if spec_cmd.is_read() { &no_values } else { &ex.values };
                let response_values = if spec_cmd.is_read() { &ex.values } else { &no_values };
                let slave = ex.slave();
                let layout = cmd.layout;

                // The request, as printed (its CRC computed where the manual prints none).
                if let Some(printed) = &ex.request {
                    let printed_request_ok = ex.erratum.as_ref().is_none_or(|e| e.corrected_request.is_none());
                    match &printed.complete {
                        Some(request) if printed_request_ok => {
                            frames += 1;
                            let decoded = (cmd.decode_request)(request)
                                .unwrap_or_else(|e| panic!("{what}: request {} fails: {e}", hex(request)));
                            assert_eq!(decoded.slave, slave, "{what}: slave");
                            check_values(&format!("{what} request"), &decoded, request_values);
                            let encoded =
                                decoded.encoded.as_ref().unwrap_or_else(|e| panic!("{what}: cannot encode: {e}"));
                            assert_eq!(hex(encoded), hex(request), "{what}: the stated values encode to the request");
                            assert_eq!((cmd.identify)(request), Some(cmd.name), "{what}: identify_request");
                            if !printed.crc_printed {
                                // As printed, without its CRC, the frame is refused.
                                assert!((cmd.decode_request)(&request[..request.len() - 2]).is_err(), "{what}");
                            }
                        }
                        Some(request) => {
                            frames += 1;
                            assert!(
                                (cmd.decode_request)(request).is_err(),
                                "{what}: the printed request is wrong but decodes"
                            );
                        }
                        None => {
                            partial += 1;
                            let mut head = vec![layout.fixed_slave.unwrap_or(slave), layout.function.code()];
                            head.extend(layout.address.to_be_bytes());
                            head.extend(layout.count.to_be_bytes());
                            check_partial_header(&what, printed, &head);
                        }
                    }
                }
                if let Some(fixed) = ex.erratum.as_ref().and_then(|e| e.corrected_request.as_deref()) {
                    frames += 1;
                    let decoded =
                        (cmd.decode_request)(fixed).unwrap_or_else(|e| panic!("{what}: corrected request: {e}"));
                    check_values(&format!("{what} corrected request"), &decoded, request_values);
                    assert_eq!(decoded.encoded.as_deref().ok(), Some(fixed), "{what}: corrected request re-encodes");
                }

                // The reply, as printed, then corrected.
                let Some(printed) = &ex.response else { continue };
                let corrected = ex.erratum.as_ref().filter(|e| e.corrected_response.is_some());
                match (&printed.complete, corrected) {
                    (Some(reply), Some(err)) => {
                        frames += 1;
                        errata.push(format!("{} {}", sensor.name, err.id));
                        let result = (cmd.decode_response)(slave, reply);
                        if err.printed_decodes {
                            let decoded = result.unwrap_or_else(|e| {
                                panic!("{what}: erratum {}: the printed reply should decode: {e}", err.id)
                            });
                            check_values(&format!("{what} printed reply"), &decoded, response_values);
                        } else {
                            let e = result.expect_err("the spec says the printed reply must not decode");
                            println!("{what}: erratum {}: printed reply {} rejected: {e}", err.id, hex(reply));
                        }
                    }
                    (Some(reply), None) => {
                        frames += 1;
                        let decoded = (cmd.decode_response)(slave, reply)
                            .unwrap_or_else(|e| panic!("{what}: reply {} fails: {e}", hex(reply)));
                        check_values(&format!("{what} reply"), &decoded, response_values);
                        if !spec_cmd.trigger {
                            assert_eq!(
                                hex(decoded.encoded.as_deref().unwrap()),
                                hex(reply),
                                "{what}: the stated values encode to the reply"
                            );
                        }
                        if !printed.crc_printed {
                            assert!((cmd.decode_response)(slave, &reply[..reply.len() - 2]).is_err(), "{what}");
                        }
                    }
                    (None, _) => {
                        partial += 1;
                        let reply_slave = layout.fixed_slave.unwrap_or(slave);
                        let mut head = vec![reply_slave, layout.function.code()];
                        if spec_cmd.is_read() {
                            // The byte count the manual prints must be one the command accepts.
                            let count = printed.byte(2).unwrap_or((2 * layout.count) as u8);
                            assert!(layout.accepts_byte_count(count), "{what}: printed byte count 0x{count:02X}");
                            head.push(count);
                            if layout.trigger && count == 0 {
                                // What the manual states of a trigger's reply, completed with
                                // no data and its CRC, is accepted.
                                let mut short = head.clone();
                                short.extend(yosemitech_rtu::crc16(&short).to_le_bytes());
                                (cmd.decode_response)(slave, &short)
                                    .unwrap_or_else(|e| panic!("{what}: the stated trigger reply: {e}"));
                            }
                        } else {
                            head.extend(layout.address.to_be_bytes());
                            head.extend(layout.count.to_be_bytes());
                        }
                        check_partial_header(&what, printed, &head);
                    }
                }
                if let Some(fixed) = ex.erratum.as_ref().and_then(|e| e.corrected_response.as_deref()) {
                    frames += 1;
                    let decoded =
                        (cmd.decode_response)(slave, fixed).unwrap_or_else(|e| panic!("{what}: corrected reply: {e}"));
                    check_values(&format!("{what} corrected reply"), &decoded, response_values);
                    assert_eq!(
                        hex(decoded.encoded.as_deref().unwrap()),
                        hex(fixed),
                        "{what}: the values encode to the corrected reply"
                    );
                }
            }
        }
        if yosemitech::SENSORS.iter().all(|m| m.info.name != sensor.name) {
            fixture_frames += frames - before;
        }
    }
    let manual_frames = frames - fixture_frames;
    let summary = codec_common::generated_spec().summary();
    yosemitech_tests::report!(
        "golden: replayed {frames} complete frames ({manual_frames} from the manuals, {fixture_frames} from the fixture spec) \
         and checked {partial} partial ones; {examples} examples of {commands} commands, {} sensors; errata checked: {}",
        sensors.len(),
        errata.join(", ")
    );
    assert_eq!(examples, summary.examples, "every example of the spec was visited");
    assert_eq!(commands, summary.commands, "every command of the spec was visited");
    assert!(manual_frames > 0 && fixture_frames > 0);
}

/// `frame` with its CRC recomputed over the rest.
fn recrc(frame: &[u8]) -> Vec<u8> {
    yosemitech_tests::with_crc(&frame[..frame.len() - 2])
}

/// Every reply erratum, both ways, through the generated codecs: a printed
/// reply the spec says decodes (a byte count the command also accepts)
/// decodes to the values of its correction and encodes to the correction,
/// with the Modbus-correct count; a printed reply the spec says must not
/// decode, read with the corrected bytes where it prints none, is refused
/// as truncated when it lacks bytes of the correction (its CRC).
#[test]
fn reply_errata_both_ways() {
    let (mut accepted, mut refused) = (0, 0);
    for (api, sensor) in &sensors() {
        for spec_cmd in &sensor.commands {
            let cmd = api.commands.iter().find(|c| c.name == spec_cmd.name).expect("checked by sensors()");
            for ex in &spec_cmd.examples {
                let (Some(printed), Some(err)) = (&ex.response, &ex.erratum) else { continue };
                let Some(corrected) = err.corrected_response.as_deref() else { continue };
                let what = format!("{}.{} erratum {}", sensor.name, spec_cmd.name, err.id);
                let slave = ex.slave();
                let truth = (cmd.decode_response)(slave, corrected).unwrap_or_else(|e| panic!("{what}: {e}"));
                if err.printed_decodes {
                    let reply = printed.complete.as_deref().expect("a printed reply that decodes is complete");
                    let decoded = (cmd.decode_response)(slave, reply).unwrap_or_else(|e| panic!("{what}: {e}"));
                    assert_eq!(decoded.values, truth.values, "{what}: the printed and the corrected values");
                    let encoded = decoded.encoded.as_deref().unwrap_or_else(|e| panic!("{what}: {e}"));
                    assert_eq!(hex(encoded), hex(corrected), "{what}: encoding writes the corrected frame");
                    accepted += 1;
                } else {
                    let reply: Vec<u8> =
                        (0..printed.bytes.len()).map(|i| printed.byte(i).unwrap_or(corrected[i])).collect();
                    let result = (cmd.decode_response)(slave, &reply);
                    assert!(result.is_err(), "{what}: {} decodes", hex(&reply));
                    if reply.len() < corrected.len() {
                        let truncated = FrameError::Truncated { expected: corrected.len(), actual: reply.len() };
                        assert_eq!(result.err(), Some(truncated), "{what}: {}", hex(&reply));
                    }
                    refused += 1;
                }
            }
        }
    }
    yosemitech_tests::report!("reply errata: {accepted} printed replies accepted, {refused} refused");
    assert!(
        accepted > 0 && refused > 0,
        "the spec has reply errata of both kinds ({accepted} accepted, {refused} refused)"
    );
}

/// The true reply of one example of a read that carries data.
struct Reply<'a> {
    what: String,
    cmd: &'a codec_common::Cmd,
    spec_cmd: &'a yosemitech_spec::CommandSpec,
    slave: u8,
    frame: &'a [u8],
}

/// The true reply of every example of every read of `sensors` that carries data.
fn true_replies<'a>(sensors: &'a [(codec_common::Api, &'a yosemitech_spec::Sensor)]) -> Vec<Reply<'a>> {
    let mut replies = Vec::new();
    for (api, sensor) in sensors {
        for spec_cmd in sensor.commands.iter().filter(|c| c.is_read() && !c.trigger) {
            let cmd = api.commands.iter().find(|c| c.name == spec_cmd.name).expect("checked by sensors()");
            for ex in &spec_cmd.examples {
                if let Some(frame) = ex.true_response() {
                    let what = format!("{}.{}", sensor.name, spec_cmd.name);
                    replies.push(Reply { what, cmd, spec_cmd, slave: ex.slave(), frame });
                }
            }
        }
    }
    replies
}

/// A read's reply with a byte count the command does not accept is
/// refused, even under a matching CRC; without its CRC it is truncated.
#[test]
fn other_byte_counts_and_missing_crcs_are_refused() {
    let sensors = sensors();
    let replies = true_replies(&sensors);
    let mut refused = 0;
    for Reply { what, cmd, spec_cmd, slave, frame: reply } in &replies {
        let expected = u8::try_from(2 * spec_cmd.count).unwrap();
        for count in (0..=u8::MAX).filter(|&c| !cmd.layout.accepts_byte_count(c)) {
            let mut other = reply.to_vec();
            other[2] = count;
            let result = (cmd.decode_response)(*slave, &recrc(&other));
            assert_eq!(result.err(), Some(FrameError::ByteCount { expected, actual: count }), "{what}: 0x{count:02X}");
            refused += 1;
        }
        let without_crc = &reply[..reply.len() - 2];
        let truncated = FrameError::Truncated { expected: reply.len(), actual: without_crc.len() };
        assert_eq!((cmd.decode_response)(*slave, without_crc).err(), Some(truncated), "{what}: no CRC");
    }
    yosemitech_tests::report!("{} replies, {refused} with another byte count refused", replies.len());
    assert!(refused > 0);
}

/// Every code an enum field names decodes to its name and encodes back;
/// a code it does not name decodes as unknown, kept as read.
#[test]
fn enum_codes_decode_by_name_and_unknown_codes_are_kept() {
    use yosemitech_spec::{EnumRepr, FieldKind};
    let sensors = sensors();
    let mut codes = 0;
    for Reply { what, cmd, spec_cmd, slave, frame: reply } in &true_replies(&sensors) {
        for field in &spec_cmd.fields {
            let FieldKind::Enum { repr, variants } = &field.kind else { continue };
            let name = field.name.as_deref().unwrap();
            // A code no variant names, if the field's size leaves one.
            let top = match repr {
                EnumRepr::U8 => u16::from(u8::MAX),
                EnumRepr::U16(_) => u16::MAX,
            };
            let unnamed = (0..=top).find(|v| variants.iter().all(|x| x.value != *v));
            let named = variants.iter().map(|v| (v.value, Some(v.name.as_str())));
            for (raw, variant) in named.chain(unnamed.map(|u| (u, None))) {
                let mut frame = reply.to_vec();
                let at = 3 + field.offset;
                match repr {
                    EnumRepr::U8 => frame[at] = u8::try_from(raw).unwrap(),
                    EnumRepr::U16(order) => {
                        frame[at..at + 2].copy_from_slice(&yosemitech_rtu::codec::u16_to_wire(*order, raw))
                    }
                }
                let frame = recrc(&frame);
                let decoded = (cmd.decode_response)(*slave, &frame).unwrap_or_else(|e| panic!("{what}: {raw}: {e}"));
                let (_, value) = decoded.values.iter().find(|(n, _)| *n == name).unwrap();
                let codec_common::Val::Enum { raw: got, name: got_name } = value else { panic!("{what}: {value:?}") };
                assert_eq!((*got, *got_name), (raw, variant), "{what}.{name}");
                assert_eq!(decoded.encoded.as_deref().ok(), Some(&frame[..]), "{what}.{name} = {raw}: re-encodes");
                if variant.is_none() {
                    assert_eq!(value.as_field().to_string(), format!("unknown ({raw})"));
                }
                codes += 1;
            }
        }
    }
    yosemitech_tests::report!("enum codes: {codes} decoded by name or kept as unknown");
    assert!(codes > 0, "the spec has enum fields in replies");
}

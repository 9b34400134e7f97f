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

/// The two frame errata of the pH manual, spelled out with the typed API.
#[test]
fn ph_errata_both_ways() {
    use yosemitech::Command;
    use yosemitech::ph_orp::{CalibrationStatus, GetCalibrationStatus, GetPhElectrodeCoefficients};

    // E4 (Fig 54): printed byte count 0x0C over 24 data bytes, CRC computed over 0x0C.
    let printed: [u8; 29] = [
        0x01, 0x03, 0x0C, 0x1F, 0x85, 0xDB, 0x40, 0x3D, 0x0A, 0xD7, 0xC0, 0x0A, 0xD7, 0x23, 0x3D, 0x1F, 0x85, 0xDB,
        0x40, 0x85, 0xEB, 0xD1, 0xC0, 0xB8, 0x1E, 0x85, 0xBF, 0xAB, 0xF5,
    ];
    let mut corrected = printed;
    corrected[2] = 0x18;
    corrected[27..].copy_from_slice(&[0xAA, 0x45]);
    let a = GetPhElectrodeCoefficients::decode_response(1, &printed).expect("E4: 0x0C is accepted");
    let b = GetPhElectrodeCoefficients::decode_response(1, &corrected).expect("the corrected 0x18 frame decodes");
    assert_eq!(a, b);
    assert_eq!([a.k1, a.k2, a.k3, a.k4, a.k5, a.k6], yosemitech::ph_orp::DEFAULT_ELECTRODE_COEFFICIENTS);
    // Any other byte count is refused, even with a matching CRC.
    let mut other = corrected;
    other[2] = 0x17;
    let crc = yosemitech_rtu::crc16(&other[..27]).to_le_bytes();
    other[27..].copy_from_slice(&crc);
    assert_eq!(
        GetPhElectrodeCoefficients::decode_response(1, &other),
        Err(FrameError::ByteCount { expected: 0x18, actual: 0x17 })
    );
    // Encoding always writes the Modbus-correct count.
    let mut out = [0u8; 64];
    let n = GetPhElectrodeCoefficients::encode_response(&a, 1, &mut out).unwrap();
    assert_eq!(out[..n], corrected);

    // E5 (Fig 42): printed without CRC; the status byte is "0".
    let printed = [0x01, 0x03, 0x02, 0x00, 0x00];
    assert_eq!(
        GetCalibrationStatus::decode_response(1, &printed),
        Err(FrameError::Truncated { expected: 7, actual: 5 })
    );
    let corrected = [0x01, 0x03, 0x02, 0x00, 0x00, 0xB8, 0x44];
    let status = GetCalibrationStatus::decode_response(1, &corrected).unwrap().status;
    assert_eq!(status, CalibrationStatus::Success);
    // The other codes of Fig 43 (frames from the datasheet notes, section 5).
    for (frame, want) in [
        ([0x01, 0x03, 0x02, 0x01, 0x00, 0xB9, 0xD4], CalibrationStatus::NotACalibrationStandard),
        ([0x01, 0x03, 0x02, 0x02, 0x00, 0xB9, 0x24], CalibrationStatus::FewerThanThreePoints),
        ([0x01, 0x03, 0x02, 0x04, 0x00, 0xBA, 0x84], CalibrationStatus::CoefficientsOutOfRange),
    ] {
        assert_eq!(GetCalibrationStatus::decode_response(1, &frame).unwrap().status, want);
    }
    assert_eq!(CalibrationStatus::from_raw(6), CalibrationStatus::Unknown(6), "combined flags are kept");
    assert_eq!(CalibrationStatus::from_raw(6).to_string(), "unknown (6)");
}

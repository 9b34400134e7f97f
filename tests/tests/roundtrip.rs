//! Property tests of the generated codecs, for every command of every
//! generated module (reached through `CommandId::ALL`, never listed here):
//!
//! - values round-trip bit-exactly: any register data (with NaN payloads,
//!   infinities, signed zeros and subnormals put into float fields) decodes
//!   to typed values that encode back to the same frame (reserved bytes
//!   normalized to their fill) and decode again to the same bits, for
//!   requests and replies;
//! - decoding arbitrary bytes never panics;
//! - a valid frame with a bit flipped, cut short or with bytes appended
//!   never decodes to `Ok` with different values.

use yosemitech_tests::codec as codec_common;

use codec_common::{Api, Cmd, Decoded, data_strategy, normalized, sensors, usable_slave};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};
use yosemitech_rtu::EncodeError;
use yosemitech_spec::interp::{self, Value};
use yosemitech_spec::{CommandSpec, Field, FieldKind, Sensor};

const CASES: u32 = 256;

fn runner() -> TestRunner {
    TestRunner::new(Config { cases: CASES, failure_persistence: None, ..Config::default() })
}

/// Runs `check` for every command, counting cases.
fn for_each_command(
    name: &str,
    mut check: impl FnMut(&mut TestRunner, &Api, &Sensor, &Cmd, &CommandSpec) -> Result<(), String>,
) {
    let mut commands = 0;
    for (api, sensor) in &sensors() {
        for cmd in &api.commands {
            let spec_cmd = sensor.command(cmd.name).unwrap();
            let mut runner = runner();
            if let Err(e) = check(&mut runner, api, sensor, cmd, spec_cmd) {
                panic!("{name}: {}.{}: {e}", sensor.name, cmd.name);
            }
            commands += 1;
        }
    }
    yosemitech_tests::report!("{name}: {commands} commands x {CASES} cases");
    assert_eq!(commands, codec_common::generated_spec().summary().commands, "every command of the spec");
}

fn same_values(a: &Decoded, b: &Decoded) -> bool {
    a.values == b.values
}

fn fail(msg: String) -> TestCaseError {
    TestCaseError::fail(msg)
}

/// Whether some range-checked field of `data` is outside its range (as the spec says).
fn out_of_range(command: &CommandSpec, data: &[u8]) -> bool {
    let values = yosemitech_spec::interp::decode_fields(command, data);
    let map = values.into_iter().collect();
    matches!(
        yosemitech_spec::interp::encode_fields(command, &map),
        Err(yosemitech_spec::interp::EncodeValuesError::OutOfRange { .. })
    )
}

/// The values of `field`'s type next to `bound`: the nearest f32 and its
/// neighbours, or the integers around it.
fn values_around(field: &Field, bound: f64) -> Vec<Value> {
    match field.kind {
        FieldKind::F32 { .. } => {
            let near = bound as f32;
            [near.next_down(), near, near.next_up()].into_iter().map(Value::Float).collect()
        }
        _ => {
            let (below, above) = (bound.floor() as i64, bound.ceil() as i64);
            [below - 1, below, above, above + 1].into_iter().map(Value::Int).collect()
        }
    }
}

/// A write's range check refuses exactly what the spec refuses, at the very
/// edges of every range (where an inexact comparison would err): for each
/// ranged field of every write, the values next to each bound are checked
/// by the generated codec and by the interpreter, which compares in `f64`.
#[test]
fn range_checks_refuse_exactly_outside_the_spec_range() {
    let mut edges = 0;
    for (api, sensor) in &sensors() {
        for cmd in &api.commands {
            let spec_cmd = sensor.command(cmd.name).unwrap();
            if spec_cmd.is_read() {
                continue;
            }
            let sample = yosemitech_tests::values::sample_values(spec_cmd);
            let data = interp::encode_fields(spec_cmd, &sample).unwrap();
            for field in spec_cmd.fields.iter().filter(|f| f.kind.is_number()) {
                let (Some(name), Some((min, max))) = (field.name.as_deref(), field.range) else { continue };
                let unranged = Field { range: None, ..field.clone() };
                for value in [min, max].into_iter().filter(|b| b.is_finite()).flat_map(|b| values_around(field, b)) {
                    // A value the type cannot hold is no edge of the range.
                    let Ok(bytes) = interp::encode_field(&unranged, &value) else { continue };
                    let mut values = sample.clone();
                    values.insert(name.to_owned(), value.clone());
                    let spec_refuses = matches!(
                        interp::encode_fields(spec_cmd, &values),
                        Err(interp::EncodeValuesError::OutOfRange { .. })
                    );
                    let mut edited = data.clone();
                    edited[field.offset..field.offset + bytes.len()].copy_from_slice(&bytes);
                    let frame = codec_common::request_frame(spec_cmd, usable_slave(spec_cmd, 1), &edited);
                    let decoded = (cmd.decode_request)(&frame).unwrap();
                    let codec_refuses =
                        matches!(decoded.encoded, Err(EncodeError::OutOfRange { field }) if field == name);
                    assert_eq!(
                        codec_refuses, spec_refuses,
                        "{}.{}.{name} = {value:?} (range {min}..={max})",
                        sensor.name, cmd.name
                    );
                    edges += 1;
                }
            }
        }
    }
    yosemitech_tests::report!("range_checks_refuse_exactly_outside_the_spec_range: {edges} values at range edges");
}

#[test]
fn requests_round_trip_bit_exactly() {
    for_each_command("requests_round_trip_bit_exactly", |runner, _, _, cmd, spec_cmd| {
        let strategy = (data_strategy(spec_cmd), 1u8..=247);
        runner
            .run(&strategy, |(data, slave)| {
                let slave = usable_slave(spec_cmd, slave);
                let frame = codec_common::request_frame(spec_cmd, slave, &data);
                let decoded = (cmd.decode_request)(&frame).map_err(|e| fail(format!("{e} decoding a valid frame")))?;
                prop_assert_eq!(decoded.slave, slave);
                match &decoded.encoded {
                    Ok(encoded) => {
                        let want = codec_common::request_frame(spec_cmd, slave, &normalized(spec_cmd, &data));
                        prop_assert_eq!(encoded, &want, "re-encoded frame");
                        let again = (cmd.decode_request)(encoded).map_err(|e| fail(e.to_string()))?;
                        prop_assert!(same_values(&decoded, &again), "{:?} != {:?}", decoded.values, again.values);
                    }
                    Err(EncodeError::OutOfRange { field }) => {
                        prop_assert!(out_of_range(spec_cmd, &data), "`{}` refused but in range", field);
                    }
                    Err(e) => return Err(fail(format!("cannot encode: {e}"))),
                }
                Ok(())
            })
            .map_err(|e| e.to_string())
    });
}

#[test]
fn responses_round_trip_bit_exactly() {
    for_each_command("responses_round_trip_bit_exactly", |runner, _, _, cmd, spec_cmd| {
        let strategy = (data_strategy(spec_cmd), 1u8..=247);
        runner
            .run(&strategy, |(data, slave)| {
                let slave = usable_slave(spec_cmd, slave);
                let frame = codec_common::response_frame(spec_cmd, slave, &data);
                let decoded =
                    (cmd.decode_response)(slave, &frame).map_err(|e| fail(format!("{e} decoding a valid frame")))?;
                let encoded = match &decoded.encoded {
                    Ok(encoded) => encoded,
                    Err(EncodeError::OutOfRange { field }) => {
                        prop_assert!(out_of_range(spec_cmd, &data), "`{}` refused but in range", field);
                        return Ok(());
                    }
                    Err(e) => return Err(fail(format!("cannot encode: {e}"))),
                };
                let want = codec_common::response_frame(spec_cmd, slave, &normalized(spec_cmd, &data));
                prop_assert_eq!(encoded, &want, "re-encoded frame");
                let again = (cmd.decode_response)(slave, encoded).map_err(|e| fail(e.to_string()))?;
                prop_assert!(same_values(&decoded, &again), "{:?} != {:?}", decoded.values, again.values);
                // Float fields keep their exact bits, NaN payloads included.
                for (offset, order, name) in spec_cmd.fields.iter().filter_map(|f| match f.kind {
                    FieldKind::F32 { order } => Some((f.offset, order, f.name.as_deref()?)),
                    _ => None,
                }) {
                    if spec_cmd.is_read() {
                        let bits =
                            yosemitech_rtu::codec::u32_from_wire(order, data[offset..offset + 4].try_into().unwrap());
                        let got = decoded.values.iter().find(|(n, _)| *n == name).map(|(_, v)| v.clone());
                        prop_assert_eq!(got, Some(codec_common::Val::F32(bits)));
                    }
                }
                Ok(())
            })
            .map_err(|e| e.to_string())
    });
}

#[test]
fn decoding_arbitrary_bytes_never_panics() {
    for_each_command("decoding_arbitrary_bytes_never_panics", |runner, _, _, cmd, spec_cmd| {
        let len = spec_cmd.layout().request_len().max(spec_cmd.layout().response_len());
        let strategy = (
            prop_oneof![
                proptest::collection::vec(any::<u8>(), 0..300),
                proptest::collection::vec(any::<u8>(), len.saturating_sub(2)..len + 2),
            ],
            any::<u8>(),
        );
        runner
            .run(&strategy, |(bytes, slave)| {
                let _ = (cmd.decode_request)(&bytes);
                let _ = (cmd.decode_response)(slave, &bytes);
                let _ = (cmd.identify)(&bytes);
                Ok(())
            })
            .map_err(|e| e.to_string())
    });
}

#[derive(Debug, Clone)]
enum Mutation {
    FlipBit { at: usize, bit: u8 },
    Truncate { len: usize },
    Append { bytes: Vec<u8> },
}

fn mutate(frame: &[u8], m: &Mutation) -> Vec<u8> {
    let mut f = frame.to_vec();
    match m {
        Mutation::FlipBit { at, bit } => {
            let at = at % f.len();
            f[at] ^= 1 << (bit % 8);
        }
        Mutation::Truncate { len } => f.truncate(len % f.len()),
        Mutation::Append { bytes } => f.extend_from_slice(bytes),
    }
    f
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, bit)| Mutation::FlipBit { at, bit }),
        any::<usize>().prop_map(|len| Mutation::Truncate { len }),
        proptest::collection::vec(any::<u8>(), 1..8).prop_map(|bytes| Mutation::Append { bytes }),
    ]
}

#[test]
fn mutated_frames_never_decode_to_other_values() {
    let accepted = std::cell::Cell::new(0usize);
    for_each_command("mutated_frames_never_decode_to_other_values", |runner, _, _, cmd, spec_cmd| {
        let strategy = (data_strategy(spec_cmd), 1u8..=247, mutation(), any::<bool>());
        runner
            .run(&strategy, |(data, slave, m, request)| {
                let slave = usable_slave(spec_cmd, slave);
                let (original, mutated) = if request {
                    let frame = codec_common::request_frame(spec_cmd, slave, &data);
                    let original = (cmd.decode_request)(&frame).map_err(|e| fail(e.to_string()))?;
                    (original, (cmd.decode_request)(&mutate(&frame, &m)))
                } else {
                    let frame = codec_common::response_frame(spec_cmd, slave, &data);
                    let original = (cmd.decode_response)(slave, &frame).map_err(|e| fail(e.to_string()))?;
                    (original, (cmd.decode_response)(slave, &mutate(&frame, &m)))
                };
                if let Ok(decoded) = mutated {
                    // Only a mutation the format cannot see may pass (none is
                    // expected: CRC-16 catches every single-bit flip).
                    accepted.set(accepted.get() + 1);
                    prop_assert!(
                        decoded.slave == original.slave && same_values(&decoded, &original),
                        "{:?} decoded to {:?}, was {:?}",
                        m,
                        decoded.values,
                        original.values
                    );
                }
                Ok(())
            })
            .map_err(|e| e.to_string())
    });
    yosemitech_tests::report!("mutated frames accepted (with unchanged values): {}", accepted.get());
}

//! Differential test: the generated codecs against the spec's reference
//! interpreter (`yosemitech_spec::CommandSpec::{decode_request, decode_response,
//! encode_request, encode_response}`), two independent walks of the same
//! spec, for every command of every generated module (through
//! `CommandId::ALL`; none is listed here).
//!
//! On arbitrary frames (noise, valid frames from random register data with
//! special floats, and valid frames with one byte changed) both sides give
//! the same outcome: the same `FrameError`, or the same values bit for bit.
//! On arbitrary values both encode the same frame or both refuse.

use yosemitech_tests::codec as codec_common;

use codec_common::{Cmd, data_strategy, sensors, usable_slave};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};
use yosemitech_spec::CommandSpec;

const CASES: u32 = 512;

/// Valid frames from random register data, and the slave they are for.
fn valid_frames(command: &CommandSpec, request: bool) -> impl Strategy<Value = (Vec<u8>, u8)> + use<> {
    let c = command.clone();
    (data_strategy(command), 1u8..=247).prop_map(move |(data, slave)| {
        let slave = usable_slave(&c, slave);
        let frame = if request {
            codec_common::request_frame(&c, slave, &data)
        } else {
            codec_common::response_frame(&c, slave, &data)
        };
        (frame, slave)
    })
}

/// Frames worth comparing on: valid ones, valid ones with a byte changed, and noise.
fn frame_strategy(command: &CommandSpec, request: bool) -> impl Strategy<Value = (Vec<u8>, u8)> + use<> {
    let len = if request { command.layout().request_len() } else { command.layout().response_len() };
    prop_oneof![
        4 => valid_frames(command, request),
        2 => (valid_frames(command, request), any::<usize>(), any::<u8>()).prop_map(|((mut frame, slave), at, byte)| {
            let at = at % frame.len();
            frame[at] = byte;
            (frame, slave)
        }),
        1 => (proptest::collection::vec(any::<u8>(), len.saturating_sub(3)..len + 3), any::<u8>()),
        1 => (proptest::collection::vec(any::<u8>(), 0..64), any::<u8>()),
    ]
}

fn runner() -> TestRunner {
    TestRunner::new(Config { cases: CASES, failure_persistence: None, ..Config::default() })
}

fn for_each_command(name: &str, mut check: impl FnMut(&mut TestRunner, &Cmd, &CommandSpec) -> Result<(), String>) {
    let mut commands = 0;
    for (api, sensor) in &sensors() {
        for cmd in &api.commands {
            let spec_cmd = sensor.command(cmd.name).unwrap();
            if let Err(e) = check(&mut runner(), cmd, spec_cmd) {
                panic!("{name}: {}.{}: {e}", sensor.name, cmd.name);
            }
            commands += 1;
        }
    }
    yosemitech_tests::report!("{name}: {commands} commands x {CASES} cases agree");
    assert_eq!(commands, codec_common::generated_spec().summary().commands, "every command of the spec");
}

fn fail(msg: String) -> TestCaseError {
    TestCaseError::fail(msg)
}

#[test]
fn decoding_agrees_with_the_interpreter() {
    for_each_command("decoding_agrees_with_the_interpreter", |runner, cmd, spec_cmd| {
        let strategy = (frame_strategy(spec_cmd, true), frame_strategy(spec_cmd, false));
        runner
            .run(&strategy, |((request, _), (reply, slave))| {
                match ((cmd.decode_request)(&request), spec_cmd.decode_request(&request)) {
                    (Ok(ours), Ok((slave, theirs))) => {
                        prop_assert_eq!(ours.slave, slave);
                        prop_assert!(ours.same_values(&theirs), "request: {:?} vs {:?}", ours.values, theirs);
                    }
                    (Err(a), Err(b)) => prop_assert_eq!(a, b, "request errors"),
                    (a, b) => return Err(fail(format!("request outcomes differ: {a:?} vs {b:?}"))),
                }
                match ((cmd.decode_response)(slave, &reply), spec_cmd.decode_response(slave, &reply)) {
                    (Ok(ours), Ok(theirs)) => {
                        prop_assert!(ours.same_values(&theirs), "reply: {:?} vs {:?}", ours.values, theirs);
                    }
                    (Err(a), Err(b)) => prop_assert_eq!(a, b, "reply errors"),
                    (a, b) => return Err(fail(format!("reply outcomes differ: {a:?} vs {b:?}"))),
                }
                Ok(())
            })
            .map_err(|e| e.to_string())
    });
}

#[test]
fn encoding_agrees_with_the_interpreter() {
    let skipped = std::cell::Cell::new(0usize);
    for_each_command("encoding_agrees_with_the_interpreter", |runner, cmd, spec_cmd| {
        let strategy = (data_strategy(spec_cmd), 1u8..=247, proptest::option::of(any::<usize>()));
        runner
            .run(&strategy, |(data, slave, text_len)| {
                let slave = usable_slave(spec_cmd, slave);
                let data = match text_len {
                    Some(len) => codec_common::asciified(spec_cmd, &data, len),
                    None => data,
                };
                // Typed values from arbitrary register data, encoded by both sides.
                let request = (cmd.decode_request)(&codec_common::request_frame(spec_cmd, slave, &data))
                    .map_err(|e| fail(e.to_string()))?;
                let reply = (cmd.decode_response)(slave, &codec_common::response_frame(spec_cmd, slave, &data))
                    .map_err(|e| fail(e.to_string()))?;
                for (what, ours, theirs) in [
                    ("request", &request, request.value_map().map(|m| spec_cmd.encode_request(slave, &m))),
                    ("reply", &reply, reply.value_map().map(|m| spec_cmd.encode_response(slave, &m))),
                ] {
                    let Some(theirs) = theirs else {
                        // Non-ASCII text: the interpreter takes text, `Ascii<N>` keeps raw bytes.
                        skipped.set(skipped.get() + 1);
                        continue;
                    };
                    match (&ours.encoded, theirs) {
                        (Ok(a), Ok(b)) => prop_assert_eq!(a, &b, "{} frames", what),
                        (Err(yosemitech_rtu::EncodeError::OutOfRange { field }), Err(e)) => {
                            prop_assert!(
                                matches!(&e, yosemitech_spec::interp::EncodeValuesError::OutOfRange { field: f, .. } if f == field),
                                "{}: we refuse `{}`, the interpreter says {}",
                                what,
                                field,
                                e
                            );
                        }
                        (a, b) => return Err(fail(format!("{what} encodings differ: {a:?} vs {b:?}"))),
                    }
                }
                Ok(())
            })
            .map_err(|e| e.to_string())
    });
    yosemitech_tests::report!("encodings skipped for non-ASCII text: {}", skipped.get());
}

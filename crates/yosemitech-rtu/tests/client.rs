//! The client against an in-process responder: framing, checks, retries and deadlines.

use std::cell::RefCell;
use std::rc::Rc;
use std::time::{Duration, Instant};

use proptest::prelude::*;
use yosemitech_rtu::{
    CharFormat, Client, ClientConfig, Command, EchoField, EncodeError, Error, ExceptionCode, FrameError, LineTiming,
    ResponderTransport, RetryPolicy, Transport,
};
use yosemitech_tests::behaviour;
use yosemitech_tests::driver::{AnyClient, Driver};
use yosemitech_tests::rtu::{
    Ph, READ_FLOAT_REPLY, READ_FLOAT_REQUEST, ReadAtFixedSlave, ReadFloat, StartMeasurement, float_probe,
};
use yosemitech_tests::with_crc;

/// Requests seen by a responder, with their arrival times.
type Log = Rc<RefCell<Vec<(Instant, Vec<u8>)>>>;

/// A simulated device.
type Device = Box<dyn FnMut(&[u8], &mut Vec<u8>)>;

/// A client on a responder that logs each request and answers with `answer(request_index, request, reply)`.
fn client_with(
    driver: Driver,
    config: ClientConfig,
    mut answer: impl FnMut(usize, &[u8], &mut Vec<u8>) + 'static,
) -> (AnyClient<ResponderTransport<Device>>, Log) {
    let log: Log = Rc::default();
    let seen = Rc::clone(&log);
    let device: Device = Box::new(move |request: &[u8], reply: &mut Vec<u8>| {
        let index = seen.borrow().len();
        seen.borrow_mut().push((Instant::now(), request.to_vec()));
        answer(index, request, reply);
    });
    (AnyClient::with_config(driver, ResponderTransport::new(device), config), log)
}

fn config(retries: u32) -> ClientConfig {
    ClientConfig {
        timeout: Duration::from_millis(50),
        retry: RetryPolicy { retries, backoff: Duration::ZERO, ..RetryPolicy::default() },
        ..ClientConfig::default()
    }
}

fn requests(log: &Log) -> usize {
    log.borrow().len()
}

behaviour! {
    fn float_read_sends_and_decodes_the_manual_frames(driver) {
        // The simulated probe reproduces pH manual Fig 25 byte for byte.
        let mut reply = Vec::new();
        float_probe(1, 7.6, &READ_FLOAT_REQUEST, &mut reply);
        assert_eq!(reply, READ_FLOAT_REPLY);

        let (mut client, log) = client_with(driver, config(0), |_, req, out| float_probe(1, 7.6, req, out));
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(log.borrow()[0].1, READ_FLOAT_REQUEST);
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6, "a second transaction works too");
        assert_eq!(requests(&log), 2);
    }

    fn exception_reply_is_reported_and_not_retried(driver) {
        let exception = with_crc(&[0x01, 0x83, 0x02]);
        let reply = exception.clone();
        let (mut client, log) = client_with(driver, config(3), move |_, _, out| out.extend_from_slice(&reply));
        let err = client.call(1, &ReadFloat).unwrap_err();
        assert!(err.is_exception(), "{err}");
        assert_eq!(err.exception(), Some(ExceptionCode::IllegalDataAddress));
        assert_eq!(
            err.frame_error(),
            Some(FrameError::Exception { function: 0x03, code: ExceptionCode::IllegalDataAddress })
        );
        assert_eq!(client.last_reply(), &exception[..]);
        assert_eq!(requests(&log), 1, "exceptions are not retried");
    }

    fn crc_corruption_is_retried_then_succeeds(driver) {
        let (mut client, log) = client_with(driver, config(1), |i, req, out| {
            float_probe(1, 7.6, req, out);
            if i == 0 {
                out[4] ^= 0x10;
            }
        });
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(requests(&log), 2);
    }

    fn crc_corruption_without_retries_reports_the_bytes(driver) {
        let mut corrupt = READ_FLOAT_REPLY;
        corrupt[4] ^= 0x10;
        let (mut client, log) = client_with(driver, config(0), move |_, _, out| out.extend_from_slice(&corrupt));
        let err = client.call(1, &ReadFloat).unwrap_err();
        assert!(matches!(err.frame_error(), Some(FrameError::Crc { .. })), "{err}");
        assert_eq!(client.last_reply(), &corrupt[..]);
        assert_eq!(requests(&log), 1);
    }

    fn reply_from_another_slave_is_retried_then_reported(driver) {
        let (mut client, log) = client_with(driver, config(2), |_, req, out| {
            let mut as_slave_2 = req.to_vec();
            as_slave_2[0] = 2;
            let as_slave_2 = with_crc(&as_slave_2[..6]);
            float_probe(2, 9.9, &as_slave_2, out);
        });
        let err = client.call(1, &ReadFloat).unwrap_err();
        assert_eq!(err.frame_error(), Some(FrameError::WrongSlave { expected: 1, actual: 2 }), "{err}");
        assert_eq!(client.last_reply().first(), Some(&2));
        assert_eq!(requests(&log), 3, "first attempt and two retries");
        assert_eq!(client.retries(), 2, "the retries are counted");

        // A foreign reply once, then ours.
        let (mut client, log) = client_with(driver, config(1), |i, req, out| {
            if i == 0 {
                out.extend_from_slice(&with_crc(&[0x02, 0x03, 0x04, 0, 0, 0x80, 0x3F]));
            } else {
                float_probe(1, 7.6, req, out);
            }
        });
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(requests(&log), 2);
        assert_eq!(client.retries(), 1, "a call answered after a retry counts it");
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(client.retries(), 0, "each call counts its own");
    }

    fn truncated_reply_times_out_with_the_partial_bytes(driver) {
        let (mut client, log) = client_with(driver, config(0), |_, _, out| out.extend_from_slice(&READ_FLOAT_REPLY[..5]));
        let err = client.call(1, &ReadFloat).unwrap_err();
        match &err {
            Error::Timeout { received, .. } => assert_eq!((*received, client.last_reply()), (5, &READ_FLOAT_REPLY[..5])),
            other => panic!("expected a timeout, got {other:?}"),
        }
        assert!(err.to_string().contains("5 bytes received"), "{err}");
        assert_eq!(requests(&log), 1);
    }

    fn truncated_reply_is_retried_on_timeout(driver) {
        let (mut client, log) = client_with(driver, config(1), |i, req, out| {
            float_probe(1, 7.6, req, out);
            if i == 0 {
                out.truncate(7);
            }
        });
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(requests(&log), 2);
    }

    fn line_noise_before_the_frame_is_skipped(driver) {
        // No retries: the first reply itself must be framed past the noise.
        let (mut client, log) = client_with(driver, config(0), |_, req, out| {
            out.extend_from_slice(&[0x00, 0xFF, 0x01]);
            float_probe(1, 7.6, req, out);
        });
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(requests(&log), 1);

        // An exception reply after noise is still an exception.
        let (mut client, _) = client_with(driver, config(0), |_, _, out| {
            out.push(0x00);
            out.extend_from_slice(&with_crc(&[0x01, 0x83, 0x04]));
        });
        assert_eq!(client.call(1, &ReadFloat).unwrap_err().exception(), Some(ExceptionCode::ServerDeviceFailure));
    }

    fn reply_arriving_one_byte_per_read_is_reassembled(driver) {
        let (client, _) = client_with(driver, config(0), |_, req, out| float_probe(1, 7.6, req, out));
        let mut transport = client.into_transport().with_read_chunk(1);
        transport.set_read_chunk(1);
        let mut client = AnyClient::with_config(driver, transport, config(0));
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(client.call_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT).unwrap(), READ_FLOAT_REPLY);
    }

    fn silent_device_times_out_at_the_deadline(driver) {
        let timeout = Duration::from_millis(200);
        let (mut client, log) = client_with(driver, ClientConfig { timeout, ..config(0) }, |_, _, _| {});
        let start = Instant::now();
        let err = client.call(1, &ReadFloat).unwrap_err();
        let elapsed = start.elapsed();
        assert!(matches!(&err, Error::Timeout { received: 0, .. }), "{err:?}");
        // The error names what went unanswered: the slave and the command.
        assert_eq!(err.to_string(), format!("no reply from slave 1 to {} before the timeout", ReadFloat::NAME));
        assert!(elapsed >= timeout, "returned before the deadline: {elapsed:?}");
        assert!(elapsed < timeout + Duration::from_secs(2), "deadline overrun: {elapsed:?}");
        assert_eq!(requests(&log), 1);
    }

    fn retries_each_get_a_full_timeout_and_backoff(driver) {
        let timeout = Duration::from_millis(40);
        let backoff = Duration::from_millis(30);
        let config =
            ClientConfig { timeout, retry: RetryPolicy { retries: 2, backoff, ..RetryPolicy::default() }, ..config(0) };
        let (mut client, log) = client_with(driver, config, |_, _, _| {});
        let start = Instant::now();
        assert!(client.call(1, &ReadFloat).unwrap_err().is_timeout());
        let elapsed = start.elapsed();
        assert_eq!(requests(&log), 3);
        assert!(elapsed >= 3 * timeout + 2 * backoff, "{elapsed:?}");
        assert!(elapsed < 3 * timeout + 2 * backoff + Duration::from_secs(3), "{elapsed:?}");
        let log = log.borrow();
        assert!(log[1].0 - log[0].0 >= timeout + backoff, "backoff between attempts");

        // A policy that does not retry timeouts.
        let no_timeouts = RetryPolicy { retries: 5, on_timeout: false, ..RetryPolicy::default() };
        let (mut client, log) = client_with(driver, ClientConfig { retry: no_timeouts, ..config }, |_, _, _| {});
        assert!(client.call(1, &ReadFloat).unwrap_err().is_timeout());
        assert_eq!(requests(&log), 1);
    }

    fn write_echo_mismatch_is_reported_and_not_retried(driver) {
        let bad_echo = with_crc(&[0x01, 0x10, 0x1C, 0x01, 0x00, 0x00]);
        let reply = bad_echo.clone();
        let (mut client, log) = client_with(driver, config(3), move |_, _, out| out.extend_from_slice(&reply));
        let err = client.call(1, &StartMeasurement).unwrap_err();
        assert_eq!(
            err.frame_error(),
            Some(FrameError::EchoMismatch { field: EchoField::Address, expected: 0x1C00, actual: 0x1C01 }),
            "{err}"
        );
        assert_eq!(client.last_reply(), &bad_echo[..]);
        assert_eq!(requests(&log), 1);

        let (mut client, log) = client_with(driver, config(0), |_, req, out| float_probe(1, 7.6, req, out));
        client.call(1, &StartMeasurement).unwrap();
        // Conductivity manual Fig 23: the zero-register write.
        assert_eq!(log.borrow()[0].1, [0x01, 0x10, 0x1C, 0x00, 0x00, 0x00, 0x00, 0xD8, 0x92]);
    }

    fn broadcast_sends_without_waiting_and_call_refuses_slave_0(driver) {
        let turnaround = Duration::from_millis(60);
        let config = ClientConfig { broadcast_turnaround: turnaround, timeout: Duration::from_secs(5), ..config(0) };
        let (mut client, log) = client_with(driver, config, |_, req, out| float_probe(1, 7.6, req, out));

        let start = Instant::now();
        client.broadcast(&StartMeasurement).unwrap();
        assert!(start.elapsed() < Duration::from_secs(5), "a broadcast does not wait for a reply");
        assert_eq!(log.borrow()[0].1, with_crc(&[0x00, 0x10, 0x1C, 0x00, 0x00, 0x00, 0x00]));

        let before = requests(&log);
        assert!(matches!(client.call(0, &StartMeasurement), Err(Error::Encode(EncodeError::InvalidSlave { slave: 0 }))));
        assert!(matches!(client.broadcast(&ReadFloat), Err(Error::Encode(EncodeError::InvalidSlave { slave: 0 }))));
        assert_eq!(requests(&log), before, "refused requests send nothing");

        // The next request keeps the turnaround after the broadcast.
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        let log = log.borrow();
        assert!(log[1].0 - log[0].0 >= turnaround, "{:?}", log[1].0 - log[0].0);
    }

    fn a_fixed_slave_read_uses_its_fixed_address(driver) {
        let (mut client, log) = client_with(driver, config(0), |_, req, out| float_probe(7, 7.6, req, out));
        assert_eq!(client.call(0xFF, &ReadAtFixedSlave).unwrap(), 7);
        assert_eq!(log.borrow()[0].1[0], 0xFF);
        assert!(matches!(client.call(7, &ReadAtFixedSlave), Err(Error::Encode(EncodeError::InvalidSlave { slave: 7 }))));
        assert_eq!(requests(&log), 1);
    }

    fn call_raw_frames_and_checks_like_call(driver) {
        let (mut client, log) = client_with(driver, config(1), |i, req, out| {
            float_probe(1, 7.6, req, out);
            if i == 0 {
                out[3] ^= 1;
            }
        });
        assert_eq!(client.call_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT).unwrap(), READ_FLOAT_REPLY, "retried past a CRC error");
        assert_eq!(requests(&log), 2);

        let mut bad = READ_FLOAT_REQUEST;
        bad[7] ^= 1;
        assert!(matches!(client.call_raw(&bad, &ReadFloat::LAYOUT), Err(Error::Request(FrameError::Crc { .. }))));
        let other_register = with_crc(&[0x01, 0x03, 0x28, 0x01, 0x00, 0x02]);
        assert!(matches!(
            client.call_raw(&other_register, &ReadFloat::LAYOUT),
            Err(Error::Request(FrameError::EchoMismatch { .. }))
        ));
        let broadcast = with_crc(&[0x00, 0x10, 0x1C, 0x00, 0x00, 0x00, 0x00]);
        assert!(matches!(
            client.call_raw(&broadcast, &StartMeasurement::LAYOUT),
            Err(Error::Encode(EncodeError::InvalidSlave { slave: 0 }))
        ));
        assert_eq!(requests(&log), 2, "invalid raw requests are not sent");
        client.broadcast_raw(&broadcast, &StartMeasurement::LAYOUT).unwrap();
        assert_eq!(log.borrow()[2].1, broadcast);
        assert!(client.broadcast_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT).is_err());

        // Exceptions come back as errors with the frame.
        let (mut client, _) = client_with(driver, config(0), |_, _, out| out.extend_from_slice(&with_crc(&[0x01, 0x83, 0x02])));
        assert!(client.call_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT).unwrap_err().is_exception());
    }

    fn stale_input_is_discarded_before_each_request(driver) {
        // The first reply is followed by a stray frame that would decode as 1.0.
        let (mut client, _) = client_with(driver, config(0), |i, req, out| {
            float_probe(1, if i == 0 { 7.6 } else { 8.0 }, req, out);
            if i == 0 {
                float_probe(1, 1.0, req, out);
            }
        });
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert!(!client.transport().pending().is_empty(), "the stray frame is waiting");
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 8.0);
    }

    fn inter_frame_delay_follows_the_line(driver) {
        let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
        let (client, _) = client_with(driver, config(0), |_, req, out| float_probe(1, 7.6, req, out));
        assert_eq!(client.inter_frame_delay(), Duration::ZERO, "no line timing: no wait");
        let transport = client.into_transport().with_line_timing(Some(line));
        let mut client = AnyClient::with_config(driver, transport, config(0));
        assert_eq!(client.inter_frame_delay(), Duration::from_millis(4), "t3.5 = 3.65 ms raised to the 4 ms floor");
        client.config_mut().min_inter_frame_delay = Duration::ZERO;
        assert_eq!(client.inter_frame_delay(), line.t3_5());
        client.config_mut().inter_frame_delay = Some(Duration::from_millis(30));
        assert_eq!(client.inter_frame_delay(), Duration::from_millis(30));

        // Two requests in a row are at least the delay apart (the reply is instant here).
        let log: Log = Rc::default();
        let seen = Rc::clone(&log);
        let transport = ResponderTransport::from_fn(move |req: &[u8], out: &mut Vec<u8>| {
            seen.borrow_mut().push((Instant::now(), req.to_vec()));
            float_probe(1, 7.6, req, out);
        })
        .with_line_timing(Some(line));
        let mut client = AnyClient::with_config(driver,
            transport,
            ClientConfig { inter_frame_delay: Some(Duration::from_millis(30)), ..config(0) },
        );
        client.call(1, &ReadFloat).unwrap();
        client.call(1, &ReadFloat).unwrap();
        let log = log.borrow();
        assert!(log[1].0 - log[0].0 >= Duration::from_millis(30), "{:?}", log[1].0 - log[0].0);
    }
}

#[test]
fn works_through_a_boxed_trait_object() {
    let transport: Box<dyn Transport> =
        Box::new(ResponderTransport::from_fn(|req: &[u8], out: &mut Vec<u8>| float_probe(1, 7.6, req, out)));
    let mut client = Client::with_config(transport, config(0));
    assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
}

/// Replies a device might send: noise, and the manual's frame mutated.
fn replies() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..40),
        (
            proptest::collection::vec(any::<u8>(), 0..4),
            0usize..9,
            any::<u8>(),
            0usize..=9,
            proptest::collection::vec(any::<u8>(), 0..12),
        )
            .prop_map(|(prefix, at, xor, keep, suffix)| {
                let mut frame = READ_FLOAT_REPLY;
                frame[at] ^= xor;
                let mut reply = prefix;
                reply.extend_from_slice(&frame[..keep]);
                reply.extend_from_slice(&suffix);
                reply
            }),
        Just(READ_FLOAT_REPLY.to_vec()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Whatever the device sends, the client returns without panicking; a
    /// value only comes from a valid frame present in the reply; error bytes
    /// are what was sent.
    #[test]
    fn arbitrary_replies_never_yield_a_value_without_a_valid_frame(
        reply in replies(),
        driver in prop_oneof![Just(Driver::Blocking), Just(Driver::Tokio)],
    ) {
        let sent = reply.clone();
        let config = ClientConfig { timeout: Duration::from_millis(2), ..config(0) };
        let (mut client, _) = client_with(driver, config, move |_, _, out| out.extend_from_slice(&sent));
        match client.call(1, &ReadFloat) {
            Ok(Ph(value)) => {
                let found = reply.windows(READ_FLOAT_REPLY.len()).any(|candidate| {
                    ReadFloat::decode_response(1, candidate).is_ok_and(|v| v.0.to_bits() == value.to_bits())
                });
                prop_assert!(found, "value {value} from {reply:02X?} without a valid frame in it");
            }
            Err(Error::Timeout { received, .. }) => {
                let bytes = client.last_reply();
                prop_assert_eq!(bytes.len(), received);
                prop_assert!(reply.starts_with(bytes), "{bytes:02X?} is not what was sent");
            }
            Err(Error::Frame { error }) => {
                let raw = client.last_reply();
                prop_assert!(!matches!(error, FrameError::Truncated { .. } | FrameError::TooLong { .. }), "{error}");
                prop_assert!(reply.windows(raw.len()).any(|w| w == raw), "{raw:02X?} is not what was sent");
            }
            Err(other) => prop_assert!(false, "unexpected error {other}"),
        }
        if reply == READ_FLOAT_REPLY {
            prop_assert_eq!(client.call(1, &ReadFloat).ok(), Some(Ph(7.6)));
        }
    }
}

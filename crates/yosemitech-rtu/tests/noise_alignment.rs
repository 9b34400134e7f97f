//! Noise before a reply whose slave address looks like a function code.
//!
//! The client skips bytes until the byte after them is the expected function
//! (or exception) code. A slave at address 3 answers a read (function 0x03)
//! with `03 03 ...`, so one byte of noise before the reply (`AA 03 03 ...`)
//! already has a function code in second place: the frame would be taken to
//! start at the noise. The same holds for address 16 and writes (0x10), and
//! for addresses 0x83 (131) and 0x90 (144), which look like the exception
//! codes of those functions. The client must still find the real frame, and
//! a reply that is really corrupt must still be reported as such, promptly.

use std::time::{Duration, Instant};

use yosemitech_rtu::transport::AsyncLink;
use yosemitech_rtu::{ClientConfig, Error, ExceptionCode, FrameError, ResponderTransport, RetryPolicy};
use yosemitech_tests::behaviour;
use yosemitech_tests::driver::{AnyClient, Driver};
use yosemitech_tests::rtu::{READ_FLOAT_REQUEST, ReadFloat, StartMeasurement, float_probe};
use yosemitech_tests::with_crc;

const TIMEOUT: Duration = Duration::from_millis(200);

/// A client without retries on a pH probe at `address` that puts `noise`
/// before every reply, handing out `chunk` bytes per read.
fn noisy_probe(
    driver: Driver,
    address: u8,
    noise: &'static [u8],
    chunk: usize,
) -> AnyClient<impl yosemitech_rtu::Transport + AsyncLink> {
    let transport = ResponderTransport::from_fn(move |request: &[u8], reply: &mut Vec<u8>| {
        reply.extend_from_slice(noise);
        float_probe(address, 7.6, request, reply);
    })
    .with_read_chunk(chunk);
    let config = ClientConfig { timeout: TIMEOUT, retry: RetryPolicy::NONE, ..ClientConfig::default() };
    AnyClient::with_config(driver, transport, config)
}

/// Noise patterns: one byte, the slave's own address, the function code,
/// and runs of both.
const NOISE: [&[u8]; 6] = [&[0xAA], &[0x00], &[0x03], &[0x03, 0x03], &[0x10, 0x03, 0x03], &[0xFF, 0x83, 0x90, 0x10]];

behaviour! {
    fn read_from_slave_3_after_noise(driver) {
        for noise in NOISE {
            for chunk in [1, 2, 3, usize::MAX] {
                let mut client = noisy_probe(driver, 3, noise, chunk);
                let result = client.call(3, &ReadFloat);
                assert!(matches!(result, Ok(v) if v == 7.6), "noise {noise:02X?}, chunk {chunk}: {result:?}");
            }
        }
    }

    fn write_to_slave_16_after_noise(driver) {
        for noise in [&[0xAA][..], &[0x10], &[0x10, 0x10], &[0x03, 0x10, 0x90]] {
            for chunk in [1, usize::MAX] {
                let noise: &'static [u8] = noise;
                let mut client = noisy_probe(driver, 16, noise, chunk);
                let result = client.call(16, &StartMeasurement);
                assert!(result.is_ok(), "noise {noise:02X?}, chunk {chunk}: {result:?}");
            }
        }
    }

    fn slaves_that_look_like_exception_codes(driver) {
        // 0x83 = 131 answering a read, 0x90 = 144 answering a write.
        for noise in NOISE {
            let mut client = noisy_probe(driver, 0x83, noise, usize::MAX);
            let result = client.call(0x83, &ReadFloat);
            assert!(matches!(result, Ok(v) if v == 7.6), "0x83, noise {noise:02X?}: {result:?}");
            let mut client = noisy_probe(driver, 0x90, noise, 1);
            let result = client.call(0x90, &StartMeasurement);
            assert!(result.is_ok(), "0x90, noise {noise:02X?}: {result:?}");
        }
    }

    fn every_slave_address_after_function_code_noise(driver) {
        for address in 1..=247u8 {
            for noise in [&[0x03][..], &[0x00, 0x03], &[address], &[0x83]] {
                let noise: &'static [u8] = Box::leak(noise.to_vec().into_boxed_slice());
                let mut client = noisy_probe(driver, address, noise, usize::MAX);
                let result = client.call(address, &ReadFloat);
                assert!(matches!(result, Ok(v) if v == 7.6), "slave {address}, noise {noise:02X?}: {result:?}");
            }
        }
    }

    fn an_exception_from_slave_3_after_noise_is_still_an_exception(driver) {
        let transport = ResponderTransport::from_fn(|_: &[u8], reply: &mut Vec<u8>| {
            reply.extend_from_slice(&[0xAA, 0x03]);
            reply.extend_from_slice(&with_crc(&[0x03, 0x83, 0x06]));
        });
        let config = ClientConfig { timeout: TIMEOUT, retry: RetryPolicy::NONE, ..ClientConfig::default() };
        let mut client = AnyClient::with_config(driver, transport, config);
        let error = client.call(3, &ReadFloat).unwrap_err();
        assert_eq!(error.exception(), Some(ExceptionCode::ServerDeviceBusy), "{error}");
    }

    fn a_corrupt_reply_from_slave_3_is_still_reported_promptly(driver) {
        // The reply's CRC is wrong and nothing follows it: a CRC error, long
        // before the timeout (the client may wait a moment for more bytes).
        for noise in [&[][..], &[0xAA], &[0x03]] {
            let transport = ResponderTransport::from_fn(move |request: &[u8], reply: &mut Vec<u8>| {
                reply.extend_from_slice(noise);
                let start = reply.len();
                float_probe(3, 7.6, request, reply);
                let last = reply.len() - 1;
                reply[last] ^= 0xFF;
                assert!(reply.len() > start);
            });
            let config = ClientConfig { timeout: TIMEOUT, retry: RetryPolicy::NONE, ..ClientConfig::default() };
            let mut client = AnyClient::with_config(driver, transport, config);
            let started = Instant::now();
            let error = client.call(3, &ReadFloat).unwrap_err();
            let took = started.elapsed();
            assert!(matches!(error, Error::Frame { error: FrameError::Crc { .. }, .. }), "noise {noise:02X?}: {error}");
            assert!(took < TIMEOUT / 2, "noise {noise:02X?}: took {took:?}");
            // The next call (the device is fixed) recovers.
            let mut client = noisy_probe(driver, 3, noise, usize::MAX);
            assert_eq!(client.call(3, &ReadFloat).unwrap(), 7.6);
        }
    }

    fn an_echoed_request_before_the_reply_is_reported_not_skipped(driver) {
        // The bytes before the reply are a whole frame (here our own request,
        // echoed): that is a misconfigured bus, not noise, and stays an error.
        let transport = ResponderTransport::from_fn(|request: &[u8], reply: &mut Vec<u8>| {
            reply.extend_from_slice(request);
            float_probe(1, 7.6, request, reply);
        });
        let config = ClientConfig { timeout: TIMEOUT, retry: RetryPolicy::NONE, ..ClientConfig::default() };
        let mut client = AnyClient::with_config(driver, transport, config);
        let error = client.call(1, &ReadFloat).unwrap_err();
        assert!(client.last_reply().starts_with(&READ_FLOAT_REQUEST), "{error}");
    }

    fn a_device_that_never_stops_talking_cannot_hold_the_client(driver) {
        let timeout = Duration::from_millis(30);
        let config = ClientConfig { timeout, retry: RetryPolicy::NONE, ..ClientConfig::default() };
        let mut client = AnyClient::with_config(driver, Babbling, config);
        let started = Instant::now();
        let error = client.call(1, &ReadFloat).unwrap_err();
        assert!(error.is_timeout(), "{error}");
        assert!(started.elapsed() < timeout + Duration::from_secs(1), "took {:?}", started.elapsed());
    }
}

/// A line that never falls silent: every read returns noise at once.
struct Babbling;

impl yosemitech_rtu::Transport for Babbling {
    fn write_all(&mut self, _frame: &[u8]) -> std::io::Result<()> {
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _timeout: Duration) -> std::io::Result<usize> {
        buf.fill(0x55);
        Ok(buf.len())
    }

    fn discard_input(&mut self) -> std::io::Result<()> {
        Ok(())
    }

    fn line_timing(&self) -> Option<yosemitech_rtu::LineTiming> {
        None
    }
}

impl AsyncLink for Babbling {
    async fn write_frame(&mut self, _frame: &[u8]) -> std::io::Result<()> {
        Ok(())
    }

    async fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        buf.fill(0x55);
        Ok(buf.len())
    }
}

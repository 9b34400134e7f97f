//! The core on a virtual clock: a scripted device answers each request with
//! bytes at chosen times, and the test driver jumps the clock to the next
//! event instead of sleeping (quinn-proto's `Pair::step`).

use std::collections::VecDeque;
use std::vec::Vec;

use super::*;
use crate::client::Sent;
use crate::crc::crc16;
use crate::error::ExceptionCode;
use crate::timing::CharFormat;

const READ_FLOAT: Layout<'static> = Layout::read(0x2800, 2);
const START: Layout<'static> = Layout { trigger: true, ..Layout::write(0x1C00, 0) };
/// A two-register float read reply (7.6), slave 1.
const READ_FLOAT_REPLY: [u8; 9] = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn at(n: u64) -> Instant {
    Instant::ZERO + ms(n)
}

fn with_crc(body: &[u8]) -> Vec<u8> {
    let mut frame = body.to_vec();
    frame.extend_from_slice(&crc16(body).to_le_bytes());
    frame
}

/// The float read reply of `slave`.
fn reply_from(slave: u8) -> Vec<u8> {
    with_crc(&[slave, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40])
}

/// What a device sends for one request: `(delay after the request, bytes)`.
type Answer = Vec<(Duration, Vec<u8>)>;

/// A scripted device: the answer to the n-th request.
type Device = Box<dyn FnMut(usize, &[u8]) -> Answer>;

/// A driver on a virtual clock.
struct Harness {
    core: ClientCore,
    now: Instant,
    /// Bytes on their way to the client, with their arrival times.
    incoming: VecDeque<(Instant, u8)>,
    /// The device: answers the n-th request.
    device: Device,
    /// Requests as written, with the time each write returned.
    sent: Vec<(Instant, Vec<u8>)>,
    /// Clock reads (times reported to the core) in the last transaction.
    clock_reads: usize,
    /// Frames offered for decoding in the last transaction.
    checks: Vec<Vec<u8>>,
}

impl Harness {
    fn new(config: ClientConfig, device: impl FnMut(usize, &[u8]) -> Answer + 'static) -> Self {
        Self {
            core: ClientCore::new(config),
            now: at(1000),
            incoming: VecDeque::new(),
            device: Box::new(device),
            sent: Vec::new(),
            clock_reads: 0,
            checks: Vec::new(),
        }
    }

    fn arrive(&mut self, after: Duration, bytes: &[u8]) {
        let when = self.now + after;
        self.incoming.extend(bytes.iter().map(|&b| (when, b)));
    }

    /// Takes the bytes that have arrived by `now`, at most `room`.
    fn take_arrived(&mut self, room: usize) -> Vec<u8> {
        let mut taken = Vec::new();
        while taken.len() < room && self.incoming.front().is_some_and(|&(t, _)| t <= self.now) {
            taken.extend(self.incoming.pop_front().map(|(_, b)| b));
        }
        taken
    }

    fn deliver(&mut self, bytes: &[u8]) {
        self.core.recv_buf()[..bytes.len()].copy_from_slice(bytes);
        self.clock_reads += 1;
        self.core.handle_received(bytes.len(), self.now);
    }

    /// Runs the started transaction to its end, decoding candidates with `layout` for `slave`.
    fn run(&mut self, slave: u8, layout: &Layout<'_>) -> Result<(), ClientError<Infallible>> {
        self.clock_reads = 0;
        self.checks.clear();
        loop {
            match self.core.poll() {
                Action::Wait { until } => {
                    self.clock_reads += 1;
                    self.now = self.now.max(until);
                    self.core.handle_timeout(self.now);
                }
                Action::ReadPending => {
                    let room = self.core.recv_buf().len();
                    let bytes = self.take_arrived(room);
                    if bytes.is_empty() {
                        self.core.handle_nothing_pending();
                    } else {
                        self.deliver(&bytes);
                    }
                }
                Action::Transmit(frame) => {
                    let frame = frame.to_vec();
                    // Input the link still held is dropped.
                    self.take_arrived(usize::MAX);
                    let index = self.sent.len();
                    for (after, bytes) in (self.device)(index, &frame) {
                        self.arrive(after, &bytes);
                    }
                    self.sent.push((self.now, frame));
                    self.clock_reads += 1;
                    self.core.handle_write_done(self.now);
                }
                Action::Receive { timeout, needs_time } => {
                    let limit = self.now + timeout;
                    match self.incoming.front() {
                        Some(&(t, _)) if t <= limit => {
                            self.now = self.now.max(t);
                            let room = self.core.recv_buf().len();
                            let bytes = self.take_arrived(room);
                            if needs_time {
                                self.deliver(&bytes);
                            } else {
                                self.core.recv_buf()[..bytes.len()].copy_from_slice(&bytes);
                                let stale = self.core.now();
                                self.core.handle_received(bytes.len(), stale);
                            }
                        }
                        _ => {
                            self.now = limit;
                            self.clock_reads += 1;
                            self.core.handle_timeout(self.now);
                        }
                    }
                }
                Action::Check => {
                    let frame = self.core.candidate();
                    self.checks.push(frame.to_vec());
                    let verdict = layout.decode_response(slave, frame).map(drop);
                    self.core.handle_check(verdict);
                }
                Action::Done(result) => return result,
                Action::Idle => panic!("no transaction"),
            }
        }
    }

    fn call(&mut self, slave: u8, layout: &Layout<'_>) -> Result<(), ClientError<Infallible>> {
        let len = layout.encode_request(slave, &[], self.core.request_buf()).unwrap();
        self.core.start_call(len, layout).unwrap();
        self.run(slave, layout)
    }

    /// Starts a call and runs it only until the request is written.
    fn send_and_abandon(&mut self, slave: u8, layout: &Layout<'_>) {
        let len = layout.encode_request(slave, &[], self.core.request_buf()).unwrap();
        self.core.start_call(len, layout).unwrap();
        while !matches!(self.core.poll(), Action::Receive { .. }) {
            match self.core.poll() {
                Action::ReadPending => self.core.handle_nothing_pending(),
                Action::Wait { until } => {
                    self.now = self.now.max(until);
                    self.core.handle_timeout(self.now);
                }
                Action::Transmit(frame) => {
                    let frame = frame.to_vec();
                    for (after, bytes) in (self.device)(self.sent.len(), &frame) {
                        self.arrive(after, &bytes);
                    }
                    self.sent.push((self.now, frame));
                    self.core.handle_write_done(self.now);
                }
                other => panic!("unexpected {other:?}"),
            }
        }
    }
}

fn no_retries() -> ClientConfig {
    ClientConfig { timeout: ms(100), retry: RetryPolicy::NONE, ..ClientConfig::default() }
}

/// The probe at `slave`: the float read reply 5 ms after each request.
fn probe(slave: u8) -> impl FnMut(usize, &[u8]) -> Answer {
    move |_, _| vec![(ms(5), reply_from(slave))]
}

use super::super::config::RetryPolicy;

#[test]
fn a_transaction_reads_the_clock_twice_and_checks_one_frame() {
    let mut h = Harness::new(no_retries(), probe(1));
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    assert_eq!(h.core.last_reply(), READ_FLOAT_REPLY);
    assert_eq!(h.clock_reads, 2, "after the write and after the reply");
    assert_eq!(h.checks, [READ_FLOAT_REPLY.to_vec()], "one candidate, decoded (and its CRC computed) once");
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    assert_eq!(h.clock_reads, 2, "the next one too: no silence to keep without line timing");
}

#[test]
fn the_silence_follows_the_line_with_the_4_ms_floor() {
    let mut h = Harness::new(no_retries(), probe(1));
    h.core.set_line_timing(Some(LineTiming::new(9600, CharFormat::EIGHT_N_1)));
    assert_eq!(h.core.inter_frame_delay(), ms(4), "t3.5 = 3.65 ms, raised to 4 ms");
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    let first_reply_end = h.now;
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    assert_eq!(h.sent[1].0, first_reply_end + ms(4), "exactly t3.5 (floored) after the reply's last byte");
    // The request's own time on the line counts: 8 bytes at 9600 baud.
    let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
    assert_eq!(h.core.bus_busy_until, Some(h.now), "busy until the last byte received");
    h.core.set_line_timing(Some(LineTiming::new(115_200, CharFormat::EIGHT_N_1)));
    assert_eq!(h.core.inter_frame_delay(), Duration::from_micros(1750), "fixed above 19200 baud, no floor");
    let _ = line;
}

#[test]
fn the_first_request_on_a_timed_line_keeps_the_silence_too() {
    let mut h = Harness::new(ClientConfig { inter_frame_delay: None, ..no_retries() }, probe(1));
    // The bus was busy until 1 s (a previous core's transaction, say): a new
    // transaction started before the line timing is set still keeps t3.5.
    h.core.bus_busy_until = Some(h.now);
    let len = READ_FLOAT.encode_request(1, &[], h.core.request_buf()).unwrap();
    h.core.start_call(len, &READ_FLOAT).unwrap();
    h.core.set_line_timing(Some(LineTiming::new(9600, CharFormat::EIGHT_N_1)));
    assert_eq!(h.run(1, &READ_FLOAT), Ok(()));
    assert_eq!(h.sent[0].0, at(1000) + ms(4));
}

#[test]
fn a_request_on_a_timed_line_is_busy_for_its_line_time() {
    let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
    // A device that never answers: the deadline runs from the request's end on the line.
    let mut h = Harness::new(no_retries(), |_, _| vec![]);
    h.core.set_line_timing(Some(line));
    let Err(ClientError::Timeout { received: 0, sent: asked }) = h.call(1, &READ_FLOAT) else { panic!("answered") };
    assert_eq!(
        asked,
        Sent { slave: 1, function: READ_FLOAT.function.code(), register: READ_FLOAT.address, command: None }
    );
    let sent = h.sent[0].0;
    assert_eq!(h.now, sent + line.frame_time(8) + ms(100));
}

#[test]
fn a_broadcast_keeps_the_turnaround() {
    let mut h = Harness::new(no_retries(), probe(1));
    let len = START.encode_request(0, &[], h.core.request_buf()).unwrap();
    h.core.start_broadcast(len, &START).unwrap();
    assert_eq!(h.run(0, &START), Ok(()));
    assert_eq!(h.core.last_reply(), &[] as &[u8]);
    let broadcast_at = h.sent[0].0;
    // The device "answered" a broadcast (it should not): that is stale input.
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    assert_eq!(h.sent[1].0, broadcast_at + ms(100), "the default turnaround");
    let len = START.encode_request(0, &[], h.core.request_buf()).unwrap();
    assert_eq!(
        h.core.start_call(len, &START),
        Err(ClientError::Encode(EncodeError::InvalidSlave { slave: 0 })),
        "a call to slave 0 is refused"
    );
}

#[test]
fn stale_input_is_drained_and_the_silence_kept_after_it() {
    let mut h = Harness::new(ClientConfig { inter_frame_delay: Some(ms(10)), ..no_retries() }, probe(1));
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    // Stray bytes arrive 20 ms later; the next call starts at 50 ms.
    h.arrive(ms(20), &[0x55, 0x55]);
    let stray_at = h.now + ms(20);
    h.now = h.now + ms(50);
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    assert_eq!(h.sent[1].0, h.sent[1].0.max(stray_at + ms(10)));
    assert_eq!(h.core.last_reply(), READ_FLOAT_REPLY);
}

#[test]
fn noise_before_a_slave_that_looks_like_a_function_code_is_realigned() {
    // Slave 3 answers a read: `AA 03 03 04 ...` frames first at the noise.
    let mut h = Harness::new(no_retries(), |_, _| {
        let mut bytes = vec![0xAA];
        bytes.extend(reply_from(3));
        vec![(ms(5), bytes)]
    });
    assert_eq!(h.call(3, &READ_FLOAT), Ok(()));
    assert_eq!(h.core.last_reply(), reply_from(3));
    assert_eq!(h.checks.len(), 2, "the misaligned candidate, then the frame: {:02X?}", h.checks);
    assert_eq!(h.checks[0][..3], [0xAA, 0x03, 0x03]);
}

#[test]
fn a_corrupt_reply_is_reported_after_one_inter_frame_wait_not_the_timeout() {
    let mut corrupt = READ_FLOAT_REPLY.to_vec();
    corrupt[8] ^= 0xFF;
    let sent = corrupt.clone();
    let mut h = Harness::new(no_retries(), move |_, _| vec![(ms(5), sent.clone())]);
    let result = h.call(1, &READ_FLOAT);
    assert!(matches!(result, Err(ClientError::Frame { error: FrameError::Crc { .. } })), "{result:?}");
    assert_eq!(h.core.last_reply(), corrupt);
    let reply_at = h.sent[0].0 + ms(5);
    assert_eq!(h.now, reply_at + ms(4), "waited min_inter_frame_delay for a better candidate");
}

#[test]
fn an_exception_is_the_reply_and_is_not_retried() {
    let exception = with_crc(&[0x01, 0x83, 0x02]);
    let reply = exception.clone();
    let config = ClientConfig { retry: RetryPolicy { retries: 3, ..RetryPolicy::NONE }, ..no_retries() };
    let mut h = Harness::new(config, move |_, _| vec![(ms(5), reply.clone())]);
    let result = h.call(1, &READ_FLOAT);
    assert_eq!(
        result,
        Err(ClientError::Frame {
            error: FrameError::Exception { function: 3, code: ExceptionCode::IllegalDataAddress }
        })
    );
    assert_eq!(h.sent.len(), 1);
    assert_eq!(h.core.last_reply(), exception);
}

#[test]
fn a_retry_waits_the_backoff_and_succeeds() {
    let config =
        ClientConfig { retry: RetryPolicy { retries: 2, backoff: ms(50), ..RetryPolicy::default() }, ..no_retries() };
    let mut h = Harness::new(config, |i, _| {
        let mut reply = reply_from(1);
        if i == 0 {
            reply[4] ^= 0x10;
        }
        vec![(ms(5), reply)]
    });
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    assert_eq!(h.sent.len(), 2);
    // The first reply failed its CRC at 5 ms, no better candidate by 9 ms; then 50 ms of backoff.
    assert_eq!(h.sent[1].0, h.sent[0].0 + ms(5) + ms(4) + ms(50));
}

#[test]
fn retries_stop_at_the_policy_and_skip_classes_it_excludes() {
    let config =
        ClientConfig { retry: RetryPolicy { retries: 2, backoff: ms(1), ..RetryPolicy::default() }, ..no_retries() };
    let mut h = Harness::new(config, |_, _| vec![]);
    assert_eq!(h.call(1, &READ_FLOAT), Err(ClientError::Timeout { received: 0, sent: h.core.sent() }));
    assert_eq!(h.sent.len(), 3, "one attempt and two retries");
    let config =
        ClientConfig { retry: RetryPolicy { retries: 2, on_timeout: false, ..RetryPolicy::default() }, ..no_retries() };
    let mut h = Harness::new(config, |_, _| vec![]);
    assert_eq!(h.call(1, &READ_FLOAT), Err(ClientError::Timeout { received: 0, sent: h.core.sent() }));
    assert_eq!(h.sent.len(), 1);
}

#[test]
fn a_partial_reply_times_out_at_the_deadline_with_its_bytes() {
    let mut h = Harness::new(no_retries(), |_, _| vec![(ms(5), READ_FLOAT_REPLY[..5].to_vec())]);
    assert_eq!(h.call(1, &READ_FLOAT), Err(ClientError::Timeout { received: 5, sent: h.core.sent() }));
    assert_eq!(h.core.last_reply(), &READ_FLOAT_REPLY[..5]);
    assert_eq!(h.now, h.sent[0].0 + ms(100), "one deadline for the whole reply");
}

#[test]
fn the_late_reply_of_an_abandoned_transaction_is_waited_out_and_discarded() {
    // The device answers each request after 30 ms with a distinct value.
    let mut h =
        Harness::new(no_retries(), |i, _| vec![(ms(30), with_crc(&[0x01, 0x03, 0x04, 0x00, 0x00, 0x00, i as u8]))]);
    h.send_and_abandon(1, &READ_FLOAT);
    let abandoned_at = h.sent[0].0;
    // The next call starts at once: it must not talk over the late reply.
    assert_eq!(h.call(1, &READ_FLOAT), Ok(()));
    assert!(h.sent[1].0 >= abandoned_at + ms(100), "no request before the abandoned deadline");
    assert_eq!(
        h.core.last_reply(),
        with_crc(&[0x01, 0x03, 0x04, 0x00, 0x00, 0x00, 1]),
        "the second reply, not the first"
    );
}

#[test]
fn a_device_that_never_stops_talking_cannot_hold_the_core() {
    let mut h = Harness::new(no_retries(), |_, _| vec![(ms(1), vec![0x55; 4096])]);
    assert!(matches!(h.call(1, &READ_FLOAT), Err(ClientError::Timeout { .. })));
}

#[test]
fn the_core_holds_its_buffers_and_little_else() {
    // Three 256-byte buffers and the bus state: what a firmware's stack or static holds.
    let size = core::mem::size_of::<ClientCore>();
    std::println!("ClientCore: {size} bytes");
    assert!(size <= 3 * MAX_ADU + 400, "{size}");
}

#[test]
fn a_short_trigger_reply_after_noise_that_opens_a_longer_frame_is_found() {
    // The noise `AA AA 01 03` aligns a frame whose head announces more
    // bytes than will come; the short reply `01 03 00 CRC` inside it checks.
    const TRIGGER_READ: Layout<'static> = Layout { trigger: true, ..Layout::read(0x2500, 2) };
    let short = with_crc(&[0x01, 0x03, 0x00]);
    let mut bytes = vec![0xAA, 0xAA, 0x01, 0x03];
    bytes.extend_from_slice(&short);
    let mut h = Harness::new(no_retries(), move |_, _| vec![(ms(5), bytes.clone())]);
    assert_eq!(h.call(1, &TRIGGER_READ), Ok(()));
    assert_eq!(h.core.last_reply(), short);
}

#[test]
fn moving_bytes_to_the_front_is_copy_within_for_every_range() {
    const LEN: usize = 24;
    let original: [u8; LEN] = core::array::from_fn(|i| i as u8 + 1);
    for start in 0..=LEN {
        for end in start..=LEN {
            let mut expected = original;
            expected.copy_within(start..end, 0);
            let mut moved = original;
            move_to_front(&mut moved, start..end);
            assert_eq!(moved, expected, "{start}..{end}");
        }
    }
}

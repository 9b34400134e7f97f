//! The firmware driver (`client::embedded::FirmwareClient`, feature `embedded`)
//! on the host: an in-memory byte pipe and a delay on one virtual clock (a
//! delay jumps the clock instead of sleeping), a device answering each
//! request with bytes at chosen times. The same behavioural cases as the
//! blocking client's tests, and no allocation per transaction.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::future::Future;
use std::pin::Pin;
use std::rc::Rc;
use std::task::{Context, Poll};
use std::time::Duration;

use embassy_futures::block_on;
use yosemitech_rtu::client::Instant;
use yosemitech_rtu::client::embedded::FirmwareClient;
use yosemitech_rtu::{
    CharFormat, ClientConfig, ClientError, Command, ExceptionCode, FrameError, LineTiming, RetryPolicy,
};
use yosemitech_tests::counting_alloc::{CountingAllocator, allocations};
use yosemitech_tests::rtu::{READ_FLOAT_REPLY, READ_FLOAT_REQUEST, ReadFloat, StartMeasurement, float_probe};
use yosemitech_tests::with_crc;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

/// What the device sends for one request: `(delay after the request, bytes)`.
type Answer = Vec<(Duration, Vec<u8>)>;

/// A device: answers the n-th request into `out` (cleared first; preallocated).
type Device = Box<dyn FnMut(usize, &[u8], &mut Answer)>;

/// The line, the device and the clock.
struct World {
    now_ns: u64,
    incoming: VecDeque<(u64, u8)>,
    device: Device,
    answer: Answer,
    /// Request times (ns) and frames.
    requests: Vec<(u64, Vec<u8>)>,
    /// Bytes handed out per read at most.
    chunk: usize,
}

type Shared = Rc<RefCell<World>>;

fn world(device: impl FnMut(usize, &[u8], &mut Answer) + 'static) -> Shared {
    Rc::new(RefCell::new(World {
        now_ns: 1_000_000_000,
        incoming: VecDeque::with_capacity(4096),
        device: Box::new(device),
        answer: Vec::with_capacity(4),
        requests: Vec::with_capacity(512),
        chunk: usize::MAX,
    }))
}

/// A device that answers get_ph like the pH probe at `address`, `delay` after each request.
fn probe(address: u8, delay: Duration) -> impl FnMut(usize, &[u8], &mut Answer) {
    move |_, request, out| {
        let mut reply = Vec::new();
        float_probe(address, 7.6, request, &mut reply);
        out.push((delay, reply));
    }
}

struct Link(Shared);
struct Delay(Shared);

#[derive(Debug)]
struct LinkError;

impl core::fmt::Display for LinkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("link error")
    }
}

impl core::error::Error for LinkError {}

impl embedded_io_async::Error for LinkError {
    fn kind(&self) -> embedded_io_async::ErrorKind {
        embedded_io_async::ErrorKind::Other
    }
}

impl embedded_io_async::ErrorType for Link {
    type Error = LinkError;
}

impl embedded_io_async::Write for Link {
    async fn write(&mut self, frame: &[u8]) -> Result<usize, LinkError> {
        let mut w = self.0.borrow_mut();
        let w = &mut *w;
        let index = w.requests.len();
        let now = w.now_ns;
        w.requests.push((now, frame.to_vec()));
        w.answer.clear();
        (w.device)(index, frame, &mut w.answer);
        for (after, bytes) in w.answer.drain(..) {
            let at = now + after.as_nanos() as u64;
            w.incoming.extend(bytes.iter().map(|&b| (at, b)));
        }
        Ok(frame.len())
    }

    async fn flush(&mut self) -> Result<(), LinkError> {
        Ok(())
    }
}

impl embedded_io_async::Read for Link {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, LinkError> {
        std::future::poll_fn(|_| {
            let mut w = self.0.borrow_mut();
            let now = w.now_ns;
            let room = buf.len().min(w.chunk);
            let mut n = 0;
            while n < room && w.incoming.front().is_some_and(|&(t, _)| t <= now) {
                buf[n] = w.incoming.pop_front().unwrap().1;
                n += 1;
            }
            if n > 0 { Poll::Ready(Ok(n)) } else { Poll::Pending }
        })
        .await
    }
}

/// Advances the virtual clock to `until`, stopping at each byte arrival on
/// the way (so a racing read sees it first).
struct Advance {
    world: Shared,
    until: u64,
}

impl Future for Advance {
    type Output = ();
    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        let mut w = self.world.borrow_mut();
        if w.now_ns >= self.until {
            return Poll::Ready(());
        }
        match w.incoming.front() {
            Some(&(t, _)) if t > w.now_ns && t < self.until => {
                w.now_ns = t;
                cx.waker().wake_by_ref();
                Poll::Pending
            }
            _ => {
                w.now_ns = self.until;
                Poll::Ready(())
            }
        }
    }
}

impl embedded_hal_async::delay::DelayNs for Delay {
    async fn delay_ns(&mut self, ns: u32) {
        let until = self.0.borrow().now_ns + u64::from(ns);
        Advance { world: Rc::clone(&self.0), until }.await
    }
}

type Client = FirmwareClient<Link, Delay, Box<dyn FnMut() -> Instant>>;

fn client_on(world: &Shared, config: ClientConfig, line: Option<LineTiming>) -> Client {
    let clock_world = Rc::clone(world);
    let clock: Box<dyn FnMut() -> Instant> = Box::new(move || Instant::from_micros(clock_world.borrow().now_ns / 1000));
    FirmwareClient::new(Link(Rc::clone(world)), Delay(Rc::clone(world)), clock, config, line)
}

fn config(retries: u32) -> ClientConfig {
    ClientConfig {
        timeout: Duration::from_millis(50),
        retry: RetryPolicy { retries, backoff: Duration::ZERO, ..RetryPolicy::default() },
        ..ClientConfig::default()
    }
}

fn requests(world: &Shared) -> usize {
    world.borrow().requests.len()
}

fn request_time(world: &Shared, i: usize) -> Duration {
    Duration::from_nanos(world.borrow().requests[i].0)
}

fn now(world: &Shared) -> Duration {
    Duration::from_nanos(world.borrow().now_ns)
}

#[test]
fn float_read_sends_and_decodes_the_manual_frames() {
    let w = world(probe(1, Duration::from_millis(5)));
    let mut client = client_on(&w, config(0), None);
    assert_eq!(block_on(client.call(1, &ReadFloat)).unwrap(), 7.6);
    assert_eq!(w.borrow().requests[0].1, READ_FLOAT_REQUEST);
    assert_eq!(client.last_reply(), READ_FLOAT_REPLY);
    assert_eq!(block_on(client.call_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT)).unwrap(), READ_FLOAT_REPLY);
    assert_eq!(requests(&w), 2);
}

#[test]
fn exception_reply_is_reported_and_not_retried() {
    let exception = with_crc(&[0x01, 0x83, 0x02]);
    let reply = exception.clone();
    let w = world(move |_, _, out| out.push((Duration::from_millis(2), reply.clone())));
    let mut client = client_on(&w, config(3), None);
    let err = block_on(client.call(1, &ReadFloat)).unwrap_err();
    assert_eq!(err.exception(), Some(ExceptionCode::IllegalDataAddress));
    assert_eq!(client.last_reply(), exception);
    assert_eq!(requests(&w), 1);
}

#[test]
fn crc_corruption_is_retried_then_succeeds() {
    let w = world(|i, request, out| {
        let mut reply = Vec::new();
        float_probe(1, 7.6, request, &mut reply);
        if i == 0 {
            reply[4] ^= 0x10;
        }
        out.push((Duration::from_millis(2), reply));
    });
    let mut client = client_on(&w, config(1), None);
    assert_eq!(block_on(client.call(1, &ReadFloat)).unwrap(), 7.6);
    assert_eq!(requests(&w), 2);
}

#[test]
fn noise_before_slave_3_is_realigned_whatever_the_chunking() {
    for noise in [&[0xAA][..], &[0x03], &[0x03, 0x03], &[0x10, 0x03, 0x03], &[0xFF, 0x83, 0x90, 0x10]] {
        for chunk in [1, 2, 3, usize::MAX] {
            let noise = noise.to_vec();
            let w = world(move |_, request, out| {
                let mut reply = noise.clone();
                float_probe(3, 7.6, request, &mut reply);
                out.push((Duration::from_millis(2), reply));
            });
            w.borrow_mut().chunk = chunk;
            let mut client = client_on(&w, ClientConfig { retry: RetryPolicy::NONE, ..config(0) }, None);
            let result = block_on(client.call(3, &ReadFloat));
            assert!(matches!(result, Ok(v) if v == 7.6), "chunk {chunk}: {result:?}");
        }
    }
}

#[test]
fn silent_device_times_out_at_the_deadline() {
    let w = world(|_, _, _| {});
    let mut client = client_on(&w, config(0), None);
    let err = block_on(client.call(1, &ReadFloat)).unwrap_err();
    assert!(matches!(err, ClientError::Timeout { received: 0, .. }), "{err:?}");
    assert_eq!(now(&w) - request_time(&w, 0), Duration::from_millis(50), "exactly the timeout, on the virtual clock");
}

#[test]
fn truncated_reply_times_out_with_the_partial_bytes() {
    let w = world(|_, _, out| out.push((Duration::from_millis(2), READ_FLOAT_REPLY[..5].to_vec())));
    let mut client = client_on(&w, config(0), None);
    let err = block_on(client.call(1, &ReadFloat)).unwrap_err();
    assert!(matches!(err, ClientError::Timeout { received: 5, .. }), "{err:?}");
    assert_eq!(client.last_reply(), &READ_FLOAT_REPLY[..5]);
}

#[test]
fn retries_each_get_a_full_timeout_and_backoff() {
    let w = world(|_, _, _| {});
    let backoff = Duration::from_millis(30);
    let retry = RetryPolicy { retries: 2, backoff, ..RetryPolicy::default() };
    let mut client = client_on(&w, ClientConfig { retry, ..config(0) }, None);
    assert!(block_on(client.call(1, &ReadFloat)).unwrap_err().is_timeout());
    assert_eq!(requests(&w), 3);
    assert_eq!(request_time(&w, 1) - request_time(&w, 0), Duration::from_millis(50) + backoff);
}

#[test]
fn the_silence_follows_the_line_and_a_broadcast_keeps_its_turnaround() {
    let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
    let w = world(probe(1, Duration::from_millis(5)));
    let mut client = client_on(&w, config(0), Some(line));
    assert_eq!(client.core().inter_frame_delay(), Duration::from_millis(4), "t3.5 raised to the 4 ms floor");
    assert_eq!(block_on(client.call(1, &ReadFloat)).unwrap(), 7.6);
    let reply_end = now(&w);
    assert_eq!(block_on(client.call(1, &ReadFloat)).unwrap(), 7.6);
    let gap = request_time(&w, 1) - reply_end;
    assert!(gap >= Duration::from_millis(4) && gap < Duration::from_micros(4010), "{gap:?}");

    block_on(client.broadcast(&StartMeasurement)).unwrap();
    let broadcast_at = request_time(&w, 2);
    assert_eq!(block_on(client.call(1, &ReadFloat)).unwrap(), 7.6);
    // The turnaround runs from the broadcast's end on the line.
    assert!(request_time(&w, 3) - broadcast_at >= Duration::from_millis(100));
}

#[test]
fn a_dropped_call_leaves_its_late_reply_to_be_discarded() {
    // Each reply comes 30 ms after its request and carries the request's index.
    let w = world(|i, _, out| {
        out.push((Duration::from_millis(30), with_crc(&[0x01, 0x03, 0x04, 0x00, 0x00, 0x00, i as u8])));
    });
    let mut client = client_on(&w, ClientConfig { timeout: Duration::from_millis(100), ..config(0) }, None);
    let mut other = Delay(Rc::clone(&w));
    let raced = block_on(embassy_futures::select::select(
        client.call_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT),
        embedded_hal_async::delay::DelayNs::delay_ms(&mut other, 10),
    ));
    assert!(matches!(raced, embassy_futures::select::Either::Second(())), "the call was dropped half-way");
    assert_eq!(requests(&w), 1);
    let reply = block_on(client.call_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT)).unwrap().to_vec();
    assert_eq!(reply, with_crc(&[0x01, 0x03, 0x04, 0x00, 0x00, 0x00, 1]), "the second request's reply");
    assert!(request_time(&w, 1) - request_time(&w, 0) >= Duration::from_millis(100), "no request over the late reply");
}

#[test]
fn transactions_do_not_allocate() {
    let w = world(probe(1, Duration::from_millis(1)));
    let mut client = client_on(&w, config(0), None);
    assert_eq!(block_on(client.call(1, &ReadFloat)).unwrap(), 7.6);
    let before = allocations();
    for _ in 0..100 {
        let value = block_on(client.call(1, &ReadFloat));
        assert!(matches!(value, Ok(v) if v == 7.6));
    }
    let after = allocations();
    // The test's device allocates: one reply Vec and one logged request per transaction.
    let device_allocations = 2 * 100;
    assert_eq!(after - before - device_allocations, 0, "allocations by the driver in 100 transactions");
    // Errors do not allocate either (the device answers with a Modbus exception).
    let unknown = yosemitech_rtu::Layout { address: 0x9900, ..ReadFloat::LAYOUT };
    let request = with_crc(&[0x01, 0x03, 0x99, 0x00, 0x00, 0x02]);
    let before = allocations();
    let err = block_on(client.call_raw(&request, &unknown)).unwrap_err();
    assert!(matches!(err, ClientError::Frame { error: FrameError::Exception { .. } }));
    assert_eq!(allocations() - before, 2, "only the device's two");
}

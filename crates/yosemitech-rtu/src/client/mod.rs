//! The Modbus RTU master: one request at a time over a [`Transport`], with
//! RTU timing, stale-input discarding, length-delimited framing, every frame
//! check, retries and frame dumps.
//!
//! # One transaction
//!
//! 1. Wait until the bus has been silent for the inter-frame delay (t3.5,
//!    [`Client::inter_frame_delay`]) since the last byte sent or received,
//!    and for the turnaround after a broadcast.
//! 2. Read and drop stale input (logged), then [`Transport::discard_input`].
//! 3. Send the request, encoded into a buffer inside the client.
//! 4. Read the first 3 bytes of the reply, then exactly the rest: 2 more for
//!    an exception, [`Layout::response_len`] in all for a normal reply
//!    ([`frame::reply_len`]). All reads share one deadline,
//!    [`ClientConfig::timeout`] after the request left. Bytes whose successor
//!    is not the expected function code (line noise as an RS-485 driver
//!    turns on) are skipped before the frame; a candidate frame whose CRC
//!    fails is tried again one byte further on while more bytes arrive (noise
//!    before a slave whose address looks like a function code, slave 3 or 16).
//! 5. Check and decode the reply; on a retryable failure ([`RetryPolicy`]),
//!    wait [`RetryPolicy::backoff`] and start again at 1.
//!
//! A successful transaction allocates nothing. Frames go to `tracing` at
//! debug level (`tx`, `rx`, stale and skipped bytes), retries at warn.

// `Error` carries up to 256 received bytes inline (no allocation on the error
// path either), so it is larger than clippy's 128-byte threshold. Requests
// take milliseconds on the line; moving ~300 bytes on return costs nothing.
#![allow(clippy::result_large_err)]

mod error;

use std::fmt;
use std::ops::Range;
use std::thread;
use std::time::{Duration, Instant};

use tracing::{debug, debug_span, warn};

pub use self::error::Error;
use crate::Hex;
use crate::command::Command;
use crate::crc::crc_ok;
use crate::error::{EncodeError, FrameError};
use crate::frame::{self, BROADCAST, EXCEPTION_BIT, EXCEPTION_LEN, Function, Layout, MAX_ADU};
use crate::raw::RawBytes;
use crate::transport::{MAX_WAIT, Transport};

/// Bytes read before the reply's length is decided: slave, function and one
/// more (an exception reply is 5 bytes, so this never reads past a frame).
const HEAD_LEN: usize = 3;

/// Reads of stale input before each request (each up to [`MAX_ADU`] bytes).
const DRAIN_ROUNDS: usize = 4;

/// Which failures are retried, how often and how far apart.
///
/// Retried (each class can be switched off): timeouts; corrupt frames (CRC
/// mismatch, truncated, too long); foreign frames (a reply from another slave
/// or for another function: another device's conversation). Never retried:
/// Modbus exceptions, byte counts and write echoes that do not match (the
/// device answered, and would answer the same again), encoding and transport
/// errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RetryPolicy {
    /// Attempts after the first.
    pub retries: u32,
    /// Wait between a failed attempt and the next.
    pub backoff: Duration,
    /// Retry when no complete reply arrived in time.
    pub on_timeout: bool,
    /// Retry CRC mismatches and truncated or overlong frames.
    pub on_corrupt: bool,
    /// Retry replies from another slave or for another function.
    pub on_foreign: bool,
}

impl RetryPolicy {
    /// One attempt, no retries.
    pub const NONE: Self =
        Self { retries: 0, backoff: Duration::ZERO, on_timeout: true, on_corrupt: true, on_foreign: true };

    /// Whether `error` is of a class this policy retries (the attempt count
    /// is the client's business).
    pub fn should_retry(&self, error: &Error) -> bool {
        match error {
            Error::Timeout { .. } => self.on_timeout,
            Error::Frame { error, .. } => match error {
                FrameError::Crc { .. } | FrameError::Truncated { .. } | FrameError::TooLong { .. } => self.on_corrupt,
                FrameError::WrongSlave { .. } | FrameError::WrongFunction { .. } => self.on_foreign,
                FrameError::ByteCount { .. } | FrameError::EchoMismatch { .. } | FrameError::Exception { .. } => false,
            },
            Error::Encode(_) | Error::Request(_) | Error::Io(_) => false,
        }
    }
}

impl Default for RetryPolicy {
    /// Two retries, 50 ms apart, of every retryable class.
    fn default() -> Self {
        Self { retries: 2, backoff: Duration::from_millis(50), on_timeout: true, on_corrupt: true, on_foreign: true }
    }
}

/// How a [`Client`] times and retries requests. Build with struct update
/// syntax: `ClientConfig { timeout, ..ClientConfig::default() }`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ClientConfig {
    /// Time allowed for the whole reply of one attempt, from the end of the
    /// request on the line to the reply's last byte. Default 1 s.
    pub timeout: Duration,
    /// Retries.
    pub retry: RetryPolicy,
    /// Silence kept on the bus before each request. `None` (the default)
    /// derives it from the transport: t3.5 of its line timing, at least
    /// [`ClientConfig::min_inter_frame_delay`], or nothing for transports
    /// without line timing (TCP, in-memory). `Some(d)` uses `d` as is;
    /// `Some(Duration::ZERO)` never waits.
    pub inter_frame_delay: Option<Duration>,
    /// The least derived inter-frame delay at 19200 baud and below. Default
    /// 4 ms: the manuals contradict themselves on 10 or 11 bits per
    /// character, whose t3.5 at 9600 baud is 3.65 or 4.01 ms (datasheet
    /// notes, section 6 item 10). Above 19200 baud t3.5 is fixed at 1.75 ms.
    pub min_inter_frame_delay: Duration,
    /// Silence kept after a broadcast before the next request, so slaves
    /// can act on it (the Modbus "turnaround delay"). Default 100 ms.
    pub broadcast_turnaround: Duration,
}

impl Default for ClientConfig {
    fn default() -> Self {
        Self {
            timeout: Duration::from_secs(1),
            retry: RetryPolicy::default(),
            inter_frame_delay: None,
            min_inter_frame_delay: Duration::from_millis(4),
            broadcast_turnaround: Duration::from_millis(100),
        }
    }
}

/// A Modbus RTU master on one transport (one bus).
///
/// ```
/// use yosemitech_rtu::{Client, ClientConfig, ResponderTransport};
///
/// // A device that never answers.
/// let transport = ResponderTransport::from_fn(|_request, _reply| {});
/// let config = ClientConfig { timeout: std::time::Duration::from_millis(5), ..ClientConfig::default() };
/// let client = Client::with_config(transport, config);
/// assert_eq!(client.config().retry.retries, 2);
/// ```
pub struct Client<T> {
    transport: T,
    config: ClientConfig,
    /// The request being sent.
    tx: [u8; MAX_ADU],
    /// The reply being received, skipped bytes first.
    rx: [u8; MAX_ADU],
    /// When the bus was last busy: last byte sent (as timed by the line) or received.
    bus_busy_until: Option<Instant>,
    /// No request before this (broadcast turnaround).
    quiet_until: Option<Instant>,
}

impl<T: Transport> Client<T> {
    /// A client with the default [`ClientConfig`].
    pub fn new(transport: T) -> Self {
        Self::with_config(transport, ClientConfig::default())
    }

    /// A client with `config`.
    pub fn with_config(transport: T, config: ClientConfig) -> Self {
        Self { transport, config, tx: [0; MAX_ADU], rx: [0; MAX_ADU], bus_busy_until: None, quiet_until: None }
    }

    /// The configuration.
    pub fn config(&self) -> &ClientConfig {
        &self.config
    }

    /// The configuration, to change between requests.
    pub fn config_mut(&mut self) -> &mut ClientConfig {
        &mut self.config
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The transport, mutably. Bytes read or written through it bypass the
    /// client's bus-silence tracking.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// The transport, dropping the client.
    pub fn into_transport(self) -> T {
        self.transport
    }

    /// The silence the client keeps before each request (see
    /// [`ClientConfig::inter_frame_delay`]).
    pub fn inter_frame_delay(&self) -> Duration {
        match self.config.inter_frame_delay {
            Some(delay) => delay,
            None => self.transport.line_timing().map_or(Duration::ZERO, |line| {
                // Above 19200 baud t3.5 is a fixed 1.75 ms whatever the
                // character format, so the floor has nothing to guard.
                if line.baud() > crate::timing::FIXED_TIMING_ABOVE_BAUD {
                    line.t3_5()
                } else {
                    line.t3_5().max(self.config.min_inter_frame_delay)
                }
            }),
        }
    }

    /// Sends `command` to `slave` and returns the decoded reply.
    ///
    /// Slave 0 (broadcast) is refused with [`EncodeError::InvalidSlave`]: use
    /// [`Client::broadcast`]. Commands with a fixed slave address (get slave
    /// id: 0xFF) must be called with that address, and their reply carries it.
    pub fn call<C: Command>(&mut self, slave: u8, command: &C) -> Result<C::Response, Error> {
        let _span = debug_span!("modbus", command = C::NAME, slave).entered();
        if slave == BROADCAST {
            return Err(EncodeError::InvalidSlave { slave }.into());
        }
        let len = command.encode_request(slave, &mut self.tx)?;
        self.transact(len, &C::LAYOUT, |frame| C::decode_response(slave, frame)).map(|(response, _)| response)
    }

    /// Sends a write `command` to every slave (address 0) and returns
    /// without waiting for a reply (none comes). The next request waits
    /// [`ClientConfig::broadcast_turnaround`]. Never retried.
    pub fn broadcast<C: Command>(&mut self, command: &C) -> Result<(), Error> {
        let _span = debug_span!("modbus", command = C::NAME, slave = BROADCAST).entered();
        if C::LAYOUT.function != Function::Write {
            return Err(EncodeError::InvalidSlave { slave: BROADCAST }.into());
        }
        let len = command.encode_request(BROADCAST, &mut self.tx)?;
        self.send_broadcast(len)
    }

    /// Sends a request frame built elsewhere (the spec interpreter) with the
    /// same timing, framing, checks and retries as [`Client::call`], and
    /// returns the checked reply frame (address to CRC). The slave is the
    /// request's first byte.
    ///
    /// The request must match `layout` ([`Layout::decode_request`]), else
    /// [`Error::Request`]; broadcast requests are refused (use
    /// [`Client::broadcast_raw`]).
    pub fn call_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<&[u8], Error> {
        let slave = self.load_request(request, layout)?;
        let _span = debug_span!("modbus", function = layout.function.code(), address = layout.address, slave).entered();
        if slave == BROADCAST {
            return Err(EncodeError::InvalidSlave { slave }.into());
        }
        let (_, range) =
            self.transact(request.len(), layout, |frame| layout.decode_response(slave, frame).map(drop))?;
        Ok(self.rx.get(range).unwrap_or(&[]))
    }

    /// Sends a broadcast request frame built elsewhere; see
    /// [`Client::broadcast`] and [`Client::call_raw`]. The request must be a
    /// write addressed to slave 0.
    pub fn broadcast_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<(), Error> {
        let slave = self.load_request(request, layout)?;
        let _span = debug_span!("modbus", function = layout.function.code(), address = layout.address, slave).entered();
        if slave != BROADCAST || layout.function != Function::Write {
            return Err(EncodeError::InvalidSlave { slave }.into());
        }
        self.send_broadcast(request.len())
    }

    /// Checks a raw request against `layout`, copies it to the send buffer
    /// and returns its slave address.
    fn load_request(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<u8, Error> {
        let (slave, _) = layout.decode_request(request).map_err(Error::Request)?;
        layout.check_slave(slave)?;
        let tx = self.tx.get_mut(..request.len()).ok_or(EncodeError::BufferTooSmall { needed: request.len() })?;
        tx.copy_from_slice(request);
        Ok(slave)
    }

    fn send_broadcast(&mut self, len: usize) -> Result<(), Error> {
        self.prepare()?;
        let sent = self.send(len)?;
        self.quiet_until = sent.checked_add(self.config.broadcast_turnaround.min(MAX_WAIT));
        Ok(())
    }

    /// Sends `tx[..len]` and reads the reply until `decode` accepts it or the
    /// retry policy gives up. Returns the decoded value and the frame's place in `rx`.
    fn transact<R>(
        &mut self,
        len: usize,
        layout: &Layout<'_>,
        decode: impl Fn(&[u8]) -> Result<R, FrameError>,
    ) -> Result<(R, Range<usize>), Error> {
        let normal_len = layout.response_len();
        let short_len = layout.short_response_len();
        if normal_len > MAX_ADU {
            return Err(EncodeError::BufferTooSmall { needed: normal_len }.into());
        }
        let function = layout.function.code();
        let policy = self.config.retry;
        let mut attempt: u32 = 0;
        loop {
            let result = self.attempt(len, function, normal_len, short_len).and_then(|range| {
                let frame = self.rx.get(range.clone()).unwrap_or(&[]);
                match decode(frame) {
                    Ok(response) => Ok((response, range)),
                    Err(error) => Err(Error::Frame { error, raw: RawBytes::new(frame) }),
                }
            });
            match result {
                Err(error) if attempt < policy.retries && policy.should_retry(&error) => {
                    attempt += 1;
                    warn!(attempt, retries = policy.retries, %error, "retrying");
                    thread::sleep(policy.backoff.min(MAX_WAIT));
                }
                other => return other,
            }
        }
    }

    /// One request and its reply: returns the reply frame's place in `rx`.
    fn attempt(
        &mut self,
        len: usize,
        function: u8,
        normal_len: usize,
        short_len: Option<usize>,
    ) -> Result<Range<usize>, Error> {
        self.prepare()?;
        let sent = self.send(len)?;
        let deadline = sent.checked_add(self.config.timeout.min(MAX_WAIT)).unwrap_or(sent);
        self.receive(function, normal_len, short_len, deadline)
    }

    /// Waits for bus silence and drops stale input.
    fn prepare(&mut self) -> Result<(), Error> {
        let gap = self.inter_frame_delay();
        self.wait_for_silence(gap);
        if self.drain_stale()? {
            // Someone was talking: give them their t3.5 too.
            self.wait_for_silence(gap);
        }
        self.transport.discard_input()?;
        Ok(())
    }

    fn wait_for_silence(&self, gap: Duration) {
        let after_activity = self.bus_busy_until.and_then(|busy| busy.checked_add(gap));
        let until = match (after_activity, self.quiet_until) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
        if let Some(until) = until {
            let wait = until.saturating_duration_since(Instant::now());
            if !wait.is_zero() {
                thread::sleep(wait.min(MAX_WAIT));
            }
        }
    }

    /// Reads and logs input that is already there. Returns whether there was any.
    fn drain_stale(&mut self) -> Result<bool, Error> {
        let mut any = false;
        for _ in 0..DRAIN_ROUNDS {
            let n = self.transport.read(&mut self.rx, Duration::ZERO)?.min(MAX_ADU);
            if n == 0 {
                break;
            }
            any = true;
            self.bus_busy_until = Some(Instant::now());
            debug!(stale = %Hex(self.rx.get(..n).unwrap_or(&[])), "discarding stale input");
        }
        Ok(any)
    }

    /// Sends `tx[..len]`; returns when it finished on the line (for a serial
    /// line, no earlier than its start plus its line time).
    fn send(&mut self, len: usize) -> Result<Instant, Error> {
        let frame = self.tx.get(..len).ok_or(EncodeError::BufferTooSmall { needed: len })?;
        debug!(frame = %Hex(frame), "tx");
        let start = Instant::now();
        let result = self.transport.write_all(frame);
        let now = Instant::now();
        let on_line = self
            .transport
            .line_timing()
            .and_then(|line| start.checked_add(line.frame_time(len)))
            .map_or(now, |end| end.max(now));
        self.bus_busy_until = Some(on_line);
        result?;
        Ok(on_line)
    }

    /// Reads one reply to `function` by length, before `deadline`.
    ///
    /// A frame starts at the first byte whose successor is the function (or
    /// exception) code; bytes before it are noise. That rule alone misframes
    /// a reply whose slave address looks like a function code (slave 3
    /// answering a read: `AA 03 03 04 ...` has 0x03 second), so a complete
    /// candidate whose CRC fails is not the end: the next alignment is tried
    /// with the bytes that keep arriving, waiting at most
    /// [`Client::inter_frame_delay`] (at least
    /// [`ClientConfig::min_inter_frame_delay`]) for each further byte. When
    /// none comes, the first failed candidate is the reply (and its CRC
    /// error is reported). After the deadline, at most [`MAX_ADU`] more bytes
    /// are looked at, so a device that never stops talking cannot hold the
    /// client.
    ///
    /// A trigger read may also be answered by a `short_len` frame (byte count
    /// 0, no data): it is taken as soon as that many bytes check.
    fn receive(
        &mut self,
        function: u8,
        normal_len: usize,
        short_len: Option<usize>,
        deadline: Instant,
    ) -> Result<Range<usize>, Error> {
        let exception = function | EXCEPTION_BIT;
        let more_bytes_wait = self.inter_frame_delay().max(self.config.min_inter_frame_delay);
        // The first complete candidate whose CRC failed, kept in case no better one follows.
        let mut rejected = [0u8; MAX_ADU];
        let mut rejected_len: Option<usize> = None;
        let mut late_bytes = 0usize;
        // rx[..start]: skipped bytes; rx[start..end]: the frame so far.
        let (mut start, mut end) = (0usize, 0usize);
        loop {
            while end.saturating_sub(start) >= 2 {
                match self.rx.get(start + 1) {
                    Some(&f) if f == function || f == exception => break,
                    _ => start += 1,
                }
            }
            let head = self.rx.get(start..end).unwrap_or(&[]);
            let target = if head.len() < HEAD_LEN {
                HEAD_LEN
            } else {
                frame::reply_len(head, function, normal_len).unwrap_or(normal_len)
            };
            if let Some(short) = short_len
                && head.len() >= short
                && head.get(1) == Some(&function)
                && head.get(2) == Some(&0)
                && head.get(..short).is_some_and(crc_ok)
            {
                debug!(frame = %Hex(head.get(..short).unwrap_or(&[])), "rx (short trigger reply)");
                return Ok(start..start + short);
            }
            if head.len() >= target {
                let frame = start..start + target;
                let bytes = self.rx.get(frame.clone()).unwrap_or(&[]);
                if crc_ok(bytes) {
                    if rejected_len.is_some() && holds_frame(self.rx.get(..start).unwrap_or(&[])) {
                        // What came before is a whole frame (an echo of the request,
                        // another conversation), not noise: report, do not guess.
                        return Ok(self.restore(&rejected, rejected_len));
                    }
                    if start > 0 {
                        debug!(skipped = %Hex(self.rx.get(..start).unwrap_or(&[])), "bytes before the reply");
                    }
                    debug!(frame = %Hex(bytes), "rx");
                    return Ok(frame);
                }
                debug!(candidate = %Hex(bytes), "CRC mismatch; looking for the frame further on");
                if rejected_len.is_none() {
                    if let Some(slot) = rejected.get_mut(..bytes.len()) {
                        slot.copy_from_slice(bytes);
                    }
                    rejected_len = Some(bytes.len());
                }
                start += 1;
                continue;
            }
            // Noise may also open a normal-length candidate around a shorter
            // exception reply (`AA 03 03 83 06 ..` from slave 3): take an
            // exception frame further on as soon as it is complete and checks.
            // (A later normal-length candidate cannot complete before this one.)
            if let Some(at) = (start + 1..end.saturating_sub(EXCEPTION_LEN - 1)).find(|&at| {
                self.rx.get(at + 1) == Some(&exception) && self.rx.get(at..at + EXCEPTION_LEN).is_some_and(crc_ok)
            }) {
                debug!(skipped = %Hex(self.rx.get(..at).unwrap_or(&[])), "bytes before the reply");
                return Ok(at..at + EXCEPTION_LEN);
            }
            if start + target > MAX_ADU {
                debug!(skipped = %Hex(self.rx.get(..start).unwrap_or(&[])), "bytes before the reply");
                self.rx.copy_within(start..end, 0);
                end -= start;
                start = 0;
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            let wait = if rejected_len.is_some() { remaining.min(more_bytes_wait) } else { remaining };
            let buf = self.rx.get_mut(end..start + target).unwrap_or_default();
            let n = self.transport.read(buf, wait)?.min(buf.len());
            if n > 0 {
                end += n;
                self.bus_busy_until = Some(Instant::now());
                if remaining.is_zero() {
                    late_bytes += n;
                }
            }
            let give_up = if n == 0 {
                rejected_len.is_some() || remaining.is_zero() || Instant::now() >= deadline
            } else {
                late_bytes > MAX_ADU
            };
            if give_up {
                if rejected_len.is_some() {
                    // No better candidate: the first one is the reply.
                    return Ok(self.restore(&rejected, rejected_len));
                }
                return Err(Error::Timeout { received: RawBytes::new(self.rx.get(..end).unwrap_or(&[])) });
            }
        }
    }
}

impl<T> Client<T> {
    /// Puts the first rejected candidate back at the start of `rx` and returns its place.
    fn restore(&mut self, rejected: &[u8; MAX_ADU], len: Option<usize>) -> Range<usize> {
        let frame = rejected.get(..len.unwrap_or(0)).unwrap_or(&[]);
        if let Some(slot) = self.rx.get_mut(..frame.len()) {
            slot.copy_from_slice(frame);
        }
        debug!(frame = %Hex(frame), "rx");
        0..frame.len()
    }
}

/// Whether `bytes` hold a whole frame: a run of at least 4 bytes that ends
/// in its own CRC (the CRC-16/MODBUS of a frame, CRC included, is zero).
fn holds_frame(bytes: &[u8]) -> bool {
    (0..bytes.len()).any(|from| {
        let mut crc = crate::crc::CRC_INIT;
        bytes.iter().skip(from).enumerate().any(|(i, &b)| {
            crc = crate::crc::crc16_update(crc, &[b]);
            i >= 3 && crc == 0
        })
    })
}

impl<T: fmt::Debug> fmt::Debug for Client<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Client")
            .field("transport", &self.transport)
            .field("config", &self.config)
            .field("bus_busy_until", &self.bus_busy_until)
            .finish_non_exhaustive()
    }
}

//! [`ClientCore`]: the Modbus RTU master transaction as a sans-IO state
//! machine. Every protocol decision of every driver lives here, once.

use core::convert::Infallible;
use core::ops::Range;
use core::time::Duration;

use super::config::ClientConfig;
use super::error::{ClientError, Sent};
use super::time::{Instant, duration_from_micros_clamped, micros_ceil};
use crate::command::Command;
use crate::crc::{CRC_INIT, crc_ok, crc16_update};
use crate::error::{EncodeError, FrameError};
use crate::frame::{self, BROADCAST, EXCEPTION_BIT, EXCEPTION_LEN, Function, Layout, MAX_ADU};
use crate::timing::{FIXED_TIMING_ABOVE_BAUD, LineTiming};

/// Bytes read before the reply's length is decided: slave, function and one
/// more (an exception reply is 5 bytes, so this never reads past a frame).
const HEAD_LEN: usize = 3;

/// Reads of pending (stale) input before each request.
const DRAIN_ROUNDS: u8 = 4;

/// What a driver must do next; returned by [`ClientCore::poll`].
///
/// Each action names the event the driver reports when it is done. Between
/// `start_*` and [`Action::Done`] the driver loops `poll`, act, report.
#[derive(Debug, PartialEq, Eq)]
// An explicit tag: a driver matches an action with one byte compare, not
// by decoding a niche inside the nested `Result` (see BENCHMARKS.md).
#[repr(u8)]
pub enum Action<'a> {
    /// Keep the bus silent: sleep until `until` on the driver's clock, then
    /// report [`ClientCore::handle_timeout`] with the time (any time at or
    /// after `until`; a driver that slept may pass `until` itself). A driver
    /// that reads its clock first and finds `until` passed skips the sleep.
    Wait {
        /// The end of the silence.
        until: Instant,
    },
    /// Read input that has already arrived, without waiting, into
    /// [`ClientCore::recv_buf`]; report [`ClientCore::handle_received`] with
    /// the count (and the time) when there was any,
    /// [`ClientCore::handle_nothing_pending`] when there was none.
    ReadPending,
    /// Drop input the link still holds (an OS or adapter buffer, where it
    /// can), then write these bytes and report
    /// [`ClientCore::handle_write_done`] with the time the write returned
    /// (also when it failed, before giving up).
    Transmit(&'a [u8]),
    /// Read into [`ClientCore::recv_buf`], waiting at most `timeout` for the
    /// first byte (zero: take only what is buffered), measured from the last
    /// time reported. Report [`ClientCore::handle_read`] with the count (0
    /// when nothing arrived) and the driver's clock, which it reads only
    /// when it needs the time (or [`ClientCore::handle_received`] with the
    /// count and the time).
    ///
    /// When `needs_time` is false, bytes read cannot complete a frame (the
    /// 3-byte head) and the core does not need their time: `handle_read`
    /// skips the clock and uses [`ClientCore::now`]. The next read then takes
    /// only what is buffered, and is timed; so a reply that is already
    /// buffered costs one clock read, not two.
    Receive {
        /// The longest wait for the first byte: at most `u32::MAX` µs (about
        /// 71 minutes); a later deadline is reached by reads asked for again.
        timeout: Duration,
        /// Whether `handle_received` needs the time the read returned.
        needs_time: bool,
    },
    /// A candidate reply frame, whole and of the expected length
    /// ([`ClientCore::candidate`]), is to be decoded: call
    /// [`ClientCore::check_with`] with the decoder (or decode the candidate
    /// and report [`ClientCore::handle_check`] with the verdict). The decoder
    /// checks the CRC, so the core does not compute it again. On `Ok` the
    /// driver keeps the decoded value; it is the reply if the next action is
    /// `Done(Ok(()))`.
    Check,
    /// No transaction: none was started, or the driver reported a link error.
    Idle,
    /// The transaction is over. The bytes received are in
    /// [`ClientCore::last_reply`] until the next transaction starts.
    Done(Result<(), ClientError<Infallible>>),
}

/// The reply a transaction waits for, from the command's [`Layout`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Expected {
    /// The function code (an exception reply carries it with the 0x80 bit).
    function: u8,
    /// Bytes in a normal reply.
    normal_len: usize,
    /// Bytes in the short reply a trigger read may also get.
    short_len: Option<usize>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
// Explicit tags, as for `Action`: `poll` and every `handle_*` match on it.
#[repr(u8)]
enum State {
    /// No transaction (none started, or abandoned on a link error).
    Idle,
    /// The last transaction is over: [`ClientCore::outcome`].
    Done,
    /// Waiting for the bus to be silent before a request (`again` after stale input).
    Silence { again: bool },
    /// Reading stale input: `round` reads done, `any` bytes seen.
    Drain { round: u8, any: bool },
    /// The request is to be written.
    Transmit,
    /// Reading the reply.
    Receive,
    /// A candidate frame is with the driver's decoder.
    Check(Candidate),
    /// Waiting out the retry policy's backoff.
    Backoff { until: Instant },
}

/// Why a frame was offered for decoding: it decides what a verdict means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum Candidate {
    /// A frame of the length its head announces, at `rx[start..]`.
    Normal,
    /// A trigger read's short reply (byte count 0, no data) at `rx[start..]`.
    Short,
    /// An exception reply, or a trigger read's short reply, further on
    /// whose CRC already checked, at `rx[at..at + len]`.
    Later { at: usize, len: usize },
}

/// Where the bytes of [`ClientCore::last_reply`] are.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Reply {
    Rx(Range<usize>),
    Rejected,
}

/// The Modbus RTU master, without I/O: one transaction at a time (request,
/// reply, retries), driven by a driver that owns the link and the clock.
///
/// It holds the request, reply and rejected-candidate buffers (3 ×
/// [`MAX_ADU`] bytes, no allocation) and the bus state that outlives a
/// transaction: when the bus was last busy and how long it must stay quiet
/// (t3.5, broadcast turnaround). A transaction abandoned half-way (a driver
/// error, a dropped future) leaves that state behind: the next transaction
/// stays quiet until the abandoned one's deadline, then discards the late
/// reply as stale input and keeps t3.5 after it.
///
/// # Driving it
///
/// Encode the request into [`ClientCore::request_buf`] and call
/// [`ClientCore::start_call`] (or [`ClientCore::start_broadcast`]), then
/// loop: [`ClientCore::poll`] names an [`Action`], the driver performs it and
/// reports the matching `handle_*` event, until [`Action::Done`]. Times are
/// [`Instant`]s on the driver's monotonic clock; the core asks for a time
/// only when it needs one (after a write, after a read that returned bytes
/// or timed out, after a wait), so a successful transaction costs two clock
/// reads when no silence is pending.
///
/// ```
/// use core::time::Duration;
/// use yosemitech_rtu::client::{Action, ClientCore, Instant};
/// use yosemitech_rtu::{ClientConfig, Layout};
///
/// const GET_PH: Layout<'static> = Layout::read(0x2800, 2);
/// let mut core = ClientCore::new(ClientConfig::default());
/// let len = GET_PH.encode_request(1, &[], core.request_buf()).unwrap();
/// core.start_call(len, &GET_PH).unwrap();
/// assert_eq!(core.poll(), Action::ReadPending);
/// core.handle_nothing_pending();
/// assert_eq!(core.poll(), Action::Transmit(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB]));
/// core.handle_write_done(Instant::from_micros(1_000));
/// assert_eq!(core.poll(), Action::Receive { timeout: Duration::from_secs(1), needs_time: false });
/// let reply = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];
/// let n = core.recv_buf().len(); // 3: the head first
/// core.recv_buf().copy_from_slice(&reply[..n]);
/// core.handle_received(n, Instant::from_micros(20_000));
/// let rest = core.recv_buf().len(); // then exactly the rest
/// core.recv_buf().copy_from_slice(&reply[n..n + rest]);
/// core.handle_received(rest, Instant::from_micros(21_000));
/// assert_eq!(core.poll(), Action::Check);
/// core.check_with(|frame| GET_PH.decode_response(1, frame).map(drop));
/// assert_eq!(core.poll(), Action::Done(Ok(())));
/// assert_eq!(core.last_reply(), reply);
/// ```
#[derive(Clone)]
pub struct ClientCore {
    config: ClientConfig,
    line: Option<LineTiming>,
    /// The request: `tx[..tx_len]`.
    tx: [u8; MAX_ADU],
    tx_len: usize,
    /// The reply being received: `rx[..start]` skipped, `rx[start..end]` the frame so far.
    rx: [u8; MAX_ADU],
    start: usize,
    end: usize,
    /// The first complete candidate whose CRC failed, kept in case no better one follows.
    rejected: [u8; MAX_ADU],
    rejected_len: usize,
    rejected_error: Option<FrameError>,
    /// The start at which a short trigger reply failed its check (not offered again).
    short_failed_at: Option<usize>,
    /// Bytes read after the deadline (a device that never stops talking).
    late_bytes: usize,
    reply: Reply,
    /// `None` for a broadcast.
    expected: Option<Expected>,
    attempt: u32,
    /// When the current attempt's reply must be complete.
    deadline: Instant,
    /// The inter-frame delay of this transaction (from the config and the
    /// line) in microseconds, rounded up: added to a time at every poll
    /// before a request, so kept in the unit of [`Instant`].
    gap_micros: u64,
    /// The latest time a driver reported, and whether it was reported in this transaction.
    now: Instant,
    now_is_fresh: bool,
    /// Bytes were reported without their time (see [`Action::Receive`]).
    time_stale: bool,
    /// When the bus was last busy: last byte sent (as timed by the line) or received.
    bus_busy_until: Option<Instant>,
    /// No request before this (broadcast turnaround, an abandoned attempt's deadline).
    quiet_until: Option<Instant>,
    state: State,
    /// How the last transaction ended (when `state` is `Done`).
    outcome: Result<(), ClientError<Infallible>>,
    /// The length to read for: 3 for the head, then the frame's (see `frame_input`).
    target: usize,
    /// The current request's command name, when it was sent as a typed command.
    command: Option<&'static str>,
}

impl ClientCore {
    /// A core with `config`, no line timing and a bus assumed silent.
    pub const fn new(config: ClientConfig) -> Self {
        Self {
            config,
            line: None,
            tx: [0; MAX_ADU],
            tx_len: 0,
            rx: [0; MAX_ADU],
            start: 0,
            end: 0,
            rejected: [0; MAX_ADU],
            rejected_len: 0,
            rejected_error: None,
            short_failed_at: None,
            late_bytes: 0,
            reply: Reply::Rx(0..0),
            expected: None,
            attempt: 0,
            deadline: Instant::ZERO,
            gap_micros: 0,
            now: Instant::ZERO,
            now_is_fresh: false,
            time_stale: false,
            bus_busy_until: None,
            quiet_until: None,
            state: State::Idle,
            outcome: Ok(()),
            target: HEAD_LEN,
            command: None,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &ClientConfig {
        &self.config
    }

    /// The configuration, to change between transactions.
    pub fn config_mut(&mut self) -> &mut ClientConfig {
        &mut self.config
    }

    /// Sets the baud rate and character format of the serial line, from
    /// which t3.5 and the request's time on the line follow; `None` for links
    /// without line timing (TCP, in-memory). Drivers call it before each
    /// transaction (it is cheap) or when the line changes.
    #[inline]
    pub fn set_line_timing(&mut self, line: Option<LineTiming>) {
        if self.line != line {
            self.line = line;
            self.set_gap();
        }
    }

    /// [`ClientCore::inter_frame_delay`] in microseconds, rounded up, from
    /// the line's timing in microseconds: the same rule without the 64-bit
    /// divisions of a `Duration` (a library routine on a 32-bit MCU).
    #[inline]
    fn set_gap(&mut self) {
        self.gap_micros = match self.config.inter_frame_delay {
            Some(delay) => micros_ceil(delay),
            None => self.line.map_or(0, |line| {
                if line.baud() > FIXED_TIMING_ABOVE_BAUD {
                    line.t3_5_micros_ceil()
                } else {
                    line.t3_5_micros_ceil().max(micros_ceil(self.config.min_inter_frame_delay))
                }
            }),
        };
    }

    /// The silence kept before each request (see
    /// [`ClientConfig::inter_frame_delay`]).
    pub fn inter_frame_delay(&self) -> Duration {
        self.inter_frame_delay_on(self.line)
    }

    /// The silence this core would keep before each request on a line of timing `line`.
    pub fn inter_frame_delay_on(&self, line: Option<LineTiming>) -> Duration {
        match self.config.inter_frame_delay {
            Some(delay) => delay,
            None => line.map_or(Duration::ZERO, |line| {
                // Above 19200 baud t3.5 is a fixed 1.75 ms whatever the
                // character format, so the floor has nothing to guard.
                if line.baud() > FIXED_TIMING_ABOVE_BAUD {
                    line.t3_5()
                } else {
                    line.t3_5().max(self.config.min_inter_frame_delay)
                }
            }),
        }
    }

    /// The buffer to encode the next request into ([`MAX_ADU`] bytes).
    pub fn request_buf(&mut self) -> &mut [u8] {
        &mut self.tx
    }

    /// Encodes `command` for `slave` and starts its transaction
    /// ([`ClientCore::start_call`]). Slave 0 is refused with
    /// [`EncodeError::InvalidSlave`]: broadcasts go through
    /// [`ClientCore::start_command_broadcast`].
    #[inline]
    pub fn start_command<C: Command>(&mut self, slave: u8, command: &C) -> Result<(), ClientError<Infallible>> {
        if slave == BROADCAST {
            return Err(EncodeError::InvalidSlave { slave }.into());
        }
        let len = command.encode_request(slave, &mut self.tx)?;
        self.start_call(len, &C::LAYOUT)?;
        self.command = Some(C::NAME);
        Ok(())
    }

    /// Encodes a write `command` for every slave (address 0) and starts its
    /// broadcast ([`ClientCore::start_broadcast`]).
    #[inline]
    pub fn start_command_broadcast<C: Command>(&mut self, command: &C) -> Result<(), ClientError<Infallible>> {
        if C::LAYOUT.function != Function::Write {
            return Err(EncodeError::InvalidSlave { slave: BROADCAST }.into());
        }
        let len = command.encode_request(BROADCAST, &mut self.tx)?;
        self.start_broadcast(len, &C::LAYOUT)?;
        self.command = Some(C::NAME);
        Ok(())
    }

    /// Starts the transaction of a raw request frame built elsewhere (the
    /// spec interpreter), checked against `layout` ([`ClientCore::load_request`]);
    /// returns its slave address, which the reply's decoder needs.
    #[inline]
    pub fn start_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<u8, ClientError<Infallible>> {
        let (len, slave) = self.load_request(request, layout)?;
        self.start_call(len, layout)?;
        Ok(slave)
    }

    /// Starts the broadcast of a raw request frame addressed to slave 0.
    pub fn start_raw_broadcast(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<(), ClientError<Infallible>> {
        let (len, _) = self.load_request(request, layout)?;
        self.start_broadcast(len, layout)
    }

    /// Checks a raw request frame built elsewhere (the spec interpreter)
    /// against `layout`, copies it to the request buffer and returns its
    /// length and slave address.
    #[inline]
    pub fn load_request(
        &mut self,
        request: &[u8],
        layout: &Layout<'_>,
    ) -> Result<(usize, u8), ClientError<Infallible>> {
        let (slave, _) = layout.decode_request(request).map_err(ClientError::Request)?;
        layout.check_slave(slave)?;
        let tx = self.tx.get_mut(..request.len()).ok_or(EncodeError::FrameTooLong { len: request.len() })?;
        tx.copy_from_slice(request);
        Ok((request.len(), slave))
    }

    /// Starts a transaction that sends `request_buf()[..request_len]` and
    /// waits for its reply, framed by `layout`. An unfinished transaction is
    /// abandoned (see the type's docs). Fails, sending nothing, when the
    /// request is addressed to slave 0 (broadcasts get no reply: use
    /// [`ClientCore::start_broadcast`]) or its reply cannot fit [`MAX_ADU`].
    #[inline]
    pub fn start_call(&mut self, request_len: usize, layout: &Layout<'_>) -> Result<(), ClientError<Infallible>> {
        if self.tx.first() == Some(&BROADCAST) {
            return Err(EncodeError::InvalidSlave { slave: BROADCAST }.into());
        }
        let normal_len = layout.response_len();
        if normal_len > MAX_ADU {
            return Err(EncodeError::FrameTooLong { len: normal_len }.into());
        }
        let expected =
            Expected { function: layout.function.code(), normal_len, short_len: layout.short_response_len() };
        self.begin(request_len, Some(expected))
    }

    /// Starts a broadcast of `request_buf()[..request_len]`: a write to slave
    /// 0, sent after the usual silence, never answered nor retried; the next
    /// request keeps [`ClientConfig::broadcast_turnaround`] after it.
    pub fn start_broadcast(&mut self, request_len: usize, layout: &Layout<'_>) -> Result<(), ClientError<Infallible>> {
        if self.tx.first() != Some(&BROADCAST) || layout.function != Function::Write {
            let slave = self.tx.first().copied().unwrap_or(BROADCAST);
            return Err(EncodeError::InvalidSlave { slave }.into());
        }
        self.begin(request_len, None)
    }

    #[inline]
    fn begin(&mut self, request_len: usize, expected: Option<Expected>) -> Result<(), ClientError<Infallible>> {
        if request_len > MAX_ADU {
            return Err(EncodeError::FrameTooLong { len: request_len }.into());
        }
        self.command = None;
        if matches!(self.state, State::Receive | State::Check(_)) {
            // The abandoned attempt's reply may still come: no request
            // before its deadline; draining then drops it.
            self.quiet_until = self.quiet_until.max(Some(self.deadline));
        }
        self.tx_len = request_len;
        self.set_gap();
        self.expected = expected;
        self.attempt = 0;
        self.now_is_fresh = false;
        self.reply = Reply::Rx(0..0);
        self.state = State::Silence { again: false };
        Ok(())
    }

    /// What the driver must do next. Calling it again without reporting an
    /// event returns the same action.
    #[inline]
    pub fn poll(&mut self) -> Action<'_> {
        match self.state {
            State::Idle => Action::Idle,
            State::Done => Action::Done(self.outcome),
            State::Silence { again } => self.poll_silence(again),
            // `handle_*` end the drain after its last round.
            State::Drain { .. } => Action::ReadPending,
            State::Transmit => Action::Transmit(self.tx.get(..self.tx_len).unwrap_or(&[])),
            State::Receive => Action::Receive { timeout: self.receive_timeout(), needs_time: self.read_needs_time() },
            State::Check(_) => Action::Check,
            State::Backoff { until } => Action::Wait { until },
        }
    }

    /// [`ClientCore::poll`] in a silence before the request. Out of line, so
    /// the silence's arithmetic is not hoisted into every other poll.
    #[inline(never)]
    fn poll_silence(&mut self, again: bool) -> Action<'_> {
        if let Some(until) = self.silence_until() {
            return Action::Wait { until };
        }
        if again {
            self.state = State::Transmit;
            Action::Transmit(self.tx.get(..self.tx_len).unwrap_or(&[]))
        } else {
            self.state = State::Drain { round: 0, any: false };
            Action::ReadPending
        }
    }

    /// Ends a drain of stale input: the request goes out at once, or after
    /// another silence when there was any.
    #[inline]
    fn end_drain(&mut self, any: bool) {
        self.state = if any { State::Silence { again: true } } else { State::Transmit };
    }

    /// The end of the silence still to keep before a request, `None` when
    /// the latest time reported is past it (and, on a timed line, is fresh:
    /// the request's time on the line is counted from it).
    #[inline]
    fn silence_until(&self) -> Option<Instant> {
        let gap = self.gap_micros;
        let after_activity = self.bus_busy_until.map(|busy| busy.add_micros(gap));
        match after_activity.max(self.quiet_until) {
            // The latest time reported may be stale: the driver checks its clock.
            Some(until) if until > self.now => Some(until),
            // On a timed line the request's end on the wire is counted from
            // its start, so the core needs a time from this transaction.
            _ if self.line.is_some() && !self.now_is_fresh => Some(self.now),
            _ => None,
        }
    }

    /// The bytes the next read should fill: the 3-byte head, then exactly
    /// the rest of the frame; for [`Action::ReadPending`], a whole buffer.
    #[inline]
    pub fn recv_buf(&mut self) -> &mut [u8] {
        match self.state {
            State::Receive => {
                let target = self.target();
                self.rx.get_mut(self.end..self.start + target).unwrap_or_default()
            }
            _ => &mut self.rx,
        }
    }

    /// Reports a wait's end: the time is now `now`.
    #[inline]
    pub fn handle_timeout(&mut self, now: Instant) {
        let before = self.now;
        self.set_now(now);
        match self.state {
            State::Backoff { until } if now >= until => self.state = State::Silence { again: false },
            // Nothing arrived: after a rejected candidate, no better one
            // comes; otherwise time out at the deadline (or at once when the
            // read started after it).
            State::Receive => {
                // After bytes reported without a time, this was a read of what
                // was buffered: nothing there is no timeout, and those bytes
                // arrived by now.
                let buffered_only = core::mem::take(&mut self.time_stale);
                if buffered_only {
                    self.bus_busy_until = Some(now);
                }
                let no_better_candidate = self.rejected_error.is_some() && !buffered_only;
                let read_after_deadline = before >= self.deadline && !buffered_only;
                if no_better_candidate || read_after_deadline || now >= self.deadline {
                    self.give_up();
                }
            }
            // A silence re-checks its end at the next poll.
            _ => {}
        }
    }

    /// Reports that a pending-input read ([`Action::ReadPending`]) found nothing.
    #[inline]
    pub fn handle_nothing_pending(&mut self) {
        if let State::Drain { any, .. } = self.state {
            self.end_drain(any);
        }
    }

    /// Reports the write of [`Action::Transmit`] returned at `now`.
    #[inline]
    pub fn handle_write_done(&mut self, now: Instant) {
        if !matches!(self.state, State::Transmit) {
            return;
        }
        // On a timed line the request is on the wire until its start (the
        // last time reported, fresh here) plus its line time.
        let on_line = self.line.map_or(now, |line| self.now.add_micros(line.frame_micros_ceil(self.tx_len)).max(now));
        self.set_now(now);
        self.bus_busy_until = Some(on_line);
        log!(debug, frame = %crate::Hex(self.tx.get(..self.tx_len).unwrap_or(&[])), "tx");
        match self.expected {
            None => {
                self.quiet_until = Some(on_line + self.config.broadcast_turnaround);
                self.outcome = Ok(());
                self.state = State::Done;
            }
            Some(_) => {
                self.deadline = on_line + self.config.timeout;
                self.start = 0;
                self.end = 0;
                self.time_stale = false;
                self.target = HEAD_LEN;
                self.rejected_error = None;
                self.rejected_len = 0;
                self.short_failed_at = None;
                self.late_bytes = 0;
                self.state = State::Receive;
            }
        }
    }

    /// Reports `n` bytes read into [`ClientCore::recv_buf`] at `now`.
    #[inline]
    pub fn handle_received(&mut self, n: usize, now: Instant) {
        if n == 0 {
            if let State::Drain { .. } = self.state {
                return self.handle_nothing_pending();
            }
            return self.handle_timeout(now);
        }
        let before = self.now;
        match self.state {
            State::Receive => {
                if self.read_needs_time() {
                    self.time_stale = false;
                    self.set_now(now);
                    self.bus_busy_until = Some(now);
                } else {
                    self.time_stale = true;
                }
                let room = (self.start + self.target).saturating_sub(self.end);
                self.end += n.min(room);
                if before >= self.deadline {
                    self.late_bytes += n;
                    if self.late_bytes > MAX_ADU {
                        return self.give_up();
                    }
                }
                self.frame_input();
            }
            State::Drain { round, .. } => {
                self.time_stale = false;
                self.set_now(now);
                self.bus_busy_until = Some(now);
                log!(debug, stale = %crate::Hex(self.rx.get(..n.min(MAX_ADU)).unwrap_or(&[])), "discarding stale input");
                if round + 1 < DRAIN_ROUNDS {
                    self.state = State::Drain { round: round + 1, any: true };
                } else {
                    self.end_drain(true);
                }
            }
            _ => {
                self.time_stale = false;
                self.set_now(now);
            }
        }
    }

    /// Reports that the driver gave up on the transaction because the link
    /// failed (a write or read error). The bus state stays (the silence after
    /// the last byte is still kept); the reply window is not waited out, as
    /// nothing more is expected from a failed link.
    pub fn handle_link_error(&mut self) {
        self.state = State::Idle;
    }

    /// Ends a driver's run of the transaction with its `result`: a link
    /// error is reported to the core ([`ClientCore::handle_link_error`]),
    /// every result is passed through.
    #[inline]
    pub fn finish<E>(&mut self, result: Result<(), ClientError<E>>) -> Result<(), ClientError<E>> {
        if let Err(ClientError::Io(_)) = result {
            self.handle_link_error();
        }
        result
    }

    /// Reports the read of [`Action::Receive`] that returned `n` bytes
    /// (0: it timed out), reading the driver's `clock` only when the core
    /// needs the time (see `needs_time`).
    #[inline]
    pub fn handle_read(&mut self, n: usize, clock: impl FnOnce() -> Instant) {
        let now = if n == 0 || self.read_needs_time() { clock() } else { self.now };
        self.handle_received(n, now);
    }

    /// Performs [`Action::Check`]: offers the candidate frame to `decode`
    /// and reports its verdict ([`ClientCore::handle_check`]). Does nothing
    /// in any other state.
    #[inline]
    pub fn check_with(&mut self, decode: impl FnOnce(&[u8]) -> Result<(), FrameError>) {
        if let State::Check(_) = self.state {
            let verdict = decode(self.candidate());
            self.handle_check(verdict);
        }
    }

    /// The candidate frame of [`Action::Check`]; empty in any other state.
    #[inline]
    pub fn candidate(&self) -> &[u8] {
        match self.state {
            State::Check(candidate) => self.rx.get(self.candidate_frame(candidate)).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Reports the decoder's verdict on [`ClientCore::candidate`]: `Ok`
    /// when it decoded, the first check that failed otherwise.
    #[inline]
    pub fn handle_check(&mut self, verdict: Result<(), FrameError>) {
        let State::Check(candidate) = self.state else { return };
        let frame = self.candidate_frame(candidate);
        // A decoder checks the CRC first; should one not, a failure is
        // checked here (on the error path only) so realignment still works.
        let crc_failed = match verdict {
            Ok(()) => false,
            Err(FrameError::Crc { .. }) => true,
            Err(_) => !matches!(candidate, Candidate::Later { .. }) && !self.rx.get(frame.clone()).is_some_and(crc_ok),
        };
        if crc_failed {
            let error = match verdict {
                Err(error @ FrameError::Crc { .. }) => error,
                _ => crc_error(self.rx.get(frame.clone()).unwrap_or(&[])),
            };
            match candidate {
                Candidate::Short => {
                    self.short_failed_at = Some(self.start);
                }
                _ => {
                    log!(debug, candidate = %crate::Hex(self.rx.get(frame.clone()).unwrap_or(&[])), "CRC mismatch; looking for the frame further on");
                    if self.rejected_error.is_none() {
                        let bytes = self.rx.get(frame).unwrap_or(&[]);
                        if let Some(slot) = self.rejected.get_mut(..bytes.len()) {
                            slot.copy_from_slice(bytes);
                        }
                        self.rejected_len = bytes.len();
                        self.rejected_error = Some(error);
                    }
                    self.start += 1;
                    self.target = HEAD_LEN;
                }
            }
            self.state = State::Receive;
            return self.frame_input();
        }
        if candidate == Candidate::Normal
            && self.rejected_error.is_some()
            && holds_frame(self.rx.get(..self.start).unwrap_or(&[]))
        {
            // What came before is a whole frame (an echo of the request,
            // another conversation), not noise: report, do not guess.
            return self.give_up();
        }
        if frame.start > 0 {
            log!(debug, skipped = %crate::Hex(self.rx.get(..frame.start).unwrap_or(&[])), "bytes before the reply");
        }
        log!(debug, frame = %crate::Hex(self.rx.get(frame.clone()).unwrap_or(&[])), "rx");
        self.reply = Reply::Rx(frame);
        self.finish_attempt(verdict.map_err(|error| ClientError::Frame { error }));
    }

    /// The bytes of the last reply: the frame for a reply that decoded or
    /// failed a check, every byte received for a timeout; empty after a
    /// broadcast or before any reply. Kept until the next transaction starts.
    #[inline]
    pub fn last_reply(&self) -> &[u8] {
        match &self.reply {
            Reply::Rx(range) => self.rx.get(range.clone()).unwrap_or(&[]),
            Reply::Rejected => self.rejected.get(..self.rejected_len).unwrap_or(&[]),
        }
    }

    /// The request of the current or last transaction, as errors name it.
    pub fn sent(&self) -> Sent {
        let [slave, function, hi, lo, ..] = self.tx;
        Sent { slave, function, register: u16::from_be_bytes([hi, lo]), command: self.command }
    }

    /// The attempts after the first that the current or last transaction
    /// took ([`RetryPolicy::retries`](crate::RetryPolicy::retries) at most):
    /// what a logger counts as a request's retries.
    #[inline]
    pub fn retries(&self) -> u32 {
        self.attempt
    }

    /// The latest time a driver reported.
    #[inline]
    pub fn now(&self) -> Instant {
        self.now
    }

    #[inline]
    fn set_now(&mut self, now: Instant) {
        self.now = self.now.max(now);
        self.now_is_fresh = true;
    }

    /// The frame length to read for, from the head received so far.
    #[inline]
    fn target(&self) -> usize {
        self.target
    }

    /// Computes [`ClientCore::target`] from the head received so far.
    #[inline]
    fn reply_target(&self) -> usize {
        let Some(expected) = self.expected else { return 0 };
        let head = self.rx.get(self.start..self.end).unwrap_or(&[]);
        if head.len() < HEAD_LEN {
            HEAD_LEN
        } else {
            frame::reply_len(head, expected.function, expected.normal_len).unwrap_or(expected.normal_len)
        }
    }

    /// Where the bytes of a candidate frame are in the reply buffer.
    #[inline]
    fn candidate_frame(&self, candidate: Candidate) -> Range<usize> {
        let len = match candidate {
            Candidate::Normal => self.target,
            Candidate::Short => self.expected.and_then(|expected| expected.short_len).unwrap_or(self.target),
            Candidate::Later { at, len } => return at..at + len,
        };
        self.start..self.start + len
    }

    /// Whether the time of the next reply read matters: it may complete a
    /// frame (the bus is busy until its last byte), or the previous read
    /// was reported without a time.
    #[inline]
    fn read_needs_time(&self) -> bool {
        self.time_stale || self.target() > HEAD_LEN
    }

    /// How long the next reply read may wait: nothing after bytes reported
    /// without a time (see [`Action::Receive`]); to the deadline, and after a
    /// rejected candidate at most one inter-frame delay (at least
    /// [`ClientConfig::min_inter_frame_delay`]) for each further byte.
    #[inline]
    fn receive_timeout(&self) -> Duration {
        if self.time_stale {
            return Duration::ZERO;
        }
        let remaining = self.deadline.as_micros().saturating_sub(self.now.as_micros());
        let micros = if self.rejected_error.is_some() {
            remaining.min(self.gap_micros.max(micros_ceil(self.config.min_inter_frame_delay)))
        } else {
            remaining
        };
        duration_from_micros_clamped(micros)
    }

    /// Frames the bytes received so far: skips noise, offers a complete
    /// candidate for checking, or asks for more bytes.
    ///
    /// A frame starts at the first byte whose successor is the function (or
    /// exception) code; bytes before it are noise. That rule alone misframes
    /// a reply whose slave address looks like a function code (slave 3
    /// answering a read: `AA 03 03 04 ...` has 0x03 second), so a complete
    /// candidate whose CRC fails is not the end: the next alignment is tried
    /// with the bytes that keep arriving. When none comes, the first failed
    /// candidate is the reply (and its CRC error is reported).
    #[inline]
    fn frame_input(&mut self) {
        // The common case: the rest of a frame whose head was aligned and
        // measured by the previous call (`target` is reset to the head's
        // length whenever the alignment moves). `frame_input_from_head`
        // would find the same alignment and length again.
        if self.target > HEAD_LEN
            && self.expected.is_some_and(|expected| expected.short_len.is_none())
            && self.end.saturating_sub(self.start) >= self.target
        {
            self.state = State::Check(Candidate::Normal);
        } else {
            self.frame_input_from_head();
        }
    }

    /// [`ClientCore::frame_input`] from the alignment up.
    #[inline(never)]
    fn frame_input_from_head(&mut self) {
        let Some(expected) = self.expected else { return };
        let exception = expected.function | EXCEPTION_BIT;
        while self.end.saturating_sub(self.start) >= 2 {
            match self.rx.get(self.start + 1) {
                Some(&f) if f == expected.function || f == exception => break,
                _ => self.start += 1,
            }
        }
        let target = self.reply_target();
        self.target = target;
        let head = self.rx.get(self.start..self.end).unwrap_or(&[]);
        if let Some(short) = expected.short_len
            && head.len() >= short
            && head.get(1) == Some(&expected.function)
            && head.get(2) == Some(&0)
            && self.short_failed_at != Some(self.start)
        {
            self.state = State::Check(Candidate::Short);
            return;
        }
        if head.len() >= target {
            self.state = State::Check(Candidate::Normal);
            return;
        }
        // Noise may also open a normal-length candidate around a shorter
        // reply: an exception (`AA 03 03 83 06 ..` from slave 3) or a
        // trigger read's short reply (`AA AA 01 03 01 03 00 ..`). Take such a
        // frame further on as soon as it is complete and checks. (A later
        // normal-length candidate cannot complete before this one.)
        // Only where the shortest such frame would already be complete: a
        // head alone costs no search.
        let shortest = expected.short_len.map_or(EXCEPTION_LEN, |short| short.min(EXCEPTION_LEN));
        let later = (self.start + 1..(self.end + 1).saturating_sub(shortest)).find_map(|at| {
            let len = match self.rx.get(at + 1) {
                Some(&f) if f == exception => EXCEPTION_LEN,
                Some(&f) if f == expected.function && self.rx.get(at + 2) == Some(&0) => expected.short_len?,
                _ => return None,
            };
            self.rx.get(at..at + len).is_some_and(crc_ok).then_some((at, len))
        });
        if let Some((at, len)) = later {
            self.state = State::Check(Candidate::Later { at, len });
            return;
        }
        if self.start + target > MAX_ADU {
            log!(debug, skipped = %crate::Hex(self.rx.get(..self.start).unwrap_or(&[])), "bytes before the reply");
            move_to_front(&mut self.rx, self.start..self.end);
            self.short_failed_at = self.short_failed_at.and_then(|at| at.checked_sub(self.start));
            self.end -= self.start;
            self.start = 0;
        }
        self.state = State::Receive;
    }

    /// Ends the attempt without a better candidate: the first rejected one
    /// is the reply, else a timeout.
    fn give_up(&mut self) {
        let result = match self.rejected_error {
            Some(error) => {
                log!(debug, frame = %crate::Hex(self.rejected.get(..self.rejected_len).unwrap_or(&[])), "rx");
                self.reply = Reply::Rejected;
                ClientError::Frame { error }
            }
            None => {
                self.reply = Reply::Rx(0..self.end);
                ClientError::Timeout { received: self.end, sent: self.sent() }
            }
        };
        self.finish_attempt(Err(result));
    }

    /// Ends an attempt: done, or a retry after the backoff.
    #[inline]
    fn finish_attempt(&mut self, result: Result<(), ClientError<Infallible>>) {
        let policy = self.config.retry;
        match result {
            Err(error) if self.attempt < policy.retries && policy.should_retry(&error) => {
                self.attempt += 1;
                log!(warn, attempt = self.attempt, retries = policy.retries, %error, "retrying");
                self.state = if policy.backoff.is_zero() {
                    State::Silence { again: false }
                } else {
                    State::Backoff { until: self.now + policy.backoff }
                };
            }
            other => {
                self.outcome = other;
                self.state = State::Done;
            }
        }
    }
}

/// Moves `buf[range]` to the front of `buf`, in pieces no longer than the
/// distance moved so that no piece overlaps its destination: copies that
/// every build links anyway, not `memmove` (1.5 KB of a firmware's flash)
/// for a move made only when noise has filled the buffer.
fn move_to_front(buf: &mut [u8], range: Range<usize>) {
    let distance = range.start;
    let mut from = range.start;
    while from < range.end && distance > 0 {
        let len = (range.end - from).min(distance);
        let (before, after) = buf.split_at_mut(from);
        match (before.get_mut(from - distance..from - distance + len), after.get(..len)) {
            (Some(to), Some(piece)) => to.copy_from_slice(piece),
            _ => return,
        }
        from += len;
    }
}

/// The CRC error of a frame whose CRC fails (computed on the error path only).
fn crc_error(frame: &[u8]) -> FrameError {
    let n = frame.len().saturating_sub(2);
    let received = crate::bytes::word(frame, n).map_or(0, u16::swap_bytes);
    FrameError::Crc { received, computed: crc16_update(CRC_INIT, frame.get(..n).unwrap_or(&[])) }
}

/// Whether `bytes` hold a whole frame: a run of at least 4 bytes that ends
/// in its own CRC (the CRC-16/MODBUS of a frame, CRC included, is zero).
fn holds_frame(bytes: &[u8]) -> bool {
    (0..bytes.len()).any(|from| {
        let mut crc = CRC_INIT;
        bytes.iter().skip(from).enumerate().any(|(i, &b)| {
            crc = crc16_update(crc, &[b]);
            i >= 3 && crc == 0
        })
    })
}

impl core::fmt::Debug for ClientCore {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ClientCore")
            .field("config", &self.config)
            .field("line", &self.line)
            .field("state", &self.state)
            .field("bus_busy_until", &self.bus_busy_until)
            .field("quiet_until", &self.quiet_until)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests;

//! [`Client`]: the blocking driver of [`ClientCore`] over a [`Transport`].

use std::fmt;
use std::thread;
use std::time::Duration;

use super::clock::MonotonicClock;
use super::{Action, ClientConfig, ClientCore, ClientError, Instant};
use crate::command::Command;
use crate::error::FrameError;
use crate::frame::Layout;
use crate::transport::{MAX_WAIT, Transport};

/// Why a request of the blocking [`Client`] failed: a [`ClientError`] whose
/// link errors are `std::io::Error`s.
pub type Error = ClientError<std::io::Error>;

/// A Modbus RTU master on one transport (one bus), blocking the calling
/// thread for the silences and the reply. Every protocol decision is the
/// [`ClientCore`]'s; this driver sleeps, reads, writes and reads the clock
/// (twice per transaction when no silence is pending).
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
    core: ClientCore,
    /// The core's clock.
    clock: MonotonicClock,
}

impl<T: Transport> Client<T> {
    /// A client with the default [`ClientConfig`].
    pub fn new(transport: T) -> Self {
        Self::with_config(transport, ClientConfig::default())
    }

    /// A client with `config`.
    pub fn with_config(transport: T, config: ClientConfig) -> Self {
        Self { transport, core: ClientCore::new(config), clock: MonotonicClock::start() }
    }

    /// The configuration.
    pub fn config(&self) -> &ClientConfig {
        self.core.config()
    }

    /// The configuration, to change between requests.
    pub fn config_mut(&mut self) -> &mut ClientConfig {
        self.core.config_mut()
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

    /// The protocol core, for its bus state and configuration.
    pub fn core(&self) -> &ClientCore {
        &self.core
    }

    /// The silence the client keeps before each request (see
    /// [`ClientConfig::inter_frame_delay`]).
    pub fn inter_frame_delay(&self) -> Duration {
        self.core.inter_frame_delay_on(self.transport.line_timing())
    }

    /// The bytes of the last reply, kept until the next request: the frame
    /// for a reply that decoded or failed a check ([`Error::Frame`]), every
    /// byte received for a timeout ([`Error::Timeout`]), empty after a
    /// broadcast or a request that was never sent.
    pub fn last_reply(&self) -> &[u8] {
        self.core.last_reply()
    }

    /// Sends `command` to `slave` and returns the decoded reply.
    ///
    /// Slave 0 (broadcast) is refused with
    /// [`EncodeError::InvalidSlave`](crate::EncodeError::InvalidSlave): use
    /// [`Client::broadcast`]. Commands with a fixed slave address (get slave
    /// id: 0xFF) must be called with that address, and their reply carries it.
    pub fn call<C: Command>(&mut self, slave: u8, command: &C) -> Result<C::Response, Error> {
        enter_span!("modbus", command = C::NAME, slave);
        self.core.start_command(slave, command).map_err(ClientError::with_io)?;
        let mut response = None;
        self.run(&mut |frame| C::decode_response(slave, frame).map(|decoded| response = Some(decoded)))?;
        // `run` succeeds only after the decoder accepted a frame.
        response.ok_or(ClientError::Timeout { received: 0, sent: self.core.sent() })
    }

    /// Sends a write `command` to every slave (address 0) and returns
    /// without waiting for a reply (none comes). The next request waits
    /// [`ClientConfig::broadcast_turnaround`]. Never retried.
    pub fn broadcast<C: Command>(&mut self, command: &C) -> Result<(), Error> {
        enter_span!("modbus", command = C::NAME, slave = crate::frame::BROADCAST);
        self.core.start_command_broadcast(command).map_err(ClientError::with_io)?;
        self.run(&mut |_| Ok(()))
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
        enter_span!("modbus", function = layout.function.code(), address = layout.address);
        let slave = self.core.start_raw(request, layout).map_err(ClientError::with_io)?;
        self.run(&mut |frame| layout.decode_response(slave, frame).map(drop))?;
        Ok(self.core.last_reply())
    }

    /// Sends a broadcast request frame built elsewhere; see
    /// [`Client::broadcast`] and [`Client::call_raw`]. The request must be a
    /// write addressed to slave 0.
    pub fn broadcast_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<(), Error> {
        enter_span!("modbus", function = layout.function.code(), address = layout.address);
        self.core.start_raw_broadcast(request, layout).map_err(ClientError::with_io)?;
        self.run(&mut |_| Ok(()))
    }

    /// The core's clock: microseconds since the client was made.
    #[inline]
    fn now(&self) -> Instant {
        self.clock.now()
    }

    /// Drives the started transaction to its end; `check` decodes each candidate reply.
    fn run(&mut self, check: &mut dyn FnMut(&[u8]) -> Result<(), FrameError>) -> Result<(), Error> {
        self.core.set_line_timing(self.transport.line_timing());
        let result = self.drive(check);
        self.core.finish(result)
    }

    fn drive(&mut self, check: &mut dyn FnMut(&[u8]) -> Result<(), FrameError>) -> Result<(), Error> {
        loop {
            match self.core.poll() {
                Action::Wait { until } => {
                    let now = self.now();
                    if now < until {
                        thread::sleep(until.saturating_duration_since(now).min(MAX_WAIT));
                    }
                    self.core.handle_timeout(now.max(until));
                }
                Action::ReadPending => {
                    let n = self.transport.read(self.core.recv_buf(), Duration::ZERO)?;
                    if n == 0 {
                        self.core.handle_nothing_pending();
                    } else {
                        let now = self.now();
                        self.core.handle_received(n, now);
                    }
                }
                Action::Transmit(frame) => {
                    self.transport.discard_input()?;
                    let written = self.transport.write_all(frame);
                    let now = self.now();
                    self.core.handle_write_done(now);
                    written?;
                }
                Action::Receive { timeout, .. } => {
                    let n = self.transport.read(self.core.recv_buf(), timeout.min(MAX_WAIT))?;
                    let clock = self.clock;
                    self.core.handle_read(n, || clock.now());
                }
                Action::Check => self.core.check_with(&mut *check),
                Action::Done(result) => return result.map_err(ClientError::with_io),
                Action::Idle => return Ok(()),
            }
        }
    }
}

impl<T: fmt::Debug> fmt::Debug for Client<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Client").field("transport", &self.transport).field("core", &self.core).finish_non_exhaustive()
    }
}

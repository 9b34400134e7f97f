//! [`FirmwareClient`]: the firmware driver of [`ClientCore`] over
//! `embedded-io-async` (a UART's `Read + Write`) and an `embedded-hal-async`
//! [`DelayNs`], for `no_std` targets without an allocator.
//!
//! The driver moves bytes and keeps time; every protocol decision is the
//! core's. A read is bounded by racing it against the delay
//! (`embassy_futures::select`), so the link's `read` must be cancel-safe (as
//! `embedded-io-async` asks of implementations): bytes are not lost when a
//! read is dropped. `embedded-io-async` has no way to drop buffered input, so
//! stale input is discarded by reading it ([`Action::ReadPending`]).

use embassy_futures::select::{Either, select};
use embedded_hal_async::delay::DelayNs;
use embedded_io_async::{Read, Write};

use super::{Action, ClientConfig, ClientCore, ClientError, Instant};
use crate::command::Command;
use crate::error::FrameError;
use crate::frame::Layout;
use crate::timing::LineTiming;

/// A monotonic clock, in microseconds since any fixed point: the firmware's
/// timer (`embassy_time::Instant::now().as_micros()`, a free-running timer
/// counter extended to 64 bits).
pub trait Clock {
    /// The time now. Never goes backwards.
    fn now(&mut self) -> Instant;
}

impl<F: FnMut() -> Instant> Clock for F {
    fn now(&mut self) -> Instant {
        self()
    }
}

/// A Modbus RTU master on one serial link, async, `no_std`, allocation-free.
///
/// `L` is the link (an RS-485 UART with its driver-enable handled below it),
/// `D` the delay for silences and timeouts, `K` the clock.
pub struct FirmwareClient<L, D, K> {
    link: L,
    delay: D,
    clock: K,
    core: ClientCore,
}

impl<L: Read + Write, D: DelayNs, K: Clock> FirmwareClient<L, D, K> {
    /// A client on `link` with `config`; `line` is the link's baud rate and
    /// character format (t3.5 and the request's time on the line follow from
    /// it), `None` for links without line timing.
    pub fn new(link: L, delay: D, clock: K, config: ClientConfig, line: Option<LineTiming>) -> Self {
        let mut core = ClientCore::new(config);
        core.set_line_timing(line);
        Self { link, delay, clock, core }
    }

    /// The protocol core (configuration, bus state).
    pub fn core(&self) -> &ClientCore {
        &self.core
    }

    /// The protocol core, mutably (to change the configuration between requests).
    pub fn core_mut(&mut self) -> &mut ClientCore {
        &mut self.core
    }

    /// The link, dropping the client.
    pub fn into_link(self) -> L {
        self.link
    }

    /// The bytes of the last reply (see [`ClientCore::last_reply`]).
    pub fn last_reply(&self) -> &[u8] {
        self.core.last_reply()
    }

    /// Sends `command` to `slave` and returns the decoded reply; the same
    /// rules as the blocking `Client::call`.
    pub async fn call<C: Command>(&mut self, slave: u8, command: &C) -> Result<C::Response, ClientError<L::Error>> {
        self.core.start_command(slave, command).map_err(ClientError::with_io)?;
        let mut response = None;
        self.run(&mut |frame| C::decode_response(slave, frame).map(|decoded| response = Some(decoded))).await?;
        // `run` succeeds only after the decoder accepted a frame.
        response.ok_or(ClientError::Timeout { received: 0, sent: self.core.sent() })
    }

    /// Sends a write `command` to every slave; no reply is awaited.
    pub async fn broadcast<C: Command>(&mut self, command: &C) -> Result<(), ClientError<L::Error>> {
        self.core.start_command_broadcast(command).map_err(ClientError::with_io)?;
        self.run(&mut |_| Ok(())).await
    }

    /// Sends a request frame built elsewhere and returns the checked reply frame.
    pub async fn call_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<&[u8], ClientError<L::Error>> {
        let slave = self.core.start_raw(request, layout).map_err(ClientError::with_io)?;
        self.run(&mut |frame| layout.decode_response(slave, frame).map(drop)).await?;
        Ok(self.core.last_reply())
    }

    /// Drives the started transaction to its end; `check` decodes each candidate reply.
    async fn run(
        &mut self,
        check: &mut dyn FnMut(&[u8]) -> Result<(), FrameError>,
    ) -> Result<(), ClientError<L::Error>> {
        let result = self.drive(check).await;
        self.core.finish(result)
    }

    async fn drive(
        &mut self,
        check: &mut dyn FnMut(&[u8]) -> Result<(), FrameError>,
    ) -> Result<(), ClientError<L::Error>> {
        loop {
            match self.core.poll() {
                Action::Wait { until } => {
                    let now = self.clock.now();
                    if now < until {
                        let wait = until.as_micros().saturating_sub(now.as_micros());
                        self.delay.delay_us(u32::try_from(wait).unwrap_or(u32::MAX)).await;
                    }
                    self.core.handle_timeout(now.max(until));
                }
                Action::ReadPending => {
                    let n = read_within(&mut self.link, &mut self.delay, self.core.recv_buf(), 0).await?;
                    if n == 0 {
                        self.core.handle_nothing_pending();
                    } else {
                        let now = self.clock.now();
                        self.core.handle_received(n, now);
                    }
                }
                Action::Transmit(frame) => {
                    let written = self.link.write_all(frame).await;
                    let flushed = match written {
                        Ok(()) => self.link.flush().await,
                        Err(error) => Err(error),
                    };
                    let now = self.clock.now();
                    self.core.handle_write_done(now);
                    flushed.map_err(ClientError::Io)?;
                }
                Action::Receive { timeout, .. } => {
                    let n = read_within(&mut self.link, &mut self.delay, self.core.recv_buf(), micros(timeout)).await?;
                    let clock = &mut self.clock;
                    self.core.handle_read(n, || clock.now());
                }
                Action::Check => self.core.check_with(&mut *check),
                Action::Done(result) => return result.map_err(ClientError::with_io),
                Action::Idle => return Ok(()),
            }
        }
    }
}

/// Reads into `buf`, giving up after `timeout_us` (0: only what is buffered).
async fn read_within<L: Read, D: DelayNs>(
    link: &mut L,
    delay: &mut D,
    buf: &mut [u8],
    timeout_us: u32,
) -> Result<usize, ClientError<L::Error>> {
    if buf.is_empty() {
        return Ok(0);
    }
    match select(link.read(buf), delay.delay_us(timeout_us)).await {
        Either::First(read) => read.map_err(ClientError::Io),
        Either::Second(()) => Ok(0),
    }
}

/// A wait in whole microseconds for [`DelayNs`], rounded up, at most ~71 minutes.
fn micros(duration: core::time::Duration) -> u32 {
    u32::try_from(super::time::micros_ceil(duration)).unwrap_or(u32::MAX)
}

impl<L, D, K> core::fmt::Debug for FirmwareClient<L, D, K> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("FirmwareClient").field("core", &self.core).finish_non_exhaustive()
    }
}

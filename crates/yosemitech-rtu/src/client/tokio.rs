//! [`AsyncClient`]: the tokio driver of [`ClientCore`] over an [`AsyncLink`].

use std::fmt;
use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};

use super::{Action, ClientConfig, ClientCore, ClientError, Error, Instant};
use crate::command::Command;
use crate::error::FrameError;
use crate::frame::Layout;
use crate::transport::AsyncLink;

/// A Modbus RTU master on one async link (one bus), for tokio: the same
/// typed [`call`](AsyncClient::call), [`broadcast`](AsyncClient::broadcast)
/// and [`call_raw`](AsyncClient::call_raw) as the blocking
/// [`Client`](crate::Client), with the same timing, framing, checks and
/// retries, because both drive one [`ClientCore`]. This driver only sleeps
/// on tokio's clock, reads, writes and reads the clock.
///
/// **Cancel-safe:** a call whose future is dropped half-way (a `select!`, a
/// `timeout`) leaves the client usable. The next call keeps the bus quiet
/// until the abandoned attempt's deadline, then discards its late reply as
/// stale input and keeps t3.5 after it (the core's rule), so a late reply
/// is never taken for the next one's. Reads of every [`AsyncLink`] are
/// cancel-safe, so no byte is lost in the link.
///
/// One client per bus; many buses are polled concurrently from one runtime
/// by running their clients' calls concurrently (`join!`, tasks). A
/// transaction allocates nothing.
///
/// ```
/// # #[tokio::main(flavor = "current_thread")] async fn main() {
/// use yosemitech_rtu::{AsyncClient, ClientConfig, RtuStream};
///
/// // A device that never answers: the far end of a pipe nobody reads.
/// let (near, _far) = tokio::io::duplex(256);
/// let config = ClientConfig { timeout: std::time::Duration::from_millis(5), ..ClientConfig::default() };
/// let mut client = AsyncClient::with_config(RtuStream::new(near), config);
/// let request = [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB];
/// let layout = yosemitech_rtu::Layout::read(0x2800, 2);
/// client.config_mut().retry = yosemitech_rtu::RetryPolicy::NONE;
/// assert!(client.call_raw(&request, &layout).await.unwrap_err().is_timeout());
/// # }
/// ```
pub struct AsyncClient<L> {
    link: L,
    core: ClientCore,
    /// The origin of the core's [`Instant`]s, on tokio's clock (which tests may pause).
    epoch: tokio::time::Instant,
}

impl<L: AsyncLink> AsyncClient<L> {
    /// A client with the default [`ClientConfig`].
    pub fn new(link: L) -> Self {
        Self::with_config(link, ClientConfig::default())
    }

    /// A client with `config`.
    pub fn with_config(link: L, config: ClientConfig) -> Self {
        Self { link, core: ClientCore::new(config), epoch: tokio::time::Instant::now() }
    }

    /// The configuration.
    pub fn config(&self) -> &ClientConfig {
        self.core.config()
    }

    /// The configuration, to change between requests.
    pub fn config_mut(&mut self) -> &mut ClientConfig {
        self.core.config_mut()
    }

    /// The link.
    pub fn link(&self) -> &L {
        &self.link
    }

    /// The link, mutably. Bytes moved through it bypass the client's
    /// bus-silence tracking.
    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }

    /// The link, dropping the client.
    pub fn into_link(self) -> L {
        self.link
    }

    /// The protocol core, for its bus state and configuration.
    pub fn core(&self) -> &ClientCore {
        &self.core
    }

    /// The silence the client keeps before each request (see
    /// [`ClientConfig::inter_frame_delay`]).
    pub fn inter_frame_delay(&self) -> std::time::Duration {
        self.core.inter_frame_delay_on(self.link.line_timing())
    }

    /// The bytes of the last reply, as [`Client::last_reply`](crate::Client::last_reply).
    pub fn last_reply(&self) -> &[u8] {
        self.core.last_reply()
    }

    /// Sends `command` to `slave` and returns the decoded reply; see
    /// [`Client::call`](crate::Client::call).
    pub async fn call<C: Command>(&mut self, slave: u8, command: &C) -> Result<C::Response, Error> {
        let call = async {
            self.core.start_command(slave, command).map_err(ClientError::with_io)?;
            let mut response = None;
            self.run(|frame| C::decode_response(slave, frame).map(|decoded| response = Some(decoded))).await?;
            // `run` succeeds only after the decoder accepted a frame.
            response.ok_or(ClientError::Timeout { received: 0, sent: self.core.sent() })
        };
        in_span!(call, "modbus", command = C::NAME, slave).await
    }

    /// Sends a write `command` to every slave; see [`Client::broadcast`](crate::Client::broadcast).
    pub async fn broadcast<C: Command>(&mut self, command: &C) -> Result<(), Error> {
        self.core.start_command_broadcast(command).map_err(ClientError::with_io)?;
        in_span!(self.run(|_| Ok(())), "modbus", command = C::NAME, slave = crate::frame::BROADCAST).await
    }

    /// Sends a request frame built elsewhere and returns the checked reply
    /// frame; see [`Client::call_raw`](crate::Client::call_raw).
    pub async fn call_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<&[u8], Error> {
        let (len, slave) = self.core.load_request(request, layout).map_err(ClientError::with_io)?;
        self.core.start_call(len, layout).map_err(ClientError::with_io)?;
        let run = self.run(|frame| layout.decode_response(slave, frame).map(drop));
        in_span!(run, "modbus", function = layout.function.code(), address = layout.address, slave).await?;
        Ok(self.core.last_reply())
    }

    /// Sends a broadcast request frame built elsewhere; see
    /// [`Client::broadcast_raw`](crate::Client::broadcast_raw).
    pub async fn broadcast_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<(), Error> {
        let (len, _) = self.core.load_request(request, layout).map_err(ClientError::with_io)?;
        self.core.start_broadcast(len, layout).map_err(ClientError::with_io)?;
        let run = self.run(|_| Ok(()));
        in_span!(
            run,
            "modbus",
            function = layout.function.code(),
            address = layout.address,
            slave = crate::frame::BROADCAST
        )
        .await
    }

    /// The core's clock: microseconds since the client was made, on tokio's clock.
    fn now(&self) -> Instant {
        since(self.epoch)
    }

    /// Drives the started transaction to its end; `check` decodes each candidate reply.
    async fn run(&mut self, check: impl FnMut(&[u8]) -> Result<(), FrameError>) -> Result<(), Error> {
        self.core.set_line_timing(self.link.line_timing());
        let result = self.drive(check).await;
        self.core.finish(result)
    }

    async fn drive(&mut self, mut check: impl FnMut(&[u8]) -> Result<(), FrameError>) -> Result<(), Error> {
        loop {
            match self.core.poll() {
                Action::Wait { until } => {
                    let now = self.now();
                    if now < until {
                        tokio::time::sleep_until(self.epoch + until.saturating_duration_since(Instant::ZERO)).await;
                    }
                    self.core.handle_timeout(now.max(until));
                }
                Action::ReadPending => match poll_once(self.link.read(self.core.recv_buf())) {
                    Some(n) => {
                        let n = n?;
                        let now = self.now();
                        self.core.handle_received(n, now);
                    }
                    None => self.core.handle_nothing_pending(),
                },
                Action::Transmit(frame) => {
                    self.link.discard_input()?;
                    let written = self.link.write_frame(frame).await;
                    let now = self.now();
                    self.core.handle_write_done(now);
                    written?;
                }
                Action::Receive { timeout, .. } => {
                    // Bytes already there need no timer (and no clock read to arm one).
                    let n = match poll_once(self.link.read(self.core.recv_buf())) {
                        Some(read) => read?,
                        None if timeout.is_zero() => 0,
                        None => {
                            let read = self.link.read(self.core.recv_buf());
                            tokio::time::timeout(timeout, read).await.unwrap_or(Ok(0))?
                        }
                    };
                    let epoch = self.epoch;
                    self.core.handle_read(n, || since(epoch));
                }
                Action::Check => self.core.check_with(&mut check),
                Action::Done(result) => return result.map_err(ClientError::with_io),
                Action::Idle => return Ok(()),
            }
        }
    }
}

/// Polls `future` once: its output if it is ready without waiting. The
/// links' reads are cancel-safe, so dropping a pending one loses nothing.
fn poll_once<F: Future>(future: F) -> Option<F::Output> {
    let mut future = pin!(future);
    match future.as_mut().poll(&mut Context::from_waker(Waker::noop())) {
        Poll::Ready(output) => Some(output),
        Poll::Pending => None,
    }
}

impl<L: fmt::Debug> fmt::Debug for AsyncClient<L> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("AsyncClient").field("link", &self.link).field("core", &self.core).finish_non_exhaustive()
    }
}

/// The core's [`Instant`]: the time since `epoch` on tokio's clock.
fn since(epoch: tokio::time::Instant) -> Instant {
    Instant::from_elapsed(epoch.elapsed())
}

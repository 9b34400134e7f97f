//! Serving a [`FrameHandler`] on a byte stream from a background thread: a
//! pseudo-terminal, RTU-over-TCP, or an in-memory pair, with optional
//! line-timing emulation; or over Modbus TCP ([`serve_mbap`], as an Ethernet
//! gateway).
//!
//! # Framing
//!
//! A slave on a serial line has no length prefix to go by; it frames
//! requests the way a Yosemitech probe must: read the slave address and the
//! function code, then the rest of the head and the request's length by
//! the runtime's length rules ([`yosemitech_rtu::segment::request_len`]:
//! a read is 8 bytes, a write `9 + byte count`);
//! for any other code, everything until [`ServeConfig::silence`] passes
//!   without a byte (t3.5); the device ignores it, as a real probe, or
//!   answers exception 01 under
//!   [`UnknownRequestPolicy::Exception`](crate::UnknownRequestPolicy) if
//!   the CRC holds and the frame is addressed to it.
//!
//! A gap longer than [`ServeConfig::inter_char_timeout`] inside a frame
//! drops the partial frame (resynchronisation); a frame whose CRC fails is
//! handed to the device (which ignores it and counts it) and the input is
//! drained until silence, so the next frame starts clean.
//!
//! # Line timing
//!
//! With [`ServeConfig::line_timing`], the server behaves as if the bytes
//! crossed a real line at that baud rate: the request is taken to have
//! started when its first byte arrived and to have lasted its line time;
//! the reply starts t3.5 after the request's end (the turnaround), and each
//! byte is released only when it would have finished on the line. A
//! benchmark against a served simulator then sees the wire limit (about 25
//! ms per get_ph at 9600 baud).
//!
//! # Line faults
//!
//! Faults of the line rather than of the device, for diagnosing a link:
//! [`ServeConfig::echo`] writes every request back, as an RS-485 adapter
//! without echo suppression does; [`ServeConfig::turnaround`] holds every
//! reply back; [`ServeConfig::settings`] gives the device serial settings
//! of its own, and on a pty a client at other settings reads garbage (see
//! the `line` module).

use std::fmt;
use std::io;
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use yosemitech_rtu::frame::MAX_ADU;
use yosemitech_rtu::{LineSettings, LineTiming, MemoryTransport, TcpTransport, Transport, crc_ok, segment};

use crate::FrameHandler;
use crate::fault::Rng;

mod line;
mod mbap;
#[cfg(all(unix, feature = "pty"))]
pub mod tap;

pub use mbap::serve_mbap;

/// The longest request a head can announce: a write of 255 data bytes.
const MAX_REQUEST: usize = yosemitech_rtu::Function::Write.request_len(255);

/// How a served device reads requests and paces replies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServeConfig {
    /// Emulate a serial line at this timing (see the module docs); `None`
    /// (the default) replies as fast as the stream allows.
    pub line_timing: Option<LineTiming>,
    /// Longest gap between two bytes of one request before the partial
    /// request is dropped. Default 50 ms: generous, because a pty or a
    /// socket delivers bytes in bursts with scheduler gaps; a real line
    /// would use t1.5.
    pub inter_char_timeout: Duration,
    /// Silence that ends a request of unknown length (an unknown function).
    /// Default 5 ms (t3.5 at 9600 baud is 3.65 ms).
    pub silence: Duration,
    /// How often the server thread checks for [`Server::stop`] while idle.
    /// Default 20 ms.
    pub poll_interval: Duration,
    /// Write every request back as it arrives, before any reply, as an
    /// RS-485 adapter without echo suppression does. Default off.
    pub echo: bool,
    /// How long the device waits after a request before it answers (its
    /// turnaround), on top of any line timing. Default zero.
    pub turnaround: Duration,
    /// The serial settings the device runs at. On a pty a client at another
    /// baud rate, data-bit count or parity is not understood and reads
    /// garbage (deterministic from [`ServeConfig::seed`]); stop bits do not
    /// matter. Linux ptys drop the parity a client sets, so there a parity
    /// mismatch goes unseen ([`pty_keeps_parity`]). `None` (the default):
    /// any settings, as a pty has none.
    pub settings: Option<LineSettings>,
    /// Seed of the garbage of [`ServeConfig::settings`].
    pub seed: u64,
}

impl ServeConfig {
    /// The default configuration, emulating `timing`.
    pub fn emulating(timing: LineTiming) -> Self {
        Self { line_timing: Some(timing), ..Self::default() }
    }
}

impl Default for ServeConfig {
    fn default() -> Self {
        Self {
            line_timing: None,
            inter_char_timeout: Duration::from_millis(50),
            silence: Duration::from_millis(5),
            poll_interval: Duration::from_millis(20),
            echo: false,
            turnaround: Duration::ZERO,
            settings: None,
            seed: 0,
        }
    }
}

/// Where a [`Server`] can be reached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// A pseudo-terminal: open this path as a serial port.
    Pty(String),
    /// A TCP listener speaking RTU over TCP (raw frames, no MBAP header).
    Tcp(SocketAddr),
    /// A TCP listener speaking Modbus TCP (MBAP header, no CRC), from [`serve_mbap`].
    Mbap(SocketAddr),
    /// The other end of an in-memory pair, returned by [`serve_memory`].
    Memory,
}

impl fmt::Display for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Endpoint::Pty(path) => f.write_str(path),
            Endpoint::Tcp(addr) => write!(f, "tcp://{addr}"),
            Endpoint::Mbap(addr) => write!(f, "mbap://{addr}"),
            Endpoint::Memory => f.write_str("memory"),
        }
    }
}

/// A device served from a background thread. Stopping it (or dropping it)
/// ends the thread and joins it; the thread notices within
/// [`ServeConfig::poll_interval`].
///
/// The device is shared behind a mutex, locked only while it handles a
/// request: tests and demos change its state through [`Server::device`]
/// while it serves.
pub struct Server<D> {
    device: Arc<Mutex<D>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<()>>>,
    endpoint: Endpoint,
}

impl<D> Server<D> {
    /// Where a client connects: a pty path, a TCP address, or in memory.
    pub fn endpoint(&self) -> &Endpoint {
        &self.endpoint
    }

    /// The pty path a client opens, for [`serve_pty`].
    pub fn tty_path(&self) -> Option<&str> {
        match &self.endpoint {
            Endpoint::Pty(path) => Some(path),
            _ => None,
        }
    }

    /// The listening address, for [`serve_tcp`] and [`serve_mbap`].
    pub fn local_addr(&self) -> Option<SocketAddr> {
        match self.endpoint {
            Endpoint::Tcp(addr) | Endpoint::Mbap(addr) => Some(addr),
            _ => None,
        }
    }

    /// The device, locked (the server waits while it is held).
    pub fn device(&self) -> MutexGuard<'_, D> {
        lock(&self.device)
    }

    /// The served device, shared with the serving thread (lock it briefly).
    pub fn shared(&self) -> Arc<Mutex<D>> {
        Arc::clone(&self.device)
    }

    /// True while the server thread runs (it ends on [`Server::stop`], when
    /// an in-memory peer goes away, or on an I/O error).
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stops the server and joins its thread; returns the I/O error that
    /// ended it early, if any.
    pub fn stop(mut self) -> io::Result<()> {
        self.shutdown()
    }

    fn shutdown(&mut self) -> io::Result<()> {
        self.stop.store(true, Ordering::Release);
        match self.thread.take().map(JoinHandle::join) {
            None => Ok(()),
            Some(Ok(result)) => result,
            Some(Err(_)) => Err(io::Error::other("the simulator thread panicked")),
        }
    }
}

impl<D> Drop for Server<D> {
    fn drop(&mut self) {
        let _ = self.shutdown();
    }
}

impl<D> fmt::Debug for Server<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Server")
            .field("endpoint", &self.endpoint)
            .field("running", &self.is_running())
            .finish_non_exhaustive()
    }
}

fn lock<D>(device: &Mutex<D>) -> MutexGuard<'_, D> {
    // A panic while handling a request leaves a usable device behind.
    device.lock().unwrap_or_else(PoisonError::into_inner)
}

fn spawn<D, F>(device: D, endpoint: Endpoint, body: F) -> io::Result<Server<D>>
where
    D: Send + 'static,
    F: FnOnce(&Mutex<D>, &AtomicBool) -> io::Result<()> + Send + 'static,
{
    let device = Arc::new(Mutex::new(device));
    let stop = Arc::new(AtomicBool::new(false));
    let (d, s) = (Arc::clone(&device), Arc::clone(&stop));
    let thread = thread::Builder::new().name(format!("yosemitech-sim {endpoint}")).spawn(move || body(&d, &s))?;
    Ok(Server { device, stop, thread: Some(thread), endpoint })
}

/// Serves `device` on any transport's far end (the device side of a link),
/// until stopped or the link closes.
pub fn serve_transport<D, T>(device: D, mut link: T, endpoint: Endpoint, config: ServeConfig) -> io::Result<Server<D>>
where
    D: FrameHandler + Send + 'static,
    T: Transport + Send + 'static,
{
    spawn(device, endpoint, move |device, stop| match serve_link(&mut link, device, stop, &config, |_| None) {
        Err(e) if is_closed(&e) => Ok(()),
        other => other,
    })
}

/// Serves `device` on one end of an in-memory pair, in a thread; returns
/// the client's end. Unlike the in-process [`yosemitech_rtu::ResponderTransport`],
/// delays and line timing happen in real time.
pub fn serve_memory<D: FrameHandler + Send + 'static>(
    device: D,
    config: ServeConfig,
) -> io::Result<(MemoryTransport, Server<D>)> {
    let (client, device_end) = MemoryTransport::pair();
    let client = client.with_line_timing(config.line_timing);
    Ok((client, serve_transport(device, device_end, Endpoint::Memory, config)?))
}

/// Serves `device` as an RTU-over-TCP gateway on `addr` (use
/// `127.0.0.1:0` for a free port; see [`Server::local_addr`]). Connections
/// are served one at a time, as a gateway serialises its one serial line;
/// a closed connection makes way for the next.
pub fn serve_tcp<D, A>(device: D, addr: A, config: ServeConfig) -> io::Result<Server<D>>
where
    D: FrameHandler + Send + 'static,
    A: ToSocketAddrs,
{
    let (listener, local) = listen(addr)?;
    spawn(device, Endpoint::Tcp(local), move |device, stop| {
        while let Some(stream) = accept(&listener, stop, config.poll_interval)? {
            stream.set_nonblocking(false)?;
            let mut link = TcpTransport::from_stream(stream)?;
            // Any error ends this connection only.
            let _ = serve_link(&mut link, device, stop, &config, |_| None);
        }
        Ok(())
    })
}

/// A non-blocking listener bound to `addr`, for [`accept`], and its address.
fn listen<A: ToSocketAddrs>(addr: A) -> io::Result<(TcpListener, SocketAddr)> {
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    listener.set_nonblocking(true)?;
    Ok((listener, local))
}

/// The next connection to `listener` (from [`listen`]), looking at `stop`
/// every `poll` while none comes; `None` once `stop` is set.
fn accept(listener: &TcpListener, stop: &AtomicBool, poll: Duration) -> io::Result<Option<TcpStream>> {
    while !stop.load(Ordering::Acquire) {
        match listener.accept() {
            Ok((stream, _)) => return Ok(Some(stream)),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted => {
                thread::sleep(poll);
            }
            Err(e) => return Err(e),
        }
    }
    Ok(None)
}

/// Serializes `TTYPort::pair()`, which `serialport` notes is not thread-safe everywhere.
#[cfg(all(unix, feature = "pty"))]
static PTY: Mutex<()> = Mutex::new(());

/// Serves `device` on a new pseudo-terminal; a client opens
/// [`Server::tty_path`] as a serial port (any baud rate: a pty has none;
/// use [`ServeConfig::line_timing`] to emulate one). The pty's slave end
/// is kept open by the server, so clients may come and go.
#[cfg(all(unix, feature = "pty"))]
pub fn serve_pty<D: FrameHandler + Send + 'static>(device: D, config: ServeConfig) -> io::Result<Server<D>> {
    use serialport::SerialPort;
    use yosemitech_rtu::{SerialConfig, SerialTransport};

    let (master, mut slave) = {
        let _guard = PTY.lock().unwrap_or_else(PoisonError::into_inner);
        serialport::TTYPort::pair().map_err(io::Error::from)?
    };
    let path = slave.name().ok_or_else(|| io::Error::other("the pty has no slave path"))?;
    let keeps_parity = line::keeps_parity(&mut slave, &master);
    let mut link = SerialTransport::from_tty(master, &SerialConfig::new(path.clone()));
    spawn(device, Endpoint::Pty(path), move |device, stop| {
        let _slave = slave;
        serve_link(&mut link, device, stop, &config, |link| {
            let client = line::settings_of(link.port())?;
            // A parity the pty does not keep is taken to be the device's own.
            Some(match config.settings {
                Some(own) if !keeps_parity => LineSettings {
                    format: yosemitech_rtu::CharFormat { parity: own.format.parity, ..client.format },
                    ..client
                },
                _ => client,
            })
        })
    })
}

/// True when this system's pseudo-terminals keep the parity a client sets,
/// so that a served device with [`ServeConfig::settings`] can tell a client
/// at another parity (Linux ptys clear it).
#[cfg(all(unix, feature = "pty"))]
pub fn pty_keeps_parity() -> bool {
    let pair = {
        let _guard = PTY.lock().unwrap_or_else(PoisonError::into_inner);
        serialport::TTYPort::pair()
    };
    pair.is_ok_and(|(master, mut slave)| line::keeps_parity(&mut slave, &master))
}

/// Closed-link errors: the peer went away.
fn is_closed(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::UnexpectedEof
            | io::ErrorKind::BrokenPipe
            | io::ErrorKind::ConnectionReset
            | io::ErrorKind::ConnectionAborted
    )
}

/// Reads requests from `link` and answers them until `stop` is set;
/// `client_settings` tells the settings the client set, where the link can.
fn serve_link<T: Transport, D: FrameHandler>(
    link: &mut T,
    device: &Mutex<D>,
    stop: &AtomicBool,
    config: &ServeConfig,
    client_settings: impl Fn(&T) -> Option<LineSettings>,
) -> io::Result<()> {
    let mut frame = [0u8; MAX_REQUEST];
    let mut reply = Vec::with_capacity(2 * MAX_ADU);
    let mut rng = Rng::new(config.seed);
    while !stop.load(Ordering::Acquire) {
        let Some(request) = read_request(link, &mut frame, config)? else { continue };
        let (request, first_at) = request;
        let request = frame.get(..request).unwrap_or(&[]);
        if config.echo {
            link.write_all(request)?;
        }
        reply.clear();
        let mismatch = config
            .settings
            .and_then(|own| client_settings(link).filter(|&client| !line::compatible(client, own)).map(|c| (c, own)));
        let delay = match mismatch {
            Some((client, own)) => {
                reply.extend(line::garbage(&mut rng, request.len(), client, own));
                Duration::ZERO
            }
            None => lock(device).handle(request, &mut reply),
        };
        let delay = delay + config.turnaround;
        if !crc_ok(request) {
            drain(link, config.silence)?;
        }
        if reply.is_empty() {
            continue;
        }
        if let Some(line) = config.line_timing {
            let turnaround = first_at + line.frame_time(request.len()) + line.t3_5();
            if sleep_until(turnaround, stop) {
                break;
            }
        }
        if !delay.is_zero() && sleep_until(Instant::now() + delay, stop) {
            break;
        }
        send(link, &reply, config.line_timing, stop)?;
    }
    Ok(())
}

/// Reads one request into `frame`; returns its length and when its first
/// byte arrived, or `None` when nothing (complete) arrived.
fn read_request<T: Transport>(
    link: &mut T,
    frame: &mut [u8; MAX_REQUEST],
    config: &ServeConfig,
) -> io::Result<Option<(usize, Instant)>> {
    let mut len = 0;
    if link.read(frame.get_mut(..1).unwrap_or_default(), config.poll_interval)? == 0 {
        return Ok(None);
    }
    let first_at = Instant::now();
    len += 1;
    let gap = config.inter_char_timeout;
    if !fill(link, frame, &mut len, 2, gap)? {
        return Ok(None);
    }
    let complete = match segment::request_head_len(frame) {
        Some(head) => {
            fill(link, frame, &mut len, head, gap)? && {
                let head = frame.get(..head).unwrap_or_default();
                match segment::request_len(head) {
                    Some(total) => fill(link, frame, &mut len, total, gap)?,
                    None => false,
                }
            }
        }
        None => {
            // Unknown length: everything until silence (too long: dropped).
            match read_until_silence(link, frame, len, config.silence)? {
                Some(n) => {
                    len = n;
                    true
                }
                None => false,
            }
        }
    };
    Ok(complete.then_some((len, first_at)))
}

/// Reads until `frame[..want]` is filled; false when a gap longer than
/// `gap` came first (the partial frame is dropped).
fn fill<T: Transport>(link: &mut T, frame: &mut [u8], len: &mut usize, want: usize, gap: Duration) -> io::Result<bool> {
    let mut last = Instant::now();
    while *len < want {
        let Some(slot) = frame.get_mut(*len..want) else { return Ok(false) };
        let remaining = gap.saturating_sub(last.elapsed());
        if remaining.is_zero() {
            return Ok(false);
        }
        let n = link.read(slot, remaining)?.min(slot.len());
        if n > 0 {
            *len += n;
            last = Instant::now();
        }
    }
    Ok(true)
}

/// Reads into `frame[len..]` until `silence` passes without a byte; the
/// new length, or `None` when the bytes overflowed the buffer.
fn read_until_silence<T: Transport>(
    link: &mut T,
    frame: &mut [u8],
    mut len: usize,
    silence: Duration,
) -> io::Result<Option<usize>> {
    let mut last = Instant::now();
    let mut overflow = [0u8; 64];
    let mut overflowed = false;
    loop {
        let remaining = silence.saturating_sub(last.elapsed());
        if remaining.is_zero() {
            return Ok((!overflowed).then_some(len));
        }
        let buf = match frame.get_mut(len..) {
            Some(rest) if !rest.is_empty() => rest,
            _ => {
                overflowed = true;
                &mut overflow[..]
            }
        };
        let n = link.read(buf, remaining)?.min(buf.len());
        if n > 0 {
            if !overflowed {
                len += n;
            }
            last = Instant::now();
        }
    }
}

/// Drops input until `silence` passes without a byte.
fn drain<T: Transport>(link: &mut T, silence: Duration) -> io::Result<()> {
    let mut scratch = [0u8; 64];
    let full = scratch.len();
    read_until_silence(link, &mut scratch, full, silence).map(drop)
}

/// Sleeps until `deadline` in short steps; true if `stop` was set meanwhile.
fn sleep_until(deadline: Instant, stop: &AtomicBool) -> bool {
    const STEP: Duration = Duration::from_millis(20);
    loop {
        if stop.load(Ordering::Acquire) {
            return true;
        }
        let remaining = deadline.saturating_duration_since(Instant::now());
        if remaining.is_zero() {
            return false;
        }
        thread::sleep(remaining.min(STEP));
    }
}

/// Sends `reply`, paced at `timing` if given: each byte leaves when it
/// would have finished on the line.
fn send<T: Transport>(link: &mut T, reply: &[u8], timing: Option<LineTiming>, stop: &AtomicBool) -> io::Result<()> {
    let Some(line) = timing else { return link.write_all(reply) };
    let start = Instant::now();
    let char_nanos = line.char_time().as_nanos().max(1);
    let mut sent = 0;
    while sent < reply.len() {
        let done = usize::try_from(start.elapsed().as_nanos() / char_nanos).unwrap_or(usize::MAX).min(reply.len());
        if done > sent {
            link.write_all(reply.get(sent..done).unwrap_or(&[]))?;
            sent = done;
        } else if sleep_until(start + line.frame_time(sent + 1), stop) {
            return Ok(());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn framed(bytes: &[u8], config: &ServeConfig) -> Option<Vec<u8>> {
        let (mut client, mut device) = MemoryTransport::pair();
        client.write_all(bytes).unwrap();
        let mut frame = [0u8; MAX_REQUEST];
        read_request(&mut device, &mut frame, config).unwrap().map(|(n, _)| frame[..n].to_vec())
    }

    #[test]
    fn frames_by_function() {
        let config = ServeConfig::default();
        let read = [1, 3, 0x28, 0, 0, 2, 0xCD, 0xAB, 0xEE];
        assert_eq!(framed(&read, &config).unwrap(), read[..8], "stops after 8 bytes");
        let write = [1, 0x10, 0x23, 0, 0, 2, 4, 0, 0, 0x80, 0x40, 0x1E, 0xAE, 0xEE];
        assert_eq!(framed(&write, &config).unwrap(), write[..13], "9 + byte count");
        let trigger = [1, 0x10, 0x1C, 0, 0, 0, 0, 0xD8, 0x92];
        assert_eq!(framed(&trigger, &config).unwrap(), trigger);
        let unknown = [1, 0x2B, 0x0E, 1, 0, 0x70, 0x77];
        assert_eq!(framed(&unknown, &config).unwrap(), unknown, "until silence");
        assert_eq!(framed(&[0x01; 300][..], &ServeConfig::default()).map(|f| f.len()), None, "overflow is dropped");
        let partial = ServeConfig { inter_char_timeout: Duration::from_millis(10), ..config };
        assert_eq!(framed(&read[..5], &partial), None, "a gap drops the partial frame");
        assert_eq!(framed(&[], &partial), None);
    }

    #[test]
    fn paced_sending_takes_the_line_time() {
        let (mut client, mut device) = MemoryTransport::pair();
        let line = LineTiming::new(9600, yosemitech_rtu::CharFormat::EIGHT_N_1);
        let start = Instant::now();
        send(&mut device, &[0u8; 9], Some(line), &AtomicBool::new(false)).unwrap();
        let took = start.elapsed();
        assert!(took >= line.frame_time(9), "{took:?}");
        assert!(took < line.frame_time(9) + Duration::from_millis(50), "{took:?}");
        let mut buf = [0u8; 16];
        assert_eq!(client.read(&mut buf, Duration::ZERO).unwrap(), 9);
    }
}

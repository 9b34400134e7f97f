//! A tapped bus: simulated probes served on a pseudo-terminal (a master
//! opens [`TappedBus::path`]) whose line is also heard on a second
//! pseudo-terminal ([`TappedBus::tap_path`]), byte for byte and as it
//! happens, the way a second RS-485 adapter on the pair hears a master and
//! its probes: what `yosemitech sniff` listens to. [`TappedBus::line`] is
//! what went over the line, in order, for a test to hold a listener to.

use std::io::{self, Write};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use super::{Endpoint, ServeConfig, Server, serve_transport};
use crate::FrameHandler;
use serialport::{SerialPort, TTYPort};
use yosemitech_rtu::{LineTiming, SerialConfig, SerialTransport, Transport};

/// Who put bytes on the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// The master (a request).
    Master,
    /// A probe (a reply, or what a fault made of it).
    Probe,
}

/// What went over the line, chunk by chunk.
pub type Line = Arc<Mutex<Vec<(Direction, Vec<u8>)>>>;

/// Probes on a tapped line.
pub struct TappedBus<D> {
    /// The served device(s).
    pub server: Server<D>,
    /// Where the master opens the bus.
    pub path: String,
    /// Where the sniffer opens the tap.
    pub tap_path: String,
    line: Line,
    /// Kept open so that the ptys outlive the openers that come and go.
    _bus_slave: TTYPort,
    _tap_slave: TTYPort,
}

impl<D> TappedBus<D> {
    /// Stops serving (see [`Server::stop`]); the ptys close after.
    pub fn stop(self) -> io::Result<()> {
        let TappedBus { server, .. } = self;
        server.stop()
    }

    /// Everything that went over the line so far, in order, with who sent
    /// it (empty unless served with `record`).
    pub fn line(&self) -> Vec<(Direction, Vec<u8>)> {
        self.line.lock().unwrap_or_else(PoisonError::into_inner).clone()
    }
}

/// How long the tap waits to hand bytes to a listener that does not read:
/// after that they are lost to the tap (never to the line), as a second
/// adapter nobody reads loses what its buffer cannot hold.
const TAP_WRITE_TIMEOUT: Duration = Duration::from_millis(20);
/// After a write the tap could not finish, how long it stops trying, so
/// that a tap nobody reads costs the line one wait now and then.
const TAP_DEAF: Duration = Duration::from_secs(1);

/// Serves `device` on a new pty, tapped; `record` keeps what goes over the
/// line for [`TappedBus::line`] (a test's record; a long-running bus would
/// grow it without end).
pub fn serve_pty_tapped<D: FrameHandler + Send + 'static>(
    device: D,
    config: ServeConfig,
    record: bool,
) -> io::Result<TappedBus<D>> {
    let ((bus_master, bus_slave), (mut tap_master, tap_slave)) = {
        let _guard = super::PTY.lock().unwrap_or_else(PoisonError::into_inner);
        (TTYPort::pair().map_err(io::Error::from)?, TTYPort::pair().map_err(io::Error::from)?)
    };
    tap_master.set_timeout(TAP_WRITE_TIMEOUT).map_err(io::Error::from)?;
    let path = bus_slave.name().ok_or_else(|| io::Error::other("the bus pty has no path"))?;
    let tap_path = tap_slave.name().ok_or_else(|| io::Error::other("the tap pty has no path"))?;
    let line = Line::default();
    let link = Tapped {
        inner: SerialTransport::from_tty(bus_master, &SerialConfig::new(path.clone())),
        tap: tap_master,
        deaf_until: None,
        line: record.then(|| Arc::clone(&line)),
    };
    let server = serve_transport(device, link, Endpoint::Pty(path.clone()), config)?;
    Ok(TappedBus { server, path, tap_path, line, _bus_slave: bus_slave, _tap_slave: tap_slave })
}

/// The device's end of the line, copying every byte to the tap.
struct Tapped {
    inner: SerialTransport,
    tap: TTYPort,
    deaf_until: Option<Instant>,
    line: Option<Line>,
}

impl Tapped {
    fn heard(&mut self, direction: Direction, bytes: &[u8]) {
        if let Some(line) = &self.line {
            line.lock().unwrap_or_else(PoisonError::into_inner).push((direction, bytes.to_vec()));
        }
        // A tap nobody reads must not hold up the line (see TAP_WRITE_TIMEOUT).
        if self.deaf_until.is_some_and(|until| Instant::now() < until) {
            return;
        }
        self.deaf_until = None;
        if self.tap.write_all(bytes).and_then(|()| self.tap.flush()).is_err() {
            self.deaf_until = Some(Instant::now() + TAP_DEAF);
        }
    }
}

impl Transport for Tapped {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        // Heard as it goes on the line: recorded before the master can have it.
        self.heard(Direction::Probe, frame);
        self.inner.write_all(frame)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let n = self.inner.read(buf, timeout)?;
        if let Some(bytes) = buf.get(..n).filter(|b| !b.is_empty()) {
            self.heard(Direction::Master, bytes);
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }

    fn line_timing(&self) -> Option<LineTiming> {
        self.inner.line_timing()
    }
}

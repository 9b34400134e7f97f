//! A bus tap for the sniffer's tests: simulated probes served on a
//! pseudo-terminal (a master opens [`TappedBus::path`]) whose line is also
//! heard on a second pseudo-terminal ([`TappedBus::tap_path`]), byte for
//! byte and as it happens, the way a second RS-485 adapter on the pair
//! hears a master and its probes. [`TappedBus::line`] is what went over
//! the line, in order: what the sniffer must account for.

use std::io::{self, Write};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use serialport::{SerialPort, TTYPort};
use yosemitech_rtu::{LineTiming, SerialConfig, SerialTransport, Transport};
use yosemitech_sim::{Endpoint, FrameHandler, ServeConfig, Server, serve_transport};

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
    /// Everything that went over the line so far, in order, with who sent it.
    pub fn line(&self) -> Vec<(Direction, Vec<u8>)> {
        self.line.lock().unwrap_or_else(PoisonError::into_inner).clone()
    }
}

/// Serves `device` on a new pty, tapped.
pub fn serve_tapped<D: FrameHandler + Send + 'static>(device: D, config: ServeConfig) -> io::Result<TappedBus<D>> {
    // `TTYPort::pair` is not thread-safe everywhere.
    static PAIRING: Mutex<()> = Mutex::new(());
    let ((bus_master, bus_slave), (tap_master, tap_slave)) = {
        let _guard = PAIRING.lock().unwrap_or_else(PoisonError::into_inner);
        (TTYPort::pair().map_err(io::Error::from)?, TTYPort::pair().map_err(io::Error::from)?)
    };
    let path = bus_slave.name().ok_or_else(|| io::Error::other("the bus pty has no path"))?;
    let tap_path = tap_slave.name().ok_or_else(|| io::Error::other("the tap pty has no path"))?;
    let line = Line::default();
    let link = Tapped {
        inner: SerialTransport::from_tty(bus_master, &SerialConfig::new(path.clone())),
        tap: tap_master,
        line: Arc::clone(&line),
    };
    let server = serve_transport(device, link, Endpoint::Pty(path.clone()), config)?;
    Ok(TappedBus { server, path, tap_path, line, _bus_slave: bus_slave, _tap_slave: tap_slave })
}

/// The device's end of the line, copying every byte to the tap.
struct Tapped {
    inner: SerialTransport,
    tap: TTYPort,
    line: Line,
}

impl Tapped {
    fn heard(&mut self, direction: Direction, bytes: &[u8]) -> io::Result<()> {
        self.line.lock().unwrap_or_else(PoisonError::into_inner).push((direction, bytes.to_vec()));
        self.tap.write_all(bytes)?;
        self.tap.flush()
    }
}

impl Transport for Tapped {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        self.inner.write_all(frame)?;
        self.heard(Direction::Probe, frame)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let n = self.inner.read(buf, timeout)?;
        if let Some(bytes) = buf.get(..n).filter(|b| !b.is_empty()) {
            self.heard(Direction::Master, bytes)?;
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

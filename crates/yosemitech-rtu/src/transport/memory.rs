//! In-memory transports: a responder called in-process, and a connected pair.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread;
use std::time::{Duration, Instant};

use super::{MAX_WAIT, Transport};
use crate::frame::MAX_ADU;
use crate::timing::LineTiming;

/// Answers request frames in-process: a simulated device (or bus of devices).
///
/// Implemented for closures `FnMut(&[u8], &mut Vec<u8>)`.
pub trait Responder {
    /// Answers one request frame by appending the reply bytes to `reply`,
    /// which is empty on entry. Leaving it empty means "no answer" (a
    /// broadcast, a request for another slave, a dead device). Any bytes
    /// may be written: garbage, partial or several frames.
    fn respond(&mut self, request: &[u8], reply: &mut Vec<u8>);
}

impl<F: FnMut(&[u8], &mut Vec<u8>)> Responder for F {
    fn respond(&mut self, request: &[u8], reply: &mut Vec<u8>) {
        self(request, reply)
    }
}

/// A transport whose other end is a [`Responder`] called on each write, in
/// the caller's thread: a simulator answers requests without threads.
///
/// Each [`Transport::write_all`] is one request frame. The reply is queued
/// and handed out by [`Transport::read`], at most
/// [`ResponderTransport::set_read_chunk`] bytes per call (to exercise
/// reassembly). When nothing is queued, `read` sleeps for its whole timeout
/// and returns 0: nothing can arrive before the next write, so this is what a
/// silent line looks like. Buffers are allocated once; a transaction
/// allocates nothing unless a reply outgrows them.
pub struct ResponderTransport<R> {
    responder: R,
    /// Bytes the responder wrote for the current request.
    scratch: Vec<u8>,
    /// Reply bytes not yet read: `pending[pos..]`.
    pending: Vec<u8>,
    pos: usize,
    read_chunk: usize,
    line_timing: Option<LineTiming>,
}

impl<R: Responder> ResponderTransport<R> {
    /// A transport answered by `responder`.
    pub fn new(responder: R) -> Self {
        Self {
            responder,
            scratch: Vec::with_capacity(2 * MAX_ADU),
            pending: Vec::with_capacity(4 * MAX_ADU),
            pos: 0,
            read_chunk: usize::MAX,
            line_timing: None,
        }
    }
}

impl<F: FnMut(&[u8], &mut Vec<u8>)> ResponderTransport<F> {
    /// A transport answered by a closure; same as [`ResponderTransport::new`]
    /// but lets the compiler infer the closure's argument types.
    pub fn from_fn(responder: F) -> Self {
        Self::new(responder)
    }
}

impl<R> ResponderTransport<R> {
    /// Hands out at most `bytes` bytes per read (at least 1), so a reply
    /// arrives in pieces.
    pub fn set_read_chunk(&mut self, bytes: usize) {
        self.read_chunk = bytes.max(1);
    }

    /// Builder form of [`ResponderTransport::set_read_chunk`].
    #[must_use]
    pub fn with_read_chunk(mut self, bytes: usize) -> Self {
        self.set_read_chunk(bytes);
        self
    }

    /// Reports `timing` as the line timing, so a client waits t3.5 between
    /// frames as on a serial line. No timing is emulated on the bytes.
    #[must_use]
    pub fn with_line_timing(mut self, timing: Option<LineTiming>) -> Self {
        self.line_timing = timing;
        self
    }

    /// The responder that answers the requests.
    pub fn responder(&self) -> &R {
        &self.responder
    }

    /// The responder, mutably (to inject faults or change state between calls).
    pub fn responder_mut(&mut self) -> &mut R {
        &mut self.responder
    }

    /// The responder, dropping the transport.
    pub fn into_responder(self) -> R {
        self.responder
    }

    /// Reply bytes queued and not yet read.
    pub fn pending(&self) -> &[u8] {
        self.pending.get(self.pos..).unwrap_or(&[])
    }
}

impl<R: Responder> Transport for ResponderTransport<R> {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        if self.pos > 0 {
            self.pending.drain(..self.pos.min(self.pending.len()));
            self.pos = 0;
        }
        if self.pending.is_empty() {
            // The usual case (a client drops unread input before writing):
            // the reply goes straight into the queue, copied once.
            self.responder.respond(frame, &mut self.pending);
        } else {
            self.scratch.clear();
            self.responder.respond(frame, &mut self.scratch);
            self.pending.extend_from_slice(&self.scratch);
        }
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let available = self.pending.get(self.pos..).unwrap_or(&[]);
        if available.is_empty() {
            if !buf.is_empty() && !timeout.is_zero() {
                thread::sleep(timeout.min(MAX_WAIT));
            }
            return Ok(0);
        }
        let n = available.len().min(buf.len()).min(self.read_chunk);
        if let (Some(slots), Some(bytes)) = (buf.get_mut(..n), available.get(..n)) {
            slots.copy_from_slice(bytes);
        }
        self.pos += n;
        if self.pos >= self.pending.len() {
            self.pending.clear();
            self.pos = 0;
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.pending.clear();
        self.pos = 0;
        Ok(())
    }

    fn line_timing(&self) -> Option<LineTiming> {
        self.line_timing
    }
}

impl<R> core::fmt::Debug for ResponderTransport<R> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ResponderTransport")
            .field("pending", &crate::Hex(self.pending()))
            .field("read_chunk", &self.read_chunk)
            .field("line_timing", &self.line_timing)
            .finish_non_exhaustive()
    }
}

/// One direction of a [`MemoryTransport`] pair.
#[derive(Debug, Default)]
struct Pipe {
    state: Mutex<PipeState>,
    ready: Condvar,
}

#[derive(Debug, Default)]
struct PipeState {
    bytes: VecDeque<u8>,
    closed: bool,
}

impl Pipe {
    fn new() -> Arc<Self> {
        Arc::new(Self {
            state: Mutex::new(PipeState { bytes: VecDeque::with_capacity(4 * MAX_ADU), closed: false }),
            ready: Condvar::new(),
        })
    }

    /// The state; a panic in another thread holding the lock leaves only bytes behind, so poisoning is ignored.
    fn lock(&self) -> MutexGuard<'_, PipeState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn close(&self) {
        self.lock().closed = true;
        self.ready.notify_all();
    }
}

/// One end of a connected in-memory pair: bytes written to one end are read
/// from the other. Both ends are `Send`, so a simulated device can answer
/// from another thread; `read` blocks with its timeout like a real line.
///
/// When one end is dropped the other reads what is left, then gets
/// [`io::ErrorKind::UnexpectedEof`]; its writes fail with
/// [`io::ErrorKind::BrokenPipe`]. Buffers are allocated once at creation.
#[derive(Debug)]
pub struct MemoryTransport {
    rx: Arc<Pipe>,
    tx: Arc<Pipe>,
    line_timing: Option<LineTiming>,
}

impl MemoryTransport {
    /// Two connected ends, for example (client side, device side).
    pub fn pair() -> (Self, Self) {
        let (a, b) = (Pipe::new(), Pipe::new());
        (Self { rx: Arc::clone(&a), tx: Arc::clone(&b), line_timing: None }, Self { rx: b, tx: a, line_timing: None })
    }

    /// Reports `timing` as the line timing, so a client on this end waits
    /// t3.5 between frames. No timing is emulated on the bytes.
    #[must_use]
    pub fn with_line_timing(mut self, timing: Option<LineTiming>) -> Self {
        self.line_timing = timing;
        self
    }

    /// Bytes that have arrived at this end and not been read.
    pub fn available(&self) -> usize {
        self.rx.lock().bytes.len()
    }
}

impl Transport for MemoryTransport {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        let mut state = self.tx.lock();
        if state.closed {
            return Err(io::Error::new(io::ErrorKind::BrokenPipe, "the other end of the memory transport is closed"));
        }
        state.bytes.extend(frame);
        drop(state);
        self.tx.ready.notify_all();
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = Instant::now().checked_add(timeout.min(MAX_WAIT));
        let mut state = self.rx.lock();
        loop {
            if !state.bytes.is_empty() {
                let n = state.bytes.len().min(buf.len());
                for (slot, byte) in buf.iter_mut().zip(state.bytes.drain(..n)) {
                    *slot = byte;
                }
                return Ok(n);
            }
            if state.closed {
                return Err(io::Error::new(
                    io::ErrorKind::UnexpectedEof,
                    "the other end of the memory transport is closed",
                ));
            }
            let remaining = deadline.map_or(Duration::ZERO, |d| d.saturating_duration_since(Instant::now()));
            if remaining.is_zero() {
                return Ok(0);
            }
            state = match self.rx.ready.wait_timeout(state, remaining) {
                Ok((guard, _)) => guard,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.rx.lock().bytes.clear();
        Ok(())
    }

    fn line_timing(&self) -> Option<LineTiming> {
        self.line_timing
    }
}

impl Drop for MemoryTransport {
    fn drop(&mut self) {
        self.rx.close();
        self.tx.close();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pair_moves_bytes_both_ways_and_times_out() {
        let (mut a, mut b) = MemoryTransport::pair();
        let mut buf = [0u8; 8];
        assert_eq!(b.read(&mut buf, Duration::ZERO).unwrap(), 0);
        a.write_all(&[1, 2, 3]).unwrap();
        assert_eq!(b.available(), 3);
        assert_eq!(b.read(&mut buf[..2], Duration::ZERO).unwrap(), 2);
        assert_eq!(b.read(&mut buf, Duration::ZERO).unwrap(), 1);
        assert_eq!(buf[0], 3);
        b.write_all(&[9]).unwrap();
        assert_eq!(a.read(&mut buf, Duration::from_millis(10)).unwrap(), 1);
        let start = Instant::now();
        assert_eq!(a.read(&mut buf, Duration::from_millis(30)).unwrap(), 0);
        assert!(start.elapsed() >= Duration::from_millis(30));
        b.write_all(&[7, 7]).unwrap();
        a.discard_input().unwrap();
        assert_eq!(a.read(&mut buf, Duration::ZERO).unwrap(), 0);
    }

    #[test]
    fn pair_reports_a_closed_peer() {
        let (mut a, b) = MemoryTransport::pair();
        let mut b = b;
        b.write_all(&[5]).unwrap();
        drop(b);
        let mut buf = [0u8; 4];
        assert_eq!(a.read(&mut buf, Duration::from_secs(1)).unwrap(), 1, "bytes sent before closing are kept");
        assert_eq!(a.read(&mut buf, Duration::from_secs(1)).unwrap_err().kind(), io::ErrorKind::UnexpectedEof);
        assert_eq!(a.write_all(&[1]).unwrap_err().kind(), io::ErrorKind::BrokenPipe);
    }

    #[test]
    fn pair_wakes_a_waiting_reader() {
        let (mut a, mut b) = MemoryTransport::pair();
        let writer = thread::spawn(move || {
            thread::sleep(Duration::from_millis(20));
            b.write_all(&[0x42]).unwrap();
            b
        });
        let mut buf = [0u8; 1];
        assert_eq!(a.read(&mut buf, Duration::from_secs(10)).unwrap(), 1);
        assert_eq!(buf, [0x42]);
        drop(writer.join().unwrap());
    }

    #[test]
    fn responder_replies_in_chunks() {
        let mut t = ResponderTransport::from_fn(|req: &[u8], out: &mut Vec<u8>| out.extend(req.iter().rev()))
            .with_read_chunk(2);
        t.write_all(&[1, 2, 3, 4, 5]).unwrap();
        let mut buf = [0u8; 8];
        assert_eq!(t.read(&mut buf, Duration::ZERO).unwrap(), 2);
        assert_eq!(&buf[..2], [5, 4]);
        assert_eq!(t.pending(), [3, 2, 1]);
        t.write_all(&[6]).unwrap();
        assert_eq!(t.pending(), [3, 2, 1, 6], "a new reply queues behind unread bytes");
        t.discard_input().unwrap();
        assert_eq!(t.pending(), [] as [u8; 0]);
        let start = Instant::now();
        assert_eq!(t.read(&mut buf, Duration::from_millis(20)).unwrap(), 0);
        assert!(start.elapsed() >= Duration::from_millis(20), "a silent responder waits out the timeout");
    }
}

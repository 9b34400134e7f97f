//! Serving a [`Device`] over Modbus TCP (MBAP): see [`serve_mbap`].

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::{self, ScopedJoinHandle};
use std::time::Instant;

use yosemitech_rtu::frame::{BROADCAST, MAX_ADU, encode_exception};
use yosemitech_rtu::mbap::{HEADER_LEN, Header, MAX_MBAP_ADU, adu_to_rtu, rtu_to_adu};
use yosemitech_rtu::{ExceptionCode, MbapError};

use super::{Endpoint, ServeConfig, Server, accept, is_closed, listen, lock, sleep_until, spawn};
use crate::FrameHandler;

/// Serves `device` over Modbus TCP on `addr` (use `127.0.0.1:0` for a free
/// port; see [`Server::local_addr`]), several connections at once, as an
/// Ethernet gateway in front of an RS-485 line does: unit id = slave address.
///
/// Each connection has its own thread, so several clients are served at
/// once; their requests reach the device one at a time (it sits behind one
/// mutex, as the probes behind a gateway share one serial line). A request
/// becomes the RTU frame carrying the same PDU
/// ([`yosemitech_rtu::mbap::adu_to_rtu`]); the device's reply goes back with
/// the request's transaction id. Like a gateway, the server answers:
///
/// * the device's reply, when it is one whole RTU frame with a valid CRC
///   (a reply from the wrong slave is passed on with that slave's unit id,
///   and a Modbus exception is passed on as it is);
/// * exception 0x0B (gateway target device failed to respond) when the
///   device stayed silent or its reply is not one valid frame (dropped,
///   corrupt, truncated, or noise around it), except for broadcasts (unit
///   0), which get nothing.
///
/// A malformed header (protocol id not 0, a length outside 2..=254) closes
/// the connection, as Modbus TCP servers do: the stream cannot be
/// resynchronised. [`ServeConfig::line_timing`] does not apply (the gateway
/// owns the line); an injected delay does.
pub fn serve_mbap<D, A>(device: D, addr: A, config: ServeConfig) -> io::Result<Server<D>>
where
    D: FrameHandler + Send + 'static,
    A: ToSocketAddrs,
{
    let (listener, local) = listen(addr)?;
    spawn(device, Endpoint::Mbap(local), move |device, stop| {
        thread::scope(|scope| {
            let mut connections: Vec<ScopedJoinHandle<'_, ()>> = Vec::new();
            let result = loop {
                let stream = match accept(&listener, stop, config.poll_interval) {
                    Ok(Some(stream)) => stream,
                    Ok(None) => break Ok(()),
                    Err(e) => break Err(e),
                };
                connections.retain(|c| !c.is_finished());
                let connection = thread::Builder::new().name(format!("yosemitech-sim mbap://{local}")).spawn_scoped(
                    scope,
                    move || {
                        // Any error ends this connection only.
                        let _ = serve_connection(stream, device, stop, &config);
                    },
                );
                match connection {
                    Ok(handle) => connections.push(handle),
                    Err(e) => break Err(e),
                }
            };
            // The scope joins the connection threads, which see `stop`.
            stop.store(true, Ordering::Release);
            result
        })
    })
}

/// Answers the requests of one connection until it closes or `stop` is set.
fn serve_connection<D: FrameHandler>(
    mut stream: TcpStream,
    device: &Mutex<D>,
    stop: &AtomicBool,
    config: &ServeConfig,
) -> io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(config.poll_interval.max(std::time::Duration::from_millis(1))))?;
    let mut adu = [0u8; MAX_MBAP_ADU];
    let mut request = [0u8; MAX_ADU];
    let mut reply = Vec::with_capacity(2 * MAX_ADU);
    let mut out = [0u8; MAX_MBAP_ADU];
    loop {
        let Some(header) = adu.get_mut(..HEADER_LEN) else { return Ok(()) };
        if !read_full(&mut stream, header, stop)? {
            return Ok(());
        }
        let header = Header::parse(header).map_err(invalid)?;
        let len = header.adu_len();
        if !read_full(&mut stream, adu.get_mut(HEADER_LEN..len).unwrap_or_default(), stop)? {
            return Ok(());
        }
        let (_, rtu_len) = adu_to_rtu(adu.get(..len).unwrap_or(&[]), &mut request).map_err(invalid)?;
        let rtu = request.get(..rtu_len).unwrap_or(&[]);
        reply.clear();
        let delay = lock(device).handle(rtu, &mut reply);
        if !delay.is_zero() && sleep_until(Instant::now() + delay, stop) {
            return Ok(());
        }
        let answer = match rtu_to_adu(&reply, header.transaction, &mut out) {
            Ok(n) => n,
            Err(_) if header.unit == BROADCAST => continue,
            Err(_) => target_failed(&header, rtu, &mut out)?,
        };
        stream.write_all(out.get(..answer).unwrap_or(&[]))?;
    }
}

/// Writes exception 0x0B for `request` into `out` as an MBAP ADU.
fn target_failed(header: &Header, request: &[u8], out: &mut [u8]) -> io::Result<usize> {
    let function = yosemitech_rtu::bytes::byte(request, 1).unwrap_or(0);
    let mut frame = [0u8; yosemitech_rtu::frame::EXCEPTION_LEN];
    encode_exception(header.unit, function, ExceptionCode::GatewayTargetFailedToRespond.to_u8(), &mut frame)
        .map_err(|e| io::Error::other(e.to_string()))?;
    rtu_to_adu(&frame, header.transaction, out).map_err(invalid)
}

fn invalid(error: MbapError) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, error)
}

/// Fills `buf` from `stream`, checking `stop` at each read timeout. False
/// when the peer closed the connection (or `stop` was set) first.
fn read_full(stream: &mut TcpStream, buf: &mut [u8], stop: &AtomicBool) -> io::Result<bool> {
    let mut filled = 0;
    while filled < buf.len() {
        if stop.load(Ordering::Acquire) {
            return Ok(false);
        }
        match stream.read(buf.get_mut(filled..).unwrap_or_default()) {
            Ok(0) => return Ok(false),
            Ok(n) => filled += n,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                ) => {}
            Err(e) if is_closed(&e) => return Ok(false),
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

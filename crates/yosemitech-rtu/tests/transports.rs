//! The client over real transports: TCP on 127.0.0.1, a serial pty pair, and
//! the in-memory pair with a device thread.

use std::io::{self, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::thread;
use std::time::{Duration, Instant};

use yosemitech_rtu::{Client, ClientConfig, Command, Error, MemoryTransport, RetryPolicy, TcpTransport, Transport};
use yosemitech_tests::rtu::{READ_FLOAT_REPLY, READ_FLOAT_REQUEST, ReadFloat, float_probe};

fn config() -> ClientConfig {
    ClientConfig { timeout: Duration::from_secs(2), retry: RetryPolicy::NONE, ..ClientConfig::default() }
}

/// Reads exactly `buf.len()` bytes through a transport, or fails after `within`.
fn read_exact(transport: &mut impl Transport, buf: &mut [u8], within: Duration) -> io::Result<()> {
    let deadline = Instant::now() + within;
    let mut got = 0;
    while got < buf.len() {
        let remaining = deadline.saturating_duration_since(Instant::now());
        if remaining.is_zero() {
            return Err(io::Error::new(io::ErrorKind::TimedOut, format!("read {got} of {} bytes", buf.len())));
        }
        got += transport.read(&mut buf[got..], remaining)?;
    }
    Ok(())
}

/// Answers get_ph requests (8 bytes each) on a stream, each reply in two writes.
fn serve_tcp(mut stream: TcpStream, requests: usize) -> io::Result<()> {
    for _ in 0..requests {
        let mut request = [0u8; 8];
        stream.read_exact(&mut request)?;
        let mut reply = Vec::new();
        float_probe(1, 7.6, &request, &mut reply);
        stream.write_all(&reply[..4])?;
        stream.flush()?;
        thread::sleep(Duration::from_millis(5));
        stream.write_all(&reply[4..])?;
    }
    Ok(())
}

#[test]
fn clients_can_move_to_other_threads() {
    fn assert_send<T: Send>() {}
    assert_send::<Client<TcpTransport>>();
    assert_send::<Client<MemoryTransport>>();
    assert_send::<Client<Box<dyn Transport + Send>>>();
    #[cfg(feature = "serial")]
    assert_send::<Client<yosemitech_rtu::SerialTransport>>();
    assert_send::<Error>();
}

#[test]
fn tcp_gateway_round_trips_and_reports_a_closed_connection() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let server = thread::spawn(move || {
        let (stream, _) = listener.accept()?;
        serve_tcp(stream, 3)
    });
    let transport = TcpTransport::connect(addr, Duration::from_secs(5)).unwrap();
    assert_eq!(transport.line_timing(), None);
    let mut client = Client::with_config(transport, config());
    assert_eq!(client.inter_frame_delay(), Duration::ZERO, "the gateway keeps the line timing");
    for _ in 0..3 {
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
    }
    server.join().unwrap().unwrap();
    // The gateway hung up after three requests.
    match client.call(1, &ReadFloat) {
        Err(Error::Io(e)) => assert!(
            matches!(
                e.kind(),
                io::ErrorKind::UnexpectedEof | io::ErrorKind::BrokenPipe | io::ErrorKind::ConnectionReset
            ),
            "{e}"
        ),
        other => panic!("expected an I/O error, got {other:?}"),
    }
}

#[test]
fn tcp_connect_to_a_closed_port_fails() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    drop(listener);
    assert!(TcpTransport::connect(addr, Duration::from_secs(2)).is_err());
}

#[test]
fn memory_pair_with_a_device_thread_dribbling_its_reply() {
    let (client_end, mut device_end) = MemoryTransport::pair();
    let device = thread::spawn(move || -> io::Result<()> {
        for _ in 0..2 {
            let mut request = [0u8; 8];
            read_exact(&mut device_end, &mut request, Duration::from_secs(5))?;
            assert_eq!(request, READ_FLOAT_REQUEST);
            for byte in READ_FLOAT_REPLY {
                device_end.write_all(&[byte])?;
                thread::sleep(Duration::from_millis(1));
            }
        }
        Ok(())
    });
    let mut client = Client::with_config(client_end, config());
    assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
    assert_eq!(client.call_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT).unwrap(), READ_FLOAT_REPLY);
    device.join().unwrap().unwrap();
}

#[test]
fn trickling_noise_does_not_extend_the_deadline() {
    let (client_end, mut device_end) = MemoryTransport::pair();
    // A babbling device: a zero byte every 5 ms until the client goes away
    // (or 5 s pass, so a client that extends its deadline fails rather than hangs).
    let device = thread::spawn(move || {
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(5) && device_end.write_all(&[0x00]).is_ok() {
            thread::sleep(Duration::from_millis(5));
        }
    });
    let timeout = Duration::from_millis(150);
    let mut client = Client::with_config(client_end, ClientConfig { timeout, ..config() });
    let start = Instant::now();
    let err = client.call(1, &ReadFloat).unwrap_err();
    let elapsed = start.elapsed();
    match &err {
        Error::Timeout { received, .. } => {
            assert!(
                client.last_reply().iter().all(|&b| b == 0) && *received > 0 && client.last_reply().len() == *received
            )
        }
        other => panic!("expected a timeout, got {other:?}"),
    }
    assert!(elapsed >= timeout, "{elapsed:?}");
    assert!(elapsed < timeout + Duration::from_secs(2), "deadline overrun: {elapsed:?}");
    drop(client);
    device.join().unwrap();
}

#[cfg(all(unix, feature = "serial"))]
mod serial {
    use std::sync::Mutex;

    use serialport::TTYPort;
    use yosemitech_rtu::{SerialConfig, SerialTransport};

    use super::*;

    /// Pty creation is not thread-safe everywhere (serialport notes it).
    static PTY: Mutex<()> = Mutex::new(());

    /// A pty pair as (client side, device side), or `None` (with the reason printed) where ptys are unavailable.
    fn pty_pair(echo_suppression: bool) -> Option<(SerialTransport, SerialTransport)> {
        let _guard = PTY.lock().unwrap_or_else(|e| e.into_inner());
        match TTYPort::pair() {
            Ok((master, slave)) => {
                let config = SerialConfig { echo_suppression, ..SerialConfig::new("pty") };
                let device = SerialConfig::new("pty");
                Some((SerialTransport::from_tty(slave, &config), SerialTransport::from_tty(master, &device)))
            }
            Err(e) => {
                eprintln!("skipping: cannot create a pty pair: {e}");
                None
            }
        }
    }

    /// A device on the master end: answers `requests` get_ph requests, first
    /// echoing each request as `echo` makes it (an RS-485 adapter's echo).
    /// Returns its port, to be kept open until the client is done: when the
    /// master end closes, the slave end polls POLLIN|POLLHUP, which
    /// `serialport` reports as a broken pipe even with data waiting.
    fn device(
        mut port: SerialTransport,
        requests: usize,
        echo: impl Fn(&[u8; 8]) -> Option<Vec<u8>> + Send + 'static,
    ) -> thread::JoinHandle<io::Result<SerialTransport>> {
        thread::spawn(move || {
            for _ in 0..requests {
                let mut request = [0u8; 8];
                read_exact(&mut port, &mut request, Duration::from_secs(5))?;
                if let Some(echo) = echo(&request) {
                    port.write_all(&echo)?;
                }
                let mut reply = Vec::new();
                float_probe(1, 7.6, &request, &mut reply);
                port.write_all(&reply)?;
            }
            Ok(port)
        })
    }

    #[test]
    fn serial_pty_round_trip() {
        let Some((client_end, device_end)) = pty_pair(false) else { return };
        let answering = device(device_end, 3, |_| None);
        let mut client = Client::with_config(client_end, config());
        assert_eq!(client.inter_frame_delay(), Duration::from_millis(4), "9600 8N1: t3.5 raised to 4 ms");
        for _ in 0..3 {
            assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        }
        let device_end = answering.join().unwrap().unwrap();
        drop(client);
        drop(device_end);
    }

    #[test]
    fn serial_echo_suppression_drops_the_echo() {
        let Some((client_end, device_end)) = pty_pair(true) else { return };
        let answering = device(device_end, 2, |request| Some(request.to_vec()));
        let mut client = Client::with_config(client_end, config());
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        let _device_end = answering.join().unwrap().unwrap();
    }

    #[test]
    fn serial_echo_without_suppression_garbles_the_reply() {
        // The same echoing adapter without suppression: the echo is read as the reply.
        let Some((client_end, device_end)) = pty_pair(false) else { return };
        let answering = device(device_end, 1, |request| Some(request.to_vec()));
        let mut client = Client::with_config(client_end, config());
        let err = client.call(1, &ReadFloat).unwrap_err();
        assert!(client.last_reply().starts_with(&READ_FLOAT_REQUEST), "{err}");
        let _device_end = answering.join().unwrap().unwrap();
    }

    #[test]
    fn serial_echo_that_differs_is_an_io_error() {
        let Some((client_end, device_end)) = pty_pair(true) else { return };
        let answering = device(device_end, 1, |request| {
            let mut collided = request.to_vec();
            collided[3] ^= 0xFF;
            Some(collided)
        });
        let mut client = Client::with_config(client_end, config());
        match client.call(1, &ReadFloat) {
            Err(Error::Io(e)) => assert_eq!(e.kind(), io::ErrorKind::InvalidData, "{e}"),
            other => panic!("expected an echo error, got {other:?}"),
        }
        let _device_end = answering.join().unwrap().unwrap();
    }
}

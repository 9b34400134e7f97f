//! The simulator served from a thread: on a pty (rtu SerialTransport), over
//! TCP (rtu TcpTransport), in memory, with line-timing emulation.
#![allow(clippy::result_large_err)]

mod sim_common;

use std::time::{Duration, Instant};

use sim_common::{command, exception, request, sensor, with_crc};
use yosemitech_rtu::{CharFormat, Client, ClientConfig, LineTiming, RetryPolicy, TcpTransport, Transport};
use yosemitech_sim::{Bus, Endpoint, ServeConfig, Simulator, UnknownRequestPolicy, serve_memory, serve_tcp};
use yosemitech_spec::Value;

fn config() -> ClientConfig {
    ClientConfig { timeout: Duration::from_secs(2), retry: RetryPolicy::NONE, ..ClientConfig::default() }
}

/// Reads exactly `n` bytes through a transport within 2 s.
fn read_n(transport: &mut impl Transport, n: usize) -> Vec<u8> {
    let deadline = Instant::now() + Duration::from_secs(2);
    let mut buf = vec![0u8; n];
    let mut got = 0;
    while got < n {
        let remaining = deadline.saturating_duration_since(Instant::now());
        assert!(!remaining.is_zero(), "read {got} of {n} bytes: {:02X?}", &buf[..got]);
        got += transport.read(&mut buf[got..], remaining).unwrap();
    }
    buf
}

#[test]
fn tcp_serves_a_bus_of_two_sensors() {
    let (ph, cond) = (sensor("ph_orp"), sensor("conductivity"));
    // The pH probe is silent for unknown requests, as a real probe; the
    // conductivity probe answers them with exceptions.
    let mut cond_sim = Simulator::new(cond.clone()).with_address(2);
    cond_sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let bus = Bus::new().with(Simulator::new(ph.clone()).with_address(1)).with(cond_sim);
    let server = serve_tcp(bus, "127.0.0.1:0", ServeConfig::default()).unwrap();
    let addr = server.local_addr().unwrap();
    assert!(addr.ip().is_loopback());
    assert_eq!(server.endpoint(), &Endpoint::Tcp(addr));
    let (get_ph, get_tc) = (command(&ph, "get_ph"), command(&cond, "get_temperature_and_conductivity"));
    for round in 0..2 {
        // Two connections, one after the other.
        let transport = TcpTransport::connect(addr, Duration::from_secs(2)).unwrap();
        let mut client = Client::with_config(transport, config());
        server.device().device_mut(1).unwrap().set("get_ph", "ph", Value::Float(6.0 + round as f32)).unwrap();
        let reply = client.call_raw(&request(&get_ph, 1, &[]), &get_ph.layout()).unwrap();
        assert_eq!(get_ph.decode_response(1, reply).unwrap()[0].1, Value::Float(6.0 + round as f32));
        let reply = client.call_raw(&request(&get_tc, 2, &[]), &get_tc.layout()).unwrap();
        let values = get_tc.decode_response(2, reply).unwrap();
        assert_eq!(values[0].1, Value::Float(17.625), "the manual's example reading");
        assert_eq!(values[1].1, Value::Float(17.625));
        // An unknown function, framed by silence: ignored by the pH probe,
        // answered with 01 by the conductivity probe.
        let t = client.transport_mut();
        t.write_all(&with_crc(&[1, 0x2B, 0x0E, 0x01, 0x00])).unwrap();
        let mut nothing = [0u8; 5];
        assert_eq!(t.read(&mut nothing, Duration::from_millis(100)).unwrap(), 0, "{nothing:02X?}");
        t.write_all(&with_crc(&[2, 0x2B, 0x0E, 0x01, 0x00])).unwrap();
        assert_eq!(read_n(t, 5), exception(2, 0x2B, 0x01));
    }
    let stats = server.device().device(1).unwrap().stats().to_owned();
    assert_eq!(stats.reads, 2);
    assert_eq!(stats.ignored_unknown, 2);
    server.stop().unwrap();
}

#[test]
fn memory_serving_with_line_timing_approaches_the_wire_limit() {
    let ph = sensor("ph_orp");
    let get_ph = command(&ph, "get_ph");
    let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
    let (transport, server) = serve_memory(Simulator::new(ph), ServeConfig::emulating(line)).unwrap();
    let mut client = Client::with_config(transport, config());
    let req = request(&get_ph, 1, &[]);
    client.call_raw(&req, &get_ph.layout()).unwrap();
    const N: u32 = 20;
    let start = Instant::now();
    for _ in 0..N {
        client.call_raw(&req, &get_ph.layout()).unwrap();
    }
    let per = start.elapsed() / N;
    // The wire: 8 + 9 characters and two t3.5 gaps (the client keeps at least 4 ms).
    let wire = line.frame_time(17) + line.t3_5() + client.inter_frame_delay();
    let floor = line.frame_time(17) + line.t3_5();
    println!(
        "get_ph at 9600 8N1: {:.2} ms per transaction, wire limit {:.2} ms ({:.0}% efficiency, {:.1}/s)",
        per.as_secs_f64() * 1e3,
        wire.as_secs_f64() * 1e3,
        100.0 * wire.as_secs_f64() / per.as_secs_f64(),
        1.0 / per.as_secs_f64()
    );
    assert!(per >= floor, "faster than the line allows: {per:?} < {floor:?}");
    assert!(per < wire * 3, "far from the wire limit: {per:?} vs {wire:?}");
    server.stop().unwrap();
}

#[test]
fn stopping_and_dropping_servers_join_their_threads() {
    let server = serve_tcp(Simulator::new(sensor("ph_orp")), "127.0.0.1:0", ServeConfig::default()).unwrap();
    assert!(server.is_running());
    let start = Instant::now();
    server.stop().unwrap();
    assert!(start.elapsed() < Duration::from_secs(1));
    let (transport, server) = serve_memory(Simulator::new(sensor("ph_orp")), ServeConfig::default()).unwrap();
    drop(transport);
    let start = Instant::now();
    while server.is_running() {
        assert!(start.elapsed() < Duration::from_secs(2), "the server notices its peer went away");
        std::thread::sleep(Duration::from_millis(5));
    }
    drop(server);
}

#[test]
fn a_gap_inside_a_request_resynchronises() {
    let ph = sensor("ph_orp");
    let get_ph = command(&ph, "get_ph");
    let serve = ServeConfig { inter_char_timeout: Duration::from_millis(30), ..ServeConfig::default() };
    let (mut transport, server) = serve_memory(Simulator::new(ph), serve).unwrap();
    let req = request(&get_ph, 1, &[]);
    // Half a request, a pause, then a whole one: the half is dropped.
    transport.write_all(&req[..4]).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    transport.write_all(&req).unwrap();
    assert_eq!(read_n(&mut transport, 9)[..3], [0x01, 0x03, 0x04]);
    // Noise with a bad CRC is ignored and drained; the next request is served.
    transport.write_all(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0x00, 0x00]).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    transport.write_all(&req).unwrap();
    assert_eq!(read_n(&mut transport, 9)[..3], [0x01, 0x03, 0x04]);
    assert_eq!(server.device().stats().ignored_bad_crc, 1);
    assert_eq!(server.device().stats().reads, 2);
    server.stop().unwrap();
}

#[cfg(unix)]
mod pty {
    use yosemitech_rtu::{SerialConfig, SerialTransport};
    use yosemitech_sim::serve_pty;

    use super::*;

    /// Opens the server's pty as a client, or `None` (reason printed) where ptys are unavailable.
    fn open(config: ServeConfig) -> Option<(yosemitech_sim::Server<Simulator>, SerialTransport)> {
        open_with(Simulator::new(sensor("ph_orp")), config)
    }

    /// [`open`] for a given simulator.
    fn open_with(sim: Simulator, config: ServeConfig) -> Option<(yosemitech_sim::Server<Simulator>, SerialTransport)> {
        let server = match serve_pty(sim, config) {
            Ok(server) => server,
            Err(e) => {
                eprintln!("skipping: cannot create a pty: {e}");
                return None;
            }
        };
        let path = server.tty_path().unwrap().to_string();
        match SerialTransport::open(&SerialConfig::new(path.clone())) {
            Ok(transport) => Some((server, transport)),
            Err(e) => {
                eprintln!("skipping: cannot open the pty {path}: {e}");
                None
            }
        }
    }

    #[test]
    fn pty_serves_the_rtu_serial_transport() {
        let mut sim = Simulator::new(sensor("ph_orp"));
        sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
        let Some((server, transport)) = open_with(sim, ServeConfig::default()) else { return };
        println!("serving on {}", server.endpoint());
        let ph = sensor("ph_orp");
        let (get_ph, set_cal, get_cal) =
            (command(&ph, "get_ph"), command(&ph, "set_ph_calibration"), command(&ph, "get_ph_calibration"));
        let mut client = Client::with_config(transport, config());
        let reply = client.call_raw(&request(&get_ph, 1, &[]), &get_ph.layout()).unwrap();
        assert_eq!(reply, [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78]);
        let write = request(&set_cal, 1, &[("k_slope", Value::Float(0.9)), ("b_offset", Value::Float(0.1))]);
        client.call_raw(&write, &set_cal.layout()).unwrap();
        let reply = client.call_raw(&request(&get_cal, 1, &[]), &get_cal.layout()).unwrap();
        assert_eq!(get_cal.decode_response(1, reply).unwrap()[0].1, Value::Float(0.9));
        // Unknown function over the pty: framed by silence, exception 01 (asked for).
        let t = client.transport_mut();
        t.write_all(&with_crc(&[1, 0x08, 0x00, 0x00, 0xA5, 0x37])).unwrap();
        assert_eq!(read_n(t, 5), exception(1, 0x08, 0x01));
        // get_slave_id via 0xFF after set_slave_id: the reply from the old address, then the new one.
        let (set_id, get_id) = (command(&ph, "set_slave_id"), command(&ph, "get_slave_id"));
        let reply =
            client.call_raw(&request(&set_id, 1, &[("slave_address", Value::Int(9))]), &set_id.layout()).unwrap();
        assert_eq!(reply[0], 1);
        let reply = client.call_raw(&request(&get_id, 0xFF, &[]), &get_id.layout()).unwrap();
        assert_eq!(get_id.decode_response(0xFF, reply).unwrap()[0].1, Value::Int(9));
        assert_eq!(server.device().address(), 9);
        drop(client);
        server.stop().unwrap();
    }

    #[test]
    fn pty_with_line_timing_emulation() {
        let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
        let Some((server, transport)) = open(ServeConfig::emulating(line)) else { return };
        let get_ph = command(&sensor("ph_orp"), "get_ph");
        let mut client = Client::with_config(transport, config());
        let req = request(&get_ph, 1, &[]);
        client.call_raw(&req, &get_ph.layout()).unwrap();
        const N: u32 = 10;
        let start = Instant::now();
        for _ in 0..N {
            client.call_raw(&req, &get_ph.layout()).unwrap();
        }
        let per = start.elapsed() / N;
        let floor = line.frame_time(17) + line.t3_5();
        println!(
            "pty get_ph at 9600 8N1: {:.2} ms per transaction (floor {:.2} ms)",
            per.as_secs_f64() * 1e3,
            floor.as_secs_f64() * 1e3
        );
        assert!(per >= floor, "{per:?} < {floor:?}");
        drop(client);
        server.stop().unwrap();
    }

    #[test]
    fn pty_server_outlives_its_clients() {
        let Some((server, transport)) = open(ServeConfig::default()) else { return };
        let get_ph = command(&sensor("ph_orp"), "get_ph");
        let req = request(&get_ph, 1, &[]);
        let mut client = Client::with_config(transport, config());
        client.call_raw(&req, &get_ph.layout()).unwrap();
        drop(client);
        let transport = SerialTransport::open(&SerialConfig::new(server.tty_path().unwrap())).unwrap();
        let mut client = Client::with_config(transport, config());
        client.call_raw(&req, &get_ph.layout()).unwrap();
        assert_eq!(server.device().stats().reads, 2);
    }
}

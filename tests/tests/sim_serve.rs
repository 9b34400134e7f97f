//! The simulator served from a thread: on a pty (rtu SerialTransport), over
//! TCP (rtu TcpTransport), in memory, with line-timing emulation.

use yosemitech_tests::sim as sim_common;

use std::time::{Duration, Instant};

use sim_common::{
    example_reading, example_reply, exception, first_field, float_read, float_write_with_readback, free_address,
    is_float_read, request, seeded_from_example, spec, with_crc,
};
use yosemitech_rtu::{CharFormat, Client, ClientConfig, LineTiming, RetryPolicy, TcpTransport, Transport};
use yosemitech_sim::{Bus, Endpoint, ServeConfig, Simulator, UnknownRequestPolicy, serve_memory, serve_tcp};
use yosemitech_spec::{CommandSpec, Role, Sensor, Value};

fn config() -> ClientConfig {
    ClientConfig { timeout: Duration::from_secs(2), retry: RetryPolicy::NONE, ..ClientConfig::default() }
}

/// The sensor of the spec that the pty test needs: a float read whose
/// example reply the simulator is seeded with, a float write read back, and
/// slave address commands (the getter answering the 0xFF wildcard) with an
/// address to move to; with those commands.
fn addressable_probe() -> (Sensor, CommandSpec, (CommandSpec, CommandSpec), (CommandSpec, CommandSpec)) {
    spec()
        .sensors
        .iter()
        .filter(|s| s.min_address < s.max_address)
        .find_map(|s| {
            let read = s.commands.iter().find(|c| is_float_read(c) && seeded_from_example(s, c))?.clone();
            example_reply(&read)?;
            let cal = float_write_with_readback(s)?;
            let set_id = s.command_with_role(Role::SetSlaveAddress)?.clone();
            let get_id = s.command_with_role(Role::GetSlaveAddress).filter(|c| c.fixed_slave == Some(0xFF))?.clone();
            Some((s.clone(), read, cal, (set_id, get_id)))
        })
        .expect("a sensor with a float read, a calibration write and the 0xFF slave id read")
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
    // A sensor with a single-float read, and another with a float read the
    // manual gives an example reply of.
    let spec = spec();
    let (first, get_one) = float_read(spec);
    let (second, get_two, reading) = spec
        .sensors
        .iter()
        .filter(|s| s.name != first.name)
        .find_map(|s| {
            let read = s.commands.iter().find(|c| is_float_read(c) && seeded_from_example(s, c))?;
            Some((s.clone(), read.clone(), example_reading(read)?))
        })
        .expect("another sensor with a float read served from its example");
    let field = first_field(&get_one);
    // The first probe is silent for unknown requests, as a real probe; the
    // second answers them with exceptions.
    let mut second_sim = Simulator::new(second.clone()).with_address(2);
    second_sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let bus = Bus::new().with(Simulator::new(first.clone()).with_address(1)).with(second_sim);
    let server = serve_tcp(bus, "127.0.0.1:0", ServeConfig::default()).unwrap();
    let addr = server.local_addr().unwrap();
    assert!(addr.ip().is_loopback());
    assert_eq!(server.endpoint(), &Endpoint::Tcp(addr));
    for round in 0..2 {
        // Two connections, one after the other.
        let transport = TcpTransport::connect(addr, Duration::from_secs(2)).unwrap();
        let mut client = Client::with_config(transport, config());
        let v = Value::Float(6.0 + round as f32);
        server.device().device_mut(1).unwrap().set(&get_one.name, &field, v.clone()).unwrap();
        let reply = client.call_raw(&request(&get_one, 1, &[]), &get_one.layout()).unwrap();
        assert_eq!(get_one.decode_response(1, reply).unwrap()[0].1, v);
        let reply = client.call_raw(&request(&get_two, 2, &[]), &get_two.layout()).unwrap();
        let values = get_two.decode_response(2, reply).unwrap();
        assert_eq!(values, reading, "the manual's example reading ({}.{})", second.name, get_two.name);
        // An unknown function, framed by silence: ignored by the first probe,
        // answered with 01 by the second.
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
    let (probe, read) = float_read(spec());
    let slave = probe.default_address;
    let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
    let (transport, server) = serve_memory(Simulator::new(probe), ServeConfig::emulating(line)).unwrap();
    let mut client = Client::with_config(transport, config());
    let req = request(&read, slave, &[]);
    client.call_raw(&req, &read.layout()).unwrap();
    const N: u32 = 20;
    let start = Instant::now();
    for _ in 0..N {
        client.call_raw(&req, &read.layout()).unwrap();
    }
    let per = start.elapsed() / N;
    // The wire: request and reply characters and two t3.5 gaps (the client keeps at least 4 ms).
    let chars = req.len() + read.layout().response_len();
    let wire = line.frame_time(chars) + line.t3_5() + client.inter_frame_delay();
    let floor = line.frame_time(chars) + line.t3_5();
    println!(
        "{} at 9600 8N1: {:.2} ms per transaction, wire limit {:.2} ms ({:.0}% efficiency, {:.1}/s)",
        read.name,
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
    let (probe, _) = float_read(spec());
    let server = serve_tcp(Simulator::new(probe.clone()), "127.0.0.1:0", ServeConfig::default()).unwrap();
    assert!(server.is_running());
    let start = Instant::now();
    server.stop().unwrap();
    assert!(start.elapsed() < Duration::from_secs(1));
    let (transport, server) = serve_memory(Simulator::new(probe), ServeConfig::default()).unwrap();
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
    let (probe, read) = float_read(spec());
    let slave = probe.default_address;
    let serve = ServeConfig { inter_char_timeout: Duration::from_millis(30), ..ServeConfig::default() };
    let (mut transport, server) = serve_memory(Simulator::new(probe), serve).unwrap();
    let req = request(&read, slave, &[]);
    let (reply_len, head) = (read.layout().response_len(), [slave, 0x03, 2 * read.count as u8]);
    // Half a request, a pause, then a whole one: the half is dropped.
    transport.write_all(&req[..4]).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    transport.write_all(&req).unwrap();
    assert_eq!(read_n(&mut transport, reply_len)[..3], head);
    // Noise with a bad CRC is ignored and drained; the next request is served.
    let mut noise = req.clone();
    noise[6..].fill(0);
    transport.write_all(&noise).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    transport.write_all(&req).unwrap();
    assert_eq!(read_n(&mut transport, reply_len)[..3], head);
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
        open_with(Simulator::new(float_read(spec()).0), config)
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
        let (probe, read, (set_cal, get_cal), (set_id, get_id)) = addressable_probe();
        // At the address of the manual's example, so that the reply is the printed one.
        let example = example_reply(&read).unwrap();
        let slave = example[0];
        let mut sim = Simulator::new(probe.clone()).with_address(slave);
        sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
        let Some((server, transport)) = open_with(sim, ServeConfig::default()) else { return };
        println!("serving on {} ({})", server.endpoint(), probe.name);
        let mut client = Client::with_config(transport, config());
        let reply = client.call_raw(&request(&read, slave, &[]), &read.layout()).unwrap();
        assert_eq!(reply, example, "the manual's example reply");
        // A value of its own for every field, however many the write has.
        let written: Vec<(String, Value)> = set_cal
            .named_fields()
            .enumerate()
            .map(|(i, f)| (f.display_name().to_owned(), Value::Float(yosemitech_tests::values::varied_float(f, i))))
            .collect();
        let values: Vec<(&str, Value)> = written.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
        client.call_raw(&request(&set_cal, slave, &values), &set_cal.layout()).unwrap();
        let reply = client.call_raw(&request(&get_cal, slave, &[]), &get_cal.layout()).unwrap();
        assert_eq!(get_cal.decode_response(slave, reply).unwrap(), written, "what was written reads back");
        // Unknown function over the pty: framed by silence, exception 01 (asked for).
        let t = client.transport_mut();
        t.write_all(&with_crc(&[slave, 0x08, 0x00, 0x00, 0xA5, 0x37])).unwrap();
        assert_eq!(read_n(t, 5), exception(slave, 0x08, 0x01));
        // get_slave_id via 0xFF after set_slave_id: the reply from the old address, then the new one.
        let address = first_field(&set_id);
        let new = free_address(&probe, &[slave]).expect("another address");
        let to = [(address.as_str(), Value::Int(i64::from(new)))];
        let reply = client.call_raw(&request(&set_id, slave, &to), &set_id.layout()).unwrap();
        assert_eq!(reply[0], slave);
        let reply = client.call_raw(&request(&get_id, 0xFF, &[]), &get_id.layout()).unwrap();
        let reported = get_id.decode_response(0xFF, reply).unwrap();
        assert_eq!(reported.iter().find(|(n, _)| *n == first_field(&get_id)).map(|(_, v)| v), Some(&to[0].1));
        assert_eq!(server.device().address(), new);
        drop(client);
        server.stop().unwrap();
    }

    #[test]
    fn pty_with_line_timing_emulation() {
        let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
        let Some((server, transport)) = open(ServeConfig::emulating(line)) else { return };
        let (probe, read) = float_read(spec());
        let mut client = Client::with_config(transport, config());
        let req = request(&read, probe.default_address, &[]);
        client.call_raw(&req, &read.layout()).unwrap();
        const N: u32 = 10;
        let start = Instant::now();
        for _ in 0..N {
            client.call_raw(&req, &read.layout()).unwrap();
        }
        let per = start.elapsed() / N;
        let floor = line.frame_time(req.len() + read.layout().response_len()) + line.t3_5();
        println!(
            "pty {} at 9600 8N1: {:.2} ms per transaction (floor {:.2} ms)",
            read.name,
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
        let (probe, read) = float_read(spec());
        let req = request(&read, probe.default_address, &[]);
        let mut client = Client::with_config(transport, config());
        client.call_raw(&req, &read.layout()).unwrap();
        drop(client);
        let transport = SerialTransport::open(&SerialConfig::new(server.tty_path().unwrap())).unwrap();
        let mut client = Client::with_config(transport, config());
        client.call_raw(&req, &read.layout()).unwrap();
        assert_eq!(server.device().stats().reads, 2);
    }
}

mod mbap {
    use std::io::{Read, Write};
    use std::net::TcpStream;

    use yosemitech_rtu::ExceptionCode;
    use yosemitech_rtu::mbap::{MAX_MBAP_ADU, adu_to_rtu, rtu_to_adu};
    use yosemitech_sim::serve_mbap;

    use super::*;

    fn connect(addr: std::net::SocketAddr) -> TcpStream {
        let stream = TcpStream::connect(addr).unwrap();
        stream.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        stream
    }

    /// Sends the RTU `request` as an MBAP ADU with `transaction`.
    fn send(stream: &mut TcpStream, request: &[u8], transaction: u16) {
        let mut adu = [0u8; MAX_MBAP_ADU];
        let n = rtu_to_adu(request, transaction, &mut adu).unwrap();
        stream.write_all(&adu[..n]).unwrap();
    }

    /// Reads one MBAP ADU and returns its transaction id and the RTU frame carrying it.
    fn receive(stream: &mut TcpStream) -> (u16, Vec<u8>) {
        let mut adu = vec![0u8; 7];
        stream.read_exact(&mut adu).unwrap();
        let header = yosemitech_rtu::mbap::Header::parse(&adu).unwrap();
        adu.resize(header.adu_len(), 0);
        stream.read_exact(&mut adu[7..]).unwrap();
        let mut rtu = [0u8; 256];
        let (header, n) = adu_to_rtu(&adu, &mut rtu).unwrap();
        (header.transaction, rtu[..n].to_vec())
    }

    #[test]
    fn mbap_serves_a_bus_to_several_connections_at_once() {
        let spec = spec();
        let (first, get_one) = float_read(spec);
        let (second, get_two) = spec
            .sensors
            .iter()
            .filter(|s| s.name != first.name)
            .find_map(|s| Some((s.clone(), s.commands.iter().find(|c| is_float_read(c))?.clone())))
            .expect("another sensor with a float read");
        let bus =
            Bus::new().with(Simulator::new(first.clone()).with_address(1)).with(Simulator::new(second).with_address(2));
        let server = serve_mbap(bus, "127.0.0.1:0", ServeConfig::default()).unwrap();
        let addr = server.local_addr().unwrap();
        assert_eq!(server.endpoint(), &Endpoint::Mbap(addr));
        let field = first_field(&get_one);
        server.device().device_mut(1).unwrap().set(&get_one.name, &field, Value::Float(7.25)).unwrap();
        // Two connections open at once, requests interleaved: each is
        // answered on its own connection with its own transaction id.
        let (mut a, mut b) = (connect(addr), connect(addr));
        for round in 0..3u16 {
            send(&mut a, &request(&get_one, 1, &[]), 100 + round);
            send(&mut b, &request(&get_two, 2, &[]), 200 + round);
            let (tid_b, reply_b) = receive(&mut b);
            let (tid_a, reply_a) = receive(&mut a);
            assert_eq!((tid_a, tid_b), (100 + round, 200 + round));
            assert_eq!(get_one.decode_response(1, &reply_a).unwrap()[0].1, Value::Float(7.25));
            get_two.decode_response(2, &reply_b).unwrap();
        }
        // A unit nobody answers for: the gateway's exception 0x0B.
        send(&mut a, &request(&get_one, 9, &[]), 42);
        let (tid, reply) = receive(&mut a);
        assert_eq!(tid, 42);
        let error = get_one.decode_response(9, &reply).unwrap_err().to_string();
        assert!(error.contains(&ExceptionCode::GatewayTargetFailedToRespond.to_string()), "{error}");
        // A malformed header (protocol id 1) closes that connection only.
        b.write_all(&[0, 1, 0, 1, 0, 6, 1, 3, 0, 0, 0, 1]).unwrap();
        let mut rest = [0u8; 16];
        assert_eq!(b.read(&mut rest).unwrap_or(0), 0, "closed");
        send(&mut a, &request(&get_one, 1, &[]), 43);
        assert_eq!(receive(&mut a).0, 43);
        assert_eq!(server.device().device(1).unwrap().stats().reads, 4);
        drop((a, b));
        let start = Instant::now();
        server.stop().unwrap();
        assert!(start.elapsed() < Duration::from_secs(2), "stop joins the connection threads");
    }
}

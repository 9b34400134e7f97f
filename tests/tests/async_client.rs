//! The tokio `AsyncClient` against the simulator: cancel safety over RTU
//! and Modbus TCP, every sensor's reads over Modbus TCP (ours and
//! tokio-modbus's server), and eight probes on eight ptys read concurrently
//! from one runtime. Probes and commands come from the spec.

use yosemitech_tests::sim as sim_common;

use std::future::Future;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use sim_common::{ReadRequest, first_field, float_read, is_float_read, read_requests, request, simulated_modules};
use yosemitech_rtu::frame::{Function, MAX_ADU};
use yosemitech_rtu::{AsyncClient, ClientConfig, ExceptionCode, MbapLink, RetryPolicy, RtuStream, SensorModule};
use yosemitech_sim::{FaultConfig, FaultKind, FrameHandler, ServeConfig, Simulator, serve_mbap, serve_tcp};
use yosemitech_spec::Value;
use yosemitech_tests::spec;

fn block_on<F: Future>(future: F) -> F::Output {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    runtime.block_on(async { tokio::time::timeout(Duration::from_secs(120), future).await.expect("the test ends") })
}

fn config(timeout: Duration) -> ClientConfig {
    ClientConfig { timeout, retry: RetryPolicy::NONE, ..ClientConfig::default() }
}

/// Polls until the served device has seen `n` requests (the test's own
/// deadline bounds it).
async fn requests_seen(server: &yosemitech_sim::Server<Simulator>, n: u64) {
    while server.device().stats().requests < n {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// A call dropped after its request reached the device, whose reply is held
/// back: the next call gets its own reply, never the late one.
async fn drop_a_call_then_call_again<L: yosemitech_rtu::AsyncLink>(
    client: &mut AsyncClient<L>,
    server: &yosemitech_sim::Server<Simulator>,
    read: &yosemitech_spec::CommandSpec,
) {
    let slave = server.device().address();
    let (field, layout) = (first_field(read), read.layout());
    let req = request(read, slave, &[]);
    server.device().set(&read.name, &field, Value::Float(1.5)).unwrap();
    tokio::select! {
        result = client.call_raw(&req, &layout) => panic!("the reply is held back, yet: {result:?}"),
        () = requests_seen(server, 1) => {}
    }
    // The held-back reply carries 1.5; the device now holds 2.5.
    server.device().set(&read.name, &field, Value::Float(2.5)).unwrap();
    let reply = client.call_raw(&req, &layout).await.unwrap().to_vec();
    assert_eq!(read.decode_response(slave, &reply).unwrap()[0].1, Value::Float(2.5), "not the late reply");
    assert_eq!(server.device().stats().reads, 2);
    // And the bus stays usable.
    server.device().set(&read.name, &field, Value::Float(3.5)).unwrap();
    let reply = client.call_raw(&req, &layout).await.unwrap().to_vec();
    assert_eq!(read.decode_response(slave, &reply).unwrap()[0].1, Value::Float(3.5));
}

/// Holds a reply back for `delay`, once.
fn delayed_once(delay: Duration) -> FaultConfig {
    FaultConfig { delay_by: delay, ..FaultConfig::scripted([Some(FaultKind::Delay)]) }
}

#[test]
fn a_call_dropped_half_way_leaves_an_rtu_bus_usable() {
    let (probe, read) = float_read(spec());
    yosemitech_tests::report!("a dropped call over RTU: {}.{}", probe.name, read.name);
    // The reply comes 0.5 s late, well inside the abandoned attempt's 3 s
    // deadline, which the next call waits out before draining it.
    let sim = Simulator::new(probe).with_faults(delayed_once(Duration::from_millis(500)));
    let server = serve_tcp(sim, "127.0.0.1:0", ServeConfig::default()).unwrap();
    let addr = server.local_addr().unwrap();
    block_on(async {
        let stream = tokio::net::TcpStream::connect(addr).await.unwrap();
        let mut client = AsyncClient::with_config(RtuStream::new(stream), config(Duration::from_secs(3)));
        drop_a_call_then_call_again(&mut client, &server, &read).await;
    });
    assert_eq!(server.device().faults().get(FaultKind::Delay), 1);
}

#[test]
fn a_call_dropped_half_way_leaves_a_modbus_tcp_link_usable() {
    let (probe, read) = float_read(spec());
    yosemitech_tests::report!("a dropped call over Modbus TCP: {}.{}", probe.name, read.name);
    let sim = Simulator::new(probe).with_faults(delayed_once(Duration::from_millis(500)));
    let server = serve_mbap(sim, "127.0.0.1:0", ServeConfig::default()).unwrap();
    let addr = server.local_addr().unwrap();
    block_on(async {
        let stream = tokio::net::TcpStream::connect(addr).await.unwrap();
        let mut client = AsyncClient::with_config(MbapLink::new(stream), config(Duration::from_secs(3)));
        drop_a_call_then_call_again(&mut client, &server, &read).await;
        assert_eq!(client.link().transaction(), 3, "one transaction id per request");
    });
}

/// Reads every read of `module` through `client` and checks each reply is
/// the simulator's own (`reference` answers the same request) and decodes
/// through the module's generated decoder. Returns the reads done.
async fn read_every_command<L: yosemitech_rtu::AsyncLink>(
    client: &mut AsyncClient<L>,
    module: &SensorModule,
    reference: &mut Simulator,
) -> usize {
    let mut done = 0;
    for ReadRequest { name, layout, slave, frame: req } in read_requests(module) {
        let reply = client.call_raw(&req, &layout).await.unwrap_or_else(|e| panic!("{}.{name}: {e}", module.info.name));
        assert_eq!(
            module.visit_response(name, slave, reply, &mut |_, _| {}),
            Some(Ok(())),
            "{}.{name}",
            module.info.name
        );
        let mut truth = Vec::new();
        reference.handle(&req, &mut truth);
        if layout.trigger {
            // Modbus TCP carries the PDU: a trigger read's meaningless data
            // may come back shortened (tokio-modbus's server) or whole (ours).
            assert_eq!(reply[..2], truth[..2], "{}.{name}", module.info.name);
        } else {
            assert_eq!(reply, &truth[..], "{}.{name}", module.info.name);
        }
        done += 1;
    }
    done
}

#[test]
fn the_async_client_reads_every_sensor_over_modbus_tcp() {
    let (mut total, mut gateway, mut expected) = (0, 0, 0);
    for (module, sim) in simulated_modules() {
        let mut reference = sim.clone();
        let server = serve_mbap(sim, "127.0.0.1:0", ServeConfig::default()).unwrap();
        let addr = server.local_addr().unwrap();
        let (done, exceptions) = block_on(async {
            let stream = tokio::net::TcpStream::connect(addr).await.unwrap();
            let mut client = AsyncClient::with_config(MbapLink::new(stream), config(Duration::from_secs(5)));
            let done = read_every_command(&mut client, module, &mut reference).await;
            // A unit nobody answers for: the gateway's exception 0x0B, typed.
            // Any read to the probe's own address will do (a sensor may have none).
            let read = module
                .commands
                .iter()
                .map(|c| (c.name, c.layout))
                .find(|(_, l)| l.function == Function::Read && l.fixed_slave.is_none());
            let Some((name, layout)) = read else {
                yosemitech_tests::report!("{}: no read to its own address, no gateway exception", module.info.name);
                return (done, 0);
            };
            let nobody = (1..=247).find(|&a| a != module.info.default_address).unwrap();
            let mut req = [0u8; MAX_ADU];
            let len = layout.encode_request(nobody, &[], &mut req).unwrap();
            let error = client.call_raw(&req[..len], &layout).await.unwrap_err();
            assert_eq!(error.exception(), Some(ExceptionCode::GatewayTargetFailedToRespond), "{name}: {error}");
            (done, 1)
        });
        total += done;
        gateway += exceptions;
        expected += read_requests(module).len();
    }
    assert_eq!(total, expected, "every read of every sensor");
    yosemitech_tests::report!(
        "{total} reads of every sensor by the async client over Modbus TCP; {gateway} sensors' gateway exceptions"
    );
}

/// A tokio-modbus server answering from a simulator: each request becomes
/// the RTU frame the simulator takes, its reply the tokio-modbus response.
mod tokio_modbus_server {
    use std::future;
    use std::sync::{Arc, Mutex};

    use tokio_modbus::prelude::{ExceptionCode, Request, Response, SlaveRequest};
    use tokio_modbus::server::Service;
    use yosemitech_rtu::crc16;
    use yosemitech_sim::{FrameHandler, Simulator};

    #[derive(Clone)]
    pub struct SimService(pub Arc<Mutex<Simulator>>);

    fn with_crc(mut frame: Vec<u8>) -> Vec<u8> {
        let crc = crc16(&frame).to_le_bytes();
        frame.extend_from_slice(&crc);
        frame
    }

    impl Service for SimService {
        type Request = SlaveRequest<'static>;
        type Response = Response;
        type Exception = ExceptionCode;
        type Future = future::Ready<Result<Response, ExceptionCode>>;

        fn call(&self, request: Self::Request) -> Self::Future {
            let slave = request.slave;
            let frame = match &request.request {
                Request::ReadHoldingRegisters(address, count) => {
                    let mut f = vec![slave, 0x03];
                    f.extend_from_slice(&address.to_be_bytes());
                    f.extend_from_slice(&count.to_be_bytes());
                    with_crc(f)
                }
                Request::WriteMultipleRegisters(address, words) => {
                    let mut f = vec![slave, 0x10];
                    f.extend_from_slice(&address.to_be_bytes());
                    f.extend_from_slice(&(words.len() as u16).to_be_bytes());
                    f.push(2 * words.len() as u8);
                    words.iter().for_each(|w| f.extend_from_slice(&w.to_be_bytes()));
                    with_crc(f)
                }
                _ => return future::ready(Err(ExceptionCode::IllegalFunction)),
            };
            let mut reply = Vec::new();
            self.0.lock().unwrap().handle(&frame, &mut reply);
            future::ready(match reply.get(1) {
                None => Err(ExceptionCode::GatewayTargetDevice),
                Some(f) if f & 0x80 != 0 => Err(ExceptionCode::new(reply[2])),
                Some(0x03) => {
                    let data = &reply[3..reply.len() - 2];
                    let data = &data[..usize::from(reply[2]).min(data.len())];
                    Ok(Response::ReadHoldingRegisters(
                        data.chunks_exact(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect(),
                    ))
                }
                Some(_) => Ok(Response::WriteMultipleRegisters(
                    u16::from_be_bytes([reply[2], reply[3]]),
                    u16::from_be_bytes([reply[4], reply[5]]),
                )),
            })
        }
    }
}

#[test]
fn our_modbus_tcp_client_reads_a_tokio_modbus_server() {
    use tokio_modbus::server::tcp::{Server, accept_tcp_connection};

    let (mut total, mut expected) = (0, 0);
    for (module, sim) in simulated_modules() {
        expected += read_requests(module).len();
        let mut reference = sim.clone();
        let service = tokio_modbus_server::SimService(Arc::new(Mutex::new(sim)));
        total += block_on(async {
            let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            let addr = listener.local_addr().unwrap();
            let server = Server::new(listener);
            let on_connected = move |stream, socket_addr| {
                let service = service.clone();
                async move { accept_tcp_connection(stream, socket_addr, move |_| Ok(Some(service.clone()))) }
            };
            let serving = tokio::spawn(async move { server.serve(&on_connected, |_| {}).await });
            let stream = tokio::net::TcpStream::connect(addr).await.unwrap();
            let mut client = AsyncClient::with_config(MbapLink::new(stream), config(Duration::from_secs(5)));
            let done = read_every_command(&mut client, module, &mut reference).await;
            serving.abort();
            done
        });
    }
    yosemitech_tests::report!("{total} reads of every sensor by our Modbus TCP client from a tokio-modbus server");
    assert_eq!(total, expected, "every read of every sensor");
}

/// A device that answers its first request only once `parties` devices
/// have each received theirs: only a client that has all its requests out
/// at once gets any reply.
struct Rendezvous {
    sim: Simulator,
    met: bool,
    meeting: Arc<(Mutex<usize>, Condvar)>,
    parties: usize,
}

impl FrameHandler for Rendezvous {
    fn handle(&mut self, request: &[u8], reply: &mut Vec<u8>) -> Duration {
        if !self.met {
            self.met = true;
            let (arrived, all_here) = &*self.meeting;
            let mut arrived = arrived.lock().unwrap();
            *arrived += 1;
            all_here.notify_all();
            let deadline = Instant::now() + Duration::from_secs(20);
            while *arrived < self.parties {
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    // Alone: stay silent, so the client's call times out.
                    return Duration::ZERO;
                }
                arrived = all_here.wait_timeout(arrived, left).unwrap().0;
            }
        }
        self.sim.handle(request, reply)
    }
}

#[cfg(unix)]
#[test]
fn one_runtime_reads_eight_probes_on_eight_ptys_concurrently() {
    use yosemitech_rtu::{AsyncSerial, SerialConfig};
    use yosemitech_sim::serve_pty;

    const PROBES: usize = 8;
    const READS: usize = 5;
    // Each probe: a sensor of the spec with a float read, in turn.
    let spec = spec();
    let readable: Vec<_> = yosemitech::SENSORS
        .iter()
        .filter_map(|module| {
            let sensor = spec.sensor(module.info.name)?;
            let read = sensor.commands.iter().find(|c| is_float_read(c))?;
            Some((module, sensor.clone(), read.clone()))
        })
        .collect();
    assert!(!readable.is_empty());
    let meeting = Arc::new((Mutex::new(0), Condvar::new()));
    let mut servers = Vec::new();
    let mut probes = Vec::new();
    for i in 0..PROBES {
        let (module, sensor, read) = readable[i % readable.len()].clone();
        let reference = Simulator::new(sensor);
        let device = Rendezvous { sim: reference.clone(), met: false, meeting: Arc::clone(&meeting), parties: PROBES };
        let server = match serve_pty(device, ServeConfig::default()) {
            Ok(server) => server,
            Err(e) => return eprintln!("skipping: cannot create a pty: {e}"),
        };
        let port = SerialConfig { baud: module.info.baud, ..SerialConfig::new(server.tty_path().unwrap()) };
        probes.push((module, reference, read, port));
        servers.push(server);
    }
    let reads = block_on(async move {
        let mut tasks = tokio::task::JoinSet::new();
        for (module, mut reference, read, port) in probes {
            let link = AsyncSerial::open(&port).unwrap();
            let mut client = AsyncClient::with_config(link, config(Duration::from_secs(30)));
            tasks.spawn(async move {
                let slave = module.info.default_address;
                let req = request(&read, slave, &[]);
                let mut truth = Vec::new();
                reference.handle(&req, &mut truth);
                for _ in 0..READS {
                    let reply = client.call_raw(&req, &read.layout()).await.unwrap();
                    assert_eq!(reply, &truth[..], "{}.{}", module.info.name, read.name);
                    let decoded = module.visit_response(&read.name, slave, reply, &mut |_, _| {});
                    assert_eq!(decoded, Some(Ok(())));
                }
                READS
            });
        }
        let mut reads = 0;
        while let Some(done) = tasks.join_next().await {
            reads += done.unwrap();
        }
        reads
    });
    assert_eq!(reads, PROBES * READS);
    assert_eq!(*meeting.0.lock().unwrap(), PROBES, "every probe had its first request out at once");
    for server in &servers {
        assert_eq!(server.device().sim.stats().reads as usize, READS);
    }
    yosemitech_tests::report!("{reads} reads of {PROBES} probes on {PROBES} ptys from one current-thread runtime");
}

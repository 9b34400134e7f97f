//! tokio-modbus interop: a tokio-modbus client reads the simulator over
//! Modbus TCP ([`serve_mbap`]), over RTU on TCP ([`serve_tcp`]) and over
//! RTU on a pty (tokio-serial), and `yosemitech_rtu::tokio_modbus` turns
//! what it returns into the frames the generated decoders take.

use yosemitech_tests::sim as sim_common;

use std::future::Future;
use std::time::Duration;

use sim_common::{ReadRequest, read_requests, simulated_modules, with_role};
use tokio_modbus::client::Context;
use tokio_modbus::prelude::{Slave, rtu, tcp};
use yosemitech_rtu::frame::{Function, MAX_ADU};
use yosemitech_rtu::tokio_modbus::{Error, Unsupported, call, call_raw};
use yosemitech_rtu::{ExceptionCode, FrameError, SensorModule};
use yosemitech_sim::{FrameHandler, ServeConfig, Simulator, UnknownRequestPolicy, serve_mbap, serve_tcp};
use yosemitech_spec::Role;
use yosemitech_tests::do_probe::{self, GetOffsets, GetOxygenSample, SetOffsets};
use yosemitech_tests::spec;

/// Bounds every tokio-modbus call: its RTU client has no timeout of its own.
const DEADLINE: Duration = Duration::from_secs(5);

fn block_on<F: Future>(future: F) -> F::Output {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    runtime.block_on(async { tokio::time::timeout(DEADLINE * 20, future).await.expect("the test finishes") })
}

/// Reads every read command of `module` through `ctx`: the reply rebuilt
/// from the registers tokio-modbus returns is the simulator's own reply
/// (`reference` answers the same request), byte for byte, and the module's
/// generated decoder takes it. Trigger reads are refused before anything
/// is sent. Returns the reads checked.
async fn read_every_command(ctx: &mut Context, module: &SensorModule, reference: &mut Simulator) -> usize {
    let mut checked = 0;
    for ReadRequest { name, layout, slave, frame } in read_requests(module) {
        let request = &frame[..];
        let result = tokio::time::timeout(DEADLINE, call_raw(ctx, request, &layout)).await.expect("a reply in time");
        if layout.trigger {
            assert!(matches!(result, Err(Error::Unsupported(Unsupported::TriggerRead))), "{name}: {result:?}");
            continue;
        }
        let frame = result.unwrap_or_else(|e| panic!("{}.{name}: {e}", module.info.name));
        let mut expected = Vec::new();
        reference.handle(request, &mut expected);
        assert_eq!(&*frame, &expected[..], "{}.{name}: the simulator's reply", module.info.name);
        let mut fields = 0;
        let decoded = module.visit_response(name, slave, &frame, &mut |_, _| fields += 1);
        assert_eq!(decoded, Some(Ok(())), "{}.{name}", module.info.name);
        // Every named field, and nothing for reserved bytes (a read may carry only those).
        let named = spec().sensor(module.info.name).and_then(|s| s.command(name)).map(|c| c.named_fields().count());
        assert_eq!(Some(fields), named, "{}.{name}: fields decoded", module.info.name);
        checked += 1;
    }
    checked
}

#[test]
fn tokio_modbus_reads_every_sensor_over_modbus_tcp() {
    let (mut total, mut expected) = (0, 0);
    for (module, sim) in simulated_modules() {
        expected += reads_sent(module);
        let mut reference = sim.clone();
        let server = serve_mbap(sim, "127.0.0.1:0", ServeConfig::default()).unwrap();
        let addr = server.local_addr().unwrap();
        total += block_on(async {
            let mut ctx = tcp::connect(addr).await.unwrap();
            read_every_command(&mut ctx, module, &mut reference).await
        });
        assert_eq!(server.device().stats().requests as usize, reads_sent(module), "trigger reads never sent");
    }
    yosemitech_tests::report!("{total} reads of every sensor through tokio-modbus over Modbus TCP");
    assert_eq!(total, expected, "every read the adapter sends, checked");
}

#[test]
fn tokio_modbus_reads_every_sensor_over_rtu_on_tcp() {
    let mut total = 0;
    for (module, sim) in simulated_modules() {
        let mut reference = sim.clone();
        let server = serve_tcp(sim, "127.0.0.1:0", ServeConfig::default()).unwrap();
        let addr = server.local_addr().unwrap();
        total += block_on(async {
            let stream = tokio::net::TcpStream::connect(addr).await.unwrap();
            let mut ctx = rtu::attach_slave(stream, Slave(module.info.default_address));
            read_every_command(&mut ctx, module, &mut reference).await
        });
        assert_eq!(server.device().stats().requests as usize, reads_sent(module));
    }
    yosemitech_tests::report!("{total} reads of every sensor through tokio-modbus over RTU on TCP");
}

/// Reads of `module` the adapter sends (all but trigger reads).
fn reads_sent(module: &SensorModule) -> usize {
    read_requests(module).iter().filter(|read| !read.layout.trigger).count()
}

#[cfg(unix)]
#[test]
fn tokio_modbus_reads_a_sensor_over_rtu_on_a_pty() {
    // A sensor with a read the adapter sends (not a trigger).
    let Some((module, sim)) = simulated_modules().into_iter().find(|(module, _)| reads_sent(module) > 0) else {
        return yosemitech_tests::report!("no sensor has a read tokio-modbus can send");
    };
    let mut reference = sim.clone();
    let server = match yosemitech_sim::serve_pty(sim, ServeConfig::default()) {
        Ok(server) => server,
        Err(e) => return eprintln!("skipping: cannot create a pty: {e}"),
    };
    let path = server.tty_path().unwrap().to_owned();
    let checked = block_on(async {
        let port = tokio_serial::SerialStream::open(&tokio_serial::new(&path, module.info.baud)).unwrap();
        let mut ctx = rtu::attach_slave(port, Slave(module.info.default_address));
        read_every_command(&mut ctx, module, &mut reference).await
    });
    assert_eq!(checked, reads_sent(module));
    yosemitech_tests::report!("{checked} reads of {} through tokio-modbus over RTU on {path}", module.info.name);
}

#[test]
fn typed_calls_write_read_back_and_report_exceptions() {
    let fixture =
        yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/do-probe/spec").into()]).unwrap();
    let sensor = fixture.sensors[0].clone();
    let slave = do_probe::SENSOR.default_address;
    let mut sim = Simulator::new(sensor).with_address(slave);
    sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    let server = serve_mbap(sim, "127.0.0.1:0", ServeConfig::default()).unwrap();
    let addr = server.local_addr().unwrap();
    block_on(async {
        let mut ctx = tcp::connect(addr).await.unwrap();
        // The fixture's example reading, typed.
        let reading = call(&mut ctx, slave, &GetOxygenSample).await.unwrap();
        assert_eq!((reading.do_mg_l, reading.sample_count), (8.25, 123_456));
        // A write, read back through the generated decoder.
        let offsets = SetOffsets { pressure_offset_pa: -1234, salinity_ppt: 12.5, membrane_correction: 7 };
        call(&mut ctx, slave, &offsets).await.unwrap();
        let back = call(&mut ctx, slave, &GetOffsets).await.unwrap();
        assert_eq!((back.pressure_offset_pa, back.salinity_ppt, back.membrane_correction), (-1234, 12.5, 7));
        // Range checks run before anything is sent.
        let too_far = SetOffsets { pressure_offset_pa: 100_001, ..offsets };
        assert!(matches!(call(&mut ctx, slave, &too_far).await, Err(Error::Encode(_))));
        // A broadcast is refused: tokio-modbus would wait for a reply.
        assert!(matches!(call(&mut ctx, 0, &offsets).await, Err(Error::Unsupported(Unsupported::Broadcast))));
        // Registers the probe lacks: its exception, through the same decoder.
        let lacking = yosemitech::SENSORS
            .iter()
            .flat_map(|m| m.commands.iter().map(|c| c.layout))
            .find(|l| {
                l.function == Function::Read
                    && !l.trigger
                    && l.fixed_slave.is_none()
                    && do_probe::MODULE.commands.iter().all(|c| c.layout.address != l.address)
            })
            .expect("a read of registers the fixture lacks");
        let mut request = [0u8; MAX_ADU];
        let len = lacking.encode_request(slave, &[], &mut request).unwrap();
        let error = call_raw(&mut ctx, &request[..len], &lacking).await.unwrap_err();
        assert!(matches!(error, Error::Frame(FrameError::Exception { function: 0x03, .. })), "{error}");
        assert_eq!(error.exception(), Some(ExceptionCode::IllegalDataAddress));
    });
    assert_eq!(server.device().stats().exceptions, 1);
}

#[test]
fn fixed_slave_and_trigger_writes_go_through() {
    // A sensor whose slave id read answers the 0xFF wildcard, and one with a
    // zero-register trigger write, both picked by role.
    let spec = spec();
    let wildcard = spec
        .sensors
        .iter()
        .find(|s| s.command_with_role(Role::GetSlaveAddress).is_some_and(|c| c.fixed_slave.is_some()))
        .expect("a sensor whose slave id read uses a fixed address")
        .clone();
    let get_id = with_role(&wildcard, Role::GetSlaveAddress);
    let server = serve_mbap(Simulator::new(wildcard.clone()), "127.0.0.1:0", ServeConfig::default()).unwrap();
    let addr = server.local_addr().unwrap();
    let module = yosemitech::SENSORS.iter().find(|m| m.info.name == wildcard.name).unwrap();
    block_on(async {
        let mut ctx = tcp::connect(addr).await.unwrap();
        let layout = module.layout(&get_id.name).unwrap();
        let fixed = layout.fixed_slave.unwrap();
        let mut request = [0u8; MAX_ADU];
        let len = layout.encode_request(fixed, &[], &mut request).unwrap();
        let frame = call_raw(&mut ctx, &request[..len], &layout).await.unwrap();
        // The address is the command's first named field.
        let mut address = None;
        module
            .visit_response(&get_id.name, fixed, &frame, &mut |_, value| {
                address.get_or_insert(value.to_string());
            })
            .unwrap()
            .unwrap();
        assert_eq!(address, Some(wildcard.default_address.to_string()), "the probe's own address");
        // The same command at another address is refused before sending.
        let other = (1..=247).find(|&a| a != fixed).unwrap();
        let refused = layout.encode_request(other, &[], &mut request);
        assert!(refused.is_err());
    });
    drop(server);

    let (trigger_module, trigger_sensor, trigger) = yosemitech::SENSORS
        .iter()
        .find_map(|m| {
            let command = m.commands.iter().find(|c| {
                let l = c.layout;
                l.function == Function::Write && l.trigger && l.fixed_slave.is_none()
            })?;
            Some((m, spec.sensor(m.info.name)?.clone(), command.name))
        })
        .expect("a zero-register trigger write");
    let server = serve_mbap(Simulator::new(trigger_sensor), "127.0.0.1:0", ServeConfig::default()).unwrap();
    let addr = server.local_addr().unwrap();
    block_on(async {
        let mut ctx = tcp::connect(addr).await.unwrap();
        let layout = trigger_module.layout(trigger).unwrap();
        let slave = trigger_module.info.default_address;
        let mut request = [0u8; MAX_ADU];
        let len = layout.encode_request(slave, &[], &mut request).unwrap();
        let frame = call_raw(&mut ctx, &request[..len], &layout).await.unwrap();
        assert_eq!(trigger_module.visit_response(trigger, slave, &frame, &mut |_, _| {}), Some(Ok(())));
    });
    assert_eq!(server.device().stats().replies, 1);
}

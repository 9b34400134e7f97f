//! `yosemitech demo`: simulated probes on pseudo-terminals, driven through
//! the real serial code path (no hardware, no root).

use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

use yosemitech::procedures::coefficients::{read_conductivity, read_ph_orp};
use yosemitech::{conductivity, ph_orp};
use yosemitech_rtu::{Client, ClientConfig, RetryPolicy, Transport, Version};
use yosemitech_sim::{Bus, Device, ServeConfig, Server, Simulator, Variation, line_timing};
use yosemitech_spec::{FieldKind, Role, Sensor, Value};

use crate::catalog::Catalog;
use crate::cli::DemoArgs;
use crate::commands::list::software_key;
use crate::commands::{measure, scan};
use crate::device::{is_typed, procedure_failed};
use crate::error::{CliError, Context, Result, request_failed};
use crate::port::Opened;

/// How much shorter the demo's measurement waits are than the manual's.
const TIME_SCALE: f64 = 0.02;

/// The readings the simulated probes start from.
const PH: f32 = 7.02;
const ORP_MV: f32 = 215.4;
const WATER_C: f32 = 21.3;
const CONDUCTIVITY_MS_CM: f32 = 1.413;

/// The reply timeout on the family bus, far below scan's usual second: the
/// simulators answer at once (in ~30 ms with `--line-timing`), and only
/// taken addresses are scanned, so the timeout is spent only on a
/// serial-number read of another layout, which no probe answers. No
/// retries: they would repeat those reads.
const BUS_TIMEOUT: Duration = Duration::from_millis(300);

/// A simulated probe served for the demo, and the client talking to it.
struct Probe {
    server: Server<Simulator>,
    opened: Opened,
}

fn setup(sensor: &Arc<Sensor>, values: &[(&str, f32)], noise: f32, line: bool) -> Result<Probe> {
    let mut sim = Simulator::new(Arc::clone(sensor));
    for (field, value) in values {
        sim.set_everywhere(field, Value::Float(*value))
            .map_err(|e| CliError::device(format!("cannot set up the simulated {}: {e}", sensor.name)))?;
    }
    sim.set_variation(Some(Variation { seed: 7, noise, drift_per_read: 0.0 }));
    let config = if line { ServeConfig::emulating(line_timing(sensor)) } else { ServeConfig::default() };
    let (server, port, transport) = serve(sim, config, sensor.serial.baud)?;
    let config = ClientConfig { timeout: Duration::from_secs(1), ..ClientConfig::default() };
    let opened = Opened { bus: Client::with_config(transport, config), port, timeout: config.timeout };
    Ok(Probe { server, opened })
}

/// Serves `sim` on a pty and opens it as a serial port.
#[cfg(unix)]
fn serve<D: Device + Send + 'static>(
    sim: D,
    config: ServeConfig,
    baud: u32,
) -> Result<(Server<D>, String, Box<dyn Transport + Send>)> {
    use yosemitech_rtu::{SerialConfig, SerialTransport};
    let server = yosemitech_sim::serve_pty(sim, config).map_err(|e| {
        CliError::device(format!("cannot create a pseudo-terminal: {e}")).hint("the demo needs ptys (/dev/ptmx)")
    })?;
    let path = server.tty_path().unwrap_or_default().to_owned();
    let serial = SerialConfig { baud, ..SerialConfig::new(path.clone()) };
    let transport = SerialTransport::open(&serial).map_err(|e| crate::port::open_failed(&path, &e))?;
    Ok((server, path, Box::new(transport)))
}

/// Without ptys, serves `sim` as an RTU-over-TCP gateway on localhost.
#[cfg(not(unix))]
fn serve<D: Device + Send + 'static>(
    sim: D,
    config: ServeConfig,
    _baud: u32,
) -> Result<(Server<D>, String, Box<dyn Transport + Send>)> {
    use yosemitech_rtu::TcpTransport;
    let server = yosemitech_sim::serve_tcp(sim, "127.0.0.1:0", config)
        .map_err(|e| CliError::device(format!("cannot serve the simulator: {e}")))?;
    let addr = server.local_addr().ok_or_else(|| CliError::device("the simulator has no address"))?;
    let port = format!("tcp://{addr}");
    let transport =
        TcpTransport::connect(addr, Duration::from_secs(1)).map_err(|e| crate::port::open_failed(&port, &e))?;
    Ok((server, port, Box::new(transport)))
}

fn row(out: &mut dyn Write, label: &str, value: impl std::fmt::Display) -> Result<()> {
    writeln!(out, "  {label:15} {value}")?;
    Ok(())
}

fn join(values: &[f32]) -> String {
    values.iter().map(f32::to_string).collect::<Vec<_>>().join(" ")
}

/// Runs `demo`.
pub fn run(catalog: &Catalog, args: &DemoArgs, out: &mut dyn Write) -> Result<()> {
    let started = Instant::now();
    let (ph_entry, cond_entry) = (catalog.entry("ph_orp")?, catalog.entry("conductivity")?);
    if !is_typed(ph_entry, "ph_orp") || !is_typed(cond_entry, "conductivity") {
        return Err(CliError::usage("the demo runs the built-in pH/ORP and conductivity sensors")
            .hint("run it without a --spec that replaces them"));
    }
    let mut ph =
        setup(&ph_entry.sensor, &[("ph", PH), ("orp_mv", ORP_MV), ("temperature_c", WATER_C)], 0.01, args.line_timing)?;
    let mut cond = setup(
        &cond_entry.sensor,
        &[("temperature_c", WATER_C), ("conductivity_ms_cm", CONDUCTIVITY_MS_CM)],
        0.002,
        args.line_timing,
    )?;
    let address = ph_orp::SENSOR.default_address;
    writeln!(out, "yosemitech demo: simulated probes on pseudo-terminals, driven through the serial port code")?;
    writeln!(out, "(no hardware; the same code talks to a real RS-485 adapter)")?;
    for (name, probe, baud) in
        [("pH/ORP probe", &ph, ph_orp::SENSOR.baud), ("conductivity probe", &cond, conductivity::SENSOR.baud)]
    {
        writeln!(out, "  {name:19} {} ({baud} baud 8N1, address {address})", probe.opened.port)?;
    }

    // The pH/ORP probe.
    let ctx = |probe: &Probe, what: &str| Context {
        port: probe.opened.port.clone(),
        slave: address,
        what: what.to_owned(),
        timeout: probe.opened.timeout,
    };
    let ph_ctx = ctx(&ph, "the pH/ORP probe");
    writeln!(out, "\n{} on {}, address {address}", ph_orp::SENSOR.title, ph.opened.port)?;
    {
        let mut probe = ph_orp::Device::new(&mut ph.opened.bus, address);
        let sn = probe.sn().map_err(|e| request_failed(&e, probe.client().last_reply(), &ph_ctx))?;
        let version = probe.version().map_err(|e| request_failed(&e, probe.client().last_reply(), &ph_ctx))?;
        row(out, "serial number", sn)?;
        row(out, "hardware", version.hardware)?;
        row(out, "software", version.software)?;
        row(
            out,
            "pH",
            format!("{:.2} pH", probe.ph().map_err(|e| request_failed(&e, probe.client().last_reply(), &ph_ctx))?),
        )?;
        row(
            out,
            "ORP",
            format!("{:.1} mV", probe.orp().map_err(|e| request_failed(&e, probe.client().last_reply(), &ph_ctx))?),
        )?;
        let both = probe.orp_and_ph().map_err(|e| request_failed(&e, probe.client().last_reply(), &ph_ctx))?;
        row(out, "ORP and pH", format!("{:.1} mV, {:.2} pH (one read)", both.orp_mv, both.ph))?;
        row(
            out,
            "temperature",
            format!(
                "{:.2} °C",
                probe.temperature().map_err(|e| request_failed(&e, probe.client().last_reply(), &ph_ctx))?
            ),
        )?;
        let status =
            probe.calibration_status().map_err(|e| request_failed(&e, probe.client().last_reply(), &ph_ctx))?;
        row(out, "calibration", format!("status {}: {}", status.raw(), status.name().unwrap_or("unknown")))?;
        let c = read_ph_orp(&mut probe).map_err(|e| procedure_failed(&e, probe.client().last_reply(), &ph_ctx))?;
        row(out, "electrode K1-K6", join(&c.electrode))?;
        row(out, "pH K, B", join(&c.ph_calibration))?;
        row(out, "ORP K, B", join(&c.orp_calibration))?;
    }

    // The conductivity probe.
    let cond_ctx = ctx(&cond, "the conductivity probe");
    writeln!(out, "\n{} on {}, address {address}", conductivity::SENSOR.title, cond.opened.port)?;
    {
        let mut probe = conductivity::Device::new(&mut cond.opened.bus, address);
        let sn = probe.sn().map_err(|e| request_failed(&e, probe.client().last_reply(), &cond_ctx))?;
        let version = probe.version().map_err(|e| request_failed(&e, probe.client().last_reply(), &cond_ctx))?;
        row(out, "serial number", sn)?;
        row(out, "hardware", version.hardware)?;
        row(out, "software", version.software)?;
        let reading = probe
            .temperature_and_conductivity()
            .map_err(|e| request_failed(&e, probe.client().last_reply(), &cond_ctx))?;
        row(out, "temperature", format!("{:.2} °C", reading.temperature_c))?;
        row(out, "conductivity", format!("{:.4} mS/cm", reading.conductivity_ms_cm))?;
        row(out, "range status", reading.range_status.name().unwrap_or("unknown code"))?;
        let c =
            read_conductivity(&mut probe).map_err(|e| procedure_failed(&e, probe.client().last_reply(), &cond_ctx))?;
        row(out, "user K, B", join(&c.user_calibration))?;
    }

    // The manual's measurement procedure, as the spec states it, waits scaled down.
    let sensor = &cond_entry.sensor;
    let procedure = sensor.procedure.as_ref().ok_or_else(|| {
        CliError::usage("the built-in conductivity spec states no procedure").hint("this is a bug in the build")
    })?;
    let timing = measure::Timing::of(procedure);
    writeln!(out, "\nconductivity measurement (manual section 3: {}),", measure::describe(procedure, timing))?;
    writeln!(out, "waits shortened {}x for the demo:", (1.0 / TIME_SCALE).round())?;
    out.flush()?;
    let mut sleep = |d: Duration| std::thread::sleep(d.mul_f64(TIME_SCALE));
    let m = measure::run_procedure(&mut cond.opened, sensor, address, timing, &mut sleep)?;
    measure::show(&m, Some(4), out)?;

    let family = family(catalog, args, out)?;

    let requests = ph.server.device().stats().requests + cond.server.device().stats().requests + family;
    writeln!(
        out,
        "\n{requests} requests answered over the serial code path in {:.1} s.",
        started.elapsed().as_secs_f64()
    )?;
    writeln!(
        out,
        "Next: `yosemitech simulate ph_orp` serves a probe; `yosemitech read ph_orp get_ph --port <its path>` reads it."
    )?;
    writeln!(out, "`yosemitech scan --port <path>` identifies the probes on a real bus.")?;
    Ok(())
}

/// Every sensor of the catalog simulated at its own address (1, 2, 3, ...)
/// on one pty bus, identified by `scan`'s reads through the serial code.
/// Returns the requests the bus answered.
fn family(catalog: &Catalog, args: &DemoArgs, out: &mut dyn Write) -> Result<u64> {
    let started = Instant::now();
    let mut bus = Bus::new();
    let mut addresses = Vec::new();
    for (address, entry) in (1..=247u8).zip(catalog.entries()) {
        let mut sim = Simulator::new(Arc::clone(&entry.sensor)).with_address(address);
        run_newest_firmware(&mut sim, &entry.sensor)?;
        bus.push(sim);
        addresses.push(address);
    }
    let (Some(&first), Some(&last)) = (addresses.first(), addresses.last()) else {
        return Ok(0);
    };
    let serial = scan::common_serial(catalog);
    let timing = catalog.entries().iter().find(|e| e.sensor.serial == serial).map(|e| line_timing(&e.sensor));
    let config = match timing {
        Some(timing) if args.line_timing => ServeConfig::emulating(timing),
        _ => ServeConfig::default(),
    };
    let (server, port, transport) = serve(bus, config, serial.baud)?;
    let config = ClientConfig { timeout: BUS_TIMEOUT, retry: RetryPolicy::NONE, ..ClientConfig::default() };
    let mut opened = Opened { bus: Client::with_config(transport, config), port, timeout: config.timeout };

    let n = addresses.len();
    writeln!(out, "\nthe whole family on one RS-485 bus: {n} simulated probes on {}", opened.port)?;
    writeln!(out, "({} baud, addresses {first}-{last}), identified as `yosemitech scan` does:", serial.baud)?;
    out.flush()?;
    let mut identified = 0;
    for &address in &addresses {
        match scan::identify_at(catalog, &mut opened, address)? {
            Some(found) => {
                identified += usize::from(found.sensor.is_some());
                writeln!(out, "  {}", found.line)?;
            }
            None => writeln!(out, "  address {address:3}  no reply to the serial-number reads")?,
        }
        out.flush()?;
    }
    let bus = server.device();
    // Every device hears every request; the replies are the answered ones.
    let requests = bus.devices().first().map_or(0, |d| d.stats().requests);
    let answered = bus.devices().iter().map(|d| d.stats().replies).sum();
    let of = if identified == n { String::new() } else { format!(" of {n}") };
    writeln!(
        out,
        "{identified}{of} probes identified in {requests} requests ({:.1} s).",
        started.elapsed().as_secs_f64()
    )?;
    Ok(answered)
}

/// Makes a simulated probe report the software revision of its newest
/// manual: the register examples it starts from often show an older one
/// (1.0), and the scan would then find no manual covering it.
fn run_newest_firmware(sim: &mut Simulator, sensor: &Sensor) -> Result<()> {
    let Some(command) = sensor.command_with_role(Role::Version) else { return Ok(()) };
    let versions: Vec<_> = command.named_fields().filter(|f| matches!(f.kind, FieldKind::Version)).collect();
    let Some(field) = versions.iter().find(|f| f.display_name() == "software").or(versions.last()) else {
        return Ok(());
    };
    let Some((major, minor)) = sensor.manuals().filter_map(|m| m.software.as_deref()).map(software_key).max() else {
        return Ok(());
    };
    let (Ok(major), Ok(minor)) = (u8::try_from(major), u8::try_from(minor)) else { return Ok(()) };
    sim.set(&command.name, field.display_name(), Value::Version(Version::new(major, minor)))
        .map_err(|e| CliError::device(format!("cannot set up the simulated {}: {e}", sensor.name)))
}

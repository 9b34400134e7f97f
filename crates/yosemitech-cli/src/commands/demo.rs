//! `yosemitech demo`: every sensor of the spec simulated on a
//! pseudo-terminal of its own and driven through the real serial code path
//! (no hardware, no root): identity, measurements, calibration and
//! coefficients read through the spec's interpreter, each manual's measuring
//! procedure with its waits shortened, then the whole family on one bus,
//! identified as `scan` does.

use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

use yosemitech_rtu::{Client, ClientConfig, RetryPolicy, Transport, Version};
use yosemitech_sim::{Bus, FrameHandler, ServeConfig, Server, Simulator, Variation};
use yosemitech_spec::beside;
use yosemitech_spec::{CommandSpec, FieldKind, Role, Sensor, Value, Values};

use yosemitech_ops::procedure::{Timing, describe};
use yosemitech_ops::{common_serial, software_revision};

use crate::catalog::Catalog;
// The procedure runner is still the measure command's (tests/tests/layering.rs lists it).
use crate::commands::measure;
use crate::device;
use crate::error::{CliError, Result};
use crate::format::{derived_text, field_value_text, unit};
use crate::identified::{found_line, identify_at};
use crate::port::Opened;
use clap::Args;

/// `demo`.
#[derive(Args, Debug, Default)]
pub struct DemoArgs {
    /// Emulate the serial line's timing at 9600 baud (slower, like real probes).
    #[arg(long)]
    pub line_timing: bool,
}

/// How long the waits of every measuring procedure may take together:
/// each wait is shortened by the same factor so that their sum fits.
const WAIT_BUDGET: Duration = Duration::from_millis(500);

/// Noise the simulators add to every measurement, in the field's unit:
/// small next to the daily cycle, large enough that an average has
/// something to average.
const NOISE: f32 = 0.002;

/// The daily cycle of the simulated water: a swing of this fraction of each
/// quantity's range, over a day shortened so that `watch` and `plot` show it
/// within minutes.
const DAILY_SWING: f32 = 0.04;
const DEMO_DAY: Duration = Duration::from_secs(15 * 60);

/// The reply timeout on the family bus, far below scan's usual second: the
/// simulators answer at once (in ~30 ms with `--line-timing`), and only
/// taken addresses are scanned, so the timeout is spent only on a
/// serial-number read of another layout, which no probe answers. No
/// retries: they would repeat those reads.
const BUS_TIMEOUT: Duration = Duration::from_millis(300);

/// A simulated probe served for the demo, and the client talking to it.
struct Probe {
    sensor: Arc<Sensor>,
    server: Server<Simulator>,
    opened: Opened,
}

fn setup(sensor: &Arc<Sensor>, line: bool) -> Result<Probe> {
    let mut sim = Simulator::new(Arc::clone(sensor));
    run_newest_firmware(&mut sim, sensor)?;
    sim.fill_with_water();
    sim.set_variation(Some(Variation { noise: NOISE, ..Variation::water(7, DAILY_SWING, DEMO_DAY) }));
    let config = if line { ServeConfig::emulating(sensor.serial.timing()) } else { ServeConfig::default() };
    let (server, port, transport) = serve(sim, config, sensor.serial.baud)?;
    let config = ClientConfig { timeout: Duration::from_secs(1), ..ClientConfig::default() };
    let opened = Opened { bus: Client::with_config(transport, config), port, timeout: config.timeout };
    Ok(Probe { sensor: Arc::clone(sensor), server, opened })
}

/// Serves `sim` on a pty and opens it as a serial port.
#[cfg(unix)]
fn serve<D: FrameHandler + Send + 'static>(
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
fn serve<D: FrameHandler + Send + 'static>(
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

/// The reads the demo sends to a probe: its identity (by role), every
/// measurement read, its calibration status and its coefficient blocks,
/// each once, in that order.
fn shown_reads(sensor: &Sensor) -> Vec<&CommandSpec> {
    let identity = [Role::SerialNumber, Role::Version].into_iter().filter_map(|r| sensor.command_with_role(r));
    let status = sensor.command_with_role(Role::CalibrationStatus);
    let blocks = sensor.coefficient_blocks().into_iter().map(|(_, read)| read);
    let mut reads: Vec<&CommandSpec> = Vec::new();
    for read in identity.chain(sensor.measurement_reads()).chain(status).chain(blocks) {
        if read.is_read() && read.named_fields().next().is_some() && !reads.iter().any(|r| r.name == read.name) {
            reads.push(read);
        }
    }
    reads
}

/// Sends each of [`shown_reads`] and prints a line per read: its name and
/// every field's value with its unit.
fn show_probe(probe: &mut Probe, out: &mut dyn Write) -> Result<()> {
    let sensor = Arc::clone(&probe.sensor);
    let reads = shown_reads(&sensor);
    let width =
        reads.iter().map(|r| r.name.len()).chain(sensor.derived.iter().map(|d| d.name.len())).max().unwrap_or(0);
    let mut read_values: Vec<(&str, Values)> = Vec::new();
    for read in reads {
        let values = device::read(&mut probe.opened, read, sensor.default_address)?;
        let shown: Vec<String> = values
            .iter()
            .map(|(name, value)| {
                let field = read.field(name);
                let text = field.map_or_else(|| value.to_string(), |f| field_value_text(f, value));
                let unit = field.and_then(|f| f.unit.as_deref()).map(|u| format!(" {}", unit(u))).unwrap_or_default();
                format!("{name} {text}{unit}")
            })
            .collect();
        writeln!(out, "  {:width$}  {}", read.name, shown.join(", "))?;
        read_values.push((read.name.as_str(), values));
    }
    // Beside the reads, what the spec derives from them (station inputs at their defaults).
    let lookup = |c: &str, f: &str| {
        let (_, values) = read_values.iter().find(|(name, _)| *name == c)?;
        values.iter().find(|(n, _)| n == f).and_then(|(_, v)| beside::field_number(v))
    };
    let derived = beside::beside(&sensor, &|c, _| read_values.iter().any(|(n, _)| *n == c), &lookup, &|_| None);
    for d in &derived {
        writeln!(out, "  {:width$}  {}", d.quantity.name, derived_text(d, None))?;
    }
    Ok(())
}

/// Runs every probe's measuring procedure (its spec's `procedure`), the
/// waits shortened by one factor so that together they fit [`WAIT_BUDGET`].
fn run_procedures(probes: &mut [Probe], out: &mut dyn Write) -> Result<()> {
    let timings: Vec<Option<Timing>> = probes.iter().map(|p| p.sensor.procedure.as_ref().map(Timing::of)).collect();
    let waited = |t: &Timing| t.warm_up + t.interval * t.readings.saturating_sub(1);
    let total: Duration = timings.iter().flatten().map(waited).sum();
    let scale = if total > WAIT_BUDGET { WAIT_BUDGET.as_secs_f64() / total.as_secs_f64() } else { 1.0 };
    writeln!(
        out,
        "\nthe manuals' measuring procedures as the spec states them, waits shortened {}x:",
        (1.0 / scale).round()
    )?;
    for (probe, timing) in probes.iter_mut().zip(timings) {
        let (Some(procedure), Some(timing)) = (probe.sensor.procedure.as_ref(), timing) else { continue };
        writeln!(out, "\n{}: {}", probe.sensor.name, describe(procedure, timing))?;
        out.flush()?;
        let mut sleep = |d: Duration| std::thread::sleep(d.mul_f64(scale));
        let sensor = Arc::clone(&probe.sensor);
        let m = measure::run_procedure(&mut probe.opened, &sensor, sensor.default_address, timing, &mut sleep)?;
        measure::show(&m, Some(4), out)?;
        measure::show_derived(&m, &m.derived(&sensor, &|_| None), out)?;
    }
    Ok(())
}

/// Runs `demo`.
pub fn run(catalog: &Catalog, args: &DemoArgs, out: &mut dyn Write) -> Result<()> {
    let started = Instant::now();
    let mut probes =
        catalog.entries().iter().map(|e| setup(&e.sensor, args.line_timing)).collect::<Result<Vec<Probe>>>()?;
    writeln!(
        out,
        "yosemitech demo: {} simulated probes on pseudo-terminals, driven through the serial port code",
        probes.len()
    )?;
    writeln!(out, "(no hardware; the same code talks to a real RS-485 adapter)")?;
    let width = probes.iter().map(|p| p.sensor.name.len()).max().unwrap_or(0);
    for p in &probes {
        let (serial, address) = (p.sensor.serial, p.sensor.default_address);
        writeln!(
            out,
            "  {:width$}  {} ({} baud {}, address {address})",
            p.sensor.name, p.opened.port, serial.baud, serial.format
        )?;
    }
    for probe in &mut probes {
        writeln!(out, "\n{} ({}) on {}", probe.sensor.title, probe.sensor.name, probe.opened.port)?;
        show_probe(probe, out)?;
    }
    run_procedures(&mut probes, out)?;

    let family = family(catalog, args, out)?;

    let requests = probes.iter().map(|p| p.server.device().stats().requests).sum::<u64>() + family;
    writeln!(
        out,
        "\n{requests} requests answered over the serial code path in {:.1} s.",
        started.elapsed().as_secs_f64()
    )?;
    if let Some(example) = catalog.example_read() {
        let name = &example.sensor.name;
        writeln!(
            out,
            "Next: `yosemitech simulate {name}` serves a probe; `yosemitech read {name} {} --port <its path>` reads it.",
            example.read.name
        )?;
    }
    writeln!(out, "`yosemitech scan --port <path>` identifies the probes on a real bus.")?;
    Ok(())
}

/// Every sensor of the catalog simulated at its own address (1, 2, 3, ...)
/// on one pty bus, identified by `scan`'s reads through the serial code.
/// A probe `scan` does not name alone (no serial-number read or model code
/// in its spec, or a model code other loaded sensors share) gets `scan`'s
/// line and the sensor simulated there; only probes named as the sensor
/// they are count as identified. Returns the requests the bus answered.
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
    let serial = common_serial(catalog.entries().iter().map(|e| e.sensor.as_ref()));
    let config = if args.line_timing { ServeConfig::emulating(serial.timing()) } else { ServeConfig::default() };
    let (server, port, transport) = serve(bus, config, serial.baud)?;
    let config = ClientConfig { timeout: BUS_TIMEOUT, retry: RetryPolicy::NONE, ..ClientConfig::default() };
    let mut opened = Opened { bus: Client::with_config(transport, config), port, timeout: config.timeout };

    let n = addresses.len();
    writeln!(out, "\nthe whole family on one RS-485 bus: {n} simulated probes on {}", opened.port)?;
    writeln!(out, "({} baud, addresses {first}-{last}), identified as `yosemitech scan` does:", serial.baud)?;
    out.flush()?;
    let mut identified = 0;
    for (&address, entry) in addresses.iter().zip(catalog.entries()) {
        let simulated = &entry.sensor;
        let line = match identify_at(catalog, &mut opened, address)? {
            Some(found) if found.identified.is_some_and(|s| s.name == simulated.name) => {
                identified += 1;
                found_line(&found)
            }
            Some(found) => format!("{}  {}", found_line(&found), simulated_note(simulated)),
            None if own_serial_number_read(simulated).is_none() => {
                format!("address {address:3}  not identified: no serial number read  {}", simulated_note(simulated))
            }
            None => {
                format!("address {address:3}  no reply to the serial-number reads  {}", simulated_note(simulated))
            }
        };
        writeln!(out, "  {line}")?;
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

/// The serial-number read `scan` can send to `sensor` (at its own address).
fn own_serial_number_read(sensor: &Sensor) -> Option<&CommandSpec> {
    sensor.command_with_role(Role::SerialNumber).filter(|c| c.fixed_slave.is_none())
}

/// What the demo knows and `scan` could not tell: the sensor simulated at
/// an address, and what its spec lacks to be identified by
/// (`[simulated: name, whose spec declares no model code]`).
fn simulated_note(sensor: &Sensor) -> String {
    let mut lacks = Vec::new();
    if own_serial_number_read(sensor).is_none() {
        lacks.push("serial-number read");
    }
    if sensor.model_code.is_none() {
        lacks.push("model code");
    }
    if lacks.is_empty() {
        format!("[simulated: {}]", sensor.name)
    } else {
        format!("[simulated: {}, whose spec declares no {}]", sensor.name, lacks.join(" and no "))
    }
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
    let Some((major, minor)) = sensor.manuals().filter_map(|m| m.software.as_deref()).map(software_revision).max()
    else {
        return Ok(());
    };
    let (Ok(major), Ok(minor)) = (u8::try_from(major), u8::try_from(minor)) else { return Ok(()) };
    sim.set(&command.name, field.display_name(), Value::Version(Version::new(major, minor)))
        .map_err(|e| CliError::device(format!("cannot set up the simulated {}: {e}", sensor.name)))
}

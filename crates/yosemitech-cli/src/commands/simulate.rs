//! `yosemitech simulate`: a simulated probe for other tools.

use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use yosemitech_rtu::{CharFormat, DataBits, LineSettings, Parity, StopBits};
#[cfg(unix)]
use yosemitech_sim::serve::tap::TappedBus;
use yosemitech_sim::{
    Bus, FaultConfig, FaultKind, FrameHandler, SerialNumberPolicy, ServeConfig, Server, Simulator,
    UnknownRequestPolicy, Variation, serve_mbap, serve_tcp,
};
use yosemitech_spec::{FieldKind, Role, Sensor};

use crate::catalog::Catalog;
use crate::error::{CliError, Result};
use crate::format::parse_duration;
use crate::port::{AddressArg, check_address};
use clap::Args;
use clap::ValueEnum;

/// What `simulate --tcp` speaks.
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TcpProtocol {
    /// RTU frames (with CRC) over TCP, as a transparent serial gateway.
    #[default]
    Rtu,
    /// Modbus TCP: MBAP header, no CRC; several connections at once.
    Mbap,
}

/// `simulate`.
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// Sensor to simulate.
    pub sensor: String,
    #[command(flatten)]
    pub address: AddressArg,
    /// Serve on a new pseudo-terminal (the default).
    #[arg(long, conflicts_with = "tcp")]
    pub pty: bool,
    /// Another probe on the same line, SENSOR@ADDRESS (repeatable): a
    /// station's bus. The line runs at the first sensor's serial settings.
    #[arg(long, value_name = "SENSOR@ADDRESS", conflicts_with = "collide")]
    pub also: Vec<String>,
    /// Copy every byte of the line, both ways, to a second pseudo-terminal,
    /// printed on the line after the first: what a second adapter on the
    /// RS-485 pair hears (`yosemitech sniff --port` it). Bytes nobody reads
    /// there are lost to the tap, never to the line.
    #[arg(long, conflicts_with = "tcp")]
    pub tap: bool,
    /// Serve over TCP on ADDR (127.0.0.1:5020; port 0 picks a free one).
    #[arg(long, value_name = "ADDR")]
    pub tcp: Option<String>,
    /// What --tcp speaks: raw RTU frames, as a transparent serial gateway
    /// (rtu), or Modbus TCP with MBAP headers, unit id = address (mbap).
    #[arg(long, value_enum, default_value_t = TcpProtocol::Rtu, requires = "tcp")]
    pub protocol: TcpProtocol,
    /// Faults to inject: kind=probability,... (see the long help).
    #[arg(long, value_name = "SPEC")]
    pub faults: Option<String>,
    /// Seed of the fault and noise generator.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Noise amplitude added to every measurement, in its unit.
    #[arg(long, value_name = "X")]
    pub noise: Option<f32>,
    /// Serve the values the manual's example replies carry, fixed, instead
    /// of natural water (what `simulate` serves by default: each quantity's
    /// typical value or the middle of its range, the temperature of a
    /// river, on a daily cycle, every register of a quantity agreeing).
    #[arg(long, conflicts_with = "water")]
    pub examples: bool,
    /// Natural water (the default; kept for scripts that ask for it).
    #[arg(long, hide = true)]
    pub water: bool,
    /// Emulate the serial line's timing at the sensor's baud rate (at 9600 baud, about 1 ms a byte).
    #[arg(long)]
    pub line_timing: bool,
    /// Answer requests for registers the probe lacks with Modbus exceptions
    /// (01/02/03), as a general Modbus stack does; a real probe stays silent.
    #[arg(long)]
    pub exceptions: bool,
    /// Send the serial number exactly as the manual prints it (0x00 before
    /// it, the manual's text), instead of with the model code, as real probes do.
    #[arg(long)]
    pub serial_as_printed: bool,
    /// Line faults, to diagnose a link (`yosemitech doctor`).
    #[command(flatten)]
    pub line: SimulatedLineArgs,
}

/// `simulate`'s line faults: what a link to a probe can get wrong.
#[derive(Args, Debug, Default)]
pub struct SimulatedLineArgs {
    /// Never answer (a probe without power, or a broken wire).
    #[arg(long)]
    pub mute: bool,
    /// Write every request back before answering (an RS-485 adapter without echo suppression).
    #[arg(long)]
    pub echo: bool,
    /// Wait this long before every reply (a probe slow to answer), e.g. 1500ms.
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    pub turnaround: Option<Duration>,
    /// Run at these serial settings, BAUD-8N1 (8N2, 8E1, 8O1); on a pty a client at
    /// another baud rate or parity reads garbage (where the pty keeps parity: Linux ptys drop it).
    #[arg(long, value_name = "BAUD-FORMAT", conflicts_with = "tcp")]
    pub serial: Option<String>,
    /// Two probes at the address answer every request at once (their serial numbers differ).
    #[arg(long)]
    pub collide: bool,
    /// Refuse Start Measurement with an exception and answer reads all the same.
    #[arg(long)]
    pub refuse_start: bool,
}

/// Parses `drop=0.05,corrupt_crc=0.02`, `all=0.1`, `delay_by=500ms`.
pub fn parse_faults(spec: &str, seed: u64) -> Result<FaultConfig> {
    let kinds: Vec<&str> = FaultKind::ALL.iter().map(|k| k.name()).collect();
    let hint = format!(
        "write kind=probability pairs, e.g. drop=0.05,corrupt_crc=0.02; kinds: {}, all; delay_by=DURATION",
        kinds.join(", ")
    );
    let mut config = FaultConfig::seeded(seed);
    for part in spec.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let Some((key, value)) = part.split_once('=') else {
            return Err(CliError::usage(format!("`{part}` in --faults is not kind=probability")).hint(hint));
        };
        let (key, value) = (key.trim(), value.trim());
        if key == "delay_by" {
            config.delay_by = parse_duration(value).map_err(|e| CliError::usage(e).hint(hint.clone()))?;
            continue;
        }
        let p: f64 = value.parse().ok().filter(|p: &f64| (0.0..=1.0).contains(p)).ok_or_else(|| {
            CliError::usage(format!("`{value}` in --faults is not a probability 0 to 1")).hint(hint.clone())
        })?;
        if key == "all" {
            let seeded = FaultConfig::uniform(seed, p);
            for kind in FaultKind::ALL {
                *config.probability_mut(kind) = seeded.probability(kind);
            }
            continue;
        }
        let Some(kind) = FaultKind::ALL.into_iter().find(|k| k.name() == key) else {
            let e = CliError::usage(format!("unknown fault kind `{key}`"));
            return Err(match yosemitech_spec::suggest::closest(key, &kinds) {
                Some(best) => e.hint(format!("did you mean `{best}`? {hint}")),
                None => e.hint(hint),
            });
        };
        *config.probability_mut(kind) = p;
    }
    Ok(config)
}

/// Parses `19200-8E1` (baud rate, data bits, parity N/E/O, stop bits).
pub fn parse_line_settings(text: &str) -> Result<LineSettings> {
    let bad = || {
        CliError::usage(format!("`{text}` is not serial settings"))
            .hint("write BAUD-FORMAT, e.g. 9600-8N1, 19200-8E1, 9600-8N2 (data bits 7 or 8, parity N, E or O, stop bits 1 or 2)")
    };
    let (baud, format) = text.trim().split_once('-').ok_or_else(bad)?;
    let baud: u32 = baud.trim().parse().ok().filter(|b| *b > 0).ok_or_else(bad)?;
    let format = format.trim().to_ascii_uppercase();
    let (data_bits, parity, stop_bits) = match format.as_bytes() {
        [d, p, s] => (*d, *p, *s),
        _ => return Err(bad()),
    };
    let data_bits = match data_bits {
        b'7' => DataBits::Seven,
        b'8' => DataBits::Eight,
        _ => return Err(bad()),
    };
    let parity = match parity {
        b'N' => Parity::None,
        b'E' => Parity::Even,
        b'O' => Parity::Odd,
        _ => return Err(bad()),
    };
    let stop_bits = match stop_bits {
        b'1' => StopBits::One,
        b'2' => StopBits::Two,
        _ => return Err(bad()),
    };
    Ok(LineSettings { baud, format: CharFormat { data_bits, parity, stop_bits } })
}

/// Two probes like `sim` at its address whose serial numbers differ in one
/// character, so that they answer a serial-number read with different
/// bytes (their other replies may agree, as two real probes' do). On the
/// line the two replies are ANDed ([`Bus`]): the character is `x|1` in one
/// and `x|2` in the other, so the collision (`x`) is neither reply.
fn colliding_pair(mut sim: Simulator) -> (Simulator, Simulator) {
    let spot = sim.sensor().command_with_role(Role::SerialNumber).and_then(|command| {
        let field = command.named_fields().find(|f| matches!(f.kind, FieldKind::Ascii { .. }))?;
        let text = sim.registers().read(command.address, command.count);
        let chars = field.offset..field.offset + field.size();
        let at = chars.clone().rev().find(|&i| text.get(i).is_some_and(|b| *b != 0)).unwrap_or(chars.start);
        Some((command.address, at, text.get(at).copied()?))
    });
    let mut other = sim.clone();
    if let Some((register, at, byte)) = spot {
        let base = if byte == 0 { b'0' } else { byte & !0x03 };
        sim.registers_mut().write_bytes(register, at, &[base | 0x01]);
        other.registers_mut().write_bytes(register, at, &[base | 0x02]);
    }
    (sim, other)
}

/// Parses `SENSOR@ADDRESS`: a sensor of `catalog` and its address.
fn parse_also(catalog: &Catalog, text: &str) -> Result<(Arc<Sensor>, u8)> {
    let (name, address) = text.split_once('@').ok_or_else(|| {
        CliError::usage(format!("`{text}` in --also is not SENSOR@ADDRESS"))
            .hint("name a sensor of `yosemitech list` and its address, e.g. --also SENSOR@2")
    })?;
    let address: u32 = address.trim().parse().map_err(|_| {
        CliError::usage(format!("`{address}` in --also {text} is not an address"))
            .hint("name a sensor of `yosemitech list` and its address, e.g. --also SENSOR@2")
    })?;
    let address = check_address(address, "--also address")?;
    Ok((Arc::clone(catalog.sensor(name.trim())?), address))
}

/// A simulated `sensor` at `address` as `args` ask (faults, noise, water,
/// policies); `nth` tells the probes of one line apart in the seeds.
fn simulator(sensor: Arc<Sensor>, address: u8, args: &SimulateArgs, nth: u64) -> Result<Simulator> {
    let seed = args.seed.wrapping_add(nth);
    let mut faults = match &args.faults {
        Some(spec) => parse_faults(spec, seed)?,
        None => FaultConfig::seeded(seed),
    };
    if args.line.mute {
        faults.drop = 1.0;
    }
    let mut sim = Simulator::new(sensor).with_address(address).with_faults(faults);
    if let Some(noise) = args.noise {
        sim.set_variation(Some(Variation::noise(seed, noise, 0.0)));
    }
    if !args.examples {
        sim.fill_with_water();
        let noise = args.noise.unwrap_or(0.0);
        sim.set_variation(Some(Variation { noise, ..Variation::water(seed, 0.04, Duration::from_secs(86_400)) }));
    }
    if args.exceptions {
        sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    }
    if args.serial_as_printed {
        sim.set_serial_number_policy(SerialNumberPolicy::AsPrinted);
    }
    sim.set_refuses_start(args.line.refuse_start);
    Ok(sim)
}

/// Runs `simulate` until `stop` is set (Ctrl-C).
pub fn run(catalog: &Catalog, args: &SimulateArgs, stop: &Arc<AtomicBool>, out: &mut dyn Write) -> Result<()> {
    let sensor = Arc::clone(catalog.sensor(&args.sensor)?);
    let address = args.address.get(sensor.default_address)?;
    let sim = simulator(Arc::clone(&sensor), address, args, 0)?;
    let config = serve_config(args, &sensor.serial)?;
    let about = format!("{} ({}) at address {address}", sensor.title, sensor.name);
    if !args.also.is_empty() {
        let mut bus = Bus::new().with(sim);
        let mut abouts = vec![about];
        for (nth, text) in (1..).zip(&args.also) {
            let (other, at) = parse_also(catalog, text)?;
            if bus.device(at).is_some() {
                return Err(CliError::usage(format!("two probes at address {at} (--also {text})"))
                    .hint("give each probe of the line an address of its own (--collide simulates two at one)"));
            }
            abouts.push(format!("{} ({}) at address {at}", other.title, other.name));
            bus.push(simulator(other, at, args, nth)?);
        }
        return serve_until_stopped(bus, args, config, &abouts.join(", "), stop, out, |bus| {
            bus.devices()
                .iter()
                .map(|d| format!("address {}: {}", d.address(), counts_text(d)))
                .collect::<Vec<_>>()
                .join("; ")
        });
    }
    if args.line.collide {
        let (one, other) = colliding_pair(sim);
        let bus = Bus::new().with(one).with(other);
        serve_until_stopped(bus, args, config, &format!("two of {about}"), stop, out, |bus| {
            let counts = bus.devices().iter().map(counts_text).collect::<Vec<_>>().join("; ");
            format!("{counts}; {} collisions", bus.collisions())
        })
    } else {
        serve_until_stopped(sim, args, config, &about, stop, out, counts_text)
    }
}

/// How the line is served: line timing and the line faults of `args`.
fn serve_config(args: &SimulateArgs, own: &LineSettings) -> Result<ServeConfig> {
    let line: &SimulatedLineArgs = &args.line;
    let settings = line.serial.as_deref().map(parse_line_settings).transpose()?;
    let timing = settings.unwrap_or(*own).timing();
    let config = if args.line_timing { ServeConfig::emulating(timing) } else { ServeConfig::default() };
    Ok(ServeConfig {
        echo: line.echo,
        turnaround: line.turnaround.unwrap_or_default(),
        settings,
        seed: args.seed,
        ..config
    })
}

/// What a simulated probe did, for the closing line.
fn counts_text(device: &Simulator) -> String {
    let stats = device.stats();
    format!(
        "{} requests, {} replies, {} exceptions, {} ignored (bad CRC), {} ignored (registers the probe lacks), {} writes, faults: {}",
        stats.requests,
        stats.replies,
        stats.exceptions,
        stats.ignored_bad_crc,
        stats.ignored_unknown,
        stats.writes,
        device.faults()
    )
}

/// Serves `device` until `stop` is set or the server ends, then says what it did.
fn serve_until_stopped<D: FrameHandler + Send + 'static>(
    device: D,
    args: &SimulateArgs,
    config: ServeConfig,
    about: &str,
    stop: &Arc<AtomicBool>,
    out: &mut dyn Write,
    counts: impl Fn(&D) -> String,
) -> Result<()> {
    let (served, endpoint): (Served<D>, String) = match &args.tcp {
        Some(addr) => {
            let served = match args.protocol {
                TcpProtocol::Rtu => serve_tcp(device, addr.as_str(), config),
                TcpProtocol::Mbap => serve_mbap(device, addr.as_str(), config),
            };
            let server = served.map_err(|e| {
                CliError::device(format!("cannot listen on {addr}: {e}"))
                    .hint("give a free local address, e.g. --tcp 127.0.0.1:5020 (port 0 picks one)")
            })?;
            let endpoint = server.endpoint().to_string();
            (Served::Plain(server), endpoint)
        }
        None => serve_pty_or_explain(device, config, args.tap)?,
    };
    writeln!(out, "{endpoint}")?;
    let tapped = match served.tap_path() {
        Some(tap) => {
            writeln!(out, "{tap}")?;
            format!("; the line is heard on {tap} (sniff --port it)")
        }
        None => String::new(),
    };
    out.flush()?;
    let mut err = std::io::stderr().lock();
    let _ = writeln!(err, "simulating {about} on {endpoint}{tapped}; Ctrl-C stops");
    drop(err);
    while !stop.load(Ordering::SeqCst) && served.server().is_running() {
        std::thread::sleep(Duration::from_millis(50));
    }
    let done = counts(&served.server().device());
    let _ = writeln!(std::io::stderr().lock(), "stopped: {done}");
    served.stop().map_err(|e| CliError::device(format!("the simulator stopped with an error: {e}")))
}

/// A server, with the tap its line is heard on where one was asked for.
enum Served<D> {
    Plain(Server<D>),
    #[cfg(unix)]
    Tapped(TappedBus<D>),
}

impl<D> Served<D> {
    /// Where the line is heard, when it is tapped.
    fn tap_path(&self) -> Option<&str> {
        match self {
            Served::Plain(_) => None,
            #[cfg(unix)]
            Served::Tapped(tapped) => Some(&tapped.tap_path),
        }
    }

    fn server(&self) -> &Server<D> {
        match self {
            Served::Plain(server) => server,
            #[cfg(unix)]
            Served::Tapped(tapped) => &tapped.server,
        }
    }

    fn stop(self) -> std::io::Result<()> {
        match self {
            Served::Plain(server) => server.stop(),
            #[cfg(unix)]
            Served::Tapped(tapped) => tapped.stop(),
        }
    }
}

#[cfg(unix)]
fn serve_pty_or_explain<D: FrameHandler + Send + 'static>(
    device: D,
    config: ServeConfig,
    tap: bool,
) -> Result<(Served<D>, String)> {
    let failed = |e: std::io::Error| {
        CliError::device(format!("cannot create a pseudo-terminal: {e}")).hint("use --tcp 127.0.0.1:0 instead")
    };
    if tap {
        let tapped = yosemitech_sim::serve_pty_tapped(device, config, false).map_err(failed)?;
        let path = tapped.path.clone();
        return Ok((Served::Tapped(tapped), path));
    }
    let server = yosemitech_sim::serve_pty(device, config).map_err(failed)?;
    let path = server.tty_path().unwrap_or_default().to_owned();
    Ok((Served::Plain(server), path))
}

#[cfg(not(unix))]
fn serve_pty_or_explain<D: FrameHandler + Send + 'static>(
    _device: D,
    _config: ServeConfig,
    _tap: bool,
) -> Result<(Served<D>, String)> {
    Err(CliError::usage("pseudo-terminals need a Unix system").hint("use --tcp 127.0.0.1:5020 instead"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_fault_specs() {
        let c = parse_faults("drop=0.1, corrupt_crc=0.05,delay_by=200ms", 3).unwrap();
        assert_eq!(c.drop, 0.1);
        assert_eq!(c.corrupt_crc, 0.05);
        assert_eq!(c.delay_by, Duration::from_millis(200));
        assert_eq!(c.seed, 3);
        let all = parse_faults("all=0.7", 1).unwrap();
        assert!((FaultKind::ALL.iter().map(|k| all.probability(*k)).sum::<f64>() - 0.7).abs() < 1e-9);
        assert!(parse_faults("dorp=0.1", 1).unwrap_err().hint.unwrap().contains("`drop`"));
        assert!(parse_faults("drop=2", 1).is_err());
        assert!(parse_faults("drop", 1).is_err());
    }

    #[test]
    fn parses_line_settings() {
        let even = parse_line_settings("19200-8E1").unwrap();
        assert_eq!(even.baud, 19_200);
        assert_eq!(even.format, CharFormat { parity: Parity::Even, ..CharFormat::EIGHT_N_1 });
        assert_eq!(even.to_string(), "19200 baud, 8E1");
        assert_eq!(parse_line_settings(" 9600-7o2 ").unwrap().to_string(), "9600 baud, 7O2");
        for bad in ["9600", "0-8N1", "9600-8N", "9600-9N1", "9600-8X1", "9600-8N3", "fast-8N1", "9600-8N1x"] {
            assert!(parse_line_settings(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_twin_answers_its_serial_number_with_bytes_that_collide() {
        let catalog = Catalog::load(&[]).unwrap();
        for entry in catalog.entries() {
            let Some(sn) = entry.sensor.command_with_role(Role::SerialNumber) else { continue };
            let (one, other) = colliding_pair(Simulator::new(Arc::clone(&entry.sensor)));
            let (a, b) = (one.registers().read(sn.address, sn.count), other.registers().read(sn.address, sn.count));
            let anded: Vec<u8> = a.iter().zip(&b).map(|(x, y)| x & y).collect();
            assert!(anded != a && anded != b, "{}: {a:?} / {b:?}", entry.sensor.name);
        }
    }
}

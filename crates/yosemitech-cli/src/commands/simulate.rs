//! `yosemitech simulate`: a simulated probe for other tools.

use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use yosemitech_sim::{
    FaultConfig, FaultKind, SerialNumberPolicy, ServeConfig, Server, Simulator, UnknownRequestPolicy, Variation,
    serve_mbap, serve_tcp,
};

use crate::catalog::Catalog;
use crate::cli::{SimulateArgs, TcpProtocol};
use crate::error::{CliError, Result};
use crate::format::parse_duration;

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
            CliError::usage(format!("`{value}` in --faults is not a probability 0..=1")).hint(hint.clone())
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
            return Err(match crate::catalog::closest(key, &kinds) {
                Some(best) => e.hint(format!("did you mean `{best}`? {hint}")),
                None => e.hint(hint),
            });
        };
        *config.probability_mut(kind) = p;
    }
    Ok(config)
}

/// Runs `simulate` until `stop` is set (Ctrl-C).
pub fn run(catalog: &Catalog, args: &SimulateArgs, stop: &Arc<AtomicBool>, out: &mut dyn Write) -> Result<()> {
    let sensor = Arc::clone(catalog.sensor(&args.sensor)?);
    let address = args.address.get(sensor.default_address)?;
    let faults = match &args.faults {
        Some(spec) => parse_faults(spec, args.seed)?,
        None => FaultConfig::seeded(args.seed),
    };
    let mut sim = Simulator::new(Arc::clone(&sensor)).with_address(address).with_faults(faults);
    if let Some(noise) = args.noise {
        sim.set_variation(Some(Variation::noise(args.seed, noise, 0.0)));
    }
    if args.water {
        sim.fill_with_water();
        let noise = args.noise.unwrap_or(0.0);
        sim.set_variation(Some(Variation { noise, ..Variation::water(args.seed, 0.04, Duration::from_secs(86_400)) }));
    }
    if args.exceptions {
        sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    }
    if args.serial_as_printed {
        sim.set_serial_number_policy(SerialNumberPolicy::AsPrinted);
    }
    let config = if args.line_timing { ServeConfig::emulating(sensor.serial.timing()) } else { ServeConfig::default() };
    let (server, endpoint): (Server<Simulator>, String) = match &args.tcp {
        Some(addr) => {
            let served = match args.protocol {
                TcpProtocol::Rtu => serve_tcp(sim, addr.as_str(), config),
                TcpProtocol::Mbap => serve_mbap(sim, addr.as_str(), config),
            };
            let server = served.map_err(|e| {
                CliError::device(format!("cannot listen on {addr}: {e}"))
                    .hint("give a free local address, e.g. --tcp 127.0.0.1:5020 (port 0 picks one)")
            })?;
            let endpoint = server.endpoint().to_string();
            (server, endpoint)
        }
        None => serve_pty_or_explain(sim, config)?,
    };
    writeln!(out, "{endpoint}")?;
    out.flush()?;
    let mut err = std::io::stderr().lock();
    let _ =
        writeln!(err, "simulating {} ({}) at address {address} on {endpoint}; Ctrl-C stops", sensor.title, sensor.name);
    drop(err);
    while !stop.load(Ordering::SeqCst) && server.is_running() {
        std::thread::sleep(Duration::from_millis(50));
    }
    let (stats, faults) = {
        let device = server.device();
        (*device.stats(), device.faults().to_owned())
    };
    let _ = writeln!(
        std::io::stderr().lock(),
        "stopped: {} requests, {} replies, {} exceptions, {} ignored (bad CRC), {} ignored (registers the probe lacks), faults: {faults}",
        stats.requests,
        stats.replies,
        stats.exceptions,
        stats.ignored_bad_crc,
        stats.ignored_unknown
    );
    server.stop().map_err(|e| CliError::device(format!("the simulator stopped with an error: {e}")))
}

#[cfg(unix)]
fn serve_pty_or_explain(sim: Simulator, config: ServeConfig) -> Result<(Server<Simulator>, String)> {
    let server = yosemitech_sim::serve_pty(sim, config).map_err(|e| {
        CliError::device(format!("cannot create a pseudo-terminal: {e}")).hint("use --tcp 127.0.0.1:0 instead")
    })?;
    let path = server.tty_path().unwrap_or_default().to_owned();
    Ok((server, path))
}

#[cfg(not(unix))]
fn serve_pty_or_explain(_sim: Simulator, _config: ServeConfig) -> Result<(Server<Simulator>, String)> {
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
}

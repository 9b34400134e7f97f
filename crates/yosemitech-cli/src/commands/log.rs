//! `yosemitech log`: run a station from its TOML file (`--check`: validate it).

use std::io::Write;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, PoisonError, mpsc};
use std::time::Duration;

use yosemitech_mqtt::Publisher;
use yosemitech_station::config::{self, ConfigErrors, Link, StationConfig};
use yosemitech_station::export::to_json;
use yosemitech_station::outbox::StoreOutbox;
use yosemitech_station::{Store, StoredReading, logger, plan};

use crate::catalog::Catalog;
use crate::cli::LogArgs;
use crate::error::{CliError, Result};

/// The station file, validated against the loaded spec.
fn load(catalog: &Catalog, args: &LogArgs) -> Result<StationConfig> {
    let sensors: Vec<_> = catalog.entries().iter().map(|e| Arc::clone(&e.sensor)).collect();
    config::load(&args.config, &sensors).map_err(|ConfigErrors(errors)| {
        let mut lines = errors.iter().map(ToString::to_string);
        let first = lines.next().unwrap_or_else(|| format!("{} is not valid", args.config.display()));
        let mut e = CliError::usage(first);
        for line in lines {
            e = e.detail(line);
        }
        e.hint("the README's sample station.toml shows every key; `yosemitech list` shows the sensors")
    })
}

/// Runs `log --check`: validates the file and prints what it describes.
pub fn check(catalog: &Catalog, args: &LogArgs, out: &mut dyn Write) -> Result<()> {
    let station = load(catalog, args)?;
    writeln!(out, "{}: station `{}`, storage {}", args.config.display(), station.station, station.storage.display())?;
    for bus in &station.buses {
        let link = match &bus.link {
            Link::Serial { port, serial } => format!("serial {port} {serial}"),
            Link::Tcp { address } => format!("RTU over TCP {address}"),
        };
        writeln!(
            out,
            "bus `{}`: {link}, timeout {:?}, {} retries, backoff up to {:?}",
            bus.name, bus.timeout, bus.retries, bus.max_backoff
        )?;
        for probe in &bus.probes {
            let chosen: Vec<&str> = probe.measurements.iter().map(String::as_str).collect();
            let planned = plan::plan(&probe.sensor, &chosen);
            let naive = plan::naive(&probe.sensor, &chosen);
            let reads: Vec<&str> = planned.reads.iter().map(|r| r.command.name.as_str()).collect();
            writeln!(
                out,
                "  probe `{}`: {} at address {}, every {:?}{}{}",
                probe.label,
                probe.sensor.name,
                probe.address,
                probe.interval,
                if probe.align { " on the clock" } else { "" },
                if probe.procedure { ", with the spec's procedure" } else { "" },
            )?;
            if !probe.inputs.is_empty() {
                let inputs: Vec<String> = probe.inputs.iter().map(|(n, v)| format!("{n} = {v}")).collect();
                writeln!(out, "    station inputs: {}", inputs.join(", "))?;
            }
            writeln!(
                out,
                "    {}: {} read{} ({}) instead of {}",
                chosen.join(", "),
                reads.len(),
                if reads.len() == 1 { "" } else { "s" },
                reads.join(", "),
                naive.reads.len()
            )?;
            if !probe.units.is_empty() {
                let units: Vec<String> = probe
                    .units
                    .iter()
                    .map(|(name, c)| format!("{name} in {} (from {})", c.to.symbol, c.from.symbol))
                    .collect();
                writeln!(out, "    units: {}", units.join(", "))?;
            }
        }
    }
    if let Some(mqtt) = &station.mqtt {
        writeln!(
            out,
            "mqtt: {}:{}{} as `{}`, topics under `{}`",
            mqtt.host,
            mqtt.port(),
            if mqtt.tls.is_some() { " (TLS)" } else { "" },
            mqtt.client_id,
            mqtt.topic_prefix
        )?;
    }
    writeln!(out, "ok")?;
    Ok(())
}

/// Runs `log` until `stop` (Ctrl-C, SIGTERM): one JSON line per committed reading on stdout.
pub fn run(catalog: &Catalog, args: &LogArgs, stop: &Arc<AtomicBool>, out: &mut dyn Write) -> Result<()> {
    let station = load(catalog, args)?;
    let store = Store::open(&station.storage).map_err(|e| {
        CliError::device(format!("cannot open the store {}: {e}", station.storage.display()))
            .hint("check `[storage] path`: its directory must exist and be writable")
    })?;
    let store = Mutex::new(store);
    // The publisher drains the store from a connection of its own, in id
    // order; it learns of each commit through `wake`.
    let publisher = match &station.mqtt {
        Some(mqtt) => {
            let outbox = Store::open(&station.storage)
                .map_err(|e| CliError::device(format!("cannot open the store {}: {e}", station.storage.display())))?;
            Some(Publisher::start(mqtt, StoreOutbox(outbox)).map_err(|e| {
                CliError::usage(format!("cannot start publishing: {e}"))
                    .hint("check the [mqtt] section of the station file")
            })?)
        }
        None => None,
    };
    // The bus threads hand each committed reading to this thread, which
    // owns stdout.
    let (lines, printed) = mpsc::channel::<String>();
    let reports = std::thread::scope(|scope| {
        let logger = scope.spawn(|| {
            let lines = lines;
            logger::run(&station, &store, stop, &|id, reading| {
                if let Some(p) = &publisher {
                    p.wake();
                }
                // As stored: with the calibration in force the insert looked up.
                let stored = store.lock().unwrap_or_else(PoisonError::into_inner).get(id).ok().flatten();
                let stored =
                    stored.unwrap_or_else(|| StoredReading { id, reading: reading.clone(), calibration_id: None });
                let _ = lines.send(to_json(&stored).to_string());
            })
        });
        for line in printed {
            // A closed stdout does not stop the logger: the store has every reading.
            let _ = writeln!(out, "{line}").and_then(|()| out.flush());
        }
        logger.join().unwrap_or_else(|_| Err(logger::LogError::Panicked("logger".into())))
    })
    .map_err(|e| CliError::device(e.to_string()).hint("the readings committed so far are in the store"))?;
    let mut err = std::io::stderr().lock();
    if let Some(p) = publisher {
        // What is not acknowledged in time stays in the outbox for the next run.
        let report = p.shutdown(Duration::from_secs(5));
        let _ = writeln!(err, "mqtt: published up to reading {:?}", report.published_up_to);
    }
    for r in reports {
        let _ = writeln!(
            err,
            "bus `{}`: {} readings ({} failed), {} requests ({} failed)",
            r.name, r.readings, r.failed_readings, r.transactions, r.failed_transactions
        );
    }
    Ok(())
}

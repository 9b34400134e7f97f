//! `yosemitech log`: run a station from its TOML file (`--check`: validate it).

use std::io::Write;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, PoisonError, mpsc};
use std::time::Duration;

use yosemitech_mqtt::Publisher;
use yosemitech_mqtt::home_assistant::{Discovery, Tracker};
use yosemitech_station::config::{self, ConfigErrors, Link, StationConfig, show_duration};
use yosemitech_station::export::to_json;
use yosemitech_station::outbox::{StoreOutbox, message};
use yosemitech_station::portal::PortalOutbox;
use yosemitech_station::preflight::{Finding, Severity, preflight, store_directory_of};
use yosemitech_station::recovery::{RunMarker, UncleanStop};
use yosemitech_station::{Store, StoredReading, logger, plan};

use crate::catalog::Catalog;
use crate::error::{CliError, Result};
use crate::service;
use crate::time::clock;
use clap::Args;
use std::path::PathBuf;

/// `log`.
#[derive(Args, Debug)]
pub struct LogArgs {
    /// The station file (TOML).
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// Validate the file against the spec, print a summary and exit.
    #[arg(long)]
    pub check: bool,
}

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
    let directory = store_directory_of(&station);
    writeln!(
        out,
        "{}: station `{}`, storage {}{}{}",
        args.config.display(),
        station.station,
        station.storage.display(),
        station.storage_max_size.map(|b| format!(" (at most {b} bytes)")).unwrap_or_default(),
        if directory.is_dir() { String::new() } else { format!(" ({} is created at start)", directory.display()) }
    )?;
    for bus in &station.buses {
        let link = match &bus.link {
            Link::Serial { port, serial } => format!("serial {port} {serial}"),
            Link::Tcp { address } => format!("RTU over TCP {address}"),
        };
        writeln!(
            out,
            "bus `{}`: {link}, timeout {}, {} retries, backoff up to {}",
            bus.name,
            show_duration(bus.timeout),
            bus.retries,
            show_duration(bus.max_backoff)
        )?;
        for probe in &bus.probes {
            let chosen: Vec<&str> = probe.measurements.iter().map(String::as_str).collect();
            let planned = plan::plan(&probe.sensor, &chosen);
            let naive = plan::naive(&probe.sensor, &chosen);
            let reads: Vec<&str> = planned.reads.iter().map(|r| r.command.name.as_str()).collect();
            writeln!(
                out,
                "  probe `{}`: {} at address {}, every {}{}{}",
                probe.label,
                probe.sensor.name,
                probe.address,
                show_duration(probe.interval),
                if probe.align { " on the clock" } else { "" },
                if probe.procedure { ", with the spec's procedure" } else { "" },
            )?;
            if !probe.inputs.is_empty() {
                let inputs: Vec<String> = probe.inputs.iter().map(|(n, v)| format!("{n} = {v}")).collect();
                writeln!(out, "    station inputs: {}", inputs.join(", "))?;
            }
            // The plan's saving, when it saves anything.
            let saving = if naive.reads.len() > reads.len() {
                format!(" instead of {}", naive.reads.len())
            } else {
                String::new()
            };
            writeln!(
                out,
                "    {}: {} read{} ({}){saving}",
                chosen.join(", "),
                reads.len(),
                if reads.len() == 1 { "" } else { "s" },
                reads.join(", "),
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
        if let Some(home_assistant) = &mqtt.home_assistant {
            writeln!(
                out,
                "home assistant: discovery under `{}`, announcements recorded in {}",
                home_assistant.prefix,
                announcements_file(&station).display()
            )?;
        }
    }
    if let Some(portal) = &station.monitor_my_watershed {
        // The token's source, never the token.
        writeln!(
            out,
            "monitor my watershed: {} for sampling feature {}, token from {}, timestamps at UTC{:+03}:00, \
             up to {} records a request",
            portal.url, portal.sampling_feature, portal.token, portal.utc_offset_hours, portal.batch
        )?;
        for (label, bindings) in &portal.results {
            let bound: Vec<String> = bindings.iter().map(|(name, uuid)| format!("{name} -> {uuid}")).collect();
            writeln!(out, "  probe `{label}`: {}", bound.join(", "))?;
        }
    }
    let findings = preflight(&station);
    if findings.iter().any(|f| f.severity == Severity::Problem) {
        out.flush()?;
        return Err(findings_error(&findings));
    }
    // Warnings name what fails until mended (an adapter not plugged in);
    // the station can start.
    let mut err = std::io::stderr().lock();
    for f in &findings {
        writeln!(err, "warning: {}\nhint: {}", f.message, f.hint)?;
    }
    match findings.len() {
        0 => writeln!(out, "ok")?,
        n => writeln!(out, "ok, with {n} warning{} (on stderr)", if n == 1 { "" } else { "s" })?,
    }
    Ok(())
}

/// The findings, problems first, as one usage error (the file's): the
/// first as the message, the others as details, each one's mend in the hint.
fn findings_error(findings: &[Finding]) -> CliError {
    let label = |f: &Finding| match f.severity {
        Severity::Problem => f.message.clone(),
        Severity::Warning => format!("warning: {}", f.message),
    };
    let mut e = CliError::usage(findings.first().map(|f| f.message.clone()).unwrap_or_default());
    for f in findings.iter().skip(1) {
        e = e.detail(label(f));
    }
    let hints: Vec<&str> = findings.iter().map(|f| f.hint.as_str()).collect();
    e.hint(hints.join("; "))
}

/// Says on stderr what the logger is about to do, so that a first run is
/// not silent until its first reading: every probe and when it first reads.
fn say_start(station: &StationConfig) {
    let mut err = std::io::stderr().lock();
    let now = std::time::SystemTime::now();
    let _ = writeln!(
        err,
        "log: station `{}`: {} probe(s) on {} bus(es), readings into {} (Ctrl-C stops)",
        station.station,
        station.probes().count(),
        station.buses.len(),
        station.storage.display()
    );
    for (bus, probe) in station.probes() {
        let first = logger::first_sample(probe, now);
        let when = if first > now + Duration::from_secs(1) {
            format!("first at {} UTC (waiting for its slot on the clock)", clock(first))
        } else {
            "first now".to_owned()
        };
        let _ = writeln!(
            err,
            "log: probe `{}` ({} at address {} on bus `{}`): every {}{}, {when}",
            probe.label,
            probe.sensor.name,
            probe.address,
            bus.name,
            show_duration(probe.interval),
            if probe.procedure { " with the spec's procedure" } else { "" },
        );
    }
}

/// Says that the previous run did not stop cleanly (a power cut, a kill)
/// and what the store holds after SQLite's own recovery; refuses to go on
/// with a store that fails its integrity check.
fn report_unclean_stop(store: &Store, previous: &UncleanStop, station: &StationConfig) -> Result<()> {
    let storage = station.storage.display();
    let failed = |e: yosemitech_station::StoreError| CliError::device(format!("cannot check the store {storage}: {e}"));
    if let Err(found) = store.check_integrity().map_err(failed)? {
        return Err(CliError::device(format!(
            "the previous run ({}) did not stop cleanly and the store {storage} fails its integrity check: {found}",
            previous.run
        ))
        .hint("keep a copy of the file; `sqlite3 FILE .recover` salvages what it can into a new store"));
    }
    let (count, last) = (store.count().map_err(failed)?, store.last_id().map_err(failed)?);
    let _ = writeln!(
        std::io::stderr(),
        "log: the previous run ({}) did not stop cleanly (a power cut, a kill or a crash); the store {storage} \
         passed its integrity check and holds {count} reading(s), the last with id {last}: every reading \
         committed then is kept, one being written was not stored",
        previous.run
    );
    Ok(())
}

/// Where the Home Assistant configs announced are recorded: beside the store.
fn announcements_file(station: &StationConfig) -> std::path::PathBuf {
    let mut file = station.storage.clone().into_os_string();
    file.push(".home-assistant.json");
    file.into()
}

/// Runs `log` until `stop` (Ctrl-C, SIGTERM): one JSON line per committed reading on stdout.
pub fn run(catalog: &Catalog, args: &LogArgs, stop: &Arc<AtomicBool>, out: &mut dyn Write) -> Result<()> {
    let station = load(catalog, args)?;
    let findings = preflight(&station);
    if findings.iter().any(|f| f.severity == Severity::Problem) {
        return Err(findings_error(&findings));
    }
    for f in &findings {
        let _ = writeln!(std::io::stderr(), "log: warning: {} ({})", f.message, f.hint);
    }
    let storage = station.storage.display();
    let directory = store_directory_of(&station);
    std::fs::create_dir_all(directory).map_err(|e| {
        CliError::device(format!("cannot create the store's directory {}: {e}", directory.display()))
            .hint("check `[storage] path`: the logger must be allowed to create it, or create it yourself")
    })?;
    let mut store = Store::open(&station.storage).map_err(|e| {
        CliError::device(format!("cannot open the store {storage}: {e}"))
            .hint("check `[storage] path`: its directory must exist and be writable")
    })?;
    let (marker, unclean) = RunMarker::begin(&station.storage).map_err(|e| {
        CliError::device(format!("cannot mark the run beside the store {storage}: {e}"))
            .hint("the store's directory must be writable")
    })?;
    if let Some(previous) = unclean {
        report_unclean_stop(&store, &previous, &station)?;
    }
    if let Some(bytes) = station.storage_max_size {
        store.set_max_size(bytes).map_err(|e| CliError::device(format!("cannot cap the store {storage}: {e}")))?;
    }
    let store = Mutex::new(store);
    // Home Assistant discovery: what changed since the last run is
    // published first (the configs of probes removed from the file cleared).
    let (tracker, at_start) = match station.mqtt.as_ref().and_then(|m| Some((m, m.home_assistant.as_ref()?))) {
        Some((mqtt, home_assistant)) => {
            let discovery = Discovery::new(home_assistant, &mqtt.topic_prefix, &station.station);
            let labels: Vec<&str> = station.probes().map(|(_, p)| p.label.as_str()).collect();
            let (tracker, at_start) = Tracker::start(discovery, &announcements_file(&station), &labels);
            (Some(Mutex::new(tracker)), at_start)
        }
        None => (None, Vec::new()),
    };
    // The publisher drains the store from a connection of its own, in id
    // order; it learns of each commit through `wake`, and takes the Home
    // Assistant messages each commit brings.
    let publisher = match &station.mqtt {
        Some(mqtt) => {
            let outbox = Store::open(&station.storage)
                .map_err(|e| CliError::device(format!("cannot open the store {}: {e}", station.storage.display())))?;
            let status_topic =
                tracker.as_ref().map(|t| t.lock().unwrap_or_else(PoisonError::into_inner).status_topic());
            let publisher = Publisher::start_with_status(mqtt, StoreOutbox(outbox), status_topic).map_err(|e| {
                CliError::usage(format!("cannot start publishing: {e}"))
                    .hint("check the [mqtt] section of the station file")
            })?;
            publisher.publish_retained(at_start);
            Some(publisher)
        }
        None => None,
    };
    // Monitor My Watershed drains the same store with a cursor of its own:
    // neither publisher waits on the other.
    let portal = match &station.monitor_my_watershed {
        Some(config) => {
            let outbox = Store::open(&station.storage)
                .map_err(|e| CliError::device(format!("cannot open the store {}: {e}", station.storage.display())))?;
            let portal = yosemitech_portal::Publisher::start(config, PortalOutbox::new(outbox, config.clone()))
                .map_err(|e| {
                    CliError::usage(format!("cannot start publishing to Monitor My Watershed: {e}"))
                        .hint("check the [monitor_my_watershed] section of the station file")
                })?;
            Some(portal)
        }
        None => None,
    };
    // Under systemd (`Type=notify`): ready now, watchdog pings while the logger runs.
    let notifier = service::Notifier::from_environment().map(Arc::new);
    let watchdog = notifier.as_ref().and_then(|n| {
        n.notify(&format!("READY=1\nSTATUS=logging {} probe(s) into {storage}", station.probes().count()));
        service::watchdog_interval().map(|every| service::Watchdog::start(Arc::clone(n), every))
    });
    say_start(&station);
    // The bus threads hand each committed reading to this thread, which
    // owns stdout.
    let (lines, printed) = mpsc::channel::<String>();
    let reports = std::thread::scope(|scope| {
        let logger = scope.spawn(|| {
            let lines = lines;
            logger::run(&station, &store, stop, &|id, reading| {
                // A failed reading is stored and printed like the others; a
                // technician watching the terminal also reads why on stderr.
                if let Some(error) = &reading.error {
                    let _ =
                        writeln!(std::io::stderr(), "log: probe `{}` on bus `{}`: {error}", reading.probe, reading.bus);
                }
                // As stored: with the calibration in force the insert looked up.
                let stored = store.lock().unwrap_or_else(PoisonError::into_inner).get(id).ok().flatten();
                let stored =
                    stored.unwrap_or_else(|| StoredReading { id, reading: reading.clone(), calibration_id: None });
                if let Some(p) = &publisher {
                    if let Some(tracker) = &tracker {
                        let message = message(&stored);
                        p.publish_retained(tracker.lock().unwrap_or_else(PoisonError::into_inner).observe(&message));
                    }
                    p.wake();
                }
                if let Some(p) = &portal {
                    p.wake();
                }
                let _ = lines.send(to_json(&stored).to_string());
            })
        });
        for line in printed {
            // A closed stdout does not stop the logger: the store has every reading.
            let _ = writeln!(out, "{line}").and_then(|()| out.flush());
        }
        logger.join().unwrap_or_else(|_| Err(logger::LogError::Panicked("logger".into())))
    })
    .map_err(|e| CliError::device(e.to_string()).hint("the readings committed so far are in the store"));
    if let Some(n) = &notifier {
        n.notify("STOPPING=1");
    }
    if let Some(w) = watchdog {
        w.stop();
    }
    // The store was closed in order, whatever the outcome: the next run has nothing to check.
    let finished = marker.finish();
    let reports = reports?;
    let mut err = std::io::stderr().lock();
    if let Err(e) = finished {
        let _ = writeln!(err, "log: cannot remove the run marker beside the store: {e}");
    }
    if let Some(p) = publisher {
        // What is not acknowledged in time stays in the outbox for the next run.
        let not_taken = p.status().undelivered;
        let report = p.shutdown(Duration::from_secs(5));
        let published = match report.published_up_to {
            Some(id) => format!("readings published up to id {id}"),
            None => "no reading published by this run".to_owned(),
        };
        let _ = writeln!(
            err,
            "mqtt: {published}; {} unacknowledged (sent again by the next run); \
             {not_taken} publication(s) the broker did not take, sent again",
            report.unacknowledged
        );
    }
    if let Some(p) = portal {
        // A request under way finishes, so a 201 is recorded; the rest waits for the next run.
        let status = p.shutdown(Duration::from_secs(10));
        let _ =
            writeln!(err, "monitor my watershed: {} request(s) accepted, {} failed", status.accepted, status.failed);
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

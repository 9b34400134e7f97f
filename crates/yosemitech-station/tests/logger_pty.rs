//! The scheduler against simulated probes served on real pseudo-terminals:
//! a shared bus with a dead address keeps every live probe's schedule, and
//! a port that disappears and comes back is reopened.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use yosemitech_sim::{Bus, ServeConfig, Simulator, serve_pty};
use yosemitech_spec::{Sensor, Value};
use yosemitech_station::config::{self, StationConfig};
use yosemitech_station::logger::{self, BusReport};
use yosemitech_station::{Datum, Store, StoredReading, plan};

fn spec() -> yosemitech_spec::Spec {
    yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()]).unwrap()
}

/// Every sensor of the spec that has a measurement, cycled to `n` (the
/// same sensor may appear twice when the spec has fewer).
fn measuring_sensors(n: usize) -> Vec<Arc<Sensor>> {
    let all: Vec<Arc<Sensor>> =
        spec().sensors.into_iter().filter(|s| !plan::measurements(s).is_empty()).map(Arc::new).collect();
    assert!(!all.is_empty(), "the spec has a sensor with a measurement");
    all.iter().cycle().take(n).cloned().collect()
}

/// A station file with one bus at `port` and a probe per (label, sensor, address).
fn station_toml(dir: &Path, port: &str, probes: &[(String, &Sensor, u8)], interval: &str) -> String {
    let mut text = format!(
        "station = \"test\"\n[storage]\npath = \"{}\"\n[[bus]]\nname = \"bus\"\nport = \"{port}\"\n\
         timeout = \"200ms\"\nretries = 1\nmax_backoff = \"4s\"\n",
        dir.join("station.sqlite").display()
    );
    // Probes of several sensors may disagree on the line; a station then
    // states it (a pty carries any setting).
    if probes.iter().any(|(_, s, _)| s.serial != probes[0].1.serial) {
        text += "baud = 9600\nparity = \"none\"\n";
    }
    for (label, sensor, address) in probes {
        text += &format!(
            "[[bus.probe]]\nlabel = \"{label}\"\nsensor = \"{}\"\naddress = {address}\ninterval = \"{interval}\"\nprocedure = false\n",
            sensor.name
        );
    }
    text
}

fn load(dir: &Path, text: &str, sensors: &[Arc<Sensor>]) -> StationConfig {
    let path = dir.join("station.toml");
    std::fs::write(&path, text).unwrap();
    config::load(&path, sensors).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// Runs the logger on a thread until `until` says stop (checked every 100
/// ms, with a 60 s watchdog); returns what the buses did.
fn run_until(config: &StationConfig, store: &Mutex<Store>, mut until: impl FnMut() -> bool) -> Vec<BusReport> {
    let stop = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let logger = scope.spawn(|| logger::run(config, store, &stop, &|_, _| {}));
        let deadline = Instant::now() + Duration::from_secs(60);
        while !until() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(100));
        }
        stop.store(true, Ordering::SeqCst);
        logger.join().unwrap().unwrap()
    })
}

fn all_rows(store: &Mutex<Store>) -> Vec<StoredReading> {
    store.lock().unwrap().range(UNIX_EPOCH, SystemTime::now() + Duration::from_secs(60)).unwrap()
}

#[test]
fn three_probes_and_a_dead_address_on_one_pty_keep_their_schedule() {
    let dir = tempfile::tempdir().unwrap();
    let sensors = measuring_sensors(4);
    // Addresses 1..=3 answer; the fourth probe's address has no device.
    let probes: Vec<(String, &Sensor, u8)> =
        sensors.iter().enumerate().map(|(i, s)| (format!("probe-{}", i + 1), s.as_ref(), i as u8 + 1)).collect();
    let bus = probes[..3]
        .iter()
        .fold(Bus::new(), |bus, (_, s, a)| bus.with(Simulator::new(Arc::new((*s).clone())).with_address(*a)));
    let server = serve_pty(bus, ServeConfig::default()).unwrap();
    let port = server.tty_path().unwrap().to_owned();
    let config = load(dir.path(), &station_toml(dir.path(), &port, &probes, "1s"), &sensors);
    let store = Mutex::new(Store::open(&config.storage).unwrap());

    let started = Instant::now();
    let reports = run_until(&config, &store, || started.elapsed() >= Duration::from_secs(8));
    let elapsed = started.elapsed().as_secs_f64();
    let rows = all_rows(&store);

    let mut per_probe: BTreeMap<&str, (u32, u32)> = BTreeMap::new();
    for r in &rows {
        let e = per_probe.entry(r.reading.probe.as_str()).or_default();
        if r.reading.error.is_none() { e.0 += 1 } else { e.1 += 1 }
    }
    eprintln!("    {elapsed:.1} s: {per_probe:?}; {reports:?}");
    // About one sample a second each; a live probe may lose a slot to the
    // dead one's timeout, never most of them.
    for (label, _, _) in &probes[..3] {
        let (ok, failed) = per_probe.get(label.as_str()).copied().unwrap_or_default();
        assert!(f64::from(ok) >= elapsed * 0.6 - 1.0, "{label}: {ok} good readings in {elapsed:.1} s");
        assert!(f64::from(ok) <= elapsed + 2.0, "{label}: no catch-up bursts");
        assert_eq!(failed, 0, "{label}");
    }
    // The dead address fails every time and backs off (1 s, 2 s, 4 s, 4 s ...).
    let (ok, failed) = per_probe.get(probes[3].0.as_str()).copied().unwrap_or_default();
    assert_eq!(ok, 0);
    assert!(failed >= 2 && f64::from(failed) <= elapsed / 2.0 + 1.0, "the dead probe backs off: {failed} attempts");

    // The values are the simulators' (through the spec interpreter).
    let device = server.device();
    for row in rows.iter().filter(|r| r.reading.error.is_none()) {
        let sim = device.device(row.reading.address).unwrap();
        let chosen = plan::measurements(sim.sensor());
        let planned = plan::plan(sim.sensor(), &chosen);
        let mut expected = 0;
        for read in &planned.reads {
            for field in &read.fields {
                let want = sim.get(&read.command.name, field).unwrap();
                let spec_field = read.command.field(field).unwrap();
                // A sub-probe that is not fitted reads as the field's `absent` value: not stored.
                if let (Value::Float(v), Some(absent)) = (&want, spec_field.absent)
                    && f64::from(*v) == absent
                {
                    assert!(row.reading.values.iter().all(|m| m.name != *field), "{field} is absent");
                    continue;
                }
                expected += 1;
                let stored =
                    row.reading.values.iter().find(|m| m.name == *field).unwrap_or_else(|| panic!("{field}: {row:?}"));
                if let (Value::Float(want), Datum::Number(got)) = (want, &stored.value) {
                    assert_eq!(*got as f32, want, "{field}");
                }
                assert_eq!(stored.unit.as_deref(), spec_field.unit.as_deref());
            }
        }
        assert_eq!(row.reading.values.iter().filter(|m| !m.derived).count(), expected, "{row:?}");
        assert!(
            row.reading.serial_number.is_some()
                || sim.sensor().command_with_role(yosemitech_spec::Role::SerialNumber).is_none()
        );
    }
}

#[test]
fn a_bus_whose_pty_goes_away_recovers_when_it_comes_back() {
    let dir = tempfile::tempdir().unwrap();
    let sensors = measuring_sensors(1);
    let sensor = Arc::clone(&sensors[0]);
    // The station names a stable link, as udev's /dev/serial/by-id names do;
    // unplugging removes it, plugging in again points it at the new tty.
    let link: PathBuf = dir.path().join("ttyRS485");
    let plug = |link: &Path| {
        let server = serve_pty(Simulator::new(Arc::clone(&sensor)).with_address(1), ServeConfig::default()).unwrap();
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(server.tty_path().unwrap(), link).unwrap();
        server
    };
    let probes = vec![("only".to_owned(), sensor.as_ref(), 1u8)];
    let config = load(dir.path(), &station_toml(dir.path(), link.to_str().unwrap(), &probes, "300ms"), &sensors);
    let store = Mutex::new(Store::open(&config.storage).unwrap());
    let good = |store: &Mutex<Store>| all_rows(store).iter().filter(|r| r.reading.error.is_none()).count();

    let mut server = Some(plug(&link));
    let mut phase = 0;
    let mut good_before = 0;
    let mut unplugged_at = Instant::now();
    let reports = run_until(&config, &store, || {
        match phase {
            // Running: unplug after three good readings.
            0 if good(&store) >= 3 => {
                if let Some(s) = server.take() {
                    s.stop().unwrap();
                }
                std::fs::remove_file(&link).unwrap();
                good_before = good(&store);
                unplugged_at = Instant::now();
                phase = 1;
            }
            // Unplugged for two seconds: plug back in.
            1 if unplugged_at.elapsed() >= Duration::from_secs(2) => {
                server = Some(plug(&link));
                phase = 2;
            }
            // Back: three more good readings.
            2 if good(&store) >= good_before + 3 => return true,
            _ => {}
        }
        false
    });
    let rows = all_rows(&store);
    let failed = rows.iter().filter(|r| r.reading.error.is_some()).count();
    eprintln!("    {} rows, {failed} failed while unplugged; {reports:?}", rows.len());
    assert_eq!(phase, 2, "the test reached the replug");
    assert!(good(&store) >= good_before + 3, "readings resumed after the port came back: {rows:#?}");
    assert!(failed >= 1, "the outage is recorded");
    assert!(reports[0].opens >= 2, "the port was reopened: {reports:?}");
}

#[test]
fn a_probe_warming_up_leaves_the_bus_to_the_others() {
    // The spec's procedure with opening commands and the longest warm-up
    // (the probe brushes or starts measuring, then waits), beside a probe
    // read without procedure every second.
    let spec = spec();
    let warming = spec
        .sensors
        .iter()
        .filter(|s| !plan::measurements(s).is_empty())
        .filter(|s| s.procedure.as_ref().is_some_and(|p| !p.before.is_empty()))
        .max_by_key(|s| s.procedure.as_ref().map_or(0, |p| p.warm_up_ms))
        .expect("a procedure with opening commands and a warm-up");
    let procedure = warming.procedure.clone().unwrap();
    let other = spec.sensors.iter().find(|s| s.name != warming.name && !plan::measurements(s).is_empty()).unwrap();
    let sensors = vec![Arc::new(warming.clone()), Arc::new(other.clone())];
    let bus = Bus::new()
        .with(Simulator::new(Arc::clone(&sensors[0])).with_address(1))
        .with(Simulator::new(Arc::clone(&sensors[1])).with_address(2));
    let server = serve_pty(bus, ServeConfig::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let port = server.tty_path().unwrap().to_owned();
    let probes = vec![("warming".to_owned(), sensors[0].as_ref(), 1u8), ("plain".to_owned(), sensors[1].as_ref(), 2u8)];
    let text = station_toml(dir.path(), &port, &probes, "1s").replacen("procedure = false\n", "procedure = true\n", 1);
    let config = load(dir.path(), &text, &sensors);
    assert!(config.buses[0].probes[0].procedure && !config.buses[0].probes[1].procedure);
    let store = Mutex::new(Store::open(&config.storage).unwrap());

    // Stop well inside the warm-up.
    let run_for = Duration::from_millis(u64::from(procedure.warm_up_ms) * 4 / 5).min(Duration::from_secs(8));
    let started = Instant::now();
    run_until(&config, &store, || started.elapsed() >= run_for);
    let elapsed = started.elapsed().as_secs_f64();
    let rows = all_rows(&store);
    let plain = rows.iter().filter(|r| r.reading.probe == "plain" && r.reading.error.is_none()).count();
    let warming_rows = rows.iter().filter(|r| r.reading.probe == "warming").count();
    let device = server.device();
    // Every request on the bus reaches every simulator; those addressed to
    // the warming probe are the opening commands, and nothing else yet.
    let stats = *device.device(1).unwrap().stats();
    let addressed = stats.requests - stats.ignored_other_slave - stats.broadcasts;
    eprintln!("    {elapsed:.1} s: {plain} plain readings, warming probe: {addressed} requests, {warming_rows} rows");
    assert_eq!(
        addressed,
        procedure.before.len() as u64,
        "the opening commands went out, and no read during the warm-up"
    );
    assert_eq!(warming_rows, 0, "no reading before the warm-up ends");
    assert!(plain as f64 >= elapsed * 0.6 - 1.0, "the other probe kept its schedule during the warm-up: {plain}");
}

#[test]
fn a_probe_that_refuses_start_measurement_is_read_all_the_same() {
    // Some probes refuse Start Measurement and measure anyway (a real Y533
    // does): the procedure reads on, and the reading says what was refused.
    let spec = spec();
    let starting = spec
        .sensors
        .iter()
        .filter(|s| !plan::measurements(s).is_empty())
        .filter(|s| {
            let start = s.command_with_role(yosemitech_spec::Role::StartMeasurement);
            s.procedure.as_ref().is_some_and(|p| start.is_some_and(|c| p.before.contains(&c.name)))
        })
        .min_by_key(|s| s.procedure.as_ref().map_or(0, |p| p.warm_up_ms));
    let Some(sensor) = starting else {
        eprintln!("    no procedure of the spec starts a measurement");
        return;
    };
    let sensors = vec![Arc::new(sensor.clone())];
    let mut device = Simulator::new(Arc::clone(&sensors[0])).with_address(1);
    device.set_refuses_start(true);
    let server = serve_pty(device, ServeConfig::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let port = server.tty_path().unwrap().to_owned();
    let probes = vec![("refusing".to_owned(), sensors[0].as_ref(), 1u8)];
    let text = station_toml(dir.path(), &port, &probes, "1s").replacen("procedure = false\n", "procedure = true\n", 1);
    let config = load(dir.path(), &text, &sensors);
    let store = Mutex::new(Store::open(&config.storage).unwrap());
    run_until(&config, &store, || !all_rows(&store).is_empty());
    let rows = all_rows(&store);
    let row = rows.first().unwrap_or_else(|| panic!("{}: no reading within a minute", sensor.name));
    assert!(!row.reading.values.is_empty(), "{}: the reading has its values: {row:?}", sensor.name);
    let error = row.reading.error.as_deref().unwrap_or_default();
    assert!(error.contains("refused"), "{}: the reading says the start was refused: {row:?}", sensor.name);
}

/// A corrupt reply is retried by the client, and the retry is counted: a
/// request with no valid reply in the bus's report, no reading lost.
#[test]
fn a_corrupt_reply_is_retried_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let sensors = measuring_sensors(1);
    let probes = vec![("probe".to_owned(), sensors[0].as_ref(), 1)];
    let mut faults = yosemitech_sim::FaultConfig::seeded(1);
    faults.script.push_back(Some(yosemitech_sim::FaultKind::CorruptCrc));
    let sim = Simulator::new(Arc::clone(&sensors[0])).with_address(1).with_faults(faults);
    let server = serve_pty(sim, ServeConfig::default()).unwrap();
    let port = server.tty_path().unwrap().to_owned();
    let config = load(dir.path(), &station_toml(dir.path(), &port, &probes, "1s"), &sensors);
    let store = Mutex::new(Store::open(&config.storage).unwrap());

    let reports = run_until(&config, &store, || all_rows(&store).len() >= 2);
    let rows = all_rows(&store);
    assert!(rows.len() >= 2 && rows.iter().all(|r| r.reading.error.is_none()), "{rows:?}");
    assert_eq!(reports[0].failed_transactions, 1, "the corrupt reply, retried: {reports:?}");
    assert_eq!(server.device().faults().get(yosemitech_sim::FaultKind::CorruptCrc), 1, "one reply corrupted");
}

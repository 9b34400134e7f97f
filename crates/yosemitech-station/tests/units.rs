//! A probe's `units` in the station file: its readings are stored (in a
//! real SQLite file), exported and published converted by the unit
//! table's factor, with the chosen unit; entries that cannot be given are
//! refused by the file's validation, located and with the probe named.
//! Measurements are picked by role ("a number whose unit has another unit
//! of its dimension"), never by name.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use yosemitech_sim::{ServeConfig, Simulator, serve_pty};
use yosemitech_spec::units::{self, Conversion, UnitDef};
use yosemitech_spec::{CommandSpec, FieldKind, Sensor, Value};
use yosemitech_station::config::{self, StationConfig};
use yosemitech_station::{Datum, Store, export, logger, outbox, plan};

fn spec() -> yosemitech_spec::Spec {
    yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()]).unwrap()
}

/// A measured number of a sensor whose unit converts to another unit,
/// with the read it is planned from and both units.
struct Pick {
    sensor: Arc<Sensor>,
    command: CommandSpec,
    field: String,
    from: &'static UnitDef,
    to: &'static UnitDef,
}

/// The first sensor of the spec with a float measurement whose unit has
/// another unit of its dimension in the table.
fn pick() -> Pick {
    for sensor in spec().sensors {
        for name in plan::measurements(&sensor) {
            let planned = plan::plan(&sensor, &[name]);
            let Some(command) = planned.reads.first().map(|r| r.command) else { continue };
            let Some(field) = command.field(name).filter(|f| matches!(f.kind, FieldKind::F32 { .. })) else {
                continue;
            };
            let Some(from) = field.unit.as_deref().and_then(units::lookup) else { continue };
            let Some(to) = units::UNITS.iter().find(|u| u.dimension == from.dimension && !std::ptr::eq(*u, from))
            else {
                continue;
            };
            let (command, field) = (command.clone(), name.to_owned());
            return Pick { sensor: Arc::new(sensor), command, field, from, to };
        }
    }
    panic!("no measurement of the spec has a unit that converts");
}

fn station_toml(dir: &Path, port: &str, sensor: &Sensor, units: &str) -> String {
    format!(
        "station = \"test\"\n[storage]\npath = \"{}\"\n[[bus]]\nname = \"bus\"\nport = \"{port}\"\n\
         timeout = \"200ms\"\nretries = 1\n[[bus.probe]]\nlabel = \"probe-1\"\nsensor = \"{}\"\naddress = {}\n\
         interval = \"200ms\"\nprocedure = false\nunits = {units}\n",
        dir.join("station.sqlite").display(),
        sensor.name,
        sensor.default_address,
    )
}

fn load(dir: &Path, text: &str, sensors: &[Arc<Sensor>]) -> StationConfig {
    let path = dir.join("station.toml");
    std::fs::write(&path, text).unwrap();
    config::load(&path, sensors).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

#[test]
fn a_chosen_unit_is_stored_exported_and_published_converted() {
    let p = pick();
    let dir = tempfile::tempdir().unwrap();
    // A value no conversion of the table leaves as it is (0 would stay 0 under a factor).
    let mut probe = Simulator::new(Arc::clone(&p.sensor)).with_address(p.sensor.default_address);
    probe.set(&p.command.name, &p.field, Value::Float(17.25)).unwrap();
    let server = serve_pty(probe, ServeConfig::default()).unwrap();
    let port = server.tty_path().unwrap().to_owned();
    let units = format!("{{ {} = \"{}\" }}", p.field, p.to.symbol);
    let config = load(dir.path(), &station_toml(dir.path(), &port, &p.sensor, &units), &[Arc::clone(&p.sensor)]);
    assert_eq!(config.buses[0].probes[0].units.get(&p.field).map(|c| c.to.symbol), Some(p.to.symbol));

    // Run until one good reading is committed.
    let store = Mutex::new(Store::open(&config.storage).unwrap());
    let stop = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let logger = scope.spawn(|| logger::run(&config, &store, &stop, &|_, _| {}));
        let deadline = Instant::now() + Duration::from_secs(60);
        let good = || {
            let rows = store.lock().unwrap().range(UNIX_EPOCH, SystemTime::now() + Duration::from_secs(60)).unwrap();
            rows.iter().any(|r| r.reading.error.is_none())
        };
        while !good() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(50));
        }
        stop.store(true, Ordering::SeqCst);
        logger.join().unwrap().unwrap();
    });
    drop(store);

    // The file, opened afresh: the value the simulator served, converted.
    let store = Store::open(&config.storage).unwrap();
    let rows = store.range(UNIX_EPOCH, SystemTime::now() + Duration::from_secs(60)).unwrap();
    let row = rows.iter().find(|r| r.reading.error.is_none()).expect("a good reading within 60 s");
    let served = match server.device().get(&p.command.name, &p.field).unwrap() {
        Value::Float(v) => f64::from(v),
        other => panic!("{other:?}"),
    };
    let want = Conversion::between(p.from, p.to).unwrap().apply(served);
    assert_ne!(want, served, "the conversion changes the value, or the test proves nothing");
    let stored = row.reading.values.iter().find(|m| m.name == p.field).unwrap();
    assert_eq!(stored.value, Datum::Number(want), "{stored:?}");
    assert_eq!(stored.unit.as_deref(), Some(p.to.symbol));
    // The probe's other measurements keep their spec unit.
    for m in row.reading.values.iter().filter(|m| m.name != p.field) {
        let spec_unit = p.command.field(&m.name).and_then(|f| f.unit.as_deref());
        if p.command.field(&m.name).is_some() {
            assert_eq!(m.unit.as_deref(), spec_unit, "{m:?}");
        }
    }

    // Export and the MQTT payload read the same row.
    let json = export::to_json(row);
    let exported = json["values"].as_array().unwrap().iter().find(|v| v["name"] == p.field.as_str()).unwrap();
    assert_eq!((exported["value"].as_f64(), exported["unit"].as_str()), (Some(want), Some(p.to.symbol)));
    let message = outbox::message(row);
    let published = message.values.iter().find(|v| v.name == p.field).unwrap();
    assert_eq!((published.value, published.unit.as_deref()), (Some(want), Some(p.to.symbol)));
    eprintln!("    served {served} {}, stored as {want} {}", p.from.symbol, p.to.symbol);
}

#[test]
fn units_that_cannot_be_given_are_refused_located_with_the_probe_named() {
    let p = pick();
    let dir = tempfile::tempdir().unwrap();
    let foreign = units::UNITS.iter().find(|u| u.dimension != p.from.dimension).unwrap();
    let cases = [
        (format!("{{ {} = \"no-such-unit\" }}", p.field), "unknown unit `no-such-unit`"),
        (format!("{{ {} = \"{}\" }}", p.field, foreign.symbol), "choose one of"),
        (format!("{{ no_such_measurement = \"{}\" }}", p.to.symbol), "no measurement or derived quantity"),
        (format!("{{ {} = \"{}\" }}", p.field, p.to.symbol.to_uppercase()), "did you mean"),
    ];
    let mut refused = 0;
    for (units, says) in &cases {
        if *says == "did you mean" && units::lookup(&p.to.symbol.to_uppercase()).is_some() {
            continue; // in upper case it is a unit (`K`): nothing to refuse
        }
        let text = station_toml(dir.path(), "/dev/null", &p.sensor, units);
        let path = dir.path().join("station.toml");
        let errors = config::parse(&path, &text, &[Arc::clone(&p.sensor)]).unwrap_err();
        let e = errors.0.first().unwrap();
        assert_eq!(errors.0.len(), 1, "{errors}");
        assert!(e.message.contains("probe `probe-1`") && e.message.contains(says), "`{says}` in {e}");
        let line = text.lines().position(|l| l.starts_with("units =")).unwrap() + 1;
        assert_eq!(e.line, line, "{e}");
        refused += 1;
    }
    assert!(refused >= 3);
    eprintln!("    {refused} station units refused");
}

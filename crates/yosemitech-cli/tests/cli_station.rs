//! `yosemitech log` and `export` as a field person runs them: the sample
//! station file validates, a broken one is reported line by line (the
//! `[mqtt]` and `[mqtt.home_assistant]` sections too), and a
//! logger on a simulated bus stops cleanly on SIGTERM with every reading it
//! announced committed to its SQLite file.

use crate::station;

use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::time::{Duration, Instant};

use serde_json::Value as Json;
use station::{Station, YOSEMITECH, command, terminate};
use yosemitech_station::{Store, plan};
use yosemitech_tests::cli::{Run, WATCHDOG};
use yosemitech_tests::spec;

/// Runs the binary with `args`.
fn yosemitech(args: &[&str]) -> Run {
    YOSEMITECH.run(args)
}

/// The README's sample station file, committed beside the station crate.
const SAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../yosemitech-station/station.toml");

#[test]
fn the_sample_station_file_checks() {
    let run = yosemitech(&["log", "--config", SAMPLE, "--check"]);
    let out = run.ok();
    assert!(out.lines().last().is_some_and(|l| l == "ok" || l.starts_with("ok, with ")), "{out}");
    assert!(out.contains("bus `") && out.contains("probe `"), "{out}");
    // The only warning a machine without the adapter may give is its port's.
    for warning in run.stderr.lines().filter(|l| l.starts_with("warning: ")) {
        assert!(warning.contains("the serial port") && warning.contains("does not exist"), "{warning}");
    }
}

#[test]
fn check_errors_carry_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let sensor = spec().sensors.iter().find(|&s| !plan::measurements(s).is_empty()).cloned().unwrap();
    let lines = [
        "station = \"s\"".to_owned(),
        "[storage]".to_owned(),
        "path = \"s.sqlite\"".to_owned(),
        "[[bus]]".to_owned(),
        "name = \"a\"".to_owned(),
        "port = \"/dev/null\"".to_owned(),
        "[[bus.probe]]".to_owned(),
        "label = \"p\"".to_owned(),
        "sensor = \"no_such_sensor\"".to_owned(), // line 9
        "address = 1".to_owned(),
        "interval = \"1m\"".to_owned(),
        "[[bus.probe]]".to_owned(),
        "label = \"q\"".to_owned(),
        format!("sensor = \"{}\"", sensor.name),
        "address = 0".to_owned(),                        // line 15
        "measurements = [\"no_such_field\"]".to_owned(), // line 16
        "interval = \"soon\"".to_owned(),                // line 17
    ];
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, lines.join("\n")).unwrap();
    let run = yosemitech(&["log", "--config", path.to_str().unwrap(), "--check"]);
    let err = run.fails_with_hint(2);
    let file = path.display().to_string();
    for (line, what) in [(9, "no_such_sensor"), (15, "address 0"), (16, "no_such_field"), (17, "soon")] {
        let located = err
            .lines()
            .find(|l| l.contains(&format!("{file}:{line}:")))
            .unwrap_or_else(|| panic!("line {line}: {err}"));
        assert!(located.contains(what), "{located}");
    }

    // The publisher's section is validated by the publisher's own rules,
    // and located; a password never appears.
    let good_probe =
        format!("[[bus.probe]]\nlabel = \"q\"\nsensor = \"{}\"\naddress = 1\ninterval = \"1m\"\n", sensor.name);
    let head = lines[..6].join("\n");
    std::fs::write(
        &path,
        format!("{head}\n{good_probe}[mqtt]\nhost = \"\"\nclient_id = \"x\"\npassword = \"hunter2\"\n"),
    )
    .unwrap();
    let run = yosemitech(&["log", "--config", path.to_str().unwrap(), "--check"]);
    let err = run.fails_with_hint(2);
    assert!(err.lines().any(|l| l.contains(&format!("{file}:")) && l.contains("[mqtt]")), "{err}");
    assert!(!err.contains("hunter2"), "{err}");

    // The Home Assistant section: its prefix is checked like a topic
    // prefix, a misspelt key refused, a good one shown by --check.
    let mqtt = "[mqtt]\nhost = \"127.0.0.1\"\nclient_id = \"x\"\n";
    for (section, refused) in [("prefix = \"home/#\"", "mqtt.home_assistant.prefix"), ("prefx = \"ha\"", "prefx")] {
        std::fs::write(&path, format!("{head}\n{good_probe}{mqtt}[mqtt.home_assistant]\n{section}\n")).unwrap();
        let run = yosemitech(&["log", "--config", path.to_str().unwrap(), "--check"]);
        let err = run.fails_with_hint(2);
        assert!(err.lines().any(|l| l.contains(&format!("{file}:")) && l.contains(refused)), "{err}");
    }
    std::fs::write(&path, format!("{head}\n{good_probe}{mqtt}[mqtt.home_assistant]\n")).unwrap();
    let run = yosemitech(&["log", "--config", path.to_str().unwrap(), "--check"]);
    let out = run.ok();
    assert!(out.lines().any(|l| l.starts_with("home assistant: discovery under `homeassistant`")), "{out}");

    // A syntax error, located too.
    std::fs::write(&path, "station = \"s\"\n[storage\n").unwrap();
    let run = yosemitech(&["log", "--config", path.to_str().unwrap(), "--check"]);
    assert!(run.fails(2).contains(&format!("{file}:2:")), "{}", run.stderr);
}

#[test]
fn log_stops_cleanly_on_sigterm_and_the_file_has_every_reading() {
    let station = Station::simulated("s", "200ms");
    let config = station.write_config();
    let db = &station.db;

    let mut child = command()
        .args(["log", "--config", config.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut announced: Vec<Json> = Vec::new();
    let deadline = Instant::now() + WATCHDOG;
    while announced.len() < 6 && Instant::now() < deadline {
        let mut line = String::new();
        if stdout.read_line(&mut line).unwrap() == 0 {
            break;
        }
        announced.push(serde_json::from_str(&line).unwrap());
    }
    assert!(announced.len() >= 6, "the logger announced readings: {announced:?}");
    let code = terminate(&mut child, Duration::from_secs(20));
    // What it announced after the first six, up to its exit.
    for line in stdout.lines() {
        announced.push(serde_json::from_str(&line.unwrap()).unwrap());
    }
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(code, 0, "SIGTERM stops the logger cleanly: {stderr}");
    assert!(stderr.contains("readings"), "a summary per bus: {stderr}");

    let store = Store::open(db).unwrap();
    let stored = store.range(std::time::UNIX_EPOCH, std::time::SystemTime::now()).unwrap();
    let ids: Vec<i64> = announced.iter().map(|r| r["id"].as_i64().unwrap()).collect();
    assert_eq!(stored.iter().map(|s| s.id).collect::<Vec<_>>(), ids, "every announced reading is stored, nothing else");
    assert!(stored.iter().all(|s| s.reading.error.is_none()), "{stored:?}");

    // export gives the same readings.
    let run = yosemitech(&["export", "--db", db.to_str().unwrap(), "--format", "jsonl"]);
    let exported: Vec<Json> = run.ok().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(exported, announced);
    let run = yosemitech(&["export", "--db", db.to_str().unwrap(), "--from", "2000-01-01", "--to", "2000-01-02"]);
    assert_eq!(run.ok().lines().count(), 1, "only the CSV header: {}", run.stdout);
    let run = yosemitech(&["export", "--db", db.to_str().unwrap()]);
    let values: usize = stored.iter().map(|s| s.reading.values.len().max(1)).sum();
    assert_eq!(run.ok().lines().count(), 1 + values, "one CSV row per value");
}

#[cfg(unix)]
#[test]
fn under_systemd_the_logger_says_ready_pings_the_watchdog_and_says_stopping() {
    use std::os::unix::net::UnixDatagram;

    let station = Station::simulated("s", "200ms");
    let config = station.write_config();
    let dir = tempfile::tempdir().unwrap();
    let socket_path = dir.path().join("notify.sock");
    let socket = UnixDatagram::bind(&socket_path).unwrap();
    socket.set_read_timeout(Some(WATCHDOG)).unwrap();
    let mut child = command()
        .args(["log", "--config", config.to_str().unwrap()])
        .env("NOTIFY_SOCKET", &socket_path)
        .env("WATCHDOG_USEC", "300000")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut receive = || {
        let mut buf = [0u8; 512];
        let n = socket.recv(&mut buf).expect("a message from the logger");
        String::from_utf8_lossy(&buf[..n]).into_owned()
    };
    let first = receive();
    assert!(first.lines().any(|l| l == "READY=1"), "the first message says ready: {first:?}");
    let probes = station.toml.matches("[[bus.probe]]").count();
    assert!(first.contains(&format!("STATUS=logging {probes} probe(s)")), "{first:?}");
    for _ in 0..3 {
        assert_eq!(receive(), "WATCHDOG=1");
    }
    let code = terminate(&mut child, Duration::from_secs(20));
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(code, 0, "{stderr}");
    // Pings may still be queued before the logger's last word.
    let last = std::iter::repeat_with(&mut receive).find(|m| m != "WATCHDOG=1").unwrap();
    assert_eq!(last, "STOPPING=1");
    // After STOPPING, nothing more.
    socket.set_nonblocking(true).unwrap();
    let mut buf = [0u8; 64];
    assert!(socket.recv(&mut buf).is_err(), "no ping after the logger stopped");
}

/// The Debian package's pieces agree: the sample station file it installs
/// checks, the service runs the file where the package puts it, and the
/// store lies in the service's state directory.
#[test]
fn the_packaged_service_runs_the_packaged_station_file() {
    let crate_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let sample = crate_dir.join("packaging/station.toml");
    let out = yosemitech(&["log", "--config", sample.to_str().unwrap(), "--check"]).ok().to_owned();
    let manifest: toml::Table = std::fs::read_to_string(crate_dir.join("Cargo.toml")).unwrap().parse().unwrap();
    let assets = manifest["package"]["metadata"]["deb"]["assets"].as_array().unwrap();
    let installed = |source: &str| {
        let asset = assets.iter().find(|a| a[0].as_str() == Some(source)).unwrap_or_else(|| panic!("{source}"));
        format!("/{}", asset[1].as_str().unwrap())
    };
    let unit = std::fs::read_to_string(crate_dir.join("packaging/yosemitech-station.service")).unwrap();
    let key = |name: &str| {
        unit.lines().find_map(|l| l.strip_prefix(&format!("{name}="))).unwrap_or_else(|| panic!("no {name}="))
    };
    let config = installed("packaging/station.toml");
    assert!(key("ExecStart").ends_with(&format!("log --config {config}")), "{unit}");
    assert!(key("ExecStart").starts_with(&installed("target/release/yosemitech")), "{unit}");
    assert_eq!(key("Type"), "notify");
    let state = format!("/var/lib/{}/", key("StateDirectory"));
    assert!(out.contains(&format!("storage {state}")), "the store is in {state}:\n{out}");
    assert!(key("SupplementaryGroups").split_whitespace().any(|g| g == "dialout"), "{unit}");
}

//! What `log --check` and `log` say before the first reading, from the one
//! place that knows what a run needs (`yosemitech_station::preflight`): a
//! procedure that outlasts its probe's interval is refused by both; a
//! store's missing directory is created; a serial port that does not exist
//! is a warning; a probe may name its sensor by model, as `read` does; and
//! `log` says on stderr what it will do before its first reading.

use crate::station;

use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use station::{Station, YOSEMITECH, command, terminate};
use yosemitech_spec::Sensor;
use yosemitech_spec::lookup::{By, Lookup, find_sensor};
use yosemitech_station::config::show_duration;
use yosemitech_station::plan;
use yosemitech_tests::cli::{Run, WATCHDOG};
use yosemitech_tests::spec;

/// A station file of one probe of `sensor` (written as `sensor_word`) on
/// serial `port`, its store at `store`.
fn station_file(store: &str, port: &str, sensor_word: &str, sensor: &Sensor, probe: &str) -> String {
    format!(
        "station = \"s\"\n[storage]\npath = \"{store}\"\n[[bus]]\nname = \"a\"\nport = \"{port}\"\n\
         [[bus.probe]]\nlabel = \"p\"\nsensor = \"{sensor_word}\"\naddress = {}\n{probe}",
        sensor.default_address
    )
}

fn check(dir: &std::path::Path, text: &str) -> Run {
    let path = dir.join("station.toml");
    std::fs::write(&path, text).unwrap();
    YOSEMITECH.run(&["log", "--config", path.to_str().unwrap(), "--check"])
}

#[test]
fn a_procedure_that_outlasts_the_interval_is_refused_by_check_and_by_log() {
    let spec = spec();
    let Some((sensor, least)) = spec.sensors.iter().filter(|s| !plan::measurements(s).is_empty()).find_map(|s| {
        let least = s.procedure.as_ref()?.least_duration();
        (least >= Duration::from_millis(2)).then_some((s, least))
    }) else {
        eprintln!("    skipped: no sensor of the spec has a procedure that takes time");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("s.sqlite");
    let store = store.to_str().unwrap();
    let too_short = show_duration(least / 2);
    let file = station_file(
        store,
        "/dev/null",
        &sensor.name,
        sensor,
        &format!("interval = \"{too_short}\"\nprocedure = true\n"),
    );
    let err = check(dir.path(), &file).fails_with_hint(2).to_owned();
    let said = format!("probe `p`: the {} procedure takes at least {}", sensor.name, show_duration(least));
    assert!(err.lines().next().is_some_and(|l| l.contains(&said)), "`{said}` first in:\n{err}");
    assert!(err.contains(&format!("interval of {too_short}")), "{err}");

    // `log` refuses the same file with the same words, before touching the store.
    let run = YOSEMITECH.run(&["log", "--config", dir.path().join("station.toml").to_str().unwrap()]);
    assert!(run.fails_with_hint(2).contains(&said), "{}", run.stderr);
    assert!(!std::path::Path::new(store).exists(), "log opened the store of a file it refused");

    // Room for the procedure: the same file checks.
    let roomy = show_duration(least + Duration::from_secs(10));
    let file =
        station_file(store, "/dev/null", &sensor.name, sensor, &format!("interval = \"{roomy}\"\nprocedure = true\n"));
    let run = check(dir.path(), &file);
    assert_eq!(run.ok().lines().last(), Some("ok"), "{}", run.stderr);
}

#[test]
fn a_missing_store_directory_is_created_and_a_missing_port_is_a_warning() {
    let spec = spec();
    let sensor = spec.sensors.iter().find(|s| !plan::measurements(s).is_empty()).expect("a sensor with measurements");
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("not/yet/s.sqlite");
    let port = format!("/dev/yosemitech-test-{}-absent", std::process::id());
    let file =
        station_file(store.to_str().unwrap(), &port, &sensor.name, sensor, "interval = \"1m\"\nprocedure = false\n");
    let run = check(dir.path(), &file);
    let out = run.ok();
    assert!(out.contains(&format!("{} is created at start", dir.path().join("not/yet").display())), "{out}");
    assert_eq!(out.lines().last(), Some("ok, with 1 warning (on stderr)"), "{out}");
    assert!(run.stderr.contains(&format!("warning: bus `a`: the serial port {port} does not exist")), "{}", run.stderr);
    assert!(!store.exists(), "--check created the store");

    // A directory that cannot be created is a problem.
    let blocker = dir.path().join("a-file");
    std::fs::write(&blocker, "").unwrap();
    let file = station_file(
        blocker.join("s.sqlite").to_str().unwrap(),
        "/dev/null",
        &sensor.name,
        sensor,
        "interval = \"1m\"\nprocedure = false\n",
    );
    let err = check(dir.path(), &file).fails_with_hint(2).to_owned();
    assert!(err.contains("cannot be created") && err.contains("is not a directory"), "{err}");
}

/// Lines of a child's pipe, sent as they come.
fn lines_of(pipe: impl std::io::Read + Send + 'static) -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(pipe).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// The next line of `rx` that `pred` accepts, within the watchdog.
fn wait_for(rx: &mpsc::Receiver<String>, what: &str, pred: impl Fn(&str) -> bool) -> String {
    let deadline = Instant::now() + WATCHDOG;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) if pred(&line) => return line,
            Ok(_) => {}
            Err(_) => panic!("no {what} within {WATCHDOG:?}"),
        }
    }
}

#[test]
fn log_says_what_it_will_do_before_the_first_reading_and_creates_the_stores_directory() {
    let mut station = Station::simulated_probes("s", "200ms", 1);
    let deeper = station.db.parent().unwrap().join("new/dir/station.sqlite");
    station.toml = station.toml.replace(&station.db.display().to_string(), &deeper.display().to_string());
    let config = station.write_config();
    let mut child = command()
        .args(["log", "--config", config.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = lines_of(child.stderr.take().unwrap());
    let stdout = lines_of(child.stdout.take().unwrap());
    let started = wait_for(&stderr, "start line", |l| l.starts_with("log: station `s`"));
    assert!(started.contains(&deeper.display().to_string()), "{started}");
    let probe = wait_for(&stderr, "probe line", |l| l.starts_with("log: probe `p0`"));
    assert!(probe.contains("every 200ms") && probe.contains("first now"), "{probe}");
    let reading = wait_for(&stdout, "reading", |l| l.starts_with('{'));
    assert!(reading.contains("\"probe\":\"p0\""), "{reading}");
    // Values as the probe sent them: an f32 has at most 9 significant
    // digits, so 17 (`15.800000190734863`) are the f32's binary error.
    let json: serde_json::Value = serde_json::from_str(&reading).unwrap();
    for value in json["values"].as_array().unwrap() {
        if let Some(number) = value["value"].as_f64() {
            let digits = number.to_string().chars().filter(char::is_ascii_digit).collect::<String>();
            let significant = digits.trim_start_matches('0').trim_end_matches('0').len();
            assert!(significant <= 9, "{} = {number}: float noise in {reading}", value["name"]);
        }
    }
    assert_eq!(terminate(&mut child, WATCHDOG), 0);
    assert!(deeper.exists(), "the store was not created in its new directory");
}

#[test]
fn log_says_when_a_probe_on_the_clock_first_reads() {
    let mut station = Station::simulated_probes("s", "1d", 1);
    station.toml += "align = true\n";
    let config = station.write_config();
    let mut child = command()
        .args(["log", "--config", config.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = lines_of(child.stderr.take().unwrap());
    let probe = wait_for(&stderr, "probe line", |l| l.starts_with("log: probe `p0`"));
    assert_eq!(terminate(&mut child, WATCHDOG), 0);
    // Its slot is the next 00:00 UTC; within a second of it, it is "now".
    let into_day = SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_secs() % 86_400;
    if into_day > 2 && into_day < 86_398 {
        assert!(probe.contains("every 1d") && probe.contains("first at 00:00:00 UTC (waiting for its slot"), "{probe}");
    }
}

#[test]
fn a_probe_may_name_its_sensor_by_model_as_read_does() {
    let spec = spec();
    let sensors: Vec<&Sensor> = spec.sensors.iter().collect();
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("s.sqlite");
    let mut named = 0;
    for (index, sensor) in sensors.iter().enumerate().filter(|(_, s)| !plan::measurements(s).is_empty()) {
        let models = sensor.model.iter().chain(sensor.aliases.iter().map(|a| &a.model));
        for model in models {
            // A model several sensors answer to names none of them.
            if find_sensor(&sensors, model) != (Lookup::Found { index, by: By::Model }) {
                continue;
            }
            let word = model.to_lowercase();
            let file = station_file(
                store.to_str().unwrap(),
                "/dev/null",
                &word,
                sensor,
                "interval = \"1m\"\nprocedure = false\n",
            );
            let run = check(dir.path(), &file);
            let out = run.ok();
            assert!(out.contains(&format!("probe `p`: {} at address", sensor.name)), "{word}: {out}");
            named += 1;
        }
    }
    if named == 0 {
        eprintln!("    skipped: no model of the spec names one sensor alone");
    }
}

//! `yosemitech log` publishing to Monitor My Watershed beside MQTT, against
//! the test kit's loopback portal (which refuses what the portal refuses)
//! and rumqttd. The portal goes away and comes back, the logger is killed
//! and started again: the portal holds every stored value exactly once,
//! MQTT went on while the portal was away, and each publisher's cursor is
//! its own. `log --check` validates the section, located, and neither it
//! nor a refused run ever shows the token.

use crate::station;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Child;
use std::time::Duration;

use station::{Station, YOSEMITECH, command, stored_ids, terminate};
use yosemitech_portal::body::timestamp;
use yosemitech_station::portal::cursor_of;
use yosemitech_station::{Datum, Store, plan};
use yosemitech_tests::broker::{Broker, BrokerKind, Subscriber, ids_and_first_occurrences, wait_until};
use yosemitech_tests::portal::{Portal, Stored};
use yosemitech_tests::spec;

const TOKEN: &str = "mmw-e2e-token-5c0ffee0";
const FEATURE: &str = "5a5a5a5a-1111-4222-8333-444455556666";
/// Readings per request at most.
const BATCH: usize = 5;

/// The result UUID of measurement `j` of probe `p<i>`.
fn result_uuid(i: usize, j: usize) -> String {
    format!("{:08x}-0000-4000-8000-{:012x}", 0xa000 + i, j + 1)
}

/// `[monitor_my_watershed]` for the portal at `url`, every measurement of
/// the station's probes bound (the probes [`Station::simulated`] makes).
fn section(url: &str) -> String {
    let sensors: Vec<_> = spec().sensors.iter().filter(|&s| !plan::measurements(s).is_empty()).take(2).collect();
    let mut toml = format!(
        "[monitor_my_watershed]\nurl = \"{url}\"\nallow_http = true\ntoken = \"environment\"\n\
         sampling_feature = \"{FEATURE}\"\nbatch = {BATCH}\ntimeout = \"5s\"\nretry_min = \"100ms\"\nretry_max = \"1s\"\n\
         poll_interval = \"100ms\"\n"
    );
    for (i, s) in sensors.iter().enumerate() {
        toml += &format!("[monitor_my_watershed.results.p{i}]\n");
        for (j, name) in plan::measurements(s).iter().enumerate() {
            toml += &format!("{name} = \"{}\"\n", result_uuid(i, j));
        }
    }
    toml
}

/// Starts the logger with `token` in its environment, its stderr into
/// `stderr` and its stdout beside it (`.out`).
fn start_logger(config: &Path, token: &str, stderr: &Path) -> Child {
    command()
        .args(["log", "--config", config.to_str().unwrap()])
        .env("YOSEMITECH_MMW_TOKEN", token)
        .stdout(std::fs::File::create(stderr.with_extension("out")).unwrap())
        .stderr(std::fs::File::create(stderr).unwrap())
        .spawn()
        .unwrap()
}

fn mark(db: &Path, publisher: &str) -> i64 {
    Store::open(db).unwrap().published_up_to(publisher).unwrap()
}

/// The result UUID of each bound measurement, by (probe label, measurement).
fn bound() -> BTreeMap<(String, String), String> {
    let sensors: Vec<_> = spec().sensors.iter().filter(|&s| !plan::measurements(s).is_empty()).take(2).collect();
    let mut m = BTreeMap::new();
    for (i, s) in sensors.iter().enumerate() {
        for (j, name) in plan::measurements(s).iter().enumerate() {
            m.insert((format!("p{i}"), (*name).to_owned()), result_uuid(i, j));
        }
    }
    m
}

/// The portal's cursor of each bound probe.
fn portal_marks(db: &Path) -> BTreeMap<String, i64> {
    bound().into_keys().map(|(label, _)| (label.clone(), mark(db, &cursor_of(&label)))).collect()
}

/// What the portal should hold for the readings up to each probe's cursor
/// in `marks`: every number of a bound measurement, with the timestamp the
/// logger sends.
fn expected(db: &Path, marks: &BTreeMap<String, i64>) -> Vec<Stored> {
    let bound = bound();
    let store = Store::open(db).unwrap();
    let mut out = Vec::new();
    for s in store.range(std::time::UNIX_EPOCH, std::time::SystemTime::now() + Duration::from_secs(60)).unwrap() {
        if s.id > marks.get(&s.reading.probe).copied().unwrap_or(0) {
            continue;
        }
        let ms = yosemitech_station::time::unix_ms(s.reading.timestamp);
        for m in &s.reading.values {
            if let (Datum::Number(n), Some(uuid)) = (&m.value, bound.get(&(s.reading.probe.clone(), m.name.clone()))) {
                out.push((uuid.clone(), timestamp(ms, 0), *n));
            }
        }
    }
    out
}

/// How many readings a request body carries.
fn records_in(body: &str) -> usize {
    match serde_json::from_str::<serde_json::Value>(body).unwrap()["timestamp"].as_array() {
        Some(stamps) => stamps.len(),
        None => 1,
    }
}

fn sorted(mut v: Vec<Stored>) -> Vec<Stored> {
    v.sort_by(|a, b| (&a.0, &a.1).cmp(&(&b.0, &b.1)).then(a.2.total_cmp(&b.2)));
    v
}

#[test]
fn portal_and_mqtt_each_get_every_reading_once_across_a_portal_outage_and_a_kill() {
    let broker = Broker::start(BrokerKind::Rumqttd, None);
    let subscriber = Subscriber::start(&broker, &format!("{}/#", yosemitech_mqtt::topic::DEFAULT_TOPIC_PREFIX));
    let mut portal = Portal::start(TOKEN, FEATURE);
    let mut station = Station::simulated("river", "200ms");
    let db = station.db.clone();
    station.toml += &format!(
        "[mqtt]\nhost = \"127.0.0.1\"\nport = {}\nclient_id = \"station-river-mmw\"\nkeep_alive_secs = 5\n\
         [mqtt.publisher]\nmax_in_flight = 4\npoll_interval_ms = 50\nreconnect_min_ms = 100\nreconnect_max_ms = 1000\n",
        broker.port
    );
    station.toml += &section(&portal.url());
    let config = station.write_config();
    let logs = tempfile::tempdir().unwrap();

    // First run: both publishers keep up.
    let mut logger = start_logger(&config, TOKEN, &logs.path().join("run1.err"));
    assert!(wait_until(|| portal.accepted().len() >= 3 && subscriber.count() >= 5), "readings reach both");

    // The portal goes away; readings are stored and MQTT goes on.
    portal.stop();
    let (stored_at_outage, mqtt_at_outage) = (stored_ids(&db).len(), subscriber.count());
    assert!(
        wait_until(|| stored_ids(&db).len() >= stored_at_outage + 15 && subscriber.count() >= mqtt_at_outage + 15),
        "logging and MQTT go on without the portal"
    );
    // (A 201 answered just before the stop is marked just after it.)
    let portal_at_outage = portal_marks(&db);
    let accepted_at_outage = portal.accepted().len();
    // Killed without warning while the portal is away: no 201 can be lost in flight.
    logger.kill().unwrap();
    logger.wait().unwrap();
    let after_kill = stored_ids(&db);
    let last_at_kill = *after_kill.last().unwrap();
    let (portal_at_kill, mqtt_at_kill) = (portal_marks(&db), mark(&db, "mqtt"));
    assert_eq!(portal_at_kill, portal_at_outage, "nothing marked sent while the portal was away");
    assert_eq!(portal.accepted().len(), accepted_at_outage);
    assert!(
        portal_at_kill.values().all(|&m| mqtt_at_kill > m + 10),
        "MQTT did not wait for the portal: {mqtt_at_kill} vs {portal_at_kill:?}"
    );
    let backlog = portal.accepted().len();

    // The portal comes back; a second run on the same store sends the backlog.
    portal.restart();
    let mut logger = start_logger(&config, TOKEN, &logs.path().join("run2.err"));
    assert!(
        wait_until(
            || portal_marks(&db).values().all(|&m| m >= last_at_kill + 10) && mark(&db, "mqtt") >= last_at_kill + 10
        ),
        "the backlog reaches the portal and the broker"
    );
    assert_eq!(terminate(&mut logger, Duration::from_secs(30)), 0, "SIGTERM stops cleanly");

    let stored = stored_ids(&db);
    assert!(stored.starts_with(&after_kill), "nothing committed before the kill is lost");
    let got = sorted(portal.stored());
    let want = sorted(expected(&db, &portal_marks(&db)));
    assert!(!want.is_empty());
    let mut keys: Vec<(&str, &str)> = got.iter().map(|(u, t, _)| (u.as_str(), t.as_str())).collect();
    keys.dedup();
    assert_eq!(keys.len(), got.len(), "no value reached the portal twice");
    assert_eq!(got.len(), want.len(), "every value of every reading up to the cursor, and none beyond it");
    assert_eq!(got, want);
    assert!(portal.refused().is_empty(), "the portal refused: {:?}", portal.refused());
    // The probes took turns in the store; the backlog went probe by probe in full batches.
    assert!(
        portal.accepted()[backlog..].iter().any(|b| records_in(b) == BATCH),
        "the backlog went in full batches: {:?}",
        portal.accepted()[backlog..].iter().map(|b| records_in(b)).collect::<Vec<_>>()
    );

    // MQTT: every stored reading up to its cursor, first copies in order.
    let mqtt_up_to = mark(&db, "mqtt");
    let received = subscriber.received();
    let (_, first) = ids_and_first_occurrences(&received);
    let published: Vec<i64> = stored.iter().copied().filter(|&id| id <= mqtt_up_to).collect();
    assert!(wait_until(|| ids_and_first_occurrences(&subscriber.received()).1.len() >= published.len()));
    assert!(first.iter().zip(&published).all(|(a, b)| a == b), "MQTT's first copies are the stored readings in order");

    for run in ["run1.err", "run1.out", "run2.err", "run2.out"] {
        let text = std::fs::read_to_string(logs.path().join(run)).unwrap();
        assert!(!text.contains(TOKEN), "{run} shows the token: {text}");
    }
    let bodies = portal.accepted();
    eprintln!(
        "    {} readings stored, {} requests accepted; bodies (first, a batch, last):",
        stored.len(),
        bodies.len()
    );
    for body in
        [bodies.first(), bodies.iter().find(|b| b.contains("\"timestamp\":[")), bodies.last()].into_iter().flatten()
    {
        eprintln!("    {body}");
    }
}

#[test]
fn a_refused_token_is_reported_once_retried_and_never_shown() {
    let portal = Portal::start(TOKEN, FEATURE);
    let mut station = Station::simulated("river", "200ms");
    station.toml += &section(&portal.url());
    let config = station.write_config();
    let logs = tempfile::tempdir().unwrap();
    let wrong = "wrong-token-of-another-site-77";
    let err = logs.path().join("run.err");
    let mut logger = start_logger(&config, wrong, &err);
    assert!(wait_until(|| portal.refused().len() >= 3), "the logger keeps trying");
    assert_eq!(terminate(&mut logger, Duration::from_secs(30)), 0);
    let text = std::fs::read_to_string(&err).unwrap();
    let out = std::fs::read_to_string(err.with_extension("out")).unwrap();
    assert!(!text.contains(wrong) && !out.contains(wrong), "{text}");
    assert!(!out.is_empty(), "readings are logged meanwhile");
    assert_eq!(text.matches("HTTP 403").count(), 1, "one line for the cause, not one per attempt: {text}");
    assert!(text.contains("token"), "{text}");
    assert!(portal.refused().iter().all(|(status, _)| *status == 403));
    assert!(portal.accepted().is_empty());
    assert!(portal_marks(&station.db).values().all(|&m| m == 0), "nothing marked sent");
    assert!(mark(&station.db, "mqtt") == 0 && !stored_ids(&station.db).is_empty());
}

/// Runs `log --check` on `toml` with the token in the environment.
fn check(dir: &Path, toml: &str, token: Option<&str>) -> yosemitech_tests::cli::Run {
    let path = dir.join("station.toml");
    std::fs::write(&path, toml).unwrap();
    let mut cmd = YOSEMITECH.command();
    cmd.args(["log", "--config", path.to_str().unwrap(), "--check"]);
    if let Some(token) = token {
        cmd.env("YOSEMITECH_MMW_TOKEN", token);
    }
    yosemitech_tests::cli::run_command(cmd, None)
}

#[test]
fn check_validates_the_section_located_and_never_shows_the_token() {
    let station = Station::simulated("river", "1m");
    let dir = tempfile::tempdir().unwrap();
    let good = format!("{}{}", station.toml, section("https://portal.example.org/api/data-stream/"));
    let run = check(dir.path(), &good, Some(TOKEN));
    let out = run.ok();
    assert!(out.contains(FEATURE) && out.contains("token from the environment (YOSEMITECH_MMW_TOKEN)"), "{out}");
    assert!(out.contains(&result_uuid(0, 0)) && out.contains("UTC+00:00"), "{out}");
    assert!(!out.contains(TOKEN) && !run.stderr.contains(TOKEN));

    // Each mistake, at its line and column.
    let line_of = |text: &str, needle: &str| text.lines().position(|l| l.contains(needle)).unwrap() + 1;
    let cases: Vec<(String, &str, &str)> = vec![
        (good.replace(FEATURE, "5a5a5a5a-1111-4222-8333-44445555666"), "sampling_feature = ", "is not a UUID"),
        (
            good.replace("[monitor_my_watershed.results.p1]", "[monitor_my_watershed.results.nope]"),
            "results.nope",
            "no probe is labelled `nope`",
        ),
        (
            good.replacen(&format!("\"{}\"", result_uuid(0, 0)), &format!("\"{}\"", result_uuid(1, 0)), 1),
            "",
            "is bound twice",
        ),
        (good.replacen(&format!("\"{}\"", result_uuid(1, 0)), "\"not-a-uuid\"", 1), "not-a-uuid", "is not a UUID"),
        (
            good.replace("https://portal.example.org", "http://portal.example.org").replace("allow_http = true\n", ""),
            "url = ",
            "use https://",
        ),
        (
            good.replace(
                "[monitor_my_watershed.results.p0]\n",
                "[monitor_my_watershed.results.p0]\nno_such_measurement = \"ffffffff-0000-4000-8000-000000000000\"\n",
            ),
            "no_such_measurement",
            "reads no `no_such_measurement`",
        ),
        (good.replace(&format!("batch = {BATCH}"), "batch = 0"), "batch = 0", "not 1 to 1000"),
        (
            good.replace("token = \"environment\"", "token = { file = \"/nonexistent/mmw.token\" }"),
            "token = ",
            "cannot read token file",
        ),
    ];
    for (toml, needle, says) in &cases {
        let run = check(dir.path(), toml, Some(TOKEN));
        let err = run.fails_with_hint(2);
        assert!(err.contains(says), "{says}: {err}");
        if !needle.is_empty() {
            let at = format!("station.toml:{}:", line_of(toml, needle));
            assert!(err.contains(&at), "{says} at {at}: {err}");
        }
        assert!(!err.contains(TOKEN) && !run.stdout.contains(TOKEN), "{err}");
    }
    // The token missing from the environment, or in a file others can read.
    let err = check(dir.path(), &good, None).fails_with_hint(2).to_owned();
    assert!(err.contains("YOSEMITECH_MMW_TOKEN is not set"), "{err}");
    let file = dir.path().join("mmw.token");
    std::fs::write(&file, format!("{TOKEN}\n")).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o644)).unwrap();
    let in_file = good.replace("token = \"environment\"", &format!("token = {{ file = \"{}\" }}", file.display()));
    let run = check(dir.path(), &in_file, None);
    let err = run.fails_with_hint(2);
    assert!(err.contains("chmod 600") && !err.contains(TOKEN), "{err}");
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).unwrap();
    let run = check(dir.path(), &in_file, None);
    assert!(run.ok().contains("token from the file") && !run.stdout.contains(TOKEN) && !run.stderr.contains(TOKEN));
}

#[test]
fn check_takes_a_derived_quantity_the_station_computes() {
    use yosemitech_spec::InputSource;
    let mut found = false;
    for sensor in spec().sensors.iter().filter(|s| !s.derived.is_empty() && !plan::measurements(s).is_empty()) {
        let all = plan::measurements(sensor);
        let planned = plan::plan(sensor, &all);
        let read = |c: &str, f: &str| planned.reads.iter().any(|r| r.command.name == c && r.fields.contains(&f));
        let Some(derived) = sensor.derived.iter().find(|d| {
            d.inputs.iter().all(|i| match &i.source {
                InputSource::Field { command, field } => read(command, field),
                InputSource::Station(_) => true,
            })
        }) else {
            continue;
        };
        found = true;
        let dir = tempfile::tempdir().unwrap();
        let toml = format!(
            "station = \"s\"\n[storage]\npath = \"s.sqlite\"\n[[bus]]\nname = \"a\"\nport = \"/dev/null\"\n\
             [[bus.probe]]\nlabel = \"d\"\nsensor = \"{}\"\naddress = {}\ninterval = \"1m\"\n\
             [monitor_my_watershed]\ntoken = \"environment\"\nsampling_feature = \"{FEATURE}\"\n\
             [monitor_my_watershed.results.d]\n{} = \"{}\"\n",
            sensor.name,
            sensor.default_address,
            derived.name,
            result_uuid(9, 9)
        );
        let run = check(dir.path(), &toml, Some(TOKEN));
        assert!(
            run.ok().contains(&format!("{} -> {}", derived.name, result_uuid(9, 9))),
            "{}: {}",
            sensor.name,
            run.stdout
        );
    }
    assert!(found, "the spec has a derived quantity a station computes");
}

//! The station logger through power cuts and a full store: killed at
//! random moments (SIGKILL, the last WAL frame torn), it restarts with the
//! store intact, every reading it announced still there, and says what
//! happened; a full store refuses readings with a log line while the
//! schedule goes on, and takes readings again once there is room.
#![cfg(unix)]

use crate::station;

use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Child, Stdio};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use station::{Station, command, terminate};
use yosemitech_sim::Rng;
use yosemitech_station::Store;
use yosemitech_tests::report;

/// Generous: a loaded 2-core machine is slow, and none of this is a timing test.
const PATIENCE: Duration = Duration::from_secs(60);

/// A running logger: its announced reading ids as they come, and its stderr at the end.
struct Logger {
    child: Child,
    ids: mpsc::Receiver<i64>,
    stdout: JoinHandle<Vec<i64>>,
    stderr: JoinHandle<String>,
}

impl Logger {
    fn start(config: &Path) -> Logger {
        let mut child = command()
            .args(["log", "--config", config.to_str().unwrap()])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (tx, ids) = mpsc::channel();
        let out = BufReader::new(child.stdout.take().unwrap());
        let stdout = std::thread::spawn(move || {
            let mut all = Vec::new();
            for line in out.lines().map_while(Result::ok) {
                let json: serde_json::Value = serde_json::from_str(&line).unwrap();
                let id = json["id"].as_i64().unwrap_or_else(|| panic!("no id: {line}"));
                all.push(id);
                let _ = tx.send(id);
            }
            all
        });
        let mut err = child.stderr.take().unwrap();
        let stderr = std::thread::spawn(move || {
            let mut text = String::new();
            let _ = err.read_to_string(&mut text);
            text
        });
        Logger { child, ids, stdout, stderr }
    }

    /// Waits for `n` more announced readings.
    fn announced(&self, n: usize) {
        for _ in 0..n {
            self.ids.recv_timeout(PATIENCE).expect("the logger announces readings");
        }
    }

    /// Kills it (SIGKILL: no cleanup at all); what it announced and printed.
    fn kill(mut self) -> (Vec<i64>, String) {
        self.child.kill().unwrap();
        let _ = self.child.wait();
        (self.stdout.join().unwrap(), self.stderr.join().unwrap())
    }

    /// Stops it as Ctrl-C does; what it announced and printed.
    fn stop(mut self) -> (Vec<i64>, String) {
        let code = terminate(&mut self.child, PATIENCE);
        let (ids, err) = (self.stdout.join().unwrap(), self.stderr.join().unwrap());
        assert_eq!(code, 0, "{err}");
        (ids, err)
    }
}

/// Appends a torn copy of the WAL's last frame: its header (valid salts)
/// and half its page, altered, as a power cut in the middle of writing a
/// frame leaves it. Returns false when the WAL holds no frame.
fn tear_last_wal_frame(db: &Path) -> bool {
    let wal = db.with_file_name(format!("{}-wal", db.file_name().unwrap().to_str().unwrap()));
    let Ok(bytes) = std::fs::read(&wal) else { return false };
    const HEADER: usize = 32;
    const FRAME_HEADER: usize = 24;
    if bytes.len() < HEADER {
        return false;
    }
    let page_size = u32::from_be_bytes(bytes[8..12].try_into().unwrap()) as usize;
    let frame = FRAME_HEADER + page_size;
    if bytes.len() < HEADER + frame {
        return false;
    }
    let last = &bytes[bytes.len() - frame..];
    let mut torn = last[..FRAME_HEADER + page_size / 2].to_vec();
    for b in &mut torn[FRAME_HEADER..] {
        *b ^= 0xA5;
    }
    let mut file = std::fs::OpenOptions::new().append(true).open(&wal).unwrap();
    std::io::Write::write_all(&mut file, &torn).unwrap();
    true
}

#[test]
fn killed_at_random_moments_the_store_keeps_every_announced_reading() {
    let station = Station::simulated("s", "100ms");
    let config = station.write_config();
    let mut rng = Rng::new(0x5EED_0FC0_FFEE);
    let (mut announced, mut torn) = (Vec::new(), 0);
    let mut previous_killed = false;
    for cycle in 0..5 {
        let logger = Logger::start(&config);
        // Kill somewhere in the middle of its work: after a few readings,
        // then a moment more (while the next batch may be in flight).
        logger.announced(1 + rng.below(4) as usize);
        std::thread::sleep(Duration::from_millis(rng.below(150)));
        let (ids, err) = logger.kill();
        assert_eq!(
            err.contains("did not stop cleanly"),
            previous_killed,
            "cycle {cycle}: the restart says whether the run before was cut short:\n{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        announced.extend(ids);
        previous_killed = true;
        if cycle % 2 == 1 && tear_last_wal_frame(&station.db) {
            torn += 1;
        }
    }
    // A last run, stopped cleanly, finds the store intact and says the
    // run before it was cut short; the one after it has nothing to say.
    let logger = Logger::start(&config);
    logger.announced(2);
    let (ids, err) = logger.stop();
    assert!(err.contains("did not stop cleanly") && err.contains("passed its integrity check"), "{err}");
    announced.extend(ids);
    let logger = Logger::start(&config);
    logger.announced(1);
    let (ids, err) = logger.stop();
    assert!(!err.contains("did not stop cleanly"), "{err}");
    announced.extend(ids);

    let store = Store::open(&station.db).unwrap();
    assert_eq!(store.check_integrity().unwrap(), Ok(()));
    for id in &announced {
        assert!(store.get(*id).unwrap().is_some(), "announced reading {id} is not in the store");
    }
    let mut sorted = announced.clone();
    sorted.sort_unstable();
    sorted.dedup();
    assert_eq!(sorted, announced, "ids only grow across restarts, none reused");
    report!(
        "power cuts: 5 kills ({torn} with a torn WAL frame), {} announced readings all kept, {} stored",
        announced.len(),
        store.count().unwrap()
    );
}

#[test]
fn a_full_store_refuses_readings_keeps_the_schedule_and_recovers() {
    let mut station = Station::simulated("s", "100ms");
    // Fill a store first, then cap it a little above its size.
    let config = station.write_config();
    let logger = Logger::start(&config);
    logger.announced(40);
    let _ = logger.stop();
    let size = Store::open(&station.db).unwrap().size().unwrap();
    let cap = (size + 8192).max(yosemitech_station::config::MIN_STORAGE_SIZE);
    station.toml = station.toml.replacen("[storage]\n", &format!("[storage]\nmax_size = \"{cap}B\"\n"), 1);
    let config = station.write_config();

    let logger = Logger::start(&config);
    let deadline = Instant::now() + PATIENCE;
    // Full: the logger refuses and goes on (its stderr says so once the store
    // is full; requests keep reaching the probes).
    let before_full = station.requests();
    let full_seen = loop {
        std::thread::sleep(Duration::from_millis(200));
        if Instant::now() > deadline {
            break false;
        }
        // Refusals are visible as announcements stopping while requests go on.
        let quiet_from = station.requests();
        let mut announced = 0;
        while logger.ids.recv_timeout(Duration::from_millis(800)).is_ok() {
            announced += 1;
        }
        if announced == 0 && station.requests() > quiet_from {
            break true;
        }
    };
    assert!(full_seen, "the store never filled (or the schedule stopped)");
    assert!(station.requests() > before_full);
    // Room returns: the oldest readings are deleted (as an operator would after exporting them).
    let mut store = Store::open(&station.db).unwrap();
    let deleted_up_to = store.last_id().unwrap() / 2;
    let freed = store.delete_up_to(deleted_up_to).unwrap();
    assert!(freed > 0);
    drop(store);
    logger.announced(3);
    let (ids, err) = logger.stop();
    assert!(err.contains("the store is full") && err.contains("readings are refused"), "{err}");
    assert!(err.contains("the store has room again"), "{err}");
    let store = Store::open(&station.db).unwrap();
    assert_eq!(store.check_integrity().unwrap(), Ok(()));
    let kept: Vec<&i64> = ids.iter().filter(|&&id| id > deleted_up_to).collect();
    assert!(kept.len() >= 3, "readings announced after the room returned: {ids:?}");
    for id in kept {
        assert!(store.get(*id).unwrap().is_some(), "announced reading {id} is not in the store");
    }
    report!("full store: refused while full, {} readings announced in the run, {freed} old ones deleted", ids.len());
}

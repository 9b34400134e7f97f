//! The station both logger tests run (`cli_station`, `cli_station_mqtt`):
//! two spec sensors with measurements on one simulated pty bus, and the
//! station file that logs them into a SQLite file in a temporary directory.
//! Each probe sits at an address of its sensor's range; where the two
//! sensors' serial settings differ, the bus states the first one's line for
//! both (as a mixed RS-485 bus must; a pty carries any).

use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::sync::Arc;
use std::time::Duration;

use yosemitech_rtu::Parity;
use yosemitech_sim::{Bus, ServeConfig, Server, Simulator, serve_pty};
use yosemitech_spec::Sensor;
use yosemitech_station::{Store, StoredReading, plan};
use yosemitech_tests::cli::{Binary, wait};
use yosemitech_tests::spec;

/// The binary under test.
pub const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// The binary, with a clean environment.
pub fn command() -> std::process::Command {
    YOSEMITECH.command()
}

/// A simulated bus and the station file that logs it.
pub struct Station {
    /// Holds the store and the station file; removed on drop.
    dir: tempfile::TempDir,
    /// The simulated bus; serves until dropped.
    bus: Server<Bus>,
    /// The probes' addresses, in the order of their `p0`, `p1`, ... labels.
    #[allow(dead_code)] // only the tests of a probe going silent use it
    pub addresses: Vec<u8>,
    /// The SQLite store the station file names.
    pub db: PathBuf,
    /// The station file's text: `station`, `[storage]`, one `[[bus]]` on
    /// the pty, one probe per simulated sensor (at [`addresses`]) polled
    /// every `interval`, no procedures. Callers append their own sections
    /// and write it with [`Station::write_config`].
    pub toml: String,
}

impl Station {
    /// Two spec sensors with measurements, simulated at [`addresses`],
    /// logged by station `name` every `interval` (a station-file duration).
    #[allow(dead_code)] // the test with three probes uses simulated_probes
    pub fn simulated(name: &str, interval: &str) -> Station {
        Self::simulated_probes(name, interval, 2)
    }

    /// [`Station::simulated`] with `count` spec sensors (each a probe `p<i>`),
    /// its probe sections last in [`Station::toml`].
    pub fn simulated_probes(name: &str, interval: &str, count: usize) -> Station {
        let dir = tempfile::tempdir().unwrap();
        let sensors: Vec<Sensor> =
            spec().sensors.iter().filter(|&s| !plan::measurements(s).is_empty()).take(count).cloned().collect();
        assert_eq!(sensors.len(), count, "the spec has {count} sensors with measurements");
        let addresses = addresses(&sensors);
        let bus = sensors
            .iter()
            .zip(&addresses)
            .fold(Bus::new(), |bus, (s, &a)| bus.with(Simulator::new(Arc::new(s.clone())).with_address(a)));
        let server = serve_pty(bus, ServeConfig::default()).unwrap();
        let db = dir.path().join("station.sqlite");
        let mut toml = format!(
            "station = \"{name}\"\n[storage]\npath = \"{}\"\n[[bus]]\nname = \"a\"\nport = \"{}\"\n",
            db.display(),
            server.tty_path().unwrap()
        );
        // Sensors whose specs disagree on the line need the bus to say it (a pty carries any).
        if let Some(first) = sensors.first()
            && sensors.iter().any(|s| s.serial != first.serial)
        {
            let parity = match first.serial.format.parity {
                Parity::None => "none",
                Parity::Even => "even",
                Parity::Odd => "odd",
            };
            toml += &format!("baud = {}\nparity = \"{parity}\"\n", first.serial.baud);
        }
        for (i, (s, address)) in sensors.iter().zip(&addresses).enumerate() {
            toml += &format!(
                "[[bus.probe]]\nlabel = \"p{i}\"\nsensor = \"{}\"\naddress = {address}\ninterval = \"{interval}\"\nprocedure = false\n",
                s.name
            );
        }
        Station { dir, bus: server, db, addresses, toml }
    }

    /// Makes the probe at `address` stop answering (every reply dropped).
    #[allow(dead_code)] // only the tests of a probe going silent use it
    pub fn mute(&self, address: u8) {
        let mut bus = self.bus.device();
        let device = bus.device_mut(address).expect("a simulated probe at that address");
        device.set_faults(yosemitech_sim::FaultConfig { drop: 1.0, ..yosemitech_sim::FaultConfig::none() });
    }

    /// Requests the simulated probes have answered or ignored so far.
    #[allow(dead_code)] // not every test binary of this module asks
    pub fn requests(&self) -> u64 {
        self.bus.device().devices().iter().map(|d| d.stats().requests).sum()
    }

    /// Writes [`Station::toml`] beside the store; returns its path.
    pub fn write_config(&self) -> PathBuf {
        let config = self.dir.path().join("station.toml");
        std::fs::write(&config, &self.toml).unwrap();
        config
    }
}

/// An address for each of `sensors` on one bus: its factory address, or
/// where another probe has that, the first free one of its range.
pub fn addresses(sensors: &[Sensor]) -> Vec<u8> {
    let mut taken = Vec::new();
    for s in sensors {
        let free = std::iter::once(s.default_address)
            .chain(s.min_address.max(1)..=s.max_address.min(247))
            .find(|a| !taken.contains(a))
            .expect("a free address in the sensor's range");
        taken.push(free);
    }
    taken
}

/// Sends SIGTERM to `child` and waits up to `limit` for it; its exit code.
pub fn terminate(child: &mut Child, limit: Duration) -> i32 {
    let status = std::process::Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    assert!(status.success(), "kill -TERM {}", child.id());
    wait(child, limit)
}

/// Starts `yosemitech log` on the station file `config`, its output discarded.
#[allow(dead_code)] // the tests that read the logger's output start it themselves
pub fn start_logger(config: &Path) -> Child {
    command()
        .args(["log", "--config", config.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// Every reading of the store at `db`, in id order.
#[allow(dead_code)] // not every test binary of this module reads the store
pub fn stored(db: &Path) -> Vec<StoredReading> {
    Store::open(db)
        .unwrap()
        .range(std::time::UNIX_EPOCH, std::time::SystemTime::now() + Duration::from_secs(60))
        .unwrap()
}

/// The ids of every reading of the store at `db`, ascending.
#[allow(dead_code)] // not every test binary of this module reads the store
pub fn stored_ids(db: &Path) -> Vec<i64> {
    stored(db).iter().map(|s| s.id).collect()
}

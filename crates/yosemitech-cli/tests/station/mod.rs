//! The station both logger tests run (`cli_station`, `cli_station_mqtt`):
//! two spec sensors with measurements on one simulated pty bus, and the
//! station file that logs them into a SQLite file in a temporary directory.

use std::path::PathBuf;
use std::process::Child;
use std::sync::Arc;
use std::time::Duration;

use yosemitech_sim::{Bus, ServeConfig, Server, Simulator, serve_pty};
use yosemitech_station::plan;
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
    _bus: Server<Bus>,
    /// The SQLite store the station file names.
    pub db: PathBuf,
    /// The station file's text: `station`, `[storage]`, one `[[bus]]` on
    /// the pty, one probe per simulated sensor (addresses 1, 2...) polled
    /// every `interval`, no procedures. Callers append their own sections
    /// and write it with [`Station::write_config`].
    pub toml: String,
}

impl Station {
    /// Two spec sensors with measurements, simulated at addresses 1 and 2,
    /// logged by station `name` every `interval` (a station-file duration).
    pub fn simulated(name: &str, interval: &str) -> Station {
        let dir = tempfile::tempdir().unwrap();
        let sensors: Vec<_> =
            spec().sensors.iter().filter(|&s| !plan::measurements(s).is_empty()).take(2).cloned().collect();
        let bus = sensors
            .iter()
            .enumerate()
            .fold(Bus::new(), |bus, (i, s)| bus.with(Simulator::new(Arc::new(s.clone())).with_address(i as u8 + 1)));
        let server = serve_pty(bus, ServeConfig::default()).unwrap();
        let db = dir.path().join("station.sqlite");
        let mut toml = format!(
            "station = \"{name}\"\n[storage]\npath = \"{}\"\n[[bus]]\nname = \"a\"\nport = \"{}\"\n",
            db.display(),
            server.tty_path().unwrap()
        );
        // Sensors whose specs disagree on the line need the bus to say it (a pty carries any).
        if sensors.iter().any(|s| s.serial != sensors[0].serial) {
            toml += "baud = 9600\nparity = \"none\"\n";
        }
        for (i, s) in sensors.iter().enumerate() {
            toml += &format!(
                "[[bus.probe]]\nlabel = \"p{i}\"\nsensor = \"{}\"\naddress = {}\ninterval = \"{interval}\"\nprocedure = false\n",
                s.name,
                i + 1
            );
        }
        Station { dir, _bus: server, db, toml }
    }

    /// Writes [`Station::toml`] beside the store; returns its path.
    pub fn write_config(&self) -> PathBuf {
        let config = self.dir.path().join("station.toml");
        std::fs::write(&config, &self.toml).unwrap();
        config
    }
}

/// Sends SIGTERM to `child` and waits up to `limit` for it; its exit code.
pub fn terminate(child: &mut Child, limit: Duration) -> i32 {
    let status = std::process::Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    assert!(status.success(), "kill -TERM {}", child.id());
    wait(child, limit)
}

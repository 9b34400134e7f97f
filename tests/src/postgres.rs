//! Debian's PostgreSQL for the tests: a cluster initialised in a scratch
//! directory and served on a Unix socket only (no TCP port to collide
//! with), started by the test and stopped when dropped.
//!
//! Found in `/usr/lib/postgresql/<version>/bin` (the newest) or on PATH.
//! Without it a test skips with a note, unless `YOSEMITECH_REQUIRE_POSTGRES=1`
//! (`.ci/run`), which makes a missing server a failure. PostgreSQL refuses
//! to run as root: as root, the cluster belongs to the `postgres` user
//! Debian's package creates, and the server runs as that user.

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The environment variable that makes a missing PostgreSQL a failure.
pub const REQUIRE_POSTGRES: &str = "YOSEMITECH_REQUIRE_POSTGRES";

/// A running cluster.
pub struct Postgres {
    dir: PathBuf,
    server: Child,
}

/// The directory of `initdb` and `postgres`, if PostgreSQL is installed.
pub fn binaries() -> Option<PathBuf> {
    let mut versions: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .into_iter()
        .flatten()
        .filter_map(|entry| {
            let entry = entry.ok()?;
            let version = entry.file_name().to_str()?.parse().ok()?;
            let bin = entry.path().join("bin");
            bin.join("postgres").exists().then_some((version, bin))
        })
        .collect();
    versions.sort();
    if let Some((_, bin)) = versions.pop() {
        return Some(bin);
    }
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).find(|dir| dir.join("initdb").exists() && dir.join("postgres").exists())
}

/// The `postgres` user's uid and gid, from /etc/passwd.
fn postgres_user() -> Option<(u32, u32)> {
    let passwd = std::fs::read_to_string("/etc/passwd").ok()?;
    passwd.lines().find_map(|line| {
        let fields: Vec<&str> = line.split(':').collect();
        (fields.first() == Some(&"postgres"))
            .then(|| Some((fields.get(2)?.parse().ok()?, fields.get(3)?.parse().ok()?)))?
    })
}

/// Whether this process runs as root.
fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("Uid:")).map(|l| l.split_whitespace().nth(1) == Some("0")))
        .unwrap_or(false)
}

impl Postgres {
    /// Starts a cluster, or says why it cannot and returns `None` (a
    /// failure under [`REQUIRE_POSTGRES`]). `settings` are server settings
    /// (`fsync=off` for tests that do not crash the server, say).
    pub fn start(name: &str, settings: &[(&str, &str)]) -> Option<Postgres> {
        let required = std::env::var(REQUIRE_POSTGRES).is_ok_and(|v| v == "1");
        let Some(bin) = binaries() else {
            assert!(!required, "{REQUIRE_POSTGRES}=1 but PostgreSQL is not installed (apt-get install postgresql)");
            eprintln!("    skipped: PostgreSQL is not installed (apt-get install postgresql; .ci/run requires it)");
            return None;
        };
        let user = if is_root() {
            let user = postgres_user();
            assert!(user.is_some() || !required, "running as root, and no `postgres` user to run PostgreSQL as");
            if user.is_none() {
                eprintln!("    skipped: running as root, and no `postgres` user to run PostgreSQL as");
                return None;
            }
            user
        } else {
            None
        };
        let dir = crate::scratch_dir(&format!("postgres-{name}"));
        let data = dir.join("data");
        let as_user = |command: &mut Command| {
            if let Some((uid, gid)) = user {
                command.uid(uid).gid(gid);
            }
        };
        if let Some((uid, gid)) = user {
            std::os::unix::fs::chown(&dir, Some(uid), Some(gid)).expect("the cluster's directory is given to postgres");
        }
        let mut initdb = Command::new(bin.join("initdb"));
        initdb.args(["-D", path_text(&data), "-U", "postgres", "-A", "trust", "-E", "UTF8", "--locale=C", "--no-sync"]);
        as_user(&mut initdb);
        let out = initdb.output().expect("initdb runs");
        assert!(out.status.success(), "initdb failed: {}", String::from_utf8_lossy(&out.stderr));
        let mut server = Command::new(bin.join("postgres"));
        server.args(["-D", path_text(&data), "-k", path_text(&dir), "-c", "listen_addresses="]);
        for (key, value) in settings {
            server.arg("-c").arg(format!("{key}={value}"));
        }
        as_user(&mut server);
        let log = std::fs::File::create(dir.join("server.log")).expect("the server's log file");
        let server = server.stdout(Stdio::null()).stderr(log).spawn().expect("postgres starts");
        let cluster = Postgres { dir, server };
        let deadline = Instant::now() + crate::broker::DEADLINE;
        while cluster.config("postgres").connect(postgres::NoTls).is_err() {
            assert!(Instant::now() < deadline, "PostgreSQL did not accept connections: {}", cluster.log());
            std::thread::sleep(Duration::from_millis(100));
        }
        Some(cluster)
    }

    /// A connection configuration for database `dbname`, as user `postgres`.
    pub fn config(&self, dbname: &str) -> postgres::Config {
        let mut config = postgres::Config::new();
        config.host_path(&self.dir).user("postgres").dbname(dbname);
        config
    }

    /// The libpq connection string of database `dbname` (what `--postgres` takes).
    pub fn conninfo(&self, dbname: &str) -> String {
        format!("host={} user=postgres dbname={dbname}", self.dir.display())
    }

    /// Creates database `dbname`; returns its configuration.
    pub fn create_database(&self, dbname: &str) -> postgres::Config {
        let mut client = self.config("postgres").connect(postgres::NoTls).expect("a connection to the cluster");
        client.batch_execute(&format!("CREATE DATABASE \"{dbname}\"")).expect("the database is created");
        self.config(dbname)
    }

    /// The server's log so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("server.log")).unwrap_or_default()
    }

    /// Where the cluster lives.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for Postgres {
    fn drop(&mut self) {
        // SIGINT: PostgreSQL's fast shutdown.
        let _ = nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(i32::try_from(self.server.id()).unwrap_or(i32::MAX)),
            nix::sys::signal::Signal::SIGINT,
        );
        let deadline = Instant::now() + Duration::from_secs(30);
        while Instant::now() < deadline {
            if matches!(self.server.try_wait(), Ok(Some(_))) {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.server.kill();
        let _ = self.server.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn path_text(path: &Path) -> &str {
    path.to_str().expect("scratch paths are UTF-8")
}

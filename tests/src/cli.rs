//! The CLI tests' kit: run a built binary ([`Binary`]) with a watchdog, and
//! serve simulated probes on pseudo-terminals in-process.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use yosemitech_sim::{ServeConfig, Server, Simulator, serve_pty};
use yosemitech_spec::Sensor;

use crate::{sensor, spec};

/// Longest any one run of the binary may take before the test fails.
pub const WATCHDOG: Duration = Duration::from_secs(60);

/// The fixture sensor's spec directory (a made-up DO probe, 19200 8E1).
pub fn fixture_spec_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/do-probe/spec"))
}

/// What a run of the binary did.
#[derive(Debug)]
pub struct Run {
    /// Exit code (-1 if killed by a signal).
    pub code: i32,
    /// Standard output.
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

impl Run {
    /// Asserts success and returns stdout.
    #[track_caller]
    pub fn ok(&self) -> &str {
        assert_eq!(self.code, 0, "expected success\nstdout:\n{}\nstderr:\n{}", self.stdout, self.stderr);
        self.assert_no_panic();
        &self.stdout
    }

    /// Asserts a clean failure with `code`: an `error:` line first, a
    /// `hint:` line, no panic or backtrace. Returns stderr.
    #[track_caller]
    pub fn fails(&self, code: i32) -> &str {
        assert_eq!(self.code, code, "expected exit {code}\nstdout:\n{}\nstderr:\n{}", self.stdout, self.stderr);
        assert!(self.stderr.contains("error:"), "no `error:` line:\n{}", self.stderr);
        self.assert_no_panic();
        &self.stderr
    }

    /// Like [`Run::fails`], and the error has a `hint:` line.
    #[track_caller]
    pub fn fails_with_hint(&self, code: i32) -> &str {
        self.fails(code);
        assert!(self.stderr.lines().any(|l| l.starts_with("hint: ")), "no `hint:` line:\n{}", self.stderr);
        &self.stderr
    }

    #[track_caller]
    fn assert_no_panic(&self) {
        for bad in ["panicked", "RUST_BACKTRACE", "stack backtrace", "internal error"] {
            assert!(!self.stderr.contains(bad), "`{bad}` in stderr:\n{}", self.stderr);
            assert!(!self.stdout.contains(bad), "`{bad}` in stdout:\n{}", self.stdout);
        }
    }

    /// Stdout parsed as JSON.
    #[track_caller]
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_str(self.ok()).unwrap_or_else(|e| panic!("not JSON ({e}):\n{}", self.stdout))
    }
}

/// A built binary under test: a test names it once with
/// `Binary(env!("CARGO_BIN_EXE_<name>"))`.
#[derive(Debug, Clone, Copy)]
pub struct Binary(pub &'static str);

impl Binary {
    /// The binary, with a clean environment for the variables it reads.
    pub fn command(self) -> Command {
        let mut cmd = Command::new(self.0);
        cmd.env_remove("YOSEMITECH_PORT")
            .env_remove("YOSEMITECH_BAUD")
            .env_remove("RUST_LOG")
            .env_remove("YOSEMITECH_MMW_TOKEN")
            .env_remove("RUST_BACKTRACE")
            // Calibrations record their history in the user's data directory: never the
            // real one, nor one shared with another checkout's build (its schema may differ).
            .env("XDG_DATA_HOME", self.data_home())
            .current_dir(std::env::temp_dir());
        cmd
    }

    /// The user data directory the binary's runs get: beside the binary, in
    /// its own target directory.
    pub fn data_home(self) -> PathBuf {
        let binary = std::path::Path::new(self.0);
        binary.parent().unwrap_or(binary).join("yosemitech-tests-data")
    }

    /// Runs the binary with `args`, stdin empty.
    pub fn run(self, args: &[&str]) -> Run {
        let mut cmd = self.command();
        cmd.args(args);
        run_command(cmd, None)
    }

    /// Starts `simulate ARGS` and returns it with the endpoint it printed
    /// first (a pty path, or the address it listens on).
    pub fn simulate(self, args: &[&str]) -> (Child, String) {
        let mut child = self
            .command()
            .arg("simulate")
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the simulator starts");
        let mut line = String::new();
        let stdout = child.stdout.take().expect("stdout is piped");
        std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line)
            .expect("the simulator prints its endpoint");
        (child, line.trim().to_owned())
    }

    /// Runs the binary with `args` and `input` on stdin.
    pub fn run_with_input(self, args: &[&str], input: &str) -> Run {
        let mut cmd = self.command();
        cmd.args(args);
        run_command(cmd, Some(input))
    }
}

/// Runs `cmd` with `input` on stdin (none: stdin is /dev/null) under the watchdog.
pub fn run_command(mut cmd: Command, input: Option<&str>) -> Run {
    cmd.stdin(if input.is_some() { Stdio::piped() } else { Stdio::null() })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = cmd.spawn().expect("the binary starts");
    if let Some(input) = input {
        let mut stdin = child.stdin.take().expect("stdin is piped");
        // The binary may exit before reading it all (a refusal): ignore a closed pipe.
        let _ = stdin.write_all(input.as_bytes());
    }
    let stdout = drain(child.stdout.take().expect("stdout is piped"));
    let stderr = drain(child.stderr.take().expect("stderr is piped"));
    let code = wait(&mut child, WATCHDOG);
    Run { code, stdout: stdout.join().expect("stdout reader"), stderr: stderr.join().expect("stderr reader") }
}

fn drain(mut pipe: impl Read + Send + 'static) -> thread::JoinHandle<String> {
    thread::spawn(move || {
        let mut bytes = Vec::new();
        let _ = pipe.read_to_end(&mut bytes);
        String::from_utf8_lossy(&bytes).into_owned()
    })
}

/// Stops a running binary as Ctrl-C does, asserts it exits cleanly and
/// returns what it wrote to stderr (piped, as [`Binary::simulate`] does).
pub fn interrupt(mut child: Child) -> String {
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill runs");
    assert!(status.success(), "the process could be signalled");
    assert_eq!(wait(&mut child, Duration::from_secs(10)), 0, "it stops cleanly on Ctrl-C");
    let mut err = String::new();
    if let Some(mut stderr) = child.stderr.take() {
        let _ = stderr.read_to_string(&mut err);
    }
    err
}

/// Waits for `child`, killing it (and failing) after `limit`.
pub fn wait(child: &mut Child, limit: Duration) -> i32 {
    let deadline = Instant::now() + limit;
    loop {
        if let Some(status) = child.try_wait().expect("the child can be waited for") {
            return status.code().unwrap_or(-1);
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("the binary ran longer than {limit:?}");
        }
        thread::sleep(Duration::from_millis(10));
    }
}

/// A simulated probe on a pseudo-terminal.
pub struct Sim<D> {
    /// The server (the device is reachable through it).
    pub server: Server<D>,
    /// The pty path to pass as `--port`.
    pub path: String,
}

/// Serves `device` on a new pty.
pub fn serve<D: yosemitech_sim::FrameHandler + Send + 'static>(device: D) -> Sim<D> {
    let server = serve_pty(device, ServeConfig::default()).expect("a pty can be created");
    let path = server.tty_path().expect("a pty path").to_owned();
    Sim { server, path }
}

/// A simulated `sensor` at `address` on a pty.
pub fn sim(sensor_name: &str, address: u8) -> Sim<Simulator> {
    serve(Simulator::new(sensor(sensor_name)).with_address(address))
}

/// The number after `label` on the line that starts (after spaces) with it.
pub fn number_after(text: &str, label: &str) -> f64 {
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with(label))
        .unwrap_or_else(|| panic!("no line starting with `{label}` in:\n{text}"));
    line.trim_start()[label.len()..]
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no number after `{label}` in `{line}`"))
}

/// Every sensor of the spec with at least one coefficient block.
pub fn sensors_with_coefficients() -> Vec<Sensor> {
    spec().sensors.iter().filter(|s| !s.coefficient_blocks().is_empty()).cloned().collect()
}

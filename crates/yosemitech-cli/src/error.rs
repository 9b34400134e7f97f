//! Errors as the user sees them: one `error:` line, optional detail lines,
//! one `hint:` line, and an exit code.

use std::fmt;
use std::io;
use std::process::ExitCode;
use std::time::Duration;

use yosemitech_rtu::{Error as RtuError, FrameError, Hex};

/// What kind of failure, which decides the exit code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The command line or an input file is wrong: exit 2.
    Usage,
    /// The device, the port or the protocol failed: exit 1.
    Device,
    /// Stdout was closed by the reader (`| head`): exit 0, say nothing.
    Closed,
}

/// An error to report and exit with.
#[derive(Debug)]
pub struct CliError {
    /// Kind, for the exit code.
    pub kind: Kind,
    /// The `error:` line.
    pub message: String,
    /// Indented lines after it (candidates, diagnostics).
    pub details: Vec<String>,
    /// The `hint:` line.
    pub hint: Option<String>,
}

/// Result of the CLI's functions.
pub type Result<T, E = CliError> = std::result::Result<T, E>;

impl CliError {
    /// A usage error (exit 2).
    pub fn usage(message: impl Into<String>) -> Self {
        Self { kind: Kind::Usage, message: message.into(), details: Vec::new(), hint: None }
    }

    /// A device or protocol error (exit 1).
    pub fn device(message: impl Into<String>) -> Self {
        Self { kind: Kind::Device, message: message.into(), details: Vec::new(), hint: None }
    }

    /// Adds the hint line.
    #[must_use]
    pub fn hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }

    /// Adds a detail line.
    #[must_use]
    pub fn detail(mut self, line: impl Into<String>) -> Self {
        self.details.push(line.into());
        self
    }

    /// The process exit code.
    pub fn exit_code(&self) -> ExitCode {
        match self.kind {
            Kind::Usage => ExitCode::from(2),
            Kind::Device => ExitCode::from(1),
            Kind::Closed => ExitCode::SUCCESS,
        }
    }

    /// Prints the error to stderr (never panics, even if stderr is closed).
    pub fn report(&self) {
        if self.kind == Kind::Closed {
            return;
        }
        use std::io::Write as _;
        let mut err = io::stderr().lock();
        let _ = writeln!(err, "error: {}", self.message);
        for line in &self.details {
            let _ = writeln!(err, "  {line}");
        }
        if let Some(hint) = &self.hint {
            let _ = writeln!(err, "hint: {hint}");
        }
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

/// Writing to stdout failed: a closed pipe ends the program quietly.
impl From<io::Error> for CliError {
    fn from(e: io::Error) -> Self {
        if e.kind() == io::ErrorKind::BrokenPipe {
            Self { kind: Kind::Closed, message: String::new(), details: Vec::new(), hint: None }
        } else {
            Self::device(format!("cannot write the output: {e}"))
        }
    }
}

/// Where a request went, for error messages.
#[derive(Debug, Clone)]
pub struct Context {
    /// The port as given.
    pub port: String,
    /// The slave address.
    pub slave: u8,
    /// What was asked (a command name).
    pub what: String,
    /// The reply timeout.
    pub timeout: Duration,
}

/// Shows a duration the way the user types it (`100ms`, `1s`, `1.5s`).
pub fn show_duration(d: Duration) -> String {
    let ms = d.as_millis();
    if ms < 1000 || !ms.is_multiple_of(100) {
        format!("{ms}ms")
    } else if ms.is_multiple_of(1000) {
        format!("{}s", ms / 1000)
    } else {
        format!("{}s", d.as_secs_f64())
    }
}

/// A failed request in a few words, for a log's error column; `reply` is
/// what the client received (`Client::last_reply`).
pub fn short(e: &RtuError, reply: &[u8]) -> String {
    yosemitech_ops::failure_text(e, reply)
}

/// A failed request, with what it was, where it went and what to try;
/// `reply` is what the client received (`Client::last_reply`).
pub fn request_failed(e: &RtuError, reply: &[u8], ctx: &Context) -> CliError {
    let Context { port, slave, what, timeout } = ctx;
    let scan = format!("`yosemitech scan --port {}` identifies the probes on the bus", crate::shell::quote(port));
    let raw = Hex(reply);
    match e {
        RtuError::Timeout { received: 0, .. } => CliError::device(format!(
            "no reply to {what} from address {slave} on {port} within {}",
            show_duration(*timeout)
        ))
        .hint(format!(
            "check power, wiring (A/B), the baud rate (--baud), the address (--address) and the sensor type (a probe does not answer a command it lacks); {scan}"
        )),
        RtuError::Timeout { received, .. } => CliError::device(format!(
            "incomplete reply to {what} from address {slave} on {port}: {received} bytes in {} ({raw})",
            show_duration(*timeout)
        ))
        .hint("a wrong baud rate or line noise; -v shows the frames, --timeout allows more time"),
        RtuError::Frame { error: FrameError::Exception { code, .. } } => CliError::device(format!(
            "address {slave} refused {what} with Modbus exception {code} (reply {raw})"
        ))
        .hint(match code.to_u8() {
            1..=3 => "the probe does not support this command: is it the sensor type you named? (`yosemitech scan` shows which kinds answer)",
            6 => "the probe is busy: try again in a moment",
            _ => "the probe could not carry out the request",
        }),
        RtuError::Frame { error: error @ FrameError::Crc { .. } } => {
            CliError::device(format!("corrupt reply to {what} from address {slave}: {error} (reply {raw})"))
                .hint("line noise, a missing RS-485 termination or a wrong baud rate; -v shows the frames")
        }
        RtuError::Frame { error: error @ FrameError::WrongSlave { .. } } => {
            CliError::device(format!("unexpected reply to {what}: {error} (reply {raw})"))
                .hint(format!("two devices may share an address; {scan}"))
        }
        RtuError::Frame { error } => {
            CliError::device(format!("bad reply to {what} from address {slave}: {error} (reply {raw})"))
                .hint("the device may not be the sensor type you named; -v shows the frames")
        }
        RtuError::Encode(error) => CliError::usage(format!("cannot build the {what} request: {error}")),
        RtuError::Request(error) => CliError::usage(format!("invalid {what} request: {error}")),
        RtuError::Io(error) => CliError::device(format!("{port}: {error}"))
            .hint("the port went away or failed: is the adapter still plugged in?"),
        other => CliError::device(format!("{what} failed: {other}")),
    }
}

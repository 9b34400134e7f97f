//! One bus's master: the transport opened from the station file, and
//! requests through the spec interpreter (`yosemitech_ops::transaction`)
//! with the client's retries, counted.

use std::collections::BTreeMap;
use std::time::Duration;

use yosemitech_rtu::{Client, ClientConfig, RetryPolicy, SerialConfig, SerialTransport, TcpTransport, Transport};
use yosemitech_spec::{CommandSpec, Values};

use crate::config::{Gap, Link};

/// A client on any transport.
pub type Master = Client<Box<dyn Transport + Send>>;

/// Opens `link` with `timeout` per attempt and `gap` before each request.
/// The client retries as [`RetryPolicy::default`] says, as many times as
/// each [`transact`] asks.
///
/// # Errors
///
/// The port or the gateway cannot be opened.
pub fn open(link: &Link, timeout: Duration, gap: Gap) -> std::io::Result<Master> {
    let transport: Box<dyn Transport + Send> = match link {
        Link::Serial { port, serial } => {
            Box::new(SerialTransport::open(&SerialConfig::with_settings(port.as_str(), *serial))?)
        }
        Link::Tcp { address } => {
            Box::new(TcpTransport::connect(address.as_str(), timeout.max(Duration::from_millis(500)))?)
        }
    };
    let mut config = ClientConfig { timeout, retry: RetryPolicy::default(), ..ClientConfig::default() };
    match gap {
        Gap::Default => {}
        Gap::T35 => config.min_inter_frame_delay = Duration::ZERO,
        Gap::Fixed(d) => config.inter_frame_delay = Some(d),
    }
    Ok(Client::with_config(transport, config))
}

/// What one request came to.
#[derive(Debug)]
pub struct Outcome {
    /// The decoded values, or why there are none.
    pub result: Result<Values, Failure>,
    /// Attempts after the first.
    pub retries: u32,
}

/// Why a request failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Failure {
    /// The command.
    pub command: String,
    /// The error, as text.
    pub message: String,
    /// No reply came in time.
    pub timeout: bool,
}

/// Sends `command` (no values) to `slave`, the client repeating retryable
/// failures (timeouts, corrupt and foreign frames) up to `retries` times,
/// and decodes the reply through the spec interpreter.
pub fn transact(master: &mut Master, command: &CommandSpec, slave: u8, retries: u32) -> Outcome {
    master.config_mut().retry.retries = retries;
    let result = yosemitech_ops::call(master, command, yosemitech_ops::target(command, slave), &BTreeMap::new());
    let retries = master.core().retries();
    let result = result.map_err(|e| Failure {
        command: command.name.clone(),
        timeout: e.bus_error().is_some_and(yosemitech_rtu::Error::is_timeout),
        message: e.to_string(),
    });
    Outcome { result, retries }
}

//! Opening a bus: a serial port (an RS-485 adapter) or `tcp://HOST:PORT`
//! (an RTU-over-TCP gateway, or `yosemitech simulate --tcp`).

use std::io;
use std::time::Duration;

use yosemitech_rtu::{Client, ClientConfig, LineSettings, SerialConfig, SerialTransport, TcpTransport, Transport};

/// A client on any transport.
pub type AnyClient = Client<Box<dyn Transport + Send>>;

/// Opens `port` (`tcp://HOST:PORT` or a serial device at `serial`'s
/// settings) for a client with `config`. A gateway is given at least half a
/// second to accept the connection.
///
/// # Errors
///
/// The port or the gateway cannot be opened.
pub fn open(port: &str, serial: LineSettings, config: ClientConfig) -> io::Result<AnyClient> {
    let transport: Box<dyn Transport + Send> = match port.strip_prefix("tcp://") {
        Some(address) => Box::new(TcpTransport::connect(address, config.timeout.max(Duration::from_millis(500)))?),
        None => Box::new(SerialTransport::open(&SerialConfig::with_settings(port.to_owned(), serial))?),
    };
    Ok(Client::with_config(transport, config))
}

//! Opening the bus: a serial port, or `tcp://HOST:PORT` for an RTU-over-TCP
//! gateway, with the client's timeout and retries from the command line.

use std::io;
use std::path::Path;
use std::time::Duration;

use clap::Args;
pub use yosemitech_ops::bus::AnyClient;
use yosemitech_rtu::{ClientConfig, LineSettings, RetryPolicy};

use crate::error::{CliError, Context, Result};
use crate::format::parse_duration;

/// The port options every device command takes.
#[derive(Args, Debug, Clone, Default)]
pub struct PortArgs {
    /// Serial port of the RS-485 adapter (/dev/ttyUSB0, COM3), or
    /// tcp://HOST:PORT for an RTU-over-TCP gateway (or `yosemitech simulate --tcp`).
    #[arg(short, long, env = "YOSEMITECH_PORT", value_name = "PATH")]
    pub port: Option<String>,
    /// Baud rate [default: the sensor's, 9600 for every Yosemitech probe].
    #[arg(short, long, env = "YOSEMITECH_BAUD", value_name = "BAUD")]
    pub baud: Option<u32>,
    /// Time allowed for each reply, e.g. 500ms, 2s [default: 1s; scan: 100ms].
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    pub timeout: Option<Duration>,
    /// Retries after a timeout or a corrupt reply [default: 2; scan: 0].
    #[arg(long, value_name = "N")]
    pub retries: Option<u32>,
}

/// The slave address option.
#[derive(Args, Debug, Clone, Default)]
pub struct AddressArg {
    /// Slave address of the probe, 1..=247 [default: the sensor's factory address, 1].
    #[arg(short, long, value_name = "N")]
    pub address: Option<u32>,
}

impl AddressArg {
    /// The address, validated, or `default`.
    pub fn get(&self, default: u8) -> Result<u8> {
        self.address.map_or(Ok(default), |a| check_address(a, "--address"))
    }
}

/// Checks a slave address given on the command line.
pub fn check_address(address: u32, what: &str) -> Result<u8> {
    match u8::try_from(address) {
        Ok(a @ 1..=247) => Ok(a),
        _ => Err(CliError::usage(format!("{what} {address} is outside 1 to 247")).hint(
            "Modbus RTU slave addresses run from 1 to 247 (0 is broadcast); Yosemitech probes leave the factory at 1",
        )),
    }
}

/// Parses `1-247`, `1,5,10-20` or `3` into sorted, distinct addresses.
pub fn parse_addresses(text: &str) -> Result<Vec<u8>> {
    let bad = |part: &str| {
        CliError::usage(format!("`{part}` in --addresses is not an address or a range"))
            .hint("write addresses 1 to 247 as 1-247, 1,5,10-20 or 3")
    };
    let mut out = Vec::new();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (a, b) = match part.split_once('-') {
            Some((a, b)) => (a.trim(), b.trim()),
            None => (part, part),
        };
        let (a, b): (u32, u32) = (a.parse().map_err(|_| bad(part))?, b.parse().map_err(|_| bad(part))?);
        if a > b {
            return Err(bad(part));
        }
        for address in a..=b {
            out.push(check_address(address, "address")?);
        }
    }
    if out.is_empty() {
        return Err(bad(text));
    }
    out.sort_unstable();
    out.dedup();
    Ok(out)
}

/// An open bus, and how to name it in messages.
pub struct Opened {
    /// The client.
    pub bus: AnyClient,
    /// The port as given.
    pub port: String,
    /// The reply timeout.
    pub timeout: Duration,
}

impl Opened {
    /// The context of a request to `slave`, for error messages.
    pub fn context(&self, slave: u8, what: &str) -> Context {
        Context { port: self.port.clone(), slave, what: what.to_owned(), timeout: self.timeout }
    }
}

/// The port given, or a usage error saying how to give one.
pub fn port_name(args: &PortArgs) -> Result<String> {
    match args.port.as_deref().map(str::trim) {
        Some(p) if !p.is_empty() => Ok(p.to_owned()),
        _ => Err(CliError::usage("no port given")
            .hint("pass --port /dev/ttyUSB0 (or COM3, or tcp://HOST:PORT), or set YOSEMITECH_PORT")),
    }
}

/// Client settings from the port options and this command's defaults.
pub fn client_config(args: &PortArgs, default_timeout: Duration, default_retries: u32) -> ClientConfig {
    let timeout = args.timeout.unwrap_or(default_timeout);
    let retries = args.retries.unwrap_or(default_retries);
    ClientConfig { timeout, retry: RetryPolicy { retries, ..RetryPolicy::default() }, ..ClientConfig::default() }
}

/// Opens the port for a sensor with `serial` settings, with the default
/// timeout (1 s) and retries (2).
pub fn open(args: &PortArgs, serial: &LineSettings) -> Result<Opened> {
    open_with(args, serial, Duration::from_secs(1), RetryPolicy::default().retries)
}

/// Opens the port.
pub fn open_with(
    args: &PortArgs,
    serial: &LineSettings,
    default_timeout: Duration,
    default_retries: u32,
) -> Result<Opened> {
    let port = port_name(args)?;
    let config = client_config(args, default_timeout, default_retries);
    let baud = args.baud.unwrap_or(serial.baud);
    if baud == 0 {
        return Err(
            CliError::usage("--baud 0 is not a baud rate").hint("Yosemitech probes use 9600 unless reconfigured")
        );
    }
    let bus = yosemitech_ops::bus::open(&port, LineSettings { baud, ..*serial }, config)
        .map_err(|e| open_failed(&port, &e))?;
    Ok(Opened { bus, port, timeout: config.timeout })
}

/// Why a port could not be opened, with what to do about it.
pub fn open_failed(port: &str, e: &io::Error) -> CliError {
    let tcp = port.starts_with("tcp://");
    match e.kind() {
        io::ErrorKind::NotFound if !tcp && Path::new(port).exists() => {
            // The transport's error names the port and the settings tried.
            CliError::device(format!("{e} (the port is in use)"))
                .hint("another program holds the port (a logger, a terminal, ModemManager): close it and retry")
        }
        io::ErrorKind::NotFound => CliError::device(format!("port {port} not found")).hint(if cfg!(windows) {
            "check the COM port number in the Device Manager"
        } else {
            "is the adapter plugged in? `ls /dev/ttyUSB* /dev/ttyACM*` lists USB serial ports"
        }),
        io::ErrorKind::PermissionDenied => CliError::device(format!("permission denied opening {port}"))
            .hint("add yourself to the group that owns the port (`sudo usermod -aG dialout $USER`, then log in again)"),
        io::ErrorKind::ConnectionRefused | io::ErrorKind::TimedOut if tcp => {
            CliError::device(format!("cannot connect to {port}: {e}"))
                .hint("is the gateway (or `yosemitech simulate --tcp`) running at that address?")
        }
        _ if tcp => CliError::device(format!("cannot connect to {port}: {e}"))
            .hint("give the gateway as tcp://HOST:PORT, e.g. tcp://192.168.1.50:4001"),
        _ => CliError::device(e.to_string())
            .hint("is it a serial device? `ls /dev/ttyUSB* /dev/ttyACM*` lists USB serial ports"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_address_ranges() {
        assert_eq!(parse_addresses("1-3").unwrap(), [1, 2, 3]);
        assert_eq!(parse_addresses("5,1-2,2").unwrap(), [1, 2, 5]);
        assert_eq!(parse_addresses("1-247").unwrap().len(), 247);
        assert!(parse_addresses("0-3").is_err());
        assert!(parse_addresses("1-248").is_err());
        assert!(parse_addresses("3-1").is_err());
        assert!(parse_addresses("x").is_err());
        assert!(parse_addresses("").is_err());
    }
}

//! `yosemitech ingest`: the stations' readings from their MQTT broker into
//! the fleet's PostgreSQL database (the library: `yosemitech_ingest`).

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use clap::Args;
use yosemitech_ingest::{IngestConfig, Totals};
use yosemitech_mqtt::{Credentials, PASSWORD_VAR, Secret, TlsConfig, USERNAME_VAR, topic};

use crate::database::database_config;
use crate::error::{CliError, Result};
use crate::format::parse_duration;

/// `ingest`.
#[derive(Args, Debug)]
pub struct IngestArgs {
    /// The broker the stations publish to: mqtt://HOST[:PORT], or mqtts://HOST[:PORT] for TLS.
    /// Its user name and password, if it asks for them, come from YOSEMITECH_MQTT_USERNAME and
    /// YOSEMITECH_MQTT_PASSWORD.
    #[arg(long, value_name = "URL")]
    pub mqtt: String,
    /// The database: a libpq connection string ("host=/run/postgresql dbname=fleet" or
    /// postgresql://user@host/fleet). Its password comes from PGPASSWORD, never from here.
    #[arg(long, value_name = "CONNINFO")]
    pub postgres: String,
    /// This worker's MQTT client id: its session on the broker, kept across restarts. Every
    /// worker needs its own [default: yosemitech-ingest-HOSTNAME].
    #[arg(long, value_name = "ID")]
    pub client_id: Option<String>,
    /// The shared subscription's group: workers of one group split the readings.
    #[arg(long, value_name = "NAME", default_value = "yosemitech-ingest")]
    pub group: String,
    /// The stations' topic prefix (their mqtt.topic_prefix).
    #[arg(long, value_name = "PREFIX", default_value = topic::DEFAULT_TOPIC_PREFIX)]
    pub topic_prefix: String,
    /// With mqtts://: the certificate authorities to trust instead of the system's (PEM).
    #[arg(long, value_name = "FILE")]
    pub ca_file: Option<PathBuf>,
    /// Readings stored in one transaction at most.
    #[arg(long, value_name = "N", default_value_t = 500)]
    pub batch: usize,
    /// How long a batch waits to fill before it is stored.
    #[arg(long, value_name = "DURATION", default_value = "200ms", value_parser = parse_duration)]
    pub batch_wait: Duration,
    /// How long the broker keeps this worker's session (and its readings) while it is away.
    #[arg(long, value_name = "DURATION", default_value = "168h", value_parser = parse_duration)]
    pub session_expiry: Duration,
}

/// Parses `mqtt://host:port` (TLS with `mqtts://`): host, port, TLS.
fn parse_broker(url: &str) -> Result<(String, u16, bool)> {
    // A URL with a user name may hold a password: never echoed.
    let shown = if url.contains('@') { "(a URL with credentials)" } else { url };
    let bad = |why: &str| {
        CliError::usage(format!("--mqtt {shown}: {why}"))
            .hint("write mqtt://HOST[:PORT] or mqtts://HOST[:PORT]; credentials come from the environment")
    };
    let (tls, rest) = if let Some(rest) = url.strip_prefix("mqtts://") {
        (true, rest)
    } else if let Some(rest) = url.strip_prefix("mqtt://") {
        (false, rest)
    } else {
        return Err(bad("not an mqtt:// or mqtts:// URL"));
    };
    let rest = rest.trim_end_matches('/');
    if rest.contains('@') {
        return Err(bad("a user name or password in the URL (anyone on the machine can read a command line)")
            .hint(format!("set {USERNAME_VAR} and {PASSWORD_VAR} instead")));
    }
    // `[v6 address]:port`, `host:port`, or either without the port.
    let (host, port) = match rest.strip_prefix('[') {
        Some(bracketed) => {
            let (host, after) = bracketed.split_once(']').ok_or_else(|| bad("an unclosed [ in the host"))?;
            (host, after.strip_prefix(':'))
        }
        None => match rest.rsplit_once(':') {
            Some((host, port)) => (host, Some(port)),
            None => (rest, None),
        },
    };
    let port = match port {
        Some(port) => port.parse::<u16>().map_err(|_| bad("the port is not a number from 1 to 65535"))?,
        None => {
            if tls {
                8883
            } else {
                1883
            }
        }
    };
    if host.is_empty() || host.contains(['/', '[', ']']) || port == 0 {
        return Err(bad("no host, or not a host and port"));
    }
    Ok((host.to_owned(), port, tls))
}

/// The broker credentials from the environment: both variables, or neither.
fn credentials() -> Result<Option<Credentials>> {
    match (std::env::var(USERNAME_VAR), std::env::var(PASSWORD_VAR)) {
        (Ok(username), Ok(password)) => Ok(Some(Credentials { username, password: Secret::new(password) })),
        (Err(_), Err(_)) => Ok(None),
        _ => Err(CliError::usage(format!("only one of {USERNAME_VAR} and {PASSWORD_VAR} is set"))
            .hint("set both for a broker that asks for them, or neither")),
    }
}

/// This machine's name, for the default client id.
fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::fs::read_to_string("/etc/hostname"))
        .map(|name| name.trim().to_owned())
        .ok()
        .filter(|name| !name.is_empty())
        .unwrap_or_else(|| "host".to_owned())
}

/// Runs `ingest` until `stop` (Ctrl-C, SIGTERM).
pub fn run(args: &IngestArgs, stop: &Arc<AtomicBool>, out: &mut dyn Write) -> Result<()> {
    let (host, port, tls) = parse_broker(&args.mqtt)?;
    if args.batch == 0 || args.batch > 10_000 {
        return Err(CliError::usage(format!("--batch {} is outside 1 to 10000", args.batch)));
    }
    topic::check_prefix(&args.topic_prefix)
        .map_err(|why| CliError::usage(format!("--topic-prefix {:?}: {why}", args.topic_prefix)))?;
    if args.group.is_empty() || args.group.contains(['/', '+', '#']) {
        return Err(CliError::usage(format!("--group {:?} is not one topic level", args.group)));
    }
    let config = IngestConfig {
        host,
        port,
        tls: tls.then(|| TlsConfig { ca_file: args.ca_file.clone() }),
        credentials: credentials()?,
        client_id: args.client_id.clone().unwrap_or_else(|| format!("yosemitech-ingest-{}", hostname())),
        topic_prefix: args.topic_prefix.clone(),
        group: Some(args.group.clone()),
        batch_size: args.batch,
        batch_wait: args.batch_wait,
        session_expiry: args.session_expiry,
    };
    let database = database_config(&args.postgres)?;
    let _ = writeln!(
        std::io::stderr(),
        "ingest: {} as {} (group {}) into PostgreSQL; Ctrl-C stops",
        args.mqtt,
        config.client_id,
        args.group
    );
    let mut last_report = Instant::now();
    let mut subscribed = false;
    let filter = config.filter();
    let totals = yosemitech_ingest::run(&config, &database, stop, |totals| {
        if totals.subscribed && !subscribed {
            let _ = writeln!(std::io::stderr(), "ingest: subscribed to {filter}");
        }
        subscribed = totals.subscribed;
        // A line a few seconds at most, for a journal.
        if last_report.elapsed() >= Duration::from_secs(5) {
            last_report = Instant::now();
            let _ = writeln!(std::io::stderr(), "ingest: {}", totals_text(totals));
        }
    })
    .map_err(|e| CliError::device(format!("ingest: {e}")))?;
    writeln!(out, "{}", totals_text(&totals))?;
    Ok(())
}

/// `1200 readings stored, 3 repeated deliveries, 0 rejected messages, in 24 transactions`.
fn totals_text(t: &Totals) -> String {
    format!(
        "{} readings stored, {} repeated deliveries, {} rejected messages, in {} transactions ({} deliveries, {} broker connections)",
        t.stored.new, t.stored.duplicates, t.stored.rejected, t.batches, t.delivered, t.connections
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn broker_urls_name_a_host_and_port_and_no_secret() {
        assert_eq!(parse_broker("mqtt://broker.example:1884").unwrap(), ("broker.example".into(), 1884, false));
        assert_eq!(parse_broker("mqtts://broker.example").unwrap(), ("broker.example".into(), 8883, true));
        assert_eq!(parse_broker("mqtt://127.0.0.1").unwrap(), ("127.0.0.1".into(), 1883, false));
        assert_eq!(parse_broker("mqtt://[::1]:1883").unwrap(), ("::1".into(), 1883, false));
        assert_eq!(parse_broker("mqtts://[::1]").unwrap(), ("::1".into(), 8883, true));
        for bad in [
            "http://x",
            "mqtt://",
            "mqtt://host:port",
            "mqtt://host:0",
            "mqtt://a/b",
            "mqtt://user:pw@host",
            "mqtt://[::1",
        ] {
            assert!(parse_broker(bad).is_err(), "{bad}");
        }
        let secret = parse_broker("mqtt://user:hunter2@host").unwrap_err();
        let said = format!("{secret} {}", secret.hint.as_deref().unwrap_or_default());
        assert!(!said.contains("hunter2") && said.contains(USERNAME_VAR), "{said}");
    }
}

//! `yosemitech scan`: find the probes on a bus.

use std::io::Write;
use std::time::Duration;

use clap::Args;
use serde_json::json;
use yosemitech_ops::{Identifier, common_serial};

use crate::catalog::Catalog;
use crate::error::{CliError, Result};
use crate::identified::{found_json, found_line, identify};
use crate::port::{self, PortArgs, parse_addresses};
use crate::progress;

/// `scan`.
#[derive(Args, Debug)]
pub struct ScanArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Addresses to probe: 1-247, 1,5,10-20 or 3.
    #[arg(long, value_name = "RANGES", default_value = "1-247")]
    pub addresses: String,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `scan`.
pub fn run(catalog: &Catalog, args: &ScanArgs, out: &mut dyn Write) -> Result<()> {
    let addresses = parse_addresses(&args.addresses)?;
    let identifier = Identifier::new(catalog.entries().iter().map(|e| e.sensor.as_ref()));
    let requests = identifier.requests();
    if requests.is_empty() {
        return Err(CliError::usage("no loaded sensor has a serial-number read to identify probes with")
            .hint("scan reads the command with `role: serial_number`; check the --spec files"));
    }
    let serial = common_serial(catalog.entries().iter().map(|e| e.sensor.as_ref()));
    let mut opened = port::open_with(&args.port, &serial, Duration::from_millis(100), 0)?;
    if !args.json {
        let with: Vec<String> = requests
            .iter()
            .map(|(address, n)| format!("0x{address:04X} ({n} sensor{})", if *n == 1 { "" } else { "s" }))
            .collect();
        writeln!(
            out,
            "scanning {} address(es) on {}; serial number at {}",
            addresses.len(),
            opened.port,
            with.join(", then ")
        )?;
        out.flush()?;
    }
    let bar = progress::bar(addresses.len() as u64, "{msg:12} [{bar:30}] {pos}/{len} addresses");
    let mut found = Vec::new();
    for &address in &addresses {
        bar.set_message(format!("address {address}"));
        if let Some(item) = identify(&identifier, &mut opened, address)? {
            if !args.json {
                let line = found_line(&item);
                bar.suspend(|| writeln!(out, "{line}"))?;
            }
            found.push(item);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    if args.json {
        let items: Vec<_> = found.iter().map(found_json).collect();
        writeln!(out, "{}", serde_json::to_string_pretty(&json!({ "devices": items })).unwrap_or_default())?;
    } else {
        writeln!(out, "found {} device(s)", found.len())?;
    }
    if found.is_empty() {
        return Err(CliError::device(format!("no device answered on {} at {}", opened.port, args.addresses))
            .hint("check power and wiring (A/B), and the baud rate (--baud); slow devices need a longer --timeout"));
    }
    Ok(())
}

//! `yosemitech encode`: a command's frame, offline.

use std::collections::BTreeMap;
use std::io::Write;

use crate::catalog::{self, Catalog};
use crate::error::{CliError, Result};
use crate::format::{hex, parse_values};
use crate::port::AddressArg;
use clap::Args;

/// `encode`.
#[derive(Args, Debug)]
pub struct EncodeArgs {
    /// Sensor.
    pub sensor: String,
    /// Command.
    pub command: String,
    /// Values: field=value pairs, or values in field order.
    #[arg(value_name = "VALUES", allow_negative_numbers = true)]
    pub values: Vec<String>,
    #[command(flatten)]
    pub address: AddressArg,
    /// Encode the reply instead of the request.
    #[arg(long)]
    pub response: bool,
}

/// Runs `encode`: prints the frame as hex on stdout.
pub fn run(catalog: &Catalog, args: &EncodeArgs, out: &mut dyn Write) -> Result<()> {
    let sensor = catalog.sensor(&args.sensor)?;
    let command = catalog::command(sensor, &args.command)?;
    let address = args.address.get(sensor.default_address)?;
    let slave = match command.fixed_slave {
        Some(fixed) if args.address.address.is_some() && address != fixed => {
            return Err(CliError::usage(format!(
                "`{}` always goes to address 0x{fixed:02X}, not {address}",
                command.name
            ))
            .hint("leave out --address"));
        }
        Some(fixed) => fixed,
        None => address,
    };
    // Values belong to a write's request or a read's reply.
    let carries_values = command.is_read() == args.response;
    let values = if carries_values {
        parse_values(command, &args.values)?
    } else if args.values.is_empty() {
        BTreeMap::new()
    } else {
        let what = if args.response { "a write's reply" } else { "a read request" };
        return Err(CliError::usage(format!("{what} carries no values, but {} were given", args.values.len())).hint(
            if command.is_read() {
                "add --response to encode the reply with these values"
            } else {
                "leave out --response to encode the request with these values"
            },
        ));
    };
    let frame =
        if args.response { command.encode_response(slave, &values) } else { command.encode_request(slave, &values) }
            .map_err(|e| CliError::usage(format!("cannot encode {}: {e}", command.name)))?;
    writeln!(out, "{}", hex(&frame))?;
    Ok(())
}

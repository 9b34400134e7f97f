//! `yosemitech write`: any write command, confirmed, backed up when it
//! touches calibration coefficients, and read back.

use std::io::Write;

use yosemitech_spec::{CommandSpec, Role, Value};

use crate::args::BackupDir;
use crate::backup;
use crate::catalog::{self, Catalog, read_back_for};
use crate::confirm::{confirm, ensure_can_ask};
use crate::device;
use crate::error::{CliError, Result};
use crate::format::{hex, parse_values, value_with_unit};
use crate::port;
use crate::port::AddressArg;
use crate::port::PortArgs;
use clap::Args;

/// `write`.
#[derive(Args, Debug)]
pub struct WriteArgs {
    /// Sensor.
    pub sensor: String,
    /// Write command (`yosemitech list SENSOR` shows them).
    pub command: String,
    /// Values: field=value pairs, or values in field order.
    #[arg(value_name = "VALUES", allow_negative_numbers = true)]
    pub values: Vec<String>,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Send without asking.
    #[arg(short, long)]
    pub yes: bool,
    #[command(flatten)]
    pub backup: BackupDir,
}

/// Runs `write`.
pub fn run(catalog: &Catalog, args: &WriteArgs, out: &mut dyn Write) -> Result<()> {
    let entry = catalog.entry(&args.sensor)?;
    let sensor = &entry.sensor;
    let command = catalog::command(sensor, &args.command)?;
    if command.is_read() {
        return Err(CliError::usage(format!("`{}` is a read command", command.name))
            .hint(format!("read it with `yosemitech read {} {}`", sensor.name, command.name)));
    }
    let address = args.address.get(sensor.default_address)?;
    let values = parse_values(command, &args.values)?;
    let slave = device::target(command, address);
    let frame = command
        .encode_request(slave, &values)
        .map_err(|e| CliError::usage(format!("cannot build the {} request: {e}", command.name)))?;
    ensure_can_ask(args.yes, &format!("send {}", command.name))?;

    let mut opened = port::open(&args.port, &sensor.serial)?;
    let is_coefficient = sensor.coefficient_blocks().iter().any(|(w, _)| w.name == command.name);
    if is_coefficient {
        let taken = backup::take_backup(&mut opened, entry, address)?;
        let path = backup::save_in(args.backup.dir.as_deref(), &taken)?;
        writeln!(out, "saved every coefficient to {}", path.display())?;
        writeln!(out, "restore with: {}", backup::restore_command(catalog, entry, &opened.port, address, &path))?;
    }

    writeln!(out, "{} ({}) to address {slave} on {}:", command.name, command.title, opened.port)?;
    for field in command.named_fields() {
        if let Some(v) = values.get(field.display_name()) {
            writeln!(out, "  {} = {}", field.display_name(), value_with_unit(v, Some(field)))?;
        }
    }
    writeln!(out, "  frame: {}", hex(&frame))?;
    out.flush()?;
    confirm(args.yes, &format!("Send {} to address {slave}?", command.name))?;
    device::call(&mut opened, command, address, &values)?;
    writeln!(out, "written: the probe acknowledged {}", command.name)?;

    // A new slave address (the write with that role, whatever its field is
    // called) applies from the next request on.
    let new_address = command
        .named_fields()
        .next()
        .filter(|_| command.role == Some(Role::SetSlaveAddress))
        .and_then(|f| values.get(f.display_name()));
    let read_from = match new_address {
        Some(Value::Int(new)) => {
            let new = u8::try_from(*new).unwrap_or(address);
            writeln!(out, "the probe now answers at address {new} (the reply came from {address})")?;
            new
        }
        _ => address,
    };
    let Some(read) = read_back_for(sensor, command) else {
        writeln!(out, "no read command covers these registers: nothing to read back")?;
        return Ok(());
    };
    let back = device::read(&mut opened, read, read_from)?;
    compare(command, read, &frame, &back, out)
}

/// Compares what was written with what a read of the same registers returns.
fn compare(
    write: &CommandSpec,
    read: &CommandSpec,
    frame: &[u8],
    back: &yosemitech_spec::Values,
    out: &mut dyn Write,
) -> Result<()> {
    // The written register data, and the read's data re-encoded, side by side.
    let written = frame.get(7..frame.len().saturating_sub(2)).unwrap_or(&[]);
    let shift = 2 * usize::from(write.address.saturating_sub(read.address));
    let mut read_values = std::collections::BTreeMap::new();
    for (k, v) in back {
        read_values.insert(k.clone(), v.clone());
    }
    let read_data = read.encode_response(1, &read_values).ok();
    let read_data = read_data.as_deref().and_then(|f| f.get(3..f.len().saturating_sub(2))).unwrap_or(&[]);
    let mut mismatches = 0;
    writeln!(out, "read back with {}:", read.name)?;
    for field in write.named_fields() {
        let range = shift + field.offset..shift + field.offset + field.size();
        let wrote = written.get(field.offset..field.offset + field.size());
        let got = read_data.get(range);
        let ok = wrote.is_some() && wrote == got;
        mismatches += usize::from(!ok);
        let shown = back
            .iter()
            .find(|(n, _)| n == field.display_name())
            .map(|(_, v)| value_with_unit(v, Some(field)))
            .unwrap_or_else(|| got.map(hex).unwrap_or_default());
        writeln!(out, "  {} = {shown} {}", field.display_name(), if ok { "(matches)" } else { "(DIFFERS)" })?;
    }
    if mismatches > 0 {
        return Err(CliError::device(format!("read-back differs from what was written in {mismatches} field(s)"))
            .hint("the probe may have rejected or rounded the values; read them again with `yosemitech read`"));
    }
    writeln!(out, "verified: the probe holds the values written")?;
    Ok(())
}

//! `yosemitech coefficients backup|restore`: every calibration coefficient
//! to and from a JSON file.

use std::io::Write;

use crate::backup::{self, Backup};
use crate::catalog::Catalog;
use crate::confirm::{confirm, ensure_can_ask};
use crate::error::{CliError, Result};
use crate::port;
use crate::port::AddressArg;
use crate::port::PortArgs;
use clap::Args;
use std::path::PathBuf;

/// `coefficients`.
#[derive(clap::Subcommand, Debug)]
pub enum CoefficientsSubcommand {
    /// Save every calibration coefficient to a JSON file.
    Backup(CoefficientsBackupArgs),
    /// Write every calibration coefficient from a JSON file, then read it back.
    Restore(CoefficientsRestoreArgs),
}

/// `coefficients backup`.
#[derive(Args, Debug)]
pub struct CoefficientsBackupArgs {
    /// Sensor.
    pub sensor: String,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// The JSON file to write (not overwritten) [default: a timestamped file here].
    #[arg(short, long, value_name = "FILE")]
    pub file: Option<PathBuf>,
}

/// `coefficients restore`.
#[derive(Args, Debug)]
pub struct CoefficientsRestoreArgs {
    /// Sensor.
    pub sensor: String,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// The JSON file written by `coefficients backup` (or by a calibration).
    #[arg(short, long, value_name = "FILE")]
    pub file: PathBuf,
    /// Write without asking.
    #[arg(short, long)]
    pub yes: bool,
}

/// Runs `coefficients backup`.
pub fn backup(catalog: &Catalog, args: &CoefficientsBackupArgs, out: &mut dyn Write) -> Result<()> {
    let entry = catalog.entry(&args.sensor)?;
    if entry.sensor.coefficient_blocks().is_empty() {
        return Err(CliError::usage(format!("sensor `{}` has no calibration coefficients", entry.sensor.name)));
    }
    let slave = args.address.get(entry.sensor.default_address)?;
    let mut opened = port::open(&args.port, &entry.sensor.serial)?;
    let taken = backup::take_backup(&mut opened, entry, slave)?;
    let path = match &args.file {
        Some(path) => {
            backup::save_to(path, &taken)?;
            path.clone()
        }
        None => backup::save_in(None, &taken)?,
    };
    writeln!(out, "saved every coefficient of {} at address {slave} to {}", entry.sensor.name, path.display())?;
    for line in backup::show(&taken.blocks) {
        writeln!(out, "  {line}")?;
    }
    writeln!(out, "restore with: {}", backup::restore_command(catalog, entry, &opened.port, slave, &path))?;
    Ok(())
}

/// Runs `coefficients restore`.
pub fn restore(catalog: &Catalog, args: &CoefficientsRestoreArgs, out: &mut dyn Write) -> Result<()> {
    let entry = catalog.entry(&args.sensor)?;
    let saved = Backup::load(&args.file)?;
    if saved.sensor != entry.sensor.name {
        return Err(CliError::usage(format!(
            "{} holds coefficients of a `{}` probe, not `{}`",
            args.file.display(),
            saved.sensor,
            entry.sensor.name
        ))
        .hint(format!("restore it with `yosemitech coefficients restore {} ...`", saved.sensor)));
    }
    let slave = args.address.get(entry.sensor.default_address)?;
    ensure_can_ask(args.yes, "restore coefficients")?;
    let mut opened = port::open(&args.port, &entry.sensor.serial)?;
    let serial_number = backup::serial_number(&mut opened, entry, slave);
    writeln!(
        out,
        "restoring the coefficients saved {} from {}{}:",
        if saved.saved_at.is_empty() { "earlier" } else { saved.saved_at.as_str() },
        saved.port,
        saved.serial_number.as_deref().map(|sn| format!(" (SN {sn})")).unwrap_or_default()
    )?;
    for line in backup::show(&saved.blocks) {
        writeln!(out, "  {line}")?;
    }
    if let (Some(was), Some(now)) = (&saved.serial_number, &serial_number)
        && was != now
    {
        writeln!(out, "warning: the file is from probe {was}, but the probe at address {slave} is {now}")?;
    }
    out.flush()?;
    confirm(args.yes, &format!("Write these coefficients to address {slave} on {}?", opened.port))?;
    // What the probe holds now is a calibration too: keep it before overwriting.
    let current = backup::take_backup(&mut opened, entry, slave)?;
    let dir = args.file.parent().filter(|d| !d.as_os_str().is_empty());
    let path = backup::save_in(dir, &current)?;
    writeln!(out, "saved the probe's current coefficients to {}", path.display())?;
    backup::write_blocks(&mut opened, entry, slave, &saved.blocks)?;
    writeln!(out, "restored and verified: every coefficient reads back as saved")?;
    Ok(())
}

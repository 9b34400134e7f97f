//! `yosemitech calibrate history` and `calibrate restore ID`: the
//! calibrations recorded, and writing an earlier one back.

use std::collections::BTreeMap;
use std::io::Write;

use serde_json::Value as Json;
use yosemitech_spec::Value;
use yosemitech_station::StoredCalibration;

use crate::args::BackupDir;
use crate::args::HistoryArgs;
use crate::backup::{self, Backup};
use crate::catalog::Catalog;
use crate::confirm::{confirm, ensure_can_ask};
use crate::error::{CliError, Result};
use crate::format::json_f32;
use crate::history::{self, Probe};
use crate::port::AddressArg;
use crate::port::PortArgs;
use crate::{port, time};
use clap::Args;

/// `calibrate history`.
#[derive(Args, Debug)]
pub struct CalibrateHistoryArgs {
    /// Only the calibrations of the probe with this serial number.
    #[arg(long, value_name = "SN")]
    pub sn: Option<String>,
    /// Print every calibration, with all its readings, as one JSON array.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub history: HistoryArgs,
}

/// `calibrate restore`.
#[derive(Args, Debug)]
pub struct CalibrateRestoreArgs {
    /// The calibration to write back (`calibrate history` lists the ids).
    pub id: i64,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Write without asking.
    #[arg(short, long)]
    pub yes: bool,
    #[command(flatten)]
    pub backup: BackupDir,
    #[command(flatten)]
    pub history: HistoryArgs,
}

/// The coefficients a record holds as `{field=value ...}` per block, on one line.
fn shown(blocks: &Json) -> String {
    let Some(blocks) = blocks.as_object() else { return String::new() };
    blocks
        .iter()
        .map(|(name, fields)| {
            let values: Vec<String> =
                fields.as_object().map(|f| f.iter().map(|(k, v)| format!("{k}={v}")).collect()).unwrap_or_default();
            format!("{name}: {}", values.join(" "))
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// Runs `calibrate history`.
pub fn list(catalog: &Catalog, args: &CalibrateHistoryArgs, out: &mut dyn Write) -> Result<()> {
    let path = history::file(catalog, &args.history)?;
    if !path.exists() {
        return Err(CliError::usage(format!("no calibration history at {}", path.display()))
            .hint("every `yosemitech calibrate` records its calibration there; --history or --config names another"));
    }
    let (store, path) = history::open(catalog, &args.history)?;
    let records = store
        .calibrations(args.sn.as_deref())
        .map_err(|e| CliError::device(format!("cannot read the calibration history {}: {e}", path.display())))?;
    if args.json {
        let all: Vec<Json> = records.iter().map(StoredCalibration::to_json).collect();
        writeln!(out, "{}", serde_json::to_string_pretty(&all).unwrap_or_default())?;
        return Ok(());
    }
    if records.is_empty() {
        writeln!(out, "no calibration recorded in {}", path.display())?;
        return Ok(());
    }
    for r in &records {
        let c = &r.calibration;
        writeln!(
            out,
            "{:>4}  {}  {} SN {}  {}{}",
            r.id,
            time::rfc3339(c.timestamp),
            c.sensor,
            c.serial_number.as_deref().unwrap_or("?"),
            c.kind,
            c.block.as_deref().map(|b| format!(" ({b})")).unwrap_or_default()
        )?;
        writeln!(out, "      after: {}", shown(&c.after))?;
        if let Some(note) = &c.note {
            writeln!(out, "      note: {note}")?;
        }
    }
    Ok(())
}

/// The blocks of a record's `after`, checked against the sensor's coefficient blocks.
fn restorable(catalog: &Catalog, record: &StoredCalibration) -> Result<Vec<(String, BTreeMap<String, Value>)>> {
    let entry = catalog.entry(&record.calibration.sensor)?;
    let bad = |what: String| CliError::usage(format!("calibration {} cannot be restored: {what}", record.id));
    let blocks = record.calibration.after.as_object().ok_or_else(|| bad("it holds no coefficients".into()))?;
    if blocks.is_empty() {
        return Err(bad("it holds no coefficients".into()));
    }
    let pairs = entry.sensor.coefficient_blocks();
    let mut planned = Vec::new();
    for (name, fields) in blocks {
        let Some((write, _)) = pairs.iter().find(|(w, _)| w.name == *name) else {
            return Err(bad(format!("`{}` has no coefficient block `{name}`", entry.sensor.name)));
        };
        let mut values = BTreeMap::new();
        for field in write.named_fields() {
            let v = fields
                .get(field.display_name())
                .and_then(json_f32)
                .ok_or_else(|| bad(format!("`{name}.{}` is missing or not a number", field.display_name())))?;
            values.insert(field.display_name().to_owned(), Value::Float(v));
        }
        planned.push((name.clone(), values));
    }
    Ok(planned)
}

/// Runs `calibrate restore ID`.
pub fn restore(catalog: &Catalog, args: &CalibrateRestoreArgs, out: &mut dyn Write) -> Result<()> {
    let path = history::file(catalog, &args.history)?;
    if !path.exists() {
        return Err(CliError::usage(format!("no calibration history at {}", path.display())));
    }
    let (mut store, path) = history::open(catalog, &args.history)?;
    let record = store
        .calibration(args.id)
        .map_err(|e| CliError::device(format!("cannot read the calibration history {}: {e}", path.display())))?
        .ok_or_else(|| {
            CliError::usage(format!("no calibration {} in {}", args.id, path.display()))
                .hint("`yosemitech calibrate history` lists the ids")
        })?;
    let planned = restorable(catalog, &record)?;
    let entry = catalog.entry(&record.calibration.sensor)?;
    let slave = args.address.get(record.calibration.address)?;
    ensure_can_ask(args.yes, "restore a calibration")?;
    let mut opened = port::open(&args.port, &entry.sensor.serial)?;
    let identity = history::identity(&mut opened, entry, slave);
    if let Some(was) = &record.calibration.serial_number
        && identity.0.as_deref() != Some(was.as_str())
    {
        return Err(CliError::usage(format!(
            "calibration {} is of probe {was}, but the probe at address {slave} is {}",
            args.id,
            identity.0.as_deref().unwrap_or("one that did not say its serial number")
        ))
        .hint("connect the probe the calibration was made on; nothing was written"));
    }
    writeln!(
        out,
        "restoring calibration {} ({}, {}) to {} at address {slave} on {}:",
        record.id,
        record.calibration.kind,
        time::rfc3339(record.calibration.timestamp),
        entry.sensor.name,
        opened.port
    )?;
    writeln!(out, "  {}", shown(&record.calibration.after))?;
    out.flush()?;
    confirm(args.yes, &format!("Write these coefficients to address {slave} on {}?", opened.port))?;
    // The probe's coefficients now are a calibration too: saved before anything is written.
    let current = backup::read_blocks(&mut opened, entry, slave)?;
    let saved = Backup::taken_now(&opened, entry, slave, identity.0.clone(), current.clone());
    let file = backup::save_in(args.backup.dir.as_deref(), &saved)?;
    let restore_command = backup::restore_command(catalog, entry, &saved.port, slave, &file);
    writeln!(out, "saved every coefficient to {}", file.display())?;
    let pairs = entry.sensor.coefficient_blocks();
    for (done, (name, values)) in planned.iter().enumerate() {
        let Some((write, read)) = pairs.iter().find(|(w, _)| w.name == *name) else { continue };
        if let Err(e) = backup::write_block(&mut opened, write, read, slave, values) {
            // The blocks written so far (and this one) get the probe's values back.
            let mut back = Ok(());
            for (name, _) in &planned[..=done] {
                let (Some((write, read)), Some(fields)) =
                    (pairs.iter().find(|(w, _)| w.name == *name), current.get(name))
                else {
                    continue;
                };
                let fields = fields.iter().map(|(k, v)| (k.clone(), Value::Float(*v))).collect();
                back = back.and(backup::write_block(&mut opened, write, read, slave, &fields));
            }
            return Err(match back {
                Ok(()) => e.detail("the probe's coefficients before the restore were written back and read back"),
                Err(_) => e.detail(format!("the coefficients before the restore are back with: {restore_command}")),
            });
        }
    }
    writeln!(out, "restored and verified: every coefficient reads back as recorded")?;
    let probe = Probe { entry, address: slave, port: opened.port.clone(), identity };
    let note = match &args.history.note {
        Some(note) => format!("restore of calibration {}: {note}", record.id),
        None => format!("restore of calibration {}", record.id),
    };
    let mut calibration = probe.record("restore", Some(&note));
    let touched: backup::Blocks =
        current.into_iter().filter(|(name, _)| planned.iter().any(|(n, _)| n == name)).collect();
    calibration.before = history::blocks_json(&touched);
    calibration.after = record.calibration.after.clone();
    calibration.block = record.calibration.block.clone();
    history::record(&mut store, &path, &calibration, out)?;
    Ok(())
}

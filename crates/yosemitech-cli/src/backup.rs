//! Calibration-coefficient backups: every coefficient of a probe in one JSON
//! file, and the command that writes it back.
//!
//! ```json
//! {
//!   "format": "yosemitech-coefficients",
//!   "version": 1,
//!   "sensor": "ph_orp",
//!   "address": 1,
//!   "port": "/dev/ttyUSB0",
//!   "serial_number": "YL4314010022",
//!   "saved_at": "2025-11-23T18:04:05.123Z",
//!   "coefficients": {
//!     "set_orp_calibration": {"b_offset": 0.0, "k_slope": 1.0},
//!     "set_ph_calibration": {"b_offset": 0.0, "k_slope": 1.0},
//!     "set_ph_electrode_coefficients": {"k1": 6.86, "k2": -6.72, ...}
//!   }
//! }
//! ```
//!
//! Blocks are named after the write command that restores them (the
//! spec's coefficient blocks: see [`crate::catalog::coefficient_blocks`]).
//! Floats are written the shortest way that reads back bit-exactly.
//! Every sensor, built in or `--spec`, goes through the interpreter: a
//! backup reads every block; a restore writes each block and reads it back,
//! comparing bit for bit.

use std::collections::BTreeMap;
use std::fs::OpenOptions;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use serde_json::{Map, Value as Json, json};
use yosemitech_spec::{CommandSpec, Role, Value, Values};

use crate::catalog::{Catalog, Entry};
use crate::device;
use crate::error::{CliError, Result};
use crate::format::{f32_json, json_f32};
use crate::port::Opened;
use crate::{shell, time};

/// The `format` tag of a backup file.
const FORMAT: &str = "yosemitech-coefficients";

/// Coefficient values by block (write command) and field.
pub type Blocks = BTreeMap<String, BTreeMap<String, f32>>;

/// A backup file's content.
#[derive(Debug, Clone, PartialEq)]
pub struct Backup {
    /// Sensor name.
    pub sensor: String,
    /// Slave address it was read from.
    pub address: u8,
    /// Port it was read on.
    pub port: String,
    /// The probe's serial number, if it answered.
    pub serial_number: Option<String>,
    /// When (RFC 3339 UTC).
    pub saved_at: String,
    /// The coefficients.
    pub blocks: Blocks,
}

impl Backup {
    /// A backup of `blocks`, just read from `entry`'s probe at `slave` on
    /// the open port, stamped with the time now.
    pub fn taken_now(opened: &Opened, entry: &Entry, slave: u8, serial_number: Option<String>, blocks: Blocks) -> Self {
        Self {
            sensor: entry.sensor.name.clone(),
            address: slave,
            port: opened.port.clone(),
            serial_number,
            saved_at: time::rfc3339(SystemTime::now()),
            blocks,
        }
    }

    /// The file's JSON.
    pub fn to_json(&self) -> Json {
        let blocks: Map<String, Json> = self
            .blocks
            .iter()
            .map(|(name, fields)| {
                (name.clone(), Json::Object(fields.iter().map(|(k, v)| (k.clone(), f32_json(*v))).collect()))
            })
            .collect();
        json!({
            "format": FORMAT,
            "version": 1,
            "sensor": self.sensor,
            "address": self.address,
            "port": self.port,
            "serial_number": self.serial_number,
            "saved_at": self.saved_at,
            "coefficients": blocks,
        })
    }

    /// Reads a backup file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| {
            CliError::usage(format!("cannot read {}: {e}", path.display()))
                .hint("give the JSON file written by `yosemitech coefficients backup` or by a calibration")
        })?;
        let bad = |what: &str| {
            CliError::usage(format!("{} is not a coefficient backup: {what}", path.display()))
                .hint("give the JSON file written by `yosemitech coefficients backup` or by a calibration")
        };
        let json: Json = serde_json::from_str(&text).map_err(|e| bad(&format!("invalid JSON ({e})")))?;
        if json.get("format").and_then(Json::as_str) != Some(FORMAT) {
            return Err(bad(&format!("no \"format\": \"{FORMAT}\"")));
        }
        let sensor = json.get("sensor").and_then(Json::as_str).ok_or_else(|| bad("no \"sensor\""))?.to_owned();
        let address = json.get("address").and_then(Json::as_u64).and_then(|a| u8::try_from(a).ok()).unwrap_or(1);
        let mut blocks = Blocks::new();
        let map = json.get("coefficients").and_then(Json::as_object).ok_or_else(|| bad("no \"coefficients\""))?;
        for (name, fields) in map {
            let fields = fields.as_object().ok_or_else(|| bad(&format!("block `{name}` is not an object")))?;
            let mut values = BTreeMap::new();
            for (field, v) in fields {
                let v = json_f32(v).ok_or_else(|| bad(&format!("`{name}.{field}` is not a number")))?;
                values.insert(field.clone(), v);
            }
            blocks.insert(name.clone(), values);
        }
        Ok(Self {
            sensor,
            address,
            port: json.get("port").and_then(Json::as_str).unwrap_or_default().to_owned(),
            serial_number: json.get("serial_number").and_then(Json::as_str).map(str::to_owned),
            saved_at: json.get("saved_at").and_then(Json::as_str).unwrap_or_default().to_owned(),
            blocks,
        })
    }
}

/// The values a coefficient read returned, under the names of the write
/// command that restores them (the two share address and register count,
/// so their fields pair up in order).
fn named_as_write(write: &CommandSpec, values: Values) -> Result<BTreeMap<String, f32>> {
    let names: Vec<&str> = write.named_fields().map(|f| f.display_name()).collect();
    let floats: Vec<f32> = values
        .into_iter()
        .filter_map(|(_, v)| match v {
            Value::Float(f) => Some(f),
            _ => None,
        })
        .collect();
    if floats.len() != names.len() {
        return Err(CliError::device(format!(
            "the coefficient read for {} returned {} values, not {}",
            write.name,
            floats.len(),
            names.len()
        )));
    }
    Ok(names.into_iter().map(str::to_owned).zip(floats).collect())
}

/// Every coefficient of the probe at `slave`: one block per coefficient
/// block of the spec (see [`coefficient_blocks`]).
pub fn read_blocks(opened: &mut Opened, entry: &Entry, slave: u8) -> Result<Blocks> {
    let mut blocks = Blocks::new();
    for (write, read) in entry.sensor.coefficient_blocks() {
        let values = device::read(opened, read, slave)?;
        blocks.insert(write.name.clone(), named_as_write(write, values)?);
    }
    Ok(blocks)
}

/// Writes every coefficient to the probe at `slave` and reads each block
/// back, comparing bit for bit. The whole file is checked before anything
/// is written.
pub fn write_blocks(opened: &mut Opened, entry: &Entry, slave: u8, blocks: &Blocks) -> Result<()> {
    let pairs = entry.sensor.coefficient_blocks();
    let mut planned = Vec::new();
    for (write, read) in &pairs {
        let values = blocks.get(&write.name).ok_or_else(|| {
            CliError::usage(format!("the backup has no `{}` block", write.name))
                .hint("restore from a complete backup file")
        })?;
        let mut fields = BTreeMap::new();
        for field in write.named_fields() {
            let v = values.get(field.display_name()).ok_or_else(|| {
                CliError::usage(format!("the backup's `{}` block has no `{}`", write.name, field.display_name()))
                    .hint("restore from a complete backup file")
            })?;
            fields.insert(field.display_name().to_owned(), Value::Float(*v));
        }
        planned.push((*write, *read, fields));
    }
    for (write, read, fields) in planned {
        write_block(opened, write, read, slave, &fields)?;
    }
    Ok(())
}

/// Writes one coefficient block and reads it back with `read` (the read
/// of the same registers), comparing bit for bit.
pub fn write_block(
    opened: &mut Opened,
    write: &CommandSpec,
    read: &CommandSpec,
    slave: u8,
    fields: &BTreeMap<String, Value>,
) -> Result<()> {
    device::call(opened, write, slave, fields)?;
    let back = named_as_write(write, device::read(opened, read, slave)?)?;
    let same = fields.iter().all(|(name, want)| back.get(name).is_some_and(|got| want.same_as(&Value::Float(*got))));
    if !same {
        return Err(CliError::device(format!("verification failed: {} did not read back as written", write.name))
            .hint("the probe did not keep the values written; read them with `yosemitech read` and retry"));
    }
    Ok(())
}

/// The probe's serial number, if its spec has a serial-number read and the
/// probe answers it.
pub fn serial_number(opened: &mut Opened, entry: &Entry, slave: u8) -> Option<String> {
    let command = entry.sensor.command_with_role(Role::SerialNumber)?;
    let values = device::read(opened, command, slave).ok()?;
    values.into_iter().find_map(|(_, v)| match v {
        Value::Text(t) => Some(t),
        _ => None,
    })
}

/// Reads every coefficient into a [`Backup`].
pub fn take_backup(opened: &mut Opened, entry: &Entry, slave: u8) -> Result<Backup> {
    let blocks = read_blocks(opened, entry, slave)?;
    let serial_number = serial_number(opened, entry, slave);
    Ok(Backup::taken_now(opened, entry, slave, serial_number, blocks))
}

/// Writes `backup` to `path`, never overwriting a file.
pub fn save_to(path: &Path, backup: &Backup) -> Result<()> {
    let text = serde_json::to_string_pretty(&backup.to_json())
        .map_err(|e| CliError::device(format!("cannot encode the backup: {e}")))?;
    let mut file = OpenOptions::new().write(true).create_new(true).open(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::AlreadyExists {
            CliError::usage(format!("{} already exists", path.display()))
                .hint("backups never overwrite a file: choose another --file or move it away")
        } else {
            let e = CliError::device(format!("cannot create {}: {e}", path.display()));
            e.hint("choose a writable place (--file, or --backup-dir for calibrations and writes)")
        }
    })?;
    file.write_all(text.as_bytes())
        .and_then(|()| file.write_all(b"\n"))
        .and_then(|()| file.sync_all())
        .map_err(|e| CliError::device(format!("cannot write {}: {e}", path.display())))
}

/// Writes `backup` to a new timestamped file in `dir` (default: the
/// current directory) and returns its path.
pub fn save_in(dir: Option<&Path>, backup: &Backup) -> Result<PathBuf> {
    let dir = dir.map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let stamp = time::compact(SystemTime::now());
    let base = format!("{}-address{}-coefficients-{stamp}", backup.sensor, backup.address);
    let mut path = dir.join(format!("{base}.json"));
    for n in 2.. {
        if !path.exists() || n > 99 {
            break;
        }
        path = dir.join(format!("{base}-{n}.json"));
    }
    save_to(&path, backup)?;
    Ok(path)
}

/// The command that restores `path` to the probe.
pub fn restore_command(catalog: &Catalog, entry: &Entry, port: &str, address: u8, path: &Path) -> String {
    let mut words: Vec<String> = vec!["yosemitech".into()];
    words.extend(catalog.spec_args(&entry.origin));
    words.extend([
        "coefficients".into(),
        "restore".into(),
        entry.sensor.name.clone(),
        "--port".into(),
        port.to_owned(),
        "--address".into(),
        address.to_string(),
        "--file".into(),
        path.display().to_string(),
    ]);
    shell::command_line(&words)
}

/// The coefficients as indented lines.
pub fn show(blocks: &Blocks) -> Vec<String> {
    blocks
        .iter()
        .map(|(name, fields)| {
            let values: Vec<String> = fields.iter().map(|(k, v)| format!("{k}={v}")).collect();
            format!("{name}: {}", values.join(" "))
        })
        .collect()
}

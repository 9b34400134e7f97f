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
//! Built-in sensors go through the `yosemitech` crate's
//! `procedures::coefficients` (with read-back); `--spec` sensors through
//! the interpreter, with the same read-back.

use std::collections::BTreeMap;
use std::fs::OpenOptions;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use serde_json::{Map, Value as Json, json};
use yosemitech::procedures::coefficients::{
    ConductivityCoefficients, PhOrpCoefficients, read_conductivity, read_ph_orp, write_conductivity, write_ph_orp,
};
use yosemitech::{Command as _, FieldInfo, conductivity, ph_orp};
use yosemitech_spec::Value;

use crate::catalog::{Catalog, Entry, coefficient_blocks};
use crate::device::{self, is_typed, procedure_failed};
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

fn block(fields: &[FieldInfo], values: &[f32]) -> BTreeMap<String, f32> {
    fields.iter().zip(values).map(|(f, v)| (f.name.to_owned(), *v)).collect()
}

fn take<const N: usize>(blocks: &Blocks, name: &str, fields: &[FieldInfo; N]) -> Result<[f32; N]> {
    let values = blocks.get(name).ok_or_else(|| {
        CliError::usage(format!("the backup has no `{name}` block")).hint("restore from a complete backup file")
    })?;
    let mut out = [0f32; N];
    for (slot, field) in out.iter_mut().zip(fields) {
        *slot = *values.get(field.name).ok_or_else(|| {
            CliError::usage(format!("the backup's `{name}` block has no `{}`", field.name))
                .hint("restore from a complete backup file")
        })?;
    }
    Ok(out)
}

/// A pH/ORP probe's coefficients as backup blocks.
pub fn ph_orp_blocks(c: &PhOrpCoefficients) -> Blocks {
    Blocks::from([
        (
            ph_orp::SetPhElectrodeCoefficients::NAME.to_owned(),
            block(&ph_orp::SetPhElectrodeCoefficients::FIELDS, &c.electrode),
        ),
        (ph_orp::SetPhCalibration::NAME.to_owned(), block(&ph_orp::SetPhCalibration::FIELDS, &c.ph_calibration)),
        (ph_orp::SetOrpCalibration::NAME.to_owned(), block(&ph_orp::SetOrpCalibration::FIELDS, &c.orp_calibration)),
    ])
}

/// Every coefficient of the probe at `slave`.
pub fn read_blocks(opened: &mut Opened, entry: &Entry, slave: u8) -> Result<Blocks> {
    let ctx = opened.context(slave, "the coefficient reads");
    if is_typed(entry, "ph_orp") {
        let mut probe = ph_orp::Device::new(&mut opened.bus, slave);
        return read_ph_orp(&mut probe).map(|c| ph_orp_blocks(&c)).map_err(|e| procedure_failed(&e, &ctx));
    }
    if is_typed(entry, "conductivity") {
        let mut probe = conductivity::Device::new(&mut opened.bus, slave);
        let c = read_conductivity(&mut probe).map_err(|e| procedure_failed(&e, &ctx))?;
        let name = conductivity::SetUserCalibration::NAME.to_owned();
        return Ok(Blocks::from([(name, block(&conductivity::SetUserCalibration::FIELDS, &c.user_calibration))]));
    }
    let mut blocks = Blocks::new();
    for (write, read) in coefficient_blocks(&entry.sensor) {
        let values = device::read(opened, read, slave)?;
        let fields = values
            .into_iter()
            .filter_map(|(name, v)| match v {
                Value::Float(f) => Some((name, f)),
                _ => None,
            })
            .collect();
        blocks.insert(write.name.clone(), fields);
    }
    Ok(blocks)
}

/// Writes every coefficient to the probe at `slave` and reads it back.
pub fn write_blocks(opened: &mut Opened, entry: &Entry, slave: u8, blocks: &Blocks) -> Result<()> {
    let ctx = opened.context(slave, "the coefficient writes");
    if is_typed(entry, "ph_orp") {
        let c = PhOrpCoefficients {
            electrode: take(
                blocks,
                ph_orp::SetPhElectrodeCoefficients::NAME,
                &ph_orp::SetPhElectrodeCoefficients::FIELDS,
            )?,
            ph_calibration: take(blocks, ph_orp::SetPhCalibration::NAME, &ph_orp::SetPhCalibration::FIELDS)?,
            orp_calibration: take(blocks, ph_orp::SetOrpCalibration::NAME, &ph_orp::SetOrpCalibration::FIELDS)?,
        };
        let mut probe = ph_orp::Device::new(&mut opened.bus, slave);
        return write_ph_orp(&mut probe, &c).map_err(|e| procedure_failed(&e, &ctx));
    }
    if is_typed(entry, "conductivity") {
        let user_calibration =
            take(blocks, conductivity::SetUserCalibration::NAME, &conductivity::SetUserCalibration::FIELDS)?;
        let mut probe = conductivity::Device::new(&mut opened.bus, slave);
        return write_conductivity(&mut probe, &ConductivityCoefficients { user_calibration })
            .map_err(|e| procedure_failed(&e, &ctx));
    }
    let sensor = entry.sensor.clone();
    let pairs = coefficient_blocks(&sensor);
    // Check the whole file before writing anything.
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
        device::call(opened, write, slave, &fields)?;
        let back = device::read(opened, read, slave)?;
        let same = back.iter().all(|(name, v)| fields.get(name).is_none_or(|want| want.same_as(v)));
        if !same {
            return Err(CliError::device(format!("verification failed: {} did not read back as written", write.name))
                .hint("the probe did not keep the values written; read them with `yosemitech read` and retry"));
        }
    }
    Ok(())
}

/// The probe's serial number, if it answers `get_sn`.
pub fn serial_number(opened: &mut Opened, entry: &Entry, slave: u8) -> Option<String> {
    let command = entry.sensor.command("get_sn")?;
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
    Ok(Backup {
        sensor: entry.sensor.name.clone(),
        address: slave,
        port: opened.port.clone(),
        serial_number,
        saved_at: time::rfc3339(SystemTime::now()),
        blocks,
    })
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

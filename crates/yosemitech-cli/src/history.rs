//! Where the calibration history lives, and recording a calibration in it.
//!
//! The history is a station store's `calibration` table
//! ([`yosemitech_station::calibration`]): the station's own store with
//! `--config station.toml` (so its readings name the calibration in force),
//! the file `--history` names, or else `calibrations.sqlite` in the user's
//! data directory (`$XDG_DATA_HOME/yosemitech`, else
//! `~/.local/share/yosemitech`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::SystemTime;

use serde_json::{Map, Value as Json};
use yosemitech_spec::{Role, Value};
use yosemitech_station::config::{self, ConfigErrors};
use yosemitech_station::{Calibration, Store};

use crate::args::HistoryArgs;
use crate::backup::Blocks;
use crate::catalog::{Catalog, Entry};
use crate::device;
use crate::error::{CliError, Result};
use crate::format::f32_json;
use crate::port::Opened;

/// The history file, when neither `--config` nor `--history` names one.
fn default_file() -> Result<PathBuf> {
    let from = |var: &str| std::env::var_os(var).filter(|v| !v.is_empty()).map(PathBuf::from);
    let base =
        from("XDG_DATA_HOME").or_else(|| from("HOME").map(|home| home.join(".local/share"))).ok_or_else(|| {
            CliError::usage("no place for the calibration history: neither XDG_DATA_HOME nor HOME is set")
                .hint("give --history FILE, or --config station.toml to keep it in the station's store")
        })?;
    Ok(base.join("yosemitech").join("calibrations.sqlite"))
}

/// The history file `args` names.
pub fn file(catalog: &Catalog, args: &HistoryArgs) -> Result<PathBuf> {
    if let Some(path) = &args.config {
        let sensors: Vec<_> = catalog.entries().iter().map(|e| Arc::clone(&e.sensor)).collect();
        let station = config::load(path, &sensors).map_err(|ConfigErrors(errors)| {
            let first = errors.first().map_or_else(|| format!("{} is not valid", path.display()), ToString::to_string);
            CliError::usage(first).hint("`yosemitech log --config FILE --check` shows every problem of the file")
        })?;
        return Ok(station.storage);
    }
    match &args.history {
        Some(path) => Ok(path.clone()),
        None => default_file(),
    }
}

/// Opens (creating it if absent) the history `args` names.
pub fn open(catalog: &Catalog, args: &HistoryArgs) -> Result<(Store, PathBuf)> {
    let path = file(catalog, args)?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty() && !d.exists()) {
        std::fs::create_dir_all(dir).map_err(|e| {
            CliError::device(format!("cannot create {} for the calibration history: {e}", dir.display()))
        })?;
    }
    let store = Store::open(&path).map_err(|e| opening_failed(&path, &e))?;
    Ok((store, path))
}

fn opening_failed(path: &Path, e: &dyn std::fmt::Display) -> CliError {
    CliError::device(format!("cannot open the calibration history {}: {e}", path.display()))
        .hint("give another file with --history FILE")
}

/// The probe's serial number and firmware as the station stores them
/// (text trimmed of padding), for the readings to find its calibrations.
pub fn identity(opened: &mut Opened, entry: &Entry, slave: u8) -> (Option<String>, Option<String>) {
    let mut text_of = |role: Role| -> Option<String> {
        let command = entry.sensor.command_with_role(role)?;
        let values = device::read(opened, command, slave).ok()?;
        values.into_iter().find_map(|(_, v)| match v {
            Value::Text(t) => Some(t.trim_end_matches(['\0', ' ']).to_owned()).filter(|t| !t.is_empty()),
            Value::Version(v) => Some(v.to_string()),
            _ => None,
        })
    };
    (text_of(Role::SerialNumber), text_of(Role::Version))
}

/// Coefficient blocks as JSON: `{block: {field: value}}`, floats bit-exact.
pub fn blocks_json(blocks: &Blocks) -> Json {
    Json::Object(
        blocks
            .iter()
            .map(|(name, fields)| {
                (name.clone(), Json::Object(fields.iter().map(|(k, v)| (k.clone(), f32_json(*v))).collect()))
            })
            .collect::<Map<String, Json>>(),
    )
}

/// What every calibration record of a probe starts with.
pub struct Probe<'a> {
    /// Its spec entry.
    pub entry: &'a Entry,
    /// Its address.
    pub address: u8,
    /// The port.
    pub port: String,
    /// Its serial number and firmware ([`identity`]).
    pub identity: (Option<String>, Option<String>),
}

impl Probe<'_> {
    /// A record of a calibration of `kind` done now, the rest empty.
    pub fn record(&self, kind: &str, note: Option<&str>) -> Calibration {
        Calibration {
            timestamp: SystemTime::now(),
            sensor: self.entry.sensor.name.clone(),
            model: self.entry.sensor.model.clone(),
            serial_number: self.identity.0.clone(),
            firmware: self.identity.1.clone(),
            address: self.address,
            port: self.port.clone(),
            kind: kind.to_owned(),
            block: None,
            note: note.map(str::to_owned),
            before: Json::Object(Map::new()),
            after: Json::Object(Map::new()),
            standards: Json::Array(Vec::new()),
            readings: Json::Array(Vec::new()),
            fit: None,
        }
    }
}

/// Records `calibration` in `store` and says so. The probe already holds
/// the new coefficients: a failure says that too.
pub fn record(store: &mut Store, path: &Path, calibration: &Calibration, out: &mut dyn Write) -> Result<i64> {
    let id = store.record_calibration(calibration).map_err(|e| {
        CliError::device(format!("the probe is calibrated, but the calibration could not be recorded: {e}"))
            .hint(format!("the history is {}; the coefficient backup file keeps the previous values", path.display()))
    })?;
    writeln!(out, "recorded as calibration {id} in {}", path.display())?;
    Ok(id)
}

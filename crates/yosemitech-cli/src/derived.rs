//! Derived quantities beside the measured values, through
//! `yosemitech_spec::beside` (the station logger's implementation too):
//! here only the command line's station inputs (`--input NAME=VALUE`) and
//! how the CLI shows the defaults it assumed.

use std::collections::BTreeMap;

use serde_json::json;
use yosemitech_spec::Sensor;
use yosemitech_spec::beside::{self, DerivedValue, station_inputs};

use crate::error::{CliError, Result};
use crate::format::f32_json;

/// Parses `NAME=VALUE` of `--input` (the sensor is checked later, when known).
pub fn parse_input(text: &str) -> std::result::Result<(String, f64), String> {
    let (name, value) = text.split_once('=').ok_or_else(|| format!("`{text}` is not NAME=VALUE (e.g. salinity=35)"))?;
    let name = name.trim();
    if name.is_empty() {
        return Err(format!("`{text}` names no input: write NAME=VALUE"));
    }
    let number: f64 = value.trim().parse().map_err(|_| format!("`{}` is not a number (in `{text}`)", value.trim()))?;
    if !number.is_finite() {
        return Err(format!("`{}` is not a finite number (in `{text}`)", value.trim()));
    }
    Ok((name.to_owned(), number))
}

/// The `--input`s given, checked against `sensor`'s derived quantities:
/// every name one of them takes, every value within its range, no name twice.
pub fn station(sensor: &Sensor, given: &[(String, f64)]) -> Result<BTreeMap<String, f64>> {
    let mut out = BTreeMap::new();
    for (name, value) in given {
        beside::check_station_input(sensor, name, *value).map_err(|e| {
            let hint = if station_inputs(sensor).is_empty() {
                format!("`yosemitech list {}` shows its derived quantities; leave out --input", sensor.name)
            } else {
                format!("`yosemitech list {}` shows its derived quantities and their inputs", sensor.name)
            };
            CliError::usage(e.to_string()).hint(hint)
        })?;
        if out.insert(name.clone(), *value).is_some() {
            return Err(CliError::usage(format!("--input {name} is given twice")).hint("give each input once"));
        }
    }
    Ok(out)
}

/// `station inputs at the spec's default: salinity = 0 ppt, ...`, when any
/// quantity shown took a default, so a reader knows what was assumed.
pub fn defaults_note(sensor: &Sensor, derived: &[DerivedValue<'_>]) -> Option<String> {
    let mut seen: Vec<(&str, f64)> = Vec::new();
    for d in derived {
        for (name, value) in &d.defaulted {
            if !seen.iter().any(|(n, _)| n == name) {
                seen.push((name, *value));
            }
        }
    }
    if seen.is_empty() {
        return None;
    }
    let inputs = station_inputs(sensor);
    let parts: Vec<String> = seen
        .iter()
        .map(|(name, value)| {
            let unit = inputs
                .iter()
                .find(|s| s.name == *name)
                .and_then(|s| s.uses.first())
                .and_then(|(_, i)| i.unit.as_deref())
                .map(|u| format!(" {u}"))
                .unwrap_or_default();
            format!("{name} = {value}{unit}")
        })
        .collect();
    Some(format!("station inputs at the spec's default: {} (give --input NAME=VALUE)", parts.join(", ")))
}

/// Derived quantities as JSON: `{name: {value, unit, defaults}}` or
/// `{name: {error, unit, defaults}}`, `defaults` the station inputs that
/// took the spec's default (`{name: value}`).
pub fn derived_json(derived: &[DerivedValue<'_>]) -> serde_json::Value {
    let map: serde_json::Map<String, serde_json::Value> = derived
        .iter()
        .map(|d| {
            let defaults: serde_json::Map<String, serde_json::Value> =
                d.defaulted.iter().map(|(n, v)| ((*n).to_owned(), json!(v))).collect();
            let v = match &d.value {
                Ok(v) => json!({"value": f32_json(*v), "unit": d.quantity.unit, "defaults": defaults}),
                Err(why) => json!({"error": why, "unit": d.quantity.unit, "defaults": defaults}),
            };
            (d.quantity.name.clone(), v)
        })
        .collect();
    serde_json::Value::Object(map)
}

//! Probes identified as `scan` identifies them (`yosemitech_ops::identify`),
//! rendered: the line `scan` prints, its JSON, and the summary other
//! commands (the demo, `set-address --plan`) act on.

use serde_json::json;
use yosemitech_ops::{Identification as Found, Identifier, IdentifyError, printable};
use yosemitech_rtu::Version;
use yosemitech_spec::Sensor;

use crate::catalog::Catalog;
use crate::error::{CliError, Result, request_failed};
use crate::port::Opened;

/// Identifies the device at `address` on `opened`; a port that fails is
/// the CLI's error for a failed request.
pub fn identify<'c>(identifier: &Identifier<'c>, opened: &mut Opened, address: u8) -> Result<Option<Found<'c>>> {
    identifier.identify(&mut opened.bus, address).map_err(|e| match e {
        IdentifyError::Request { .. } => CliError::usage(e.to_string()),
        IdentifyError::Bus { command, error } => {
            request_failed(&error, opened.bus.last_reply(), &opened.context(address, &command))
        }
    })
}

/// A device identified as `scan` identifies it, for other commands (the
/// demo, `set-address --plan`).
pub struct Identification<'c> {
    /// The line `scan` prints for it.
    pub line: String,
    /// The sensor, when exactly one loaded sensor matches.
    pub sensor: Option<&'c Sensor>,
    /// The loaded sensors it may be (one when identified).
    pub candidates: Vec<&'c Sensor>,
    /// Its serial number as printed (control characters escaped), if it answered one.
    pub serial_number: Option<String>,
    /// The models it is: one, or several that no read tells apart.
    pub models: Vec<String>,
    /// Its software revision, if it answered the version read.
    pub software: Option<Version>,
}

/// Identifies the device at `address` on `opened` with the reads `scan`
/// makes; `None` when nothing answers (or no loaded sensor has a
/// serial-number read).
pub fn identify_at<'c>(catalog: &'c Catalog, opened: &mut Opened, address: u8) -> Result<Option<Identification<'c>>> {
    let identifier = Identifier::new(catalog.entries().iter().map(|e| e.sensor.as_ref()));
    let found = identify(&identifier, opened, address)?;
    Ok(found.map(|f| Identification {
        line: found_line(&f),
        sensor: f.identified,
        candidates: f.candidates.clone(),
        serial_number: f.serial_number.as_deref().map(printable),
        models: f.models.clone(),
        software: f.software,
    }))
}

pub fn found_json(f: &Found<'_>) -> serde_json::Value {
    json!({
        "address": f.address,
        "serial_number": f.serial_number,
        "model_code": f.model_code,
        "sensors": f.candidates.iter().map(|s| s.name.as_str()).collect::<Vec<_>>(),
        "sensor": f.identified.map(|s| s.name.as_str()),
        "model": f.identified.and_then(|s| s.model.as_deref()),
        "models": f.models,
        "models_reason": f.models_reason,
        "telling_reads": f.telling_reads,
        "reason": f.reason,
        "hardware": f.hardware.map(|v| v.to_string()),
        "software": f.software.map(|v| v.to_string()),
        "manual": f.manual.map(|m| json!({
            "title": m.title,
            "revision": m.revision,
            "software": m.software,
            "file": m.file,
        })),
        "notes": f.notes,
    })
}

pub fn found_line(f: &Found<'_>) -> String {
    let sn = f.serial_number.as_deref().map_or_else(|| "?".to_owned(), printable);
    let mut line = format!("address {:3}  SN {sn:12}  ", f.address);
    match (f.identified, &f.reason) {
        (Some(sensor), _) => {
            line.push_str(&sensor_text(sensor));
            if f.models.len() > 1 || f.models.first().is_some_and(|m| Some(m) != sensor.model.as_ref()) {
                line.push_str(&format!(": model {}", f.models.join(" or ")));
            }
            if let Some(why) = &f.models_reason {
                line.push_str(&format!(" ({why})"));
            }
            if !f.telling_reads.is_empty() {
                line.push_str(&format!(" [told apart by {}]", f.telling_reads.join(", ")));
            }
        }
        (None, reason) => {
            let candidates: Vec<String> = f.candidates.iter().map(|s| sensor_text(s)).collect();
            let which = match candidates.as_slice() {
                [] => "no loaded sensor".to_owned(),
                [one] => format!("perhaps {one}"),
                many => format!("one of {}", many.join(", ")),
            };
            line.push_str(&format!("not identified: {which}"));
            if let Some(reason) = reason {
                line.push_str(&format!(" ({reason})"));
            }
        }
    }
    if let Some(hw) = f.hardware {
        line.push_str(&format!("  HW {hw}"));
    }
    if let Some(sw) = f.software {
        line.push_str(&format!(" SW {sw}"));
    }
    if let Some(sw) = f.manual.and_then(|m| m.software.as_deref()) {
        line.push_str(&format!("  manual SW {sw}"));
    }
    if !f.notes.is_empty() {
        line.push_str(&format!("  ({})", f.notes.join("; ")));
    }
    line
}

/// `conductivity (Y520, code 09)`.
fn sensor_text(s: &Sensor) -> String {
    let about: Vec<String> = s.model.iter().cloned().chain(s.model_code.iter().map(|c| format!("code {c}"))).collect();
    if about.is_empty() { s.name.clone() } else { format!("{} ({})", s.name, about.join(", ")) }
}

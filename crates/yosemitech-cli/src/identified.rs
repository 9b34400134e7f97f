//! Probes identified as `scan` identifies them (`yosemitech_ops::identify`),
//! with the CLI's errors, and rendered: the line `scan` prints and its JSON.

use serde_json::json;
use yosemitech_ops::{Identification as Found, Identifier, TransactionError, printable};
use yosemitech_spec::Sensor;

use crate::catalog::Catalog;
use crate::error::{CliError, Result, request_failed};
use crate::port::Opened;

/// Identifies the device at `address` on `opened`; a port that fails is
/// the CLI's error for a failed request.
pub fn identify<'c>(identifier: &Identifier<'c>, opened: &mut Opened, address: u8) -> Result<Option<Found<'c>>> {
    identifier.identify(&mut opened.bus, address).map_err(|e| match e {
        TransactionError::Bus { command, error } => {
            request_failed(&error, opened.bus.last_reply(), &opened.context(address, &command))
        }
        other => CliError::usage(format!("{}: {other}", other.command())),
    })
}

/// Identifies the device at `address` on `opened` with every loaded
/// sensor's reads, as `scan` does (for the demo, `set-address --plan`);
/// `None` when nothing answers (or no loaded sensor has a serial-number read).
pub fn identify_at<'c>(catalog: &'c Catalog, opened: &mut Opened, address: u8) -> Result<Option<Found<'c>>> {
    identify(&Identifier::new(catalog.entries().iter().map(|e| e.sensor.as_ref())), opened, address)
}

/// What `scan --json` prints of a device.
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

/// The line `scan` prints for a device.
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

//! `yosemitech read`: any read command, values with units.

use std::io::Write;
use std::time::SystemTime;

use serde_json::json;
use yosemitech_spec::{CommandSpec, Values};

use crate::catalog::{self, Catalog};
use crate::cli::{Global, ReadArgs};
use crate::device;
use crate::error::{CliError, Result};
use crate::format::{fields_json, value_with_unit, values_json};
use crate::{port, time};

/// Runs `read`.
pub fn run(catalog: &Catalog, global: &Global, args: &ReadArgs, out: &mut dyn Write) -> Result<()> {
    let sensor = catalog.sensor(&args.sensor)?;
    let command = catalog::command(sensor, &args.command)?;
    if !command.is_read() {
        return Err(CliError::usage(format!("`{}` is a write command", command.name))
            .hint(format!("send it with `yosemitech write {} {} ...`", sensor.name, command.name)));
    }
    let address = args.address.get(sensor.default_address)?;
    let mut opened = port::open(&args.port, global, &sensor.serial)?;
    let values = device::read(&mut opened, command, address)?;
    if args.json {
        let doc = json!({
            "sensor": sensor.name,
            "command": command.name,
            "address": device::target(command, address),
            "port": opened.port,
            "timestamp": time::rfc3339(SystemTime::now()),
            "values": values_json(&values),
            "fields": fields_json(command, &values),
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&doc).unwrap_or_default())?;
    } else {
        show(command, &values, out)?;
    }
    Ok(())
}

/// Values as aligned `name  value unit` lines.
pub fn show(command: &CommandSpec, values: &Values, out: &mut dyn Write) -> Result<()> {
    let width = values.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
    for (name, value) in values {
        writeln!(out, "{name:width$}  {}", value_with_unit(value, command.field(name)))?;
    }
    Ok(())
}

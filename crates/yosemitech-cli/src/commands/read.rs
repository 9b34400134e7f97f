//! `yosemitech read`: any read command, values with units.

use std::io::Write;
use std::time::SystemTime;

use serde_json::json;
use yosemitech_spec::{CommandSpec, Derived, Values};

use crate::args::InputArgs;
use crate::catalog::{self, Catalog};
use crate::derived;
use crate::device;
use crate::error::{CliError, Result};
use crate::format::{derived_text, fields_json, value_with_unit, values_json};
use crate::port::AddressArg;
use crate::port::PortArgs;
use crate::units::{self, Chosen};
use crate::{port, time};
use clap::Args;
use yosemitech_spec::beside::{self, DerivedValue};

/// `read`.
#[derive(Args, Debug)]
pub struct ReadArgs {
    /// Sensor (`yosemitech list` shows them).
    pub sensor: String,
    /// Read command (`yosemitech list SENSOR` shows them; without one, `read` names them).
    pub command: Option<String>,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub inputs: InputArgs,
    /// Show values in another unit of the same dimension: `UNIT` for every
    /// value of its dimension (`degF`, `uS/cm`), `NAME=UNIT` for one field
    /// or derived quantity; repeatable.
    #[arg(long = "unit", value_name = "[NAME=]UNIT")]
    pub units: Vec<String>,
}

/// Runs `read`.
pub fn run(catalog: &Catalog, args: &ReadArgs, out: &mut dyn Write) -> Result<()> {
    let sensor = catalog.sensor(&args.sensor)?;
    let Some(name) = args.command.as_deref() else {
        return Err(which_read(sensor));
    };
    let command = catalog::command(sensor, name)?;
    if !command.is_read() {
        return Err(CliError::usage(format!("`{}` is a write command", command.name))
            .hint(format!("send it with `yosemitech write {} {} ...`", sensor.name, command.name)));
    }
    let station = derived::station(sensor, &args.inputs.inputs)?;
    let address = args.address.get(sensor.default_address)?;
    // The units are checked before the port opens: a typo costs no transaction.
    let covered: Vec<&Derived> =
        beside::beside(sensor, &|c, _| c == command.name, &|_, _| None, &|_| None).iter().map(|d| d.quantity).collect();
    let chosen = Chosen::resolve(&args.units, &units::quantities(command, &covered), &sensor.name)?;
    let mut opened = port::open(&args.port, &sensor.serial)?;
    let values = device::read(&mut opened, command, address)?;
    let lookup = |c: &str, f: &str| {
        if c == command.name {
            values.iter().find(|(n, _)| n == f).and_then(|(_, v)| beside::field_number(v))
        } else {
            None
        }
    };
    // Derived quantities take the spec's units: convert after computing them.
    let derived = beside::beside(sensor, &|c, _| c == command.name, &lookup, &|name: &str| station.get(name).copied());
    let (command, values) = (&chosen.command(command), chosen.values(&values));
    let quantities: Vec<Derived> = derived.iter().map(|d| chosen.derived(d.quantity)).collect();
    let derived: Vec<DerivedValue<'_>> = derived
        .iter()
        .zip(&quantities)
        .map(|(d, q)| DerivedValue {
            quantity: q,
            value: d.value.clone().map(|v| chosen.number(&q.name, v)),
            defaulted: d.defaulted.clone(),
        })
        .collect();
    if args.json {
        let doc = json!({
            "sensor": sensor.name,
            "command": command.name,
            "address": device::target(command, address),
            "port": opened.port,
            "timestamp": time::rfc3339(SystemTime::now()),
            "values": values_json(&values),
            "fields": fields_json(command, &values),
            "derived": derived::derived_json(&derived),
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&doc).unwrap_or_default())?;
    } else {
        show(command, &values, out)?;
        show_derived(&derived, out)?;
        if let Some(note) = derived::defaults_note(sensor, &derived) {
            writeln!(out, "note: {note}")?;
        }
    }
    Ok(())
}

/// Derived quantities as `name  value unit  (derived)` lines, or why there is none.
pub fn show_derived(derived: &[DerivedValue<'_>], out: &mut dyn Write) -> Result<()> {
    let width = derived.iter().map(|d| d.quantity.name.len()).max().unwrap_or(0);
    for d in derived {
        writeln!(out, "{:width$}  {}", d.quantity.name, derived_text(d, None))?;
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

/// The error of a `read` that names no command: the sensor's reads, and the
/// commands that read every measurement at once.
fn which_read(sensor: &yosemitech_spec::Sensor) -> CliError {
    let reads: Vec<&str> = sensor.commands.iter().filter(|c| c.is_read()).map(|c| c.name.as_str()).collect();
    let example = sensor.measurement_reads().next().map_or("COMMAND", |c| c.name.as_str());
    CliError::usage(format!("say which read of `{}`: {}", sensor.name, reads.join(", "))).hint(format!(
        "e.g. `yosemitech read {0} {example} --port PORT`; `yosemitech poll {0} -n 1 --port PORT` reads every \
         measurement once, `yosemitech list {0}` describes each read",
        sensor.name
    ))
}

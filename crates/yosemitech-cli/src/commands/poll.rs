//! `yosemitech poll`: timestamped measurements for loggers, read with the
//! fewest transactions that cover them (`yosemitech_station::plan`).

use std::collections::BTreeMap;
use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

use serde_json::{Map, Value as Json, json};
use yosemitech_spec::units::Quantity;
use yosemitech_spec::{CommandSpec, Derived, Sensor, Value};

use yosemitech_station::plan;

use crate::args::InputArgs;
use crate::catalog::Catalog;
use crate::derived;
use crate::derived::derived_json;
use crate::error::{CliError, Result, short};
use crate::format::{csv_field, parse_duration};
use crate::format::{unit, value_json, value_text};
use crate::port::AddressArg;
use crate::port::PortArgs;
use crate::units::Chosen;
use crate::{device, port, time};
use clap::Args;
use clap::ValueEnum;
use yosemitech_spec::beside::{self, DerivedValue};

/// Output formats of `poll`.
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PollFormat {
    /// Aligned columns with units.
    #[default]
    Table,
    /// Comma-separated values with a header row.
    Csv,
    /// One JSON object per line.
    Json,
}

/// `poll`.
#[derive(Args, Debug)]
pub struct PollArgs {
    /// Sensor.
    pub sensor: String,
    /// Measurements to read: field names or measurement reads (`yosemitech list SENSOR`) [default: every one].
    #[arg(value_name = "MEASUREMENT")]
    pub measurements: Vec<String>,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Time between the starts of two polls; 0 polls back to back.
    #[arg(short, long, value_name = "DURATION", default_value = "3s", value_parser = parse_duration)]
    pub interval: Duration,
    /// Stop after N polls [default: until Ctrl-C].
    #[arg(short = 'n', long, value_name = "N")]
    pub count: Option<u64>,
    /// Output format.
    #[arg(short, long, value_enum, default_value_t = PollFormat::Table)]
    pub format: PollFormat,
    #[command(flatten)]
    pub inputs: InputArgs,
    /// Show values in another unit of the same dimension: `UNIT` for every
    /// value of its dimension (`degF`, `uS/cm`), `NAME=UNIT` for one field
    /// or derived quantity; repeatable.
    #[arg(long = "unit", value_name = "[NAME=]UNIT")]
    pub units: Vec<String>,
}

/// One output column: a chosen measurement and the planned read it comes from.
struct Column<'s> {
    command: &'s CommandSpec,
    field: &'s str,
    unit: Option<String>,
    /// The unit as the spec spells it (`degF`), when the column has one.
    symbol: Option<&'s str>,
    /// Shown in a unit `--unit` chose: CSV's header then names the unit.
    converted: bool,
}

/// A value as a logger wants it: numbers plain, enums by name.
fn plain(value: &Value) -> String {
    match value {
        Value::Enum { name: Some(name), .. } => name.clone(),
        Value::Enum { raw, name: None } => raw.to_string(),
        other => value_text(other),
    }
}

/// Runs `poll` until `count` polls are done or `stop` is set (Ctrl-C).
pub fn run(catalog: &Catalog, args: &PollArgs, stop: &Arc<AtomicBool>, out: &mut dyn Write) -> Result<()> {
    let sensor = catalog.sensor(&args.sensor)?;
    let chosen = plan::choose(sensor, &args.measurements).map_err(|e| {
        CliError::usage(e.to_string())
            .hint("poll reads the measurements named (fields or reads), every one by default; `yosemitech list SENSOR` shows them")
    })?;
    // The fewest reads that cover the chosen measurements.
    let planned = plan::plan(sensor, &chosen);
    let reads: Vec<&CommandSpec> = planned.reads.iter().map(|r| r.command).collect();
    let station = derived::station(sensor, &args.inputs.inputs)?;
    let station = |name: &str| station.get(name).copied();
    let address = args.address.get(sensor.default_address)?;
    let read_names: Vec<&str> = reads.iter().map(|c| c.name.as_str()).collect();
    // The units are checked before the port opens: a typo costs no transaction.
    let chosen = choose_units(sensor, &planned, &read_names, &args.units)?;
    let mut opened = port::open(&args.port, &sensor.serial)?;

    let columns: Vec<Column<'_>> = planned
        .reads
        .iter()
        .flat_map(|r| {
            r.fields.iter().map(|f| {
                let symbol = chosen.unit(f, r.command.field(f).and_then(|f| f.unit.as_deref()));
                Column {
                    command: r.command,
                    field: f,
                    unit: symbol.map(|u| unit(u).to_owned()),
                    symbol,
                    converted: chosen.conversion(f).is_some(),
                }
            })
        })
        .collect();
    let widths: Vec<usize> =
        columns.iter().map(|c| (c.field.len() + c.unit.as_ref().map_or(0, |u| u.chars().count() + 3)).max(9)).collect();
    // Derived quantities whose field inputs the planned reads give, after the measured columns.
    let was_read = |c: &str, _: &str| read_names.contains(&c);
    let heads = beside::beside(sensor, &was_read, &|_, _| None, &station);
    let derived_heads: Vec<String> = heads
        .iter()
        .map(|d| match chosen.unit(&d.quantity.name, d.quantity.unit.as_deref()) {
            Some(u) => format!("{} [{}] (derived)", d.quantity.name, unit(u)),
            None => format!("{} (derived)", d.quantity.name),
        })
        .collect();
    let derived_widths: Vec<usize> = derived_heads.iter().map(|h| h.chars().count().max(9)).collect();

    match args.format {
        PollFormat::Table => {
            if let Some(note) = derived::defaults_note(sensor, &heads) {
                writeln!(out, "note: {note}")?;
            }
            write!(out, "{:24}", "timestamp")?;
            for (c, w) in columns.iter().zip(&widths) {
                let head = match &c.unit {
                    Some(u) => format!("{} [{u}]", c.field),
                    None => c.field.to_owned(),
                };
                write!(out, "  {head:>w$}")?;
            }
            for (head, w) in derived_heads.iter().zip(&derived_widths) {
                write!(out, "  {head:>w$}")?;
            }
            writeln!(out, "  error")?;
        }
        PollFormat::Csv => {
            // A converted column names its unit: the spec's unit is no longer the column's.
            let head = |c: &Column<'_>| match (&c.unit, c.converted) {
                (Some(u), true) => csv_field(&format!("{} [{u}]", c.field)),
                _ => csv_field(c.field),
            };
            let names: Vec<String> =
                columns.iter().map(head).chain(derived_heads.iter().map(|h| csv_field(h))).collect();
            writeln!(out, "timestamp,{},error", names.join(","))?;
        }
        PollFormat::Json => {}
    }
    out.flush()?;

    let (mut polls, mut failed) = (0u64, 0u64);
    while args.count.is_none_or(|n| polls < n) && !stop.load(Ordering::SeqCst) {
        let started = Instant::now();
        let timestamp = time::rfc3339(SystemTime::now());
        let mut values: BTreeMap<&str, BTreeMap<String, Value>> = BTreeMap::new();
        // Failed commands grouped by what went wrong: "no reply: get_ph, get_orp".
        let mut failures: Vec<(String, Vec<&str>)> = Vec::new();
        for command in &reads {
            match device::try_read(&mut opened, command, address)? {
                Ok(v) => {
                    values.insert(&command.name, v.into_iter().collect());
                }
                Err(e) => {
                    let why = short(&e, opened.bus.last_reply());
                    match failures.iter_mut().find(|(w, _)| *w == why) {
                        Some((_, names)) => names.push(&command.name),
                        None => failures.push((why, vec![&command.name])),
                    }
                }
            }
        }
        let errors: Vec<String> = failures.iter().map(|(why, names)| format!("{}: {why}", names.join(", "))).collect();
        polls += 1;
        if values.is_empty() {
            failed += 1;
        }
        let cell = |c: &Column<'_>| {
            values.get(c.command.name.as_str()).and_then(|v| v.get(c.field)).map(|v| chosen.value(c.field, v))
        };
        let lookup = |c: &str, f: &str| values.get(c).and_then(|v| v.get(f)).and_then(beside::field_number);
        let computed = beside::beside(sensor, &was_read, &lookup, &station);
        let quantities: Vec<Derived> = computed.iter().map(|d| chosen.derived(d.quantity)).collect();
        let derived_cell =
            |d: &DerivedValue<'_>| d.value.as_ref().map(|v| chosen.number(&d.quantity.name, *v).to_string()).ok();
        let error = errors.join("; ");
        match args.format {
            PollFormat::Table => {
                write!(out, "{timestamp:24}")?;
                for (c, w) in columns.iter().zip(&widths) {
                    write!(out, "  {:>w$}", cell(c).as_ref().map(plain).unwrap_or_else(|| "-".into()))?;
                }
                for (d, w) in computed.iter().zip(&derived_widths) {
                    write!(out, "  {:>w$}", derived_cell(d).unwrap_or_else(|| "-".into()))?;
                }
                if error.is_empty() {
                    writeln!(out)?;
                } else {
                    writeln!(out, "  {error}")?;
                }
            }
            PollFormat::Csv => {
                let cells: Vec<String> = columns
                    .iter()
                    .map(|c| csv_field(&cell(c).as_ref().map(plain).unwrap_or_default()))
                    .chain(computed.iter().map(|d| csv_field(&derived_cell(d).unwrap_or_default())))
                    .collect();
                writeln!(out, "{timestamp},{},{}", cells.join(","), csv_field(&error))?;
            }
            PollFormat::Json => {
                let map: Map<String, Json> = columns
                    .iter()
                    .map(|c| (c.field.to_owned(), cell(c).as_ref().map_or(Json::Null, value_json)))
                    .collect();
                let units: Map<String, Json> = columns
                    .iter()
                    .filter_map(|c| c.symbol.map(|u| (c.field.to_owned(), Json::String(u.to_owned()))))
                    .collect();
                let row = json!({
                    "timestamp": timestamp,
                    "values": map,
                    "units": units,
                    "derived": derived_json(&shown_derived(&chosen, &computed, &quantities)),
                    "error": if errors.is_empty() { Json::Null } else { Json::String(error) },
                });
                writeln!(out, "{row}")?;
            }
        }
        out.flush()?;
        if args.count.is_some_and(|n| polls >= n) {
            break;
        }
        let next = started + args.interval;
        while !stop.load(Ordering::SeqCst) {
            let left = next.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            std::thread::sleep(left.min(Duration::from_millis(50)));
        }
    }
    out.flush()?;
    if polls > 0 && failed == polls {
        return Err(CliError::device(format!(
            "every poll failed ({polls} of {polls}) on {} at address {address}",
            opened.port
        ))
        .hint("the error column says why; check the port, the address and the sensor type"));
    }
    Ok(())
}

/// The units `--unit` asks for, resolved against the planned columns and
/// the derived quantities beside them.
fn choose_units(sensor: &Sensor, planned: &plan::Plan<'_>, reads: &[&str], args: &[String]) -> Result<Chosen> {
    let was_read = |c: &str, _: &str| reads.contains(&c);
    let beside = beside::beside(sensor, &was_read, &|_, _| None, &|_| None);
    let quantities: Vec<Quantity<'_>> = planned
        .reads
        .iter()
        .flat_map(|r| {
            r.fields.iter().map(|f| Quantity { name: f, unit: r.command.field(f).and_then(|f| f.unit.as_deref()) })
        })
        .chain(beside.iter().map(|d| Quantity { name: &d.quantity.name, unit: d.quantity.unit.as_deref() }))
        .collect();
    Chosen::resolve(args, &quantities, &sensor.name)
}

/// Derived values in their chosen units, each beside its quantity as shown (`quantities`, in the same order).
fn shown_derived<'q>(
    chosen: &Chosen,
    computed: &[DerivedValue<'q>],
    quantities: &'q [Derived],
) -> Vec<DerivedValue<'q>> {
    computed
        .iter()
        .zip(quantities)
        .map(|(d, q)| DerivedValue {
            quantity: q,
            value: d.value.clone().map(|v| chosen.number(&q.name, v)),
            defaulted: d.defaulted.clone(),
        })
        .collect()
}

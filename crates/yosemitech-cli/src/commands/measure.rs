//! `yosemitech measure SENSOR`: the measuring procedure a sensor's spec
//! states (its manual's section 3), run through the interpreter, with
//! progress bars. Nothing here knows a sensor: the commands to send, the
//! waits, the reads and the number of readings all come from the spec's
//! `procedure`.

use std::collections::BTreeMap;
use std::io::Write;
use std::time::{Duration, SystemTime};

use serde_json::{Map, Value as Json, json};
use yosemitech_spec::{CommandSpec, Field, FieldKind, Procedure, Role, Sensor, Value};

use yosemitech_spec::beside::{self, DerivedValue};

use crate::args::InputArgs;
use crate::catalog::Catalog;
use crate::derived::derived_json;
use crate::error::{CliError, Result};
use crate::format::parse_duration;
use crate::format::{derived_text, f32_json, field_value_text, unit, value_json};
use crate::port::AddressArg;
use crate::port::PortArgs;
use crate::port::{self, Opened};
use crate::{derived, device, progress, time};
use clap::Args;
use yosemitech_ops::procedure::{Timing, describe};

/// `measure`.
#[derive(Args, Debug)]
pub struct MeasureArgs {
    /// Sensor (`yosemitech list` shows which have a procedure).
    pub sensor: String,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Override the warm-up (tests, demos).
    #[arg(long, hide = true, value_parser = parse_duration)]
    pub warm_up: Option<Duration>,
    /// Override the reading interval (tests, demos).
    #[arg(long, hide = true, value_parser = parse_duration)]
    pub interval: Option<Duration>,
    /// Override the number of readings averaged (tests, demos).
    #[arg(long, hide = true)]
    pub readings: Option<u32>,
    /// Shorthand for --warm-up 0 --interval 0 (tests, demos).
    #[arg(long, hide = true)]
    pub fast: bool,
    #[command(flatten)]
    pub inputs: InputArgs,
}

/// What the readings of one field came to.
#[derive(Debug, Clone)]
pub struct FieldResult {
    /// The read command.
    pub command: String,
    /// The field (its spec).
    pub field: Field,
    /// The name shown: the field's, or `command.field` where two reads share a field name.
    pub label: String,
    /// Sum, count, least and greatest of the numeric readings averaged.
    sum: f64,
    /// Numeric readings averaged.
    pub count: u32,
    min: f64,
    max: f64,
    /// Readings of the field's `absent` value (a sub-probe not fitted).
    pub absent: u32,
    /// Readings that were not finite (NaN, infinity): not averaged.
    pub not_finite: u32,
    /// The last value read.
    pub last: Option<Value>,
    /// For enum and flag fields: how often each value was read, in order of first reading.
    pub tally: Vec<(String, u32)>,
}

impl FieldResult {
    fn new(command: &CommandSpec, field: &Field, label: String) -> Self {
        Self {
            command: command.name.clone(),
            field: field.clone(),
            label,
            sum: 0.0,
            count: 0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            absent: 0,
            not_finite: 0,
            last: None,
            tally: Vec::new(),
        }
    }

    /// True for a field that is averaged (numbers); false for enums, flags, text and versions.
    pub fn is_averaged(&self) -> bool {
        averaged(&self.field.kind)
    }

    /// The mean of the numeric readings, if any.
    pub fn mean(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum / f64::from(self.count))
    }

    fn add(&mut self, value: Value) {
        if self.is_averaged() {
            let number = value.number();
            match number {
                Some(v) if self.field.absent.is_some_and(|a| a == v) => self.absent += 1,
                Some(v) if v.is_finite() => {
                    self.sum += v;
                    self.count += 1;
                    self.min = self.min.min(v);
                    self.max = self.max.max(v);
                }
                _ => self.not_finite += 1,
            }
        } else {
            let text = field_value_text(&self.field, &value);
            match self.tally.iter_mut().find(|(t, _)| *t == text) {
                Some((_, n)) => *n += 1,
                None => self.tally.push((text, 1)),
            }
        }
        self.last = Some(value);
    }

    /// A number of this field as text: an f32 field's mean as the nearest
    /// f32 (shortest form), others as f64; `digits` fixes the decimals.
    fn number_text(&self, v: f64, digits: Option<usize>) -> String {
        match digits {
            Some(d) => format!("{v:.d$}"),
            None if matches!(self.field.kind, FieldKind::F32 { .. }) => (v as f32).to_string(),
            None => v.to_string(),
        }
    }

    fn number_json(&self, v: f64) -> Json {
        if matches!(self.field.kind, FieldKind::F32 { .. }) {
            f32_json(v as f32)
        } else {
            serde_json::Number::from_f64(v).map_or(Json::Null, Json::Number)
        }
    }

    /// The result as JSON: the mean (numbers), the last value (others), or null.
    pub fn value_json(&self) -> Json {
        if self.is_averaged() {
            self.mean().map_or(Json::Null, |m| self.number_json(m))
        } else {
            self.last.as_ref().map_or(Json::Null, value_json)
        }
    }
}

fn averaged(kind: &FieldKind) -> bool {
    !matches!(
        kind,
        FieldKind::Enum { .. }
            | FieldKind::Flags { .. }
            | FieldKind::Ascii { .. }
            | FieldKind::Version
            | FieldKind::Reserved { .. }
    )
}

/// The result of a procedure.
#[derive(Debug, Clone)]
pub struct ProcedureResult {
    /// Readings taken.
    pub readings: u32,
    /// Every named field of every read, in the procedure's order.
    pub fields: Vec<FieldResult>,
    /// What failed without stopping the procedure (a refused Start Measurement).
    pub warnings: Vec<String>,
}

impl ProcedureResult {
    /// The derived quantities whose fields the procedure read, from the
    /// fields' means (a field with no valid reading leaves its quantities
    /// not computable); station inputs from `station`, else the spec's defaults.
    pub fn derived<'s>(&self, sensor: &'s Sensor, station: &dyn Fn(&str) -> Option<f64>) -> Vec<DerivedValue<'s>> {
        let of = |c: &str, f: &str| self.fields.iter().find(|r| r.command == c && r.field.name.as_deref() == Some(f));
        beside::beside(sensor, &|c, f| of(c, f).is_some(), &|c, f| of(c, f).and_then(FieldResult::mean), station)
    }
}

/// The commands a procedure names, in order (a name the spec lacks is an error).
fn commands<'s>(sensor: &'s Sensor, names: &[String], what: &str) -> Result<Vec<&'s CommandSpec>> {
    names
        .iter()
        .map(|name| {
            sensor.command(name).ok_or_else(|| {
                CliError::usage(format!("the procedure of `{}` {what} `{name}`, which it does not define", sensor.name))
                    .hint("fix the spec; `yosemitech list --spec FILE` checks it again")
            })
        })
        .collect()
}

/// Runs `sensor`'s procedure on the probe at `slave`: the `before`
/// commands, the warm-up (`sleep` waits, with a progress bar), the
/// readings, then the `after` commands (also when a reading failed).
pub fn run_procedure(
    opened: &mut Opened,
    sensor: &Sensor,
    slave: u8,
    timing: Timing,
    sleep: &mut dyn FnMut(Duration),
) -> Result<ProcedureResult> {
    let procedure = sensor.procedure.as_ref().ok_or_else(|| no_procedure(sensor, None))?;
    let before = commands(sensor, &procedure.before, "sends first")?;
    let reads = commands(sensor, &procedure.read, "reads")?;
    let after = commands(sensor, &procedure.after, "sends last")?;

    let mut seen: BTreeMap<&str, usize> = BTreeMap::new();
    for read in &reads {
        for f in read.named_fields() {
            *seen.entry(f.display_name()).or_default() += 1;
        }
    }
    let mut fields: Vec<FieldResult> = Vec::new();
    for read in &reads {
        for f in read.named_fields() {
            let label = if seen.get(f.display_name()).copied().unwrap_or(0) > 1 {
                format!("{}.{}", read.name, f.display_name())
            } else {
                f.display_name().to_owned()
            };
            fields.push(FieldResult::new(read, f, label));
        }
    }

    let mut taken = 0;
    let mut warnings = Vec::new();
    let result = (|| -> Result<()> {
        for command in &before {
            match device::read(opened, command, slave) {
                // Some probes refuse Start Measurement and measure all the
                // same (a real Y533 does): go on and read.
                Err(e) if command.role == Some(Role::StartMeasurement) => {
                    warnings.push(format!("{} failed ({}); reading anyway", command.name, e.message));
                }
                other => {
                    other?;
                }
            }
        }
        if !timing.warm_up.is_zero() {
            let bar = progress::timer(timing.warm_up, "warming up");
            progress::wait(&bar, timing.warm_up, &mut *sleep, || true);
        }
        let bar = progress::bar(u64::from(timing.readings), "{msg:24} [{bar:30}] {pos}/{len} readings");
        for n in 0..timing.readings {
            if n > 0 && !timing.interval.is_zero() {
                sleep(timing.interval);
            }
            for read in &reads {
                for (name, value) in device::read(opened, read, slave)? {
                    if let Some(r) =
                        fields.iter_mut().find(|r| r.command == read.name && r.field.name.as_deref() == Some(&name))
                    {
                        r.add(value);
                    }
                }
            }
            taken += 1;
            bar.set_position(u64::from(taken));
            if let Some(first) = fields.iter().find(|r| r.is_averaged())
                && let Some(last) = &first.last
            {
                bar.set_message(format!("{} {}", first.label, field_value_text(&first.field, last)));
            }
        }
        bar.finish_and_clear();
        Ok(())
    })();
    // The closing commands go out even after a failed reading.
    let mut closing = Ok(());
    for command in &after {
        if let Err(e) = device::read(opened, command, slave) {
            closing = Err(e);
            break;
        }
    }
    result?;
    closing?;
    Ok(ProcedureResult { readings: taken, fields, warnings })
}

/// The error for a sensor without a procedure, naming those that have one.
fn no_procedure(sensor: &Sensor, catalog: Option<&Catalog>) -> CliError {
    let with: Vec<&str> = catalog
        .map(|c| c.entries().iter().filter(|e| e.sensor.procedure.is_some()).map(|e| e.sensor.name.as_str()).collect())
        .unwrap_or_default();
    let e = CliError::usage(format!("sensor `{}` states no measuring procedure", sensor.name));
    if with.is_empty() {
        e.hint(format!("read its values with `yosemitech poll {}` or `yosemitech read`", sensor.name))
    } else {
        e.hint(format!(
            "sensors with a procedure: {}; `yosemitech poll {}` reads its measurements",
            with.join(", "),
            sensor.name
        ))
    }
}

/// The run's timing: the procedure's, with the hidden test options.
fn timing(procedure: &Procedure, args: &MeasureArgs) -> Result<Timing> {
    let mut timing = Timing::of(procedure);
    if args.fast {
        timing.warm_up = Duration::ZERO;
        timing.interval = Duration::ZERO;
    }
    timing.warm_up = args.warm_up.unwrap_or(timing.warm_up);
    timing.interval = args.interval.unwrap_or(timing.interval);
    if let Some(n) = args.readings {
        if n == 0 {
            return Err(CliError::usage("--readings 0 averages nothing")
                .hint(format!("the manual takes {} reading(s)", procedure.readings)));
        }
        timing.readings = n;
    }
    Ok(timing)
}

/// Runs `measure`.
pub fn run(catalog: &Catalog, args: &MeasureArgs, out: &mut dyn Write) -> Result<()> {
    let sensor = catalog.sensor(&args.sensor)?;
    let procedure = sensor.procedure.as_ref().ok_or_else(|| no_procedure(sensor, Some(catalog)))?;
    let timing = timing(procedure, args)?;
    let station = derived::station(sensor, &args.inputs.inputs)?;
    let slave = args.address.get(sensor.default_address)?;
    let mut opened = port::open(&args.port, &sensor.serial)?;
    if !args.json {
        let section = procedure.source.as_ref().map(|s| format!(" (manual section {})", s.section)).unwrap_or_default();
        writeln!(
            out,
            "{} at address {slave} on {}: {}{section}",
            sensor.title,
            opened.port,
            describe(procedure, timing)
        )?;
        out.flush()?;
    }
    let m = run_procedure(&mut opened, sensor, slave, timing, &mut std::thread::sleep)?;
    let computed = m.derived(sensor, &|name| station.get(name).copied());
    if args.json {
        let values: Map<String, Json> = m.fields.iter().map(|r| (r.label.clone(), r.value_json())).collect();
        let fields: Vec<Json> = m
            .fields
            .iter()
            .map(|r| {
                json!({
                    "name": r.label,
                    "command": r.command,
                    "field": r.field.display_name(),
                    "unit": r.field.unit,
                    "averaged": r.is_averaged(),
                    "value": r.value_json(),
                    "readings": if r.is_averaged() { r.count } else { r.tally.iter().map(|(_, n)| n).sum() },
                    "min": if r.count > 0 { r.number_json(r.min) } else { Json::Null },
                    "max": if r.count > 0 { r.number_json(r.max) } else { Json::Null },
                    "absent": r.absent,
                    "not_finite": r.not_finite,
                    "tally": r.tally.iter().map(|(v, n)| json!({ "value": v, "readings": n })).collect::<Vec<_>>(),
                })
            })
            .collect();
        let doc = json!({
            "sensor": sensor.name,
            "address": slave,
            "port": opened.port,
            "timestamp": time::rfc3339(SystemTime::now()),
            "procedure": {
                "before": procedure.before,
                "warm_up_ms": u64::try_from(timing.warm_up.as_millis()).unwrap_or(u64::MAX),
                "read": procedure.read,
                "readings": timing.readings,
                "interval_ms": u64::try_from(timing.interval.as_millis()).unwrap_or(u64::MAX),
                "after": procedure.after,
            },
            "readings": m.readings,
            "values": values,
            "fields": fields,
            "derived": derived_json(&computed),
            "warnings": m.warnings,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&doc).unwrap_or_default())?;
    } else {
        show(&m, None, out)?;
        show_derived(&m, &computed, out)?;
        if let Some(note) = derived::defaults_note(sensor, &computed) {
            writeln!(out, "note: {note}")?;
        }
    }
    Ok(())
}

/// Derived quantities under the fields, aligned with them and marked.
pub fn show_derived(m: &ProcedureResult, computed: &[DerivedValue<'_>], out: &mut dyn Write) -> Result<()> {
    let width = m.fields.iter().map(|r| r.label.len()).chain(computed.iter().map(|d| d.quantity.name.len())).max();
    let width = width.unwrap_or(0);
    for d in computed {
        writeln!(out, "  {:width$}  {}", d.quantity.name, derived_text(d, Some("from the means")))?;
    }
    Ok(())
}

/// The result, one field a line with its unit; `digits` rounds the means
/// to that many decimals, `None` shows every digit.
pub fn show(m: &ProcedureResult, digits: Option<usize>, out: &mut dyn Write) -> Result<()> {
    for warning in &m.warnings {
        writeln!(out, "note: {warning}")?;
    }
    let width = m.fields.iter().map(|r| r.label.len()).max().unwrap_or(0);
    for r in &m.fields {
        let text = if r.is_averaged() {
            let mut parts = Vec::new();
            if r.count > 1 && r.max > r.min {
                parts.push(format!("min {}, max {}", r.number_text(r.min, digits), r.number_text(r.max, digits)));
            }
            if r.absent > 0 {
                parts.push(format!("{} absent", r.absent));
            }
            if r.not_finite > 0 {
                parts.push(format!("{} not a number", r.not_finite));
            }
            let extra = if parts.is_empty() { String::new() } else { format!("; {}", parts.join(", ")) };
            match r.mean() {
                Some(mean) => {
                    let unit = r.field.unit.as_deref().map(|u| format!(" {}", unit(u))).unwrap_or_default();
                    let outside = r
                        .field
                        .range
                        .filter(|(min, max)| !(*min..=*max).contains(&mean))
                        .map(|(min, max)| format!(" [outside the measuring range {min} to {max}]"))
                        .unwrap_or_default();
                    let of =
                        if r.count == 1 { "1 reading".to_owned() } else { format!("mean of {} readings", r.count) };
                    format!("{}{unit}{outside} ({of}{extra})", r.number_text(mean, digits))
                }
                None if r.absent > 0 && r.not_finite == 0 => {
                    format!("absent (the sub-probe is not fitted: {} of {} readings)", r.absent, m.readings)
                }
                None => format!("no valid reading ({} readings{extra})", m.readings),
            }
        } else {
            let last = r.last.as_ref().map(|v| field_value_text(&r.field, v)).unwrap_or_else(|| "-".into());
            let unit = r.field.unit.as_deref().map(|u| format!(" {}", unit(u))).unwrap_or_default();
            match r.tally.as_slice() {
                [] => last,
                [(_, n)] if *n <= 1 => format!("{last}{unit}"),
                [(_, n)] => format!("{last}{unit} (all {n} readings)"),
                many => {
                    let counts: Vec<String> = many.iter().map(|(v, n)| format!("{v} {n}x")).collect();
                    format!("{last}{unit} (last reading; {})", counts.join(", "))
                }
            }
        };
        writeln!(out, "  {:width$}  {text}", r.label)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    use yosemitech_tests::spec;

    #[test]
    fn averages_numbers_tallies_enums_and_keeps_absent_values_apart() {
        let spec = spec();
        // Any read with a float field and an enum or absent field will do; take them from the spec.
        for sensor in &spec.sensors {
            for command in sensor.commands.iter().filter(|c| c.is_read()) {
                for field in command.named_fields() {
                    let mut r = FieldResult::new(command, field, field.display_name().to_owned());
                    match &field.kind {
                        FieldKind::F32 { .. } => {
                            for v in [1.0f32, 2.0, 4.5] {
                                r.add(Value::Float(v));
                            }
                            r.add(Value::Float(f32::NAN));
                            if let Some(a) = field.absent {
                                r.add(Value::Float(a as f32));
                                assert_eq!(r.absent, 1);
                            }
                            assert_eq!(r.count, 3);
                            assert_eq!(r.not_finite, 1);
                            assert_eq!(r.mean(), Some(2.5));
                            assert_eq!(r.value_json(), json!(2.5));
                        }
                        FieldKind::Enum { variants, .. } if variants.len() >= 2 => {
                            let v =
                                |i: usize| Value::Enum { raw: variants[i].value, name: Some(variants[i].name.clone()) };
                            for value in [v(0), v(0), v(1)] {
                                r.add(value);
                            }
                            assert!(!r.is_averaged());
                            assert_eq!(r.tally.len(), 2, "{}", r.label);
                            assert_eq!(r.tally[0].1, 2);
                            assert_eq!(r.value_json()["name"], variants[1].name.as_str());
                        }
                        _ => {}
                    }
                }
            }
        }
    }

    #[test]
    fn every_procedure_names_commands_its_sensor_has() {
        for sensor in &spec().sensors {
            let Some(p) = &sensor.procedure else { continue };
            assert!(commands(sensor, &p.before, "").is_ok() && commands(sensor, &p.read, "").is_ok());
            let text = describe(p, Timing::of(p));
            assert!(p.read.iter().all(|r| text.contains(r.as_str())), "{text}");
        }
    }
}

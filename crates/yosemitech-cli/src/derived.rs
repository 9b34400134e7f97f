//! Derived quantities beside the measured values: each quantity of the
//! spec whose field inputs were all read, its station inputs at the spec's
//! defaults, computed by the interpreter (so a `--spec` sensor has them too).

use yosemitech_spec::{Derived, InputSource, Sensor, Value};

/// One derived quantity's outcome.
pub struct DerivedValue<'s> {
    /// The quantity.
    pub quantity: &'s Derived,
    /// Its value, or why there is none.
    pub value: Result<f32, String>,
}

/// The number a field's value is, for a formula.
fn number(value: &Value) -> Option<f32> {
    match value {
        Value::Float(f) => Some(*f),
        // Integer fields are whole numbers well within f32's exact range in practice.
        Value::Int(i) => Some(*i as f32),
        _ => None,
    }
}

/// The quantities whose field inputs are all among the reads `values`
/// gives (`(command, field) -> value`), computed; the others are left out.
pub fn beside<'s, 'v>(
    sensor: &'s Sensor,
    values: &dyn Fn(&str, &str) -> Option<&'v Value>,
    reads: &[&str],
) -> Vec<DerivedValue<'s>> {
    let mut out = Vec::new();
    for d in &sensor.derived {
        let covered = d.inputs.iter().all(|i| match &i.source {
            InputSource::Field { command, .. } => reads.contains(&command.as_str()),
            InputSource::Station(_) => true,
        });
        if !covered {
            continue;
        }
        let mut inputs = Vec::with_capacity(d.inputs.len());
        let mut missing = None;
        for i in &d.inputs {
            let v = match &i.source {
                InputSource::Field { command, field } => values(command, field).and_then(number),
                InputSource::Station(_) => i.default.map(|v| v as f32),
            };
            match v {
                Some(v) => inputs.push(v),
                None => {
                    missing = Some(match &i.source {
                        InputSource::Field { command, field } => format!("no value for {command}.{field}"),
                        InputSource::Station(name) => format!("no value for the station's {name}"),
                    });
                    break;
                }
            }
        }
        let value = match missing {
            Some(why) => Err(why),
            None => d.compute(&inputs).map_err(|e| e.to_string()),
        };
        out.push(DerivedValue { quantity: d, value });
    }
    out
}

//! The derived quantities of a sample, computed where the logger stores
//! it: through `yosemitech_spec::beside`, the implementation the CLI shows,
//! from the sample's stored values and the probe's station inputs.

use yosemitech_spec::beside;
use yosemitech_spec::interp::f32_decimal;

use crate::config::ProbeConfig;
use crate::plan::Plan;
use crate::store::{Datum, Measurement};

/// The derived quantities of `probe` whose fields its plan reads, from the
/// sample's `values`, each marked derived; one the sample cannot give a
/// value (an input missing, NaN or out of range) carries the reason.
pub fn measurements(probe: &ProbeConfig, plan: &Plan<'_>, values: &[Measurement]) -> Vec<Measurement> {
    let read = |c: &str, f: &str| plan.reads.iter().any(|r| r.command.name == c && r.fields.contains(&f));
    let value = |_: &str, f: &str| {
        values.iter().find(|m| m.name == f && !m.derived).and_then(|m| match m.value {
            Datum::Number(n) => Some(n),
            Datum::Text(_) | Datum::NotComputable(_) => None,
        })
    };
    let station = |name: &str| probe.inputs.get(name).copied();
    beside::beside(&probe.sensor, &read, &value, &station)
        .into_iter()
        .map(|d| Measurement {
            name: d.quantity.name.clone(),
            value: match d.value {
                Ok(v) => Datum::Number(f32_decimal(v)),
                Err(why) => Datum::NotComputable(why),
            },
            unit: d.quantity.unit.clone(),
            derived: true,
        })
        .collect()
}

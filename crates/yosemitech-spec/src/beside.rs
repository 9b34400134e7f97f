//! Derived quantities beside measured values: the one implementation the
//! CLI (`read`, `poll`, `measure`) and the station logger share, so a
//! quantity is computed from the same inputs, defaults and range checks
//! wherever it is shown or stored.
//!
//! A quantity is computed when every field it takes was read; its station
//! inputs come from a lookup (`--input`, the station file) or else the
//! spec's default. A station value outside an input's declared range is
//! refused by [`check_station_input`] before anything is read, and makes
//! the quantity not computable if it gets through, never a silent number.

use std::fmt;

use crate::interp::Value;
use crate::model::{Derived, DerivedInput, InputSource, Sensor};

/// One derived quantity's outcome.
#[derive(Debug, Clone)]
pub struct DerivedValue<'s> {
    /// The quantity.
    pub quantity: &'s Derived,
    /// Its value, or why there is none.
    pub value: Result<f32, String>,
    /// The station inputs that took the spec's default (none was given),
    /// with that default, in parameter order.
    pub defaulted: Vec<(&'s str, f64)>,
}

/// The number a field's value is, for a formula.
pub fn field_number(value: &Value) -> Option<f64> {
    match value {
        Value::Float(f) => Some(f64::from(*f)),
        // Integer fields are whole numbers well within f64's exact range.
        Value::Int(i) => Some(*i as f64),
        Value::Bcd(b) => b.value().map(f64::from),
        _ => None,
    }
}

/// The quantities whose field inputs were all read (`read(command, field)`),
/// computed from `values` (`(command, field) -> number`, `None` when the
/// read gave none) and `station` (`name -> value`, `None` for the spec's
/// default). The quantities a read does not cover are left out.
pub fn beside<'s>(
    sensor: &'s Sensor,
    read: &dyn Fn(&str, &str) -> bool,
    values: &dyn Fn(&str, &str) -> Option<f64>,
    station: &dyn Fn(&str) -> Option<f64>,
) -> Vec<DerivedValue<'s>> {
    sensor
        .derived
        .iter()
        .filter(|d| {
            d.inputs.iter().all(|i| match &i.source {
                InputSource::Field { command, field } => read(command, field),
                InputSource::Station(_) => true,
            })
        })
        .map(|d| compute(d, values, station))
        .collect()
}

/// One quantity from its inputs' lookups.
fn compute<'s>(
    d: &'s Derived,
    values: &dyn Fn(&str, &str) -> Option<f64>,
    station: &dyn Fn(&str) -> Option<f64>,
) -> DerivedValue<'s> {
    let mut inputs = Vec::with_capacity(d.inputs.len());
    let mut defaulted = Vec::new();
    for i in &d.inputs {
        let v = match &i.source {
            InputSource::Field { command, field } => values(command, field),
            InputSource::Station(name) => match station(name) {
                Some(v) => Some(v),
                None => i.default.inspect(|v| defaulted.push((name.as_str(), *v))),
            },
        };
        let Some(v) = v else {
            let why = match &i.source {
                InputSource::Field { command, field } => format!("no value for {command}.{field}"),
                InputSource::Station(name) => {
                    format!("no value for the station's {name} (the spec has no default: give one)")
                }
            };
            return DerivedValue { quantity: d, value: Err(why), defaulted };
        };
        // Checked here in f64 so that a value f32 would round into the
        // range is still refused.
        if let (InputSource::Station(name), Some((min, max))) = (&i.source, i.range)
            && v.is_finite()
            && !(min..=max).contains(&v)
        {
            let why = format!("station input {name} is {v}, outside {min} to {max}");
            return DerivedValue { quantity: d, value: Err(why), defaulted };
        }
        inputs.push(v as f32);
    }
    DerivedValue { quantity: d, value: d.compute(&inputs).map_err(|e| e.to_string()), defaulted }
}

/// A station input of a sensor, as its quantities declare it (one entry
/// per name: quantities sharing an input share its value).
#[derive(Debug, Clone)]
pub struct StationInput<'s> {
    /// The name given on the command line or in the station file.
    pub name: &'s str,
    /// Every declaration of it, with its quantity.
    pub uses: Vec<(&'s Derived, &'s DerivedInput)>,
}

impl StationInput<'_> {
    /// `salinity [ppt] (default 0, 0..=40)`, from its first declaration.
    pub fn describe(&self) -> String {
        let Some((_, i)) = self.uses.first() else { return self.name.to_owned() };
        let mut text = self.name.to_owned();
        if let Some(u) = &i.unit {
            text.push_str(&format!(" [{u}]"));
        }
        let mut notes = Vec::new();
        if let Some(d) = i.default {
            notes.push(format!("default {d}"));
        }
        if let Some((min, max)) = i.range {
            notes.push(format!("{min} to {max}"));
        }
        if !notes.is_empty() {
            text.push_str(&format!(" ({})", notes.join(", ")));
        }
        text
    }
}

/// The station inputs `sensor`'s derived quantities take, by name, in the
/// order they first appear.
pub fn station_inputs(sensor: &Sensor) -> Vec<StationInput<'_>> {
    let mut out: Vec<StationInput<'_>> = Vec::new();
    for d in &sensor.derived {
        for i in &d.inputs {
            let InputSource::Station(name) = &i.source else { continue };
            match out.iter_mut().find(|s| s.name == name) {
                Some(s) => s.uses.push((d, i)),
                None => out.push(StationInput { name, uses: vec![(d, i)] }),
            }
        }
    }
    out
}

/// Why a station input's value is refused.
#[derive(Debug, Clone, PartialEq)]
pub enum StationInputError {
    /// No derived quantity of the sensor takes an input of this name.
    Unknown {
        /// The sensor.
        sensor: String,
        /// The name given.
        name: String,
        /// The sensor's station inputs, described (empty: it has none).
        known: Vec<String>,
    },
    /// The value is NaN or infinite.
    NotFinite {
        /// The input.
        name: String,
    },
    /// The value lies outside the range a quantity takes it in.
    OutOfRange {
        /// The input.
        name: String,
        /// The value given.
        value: f64,
        /// The quantity whose range it misses.
        quantity: String,
        /// Lowest value taken.
        min: f64,
        /// Highest value taken.
        max: f64,
    },
}

impl fmt::Display for StationInputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Unknown { sensor, name, known } if known.is_empty() => write!(
                f,
                "no derived quantity of `{sensor}` takes a station input `{name}`: `{sensor}` takes no station input"
            ),
            Self::Unknown { sensor, name, known } => write!(
                f,
                "no derived quantity of `{sensor}` takes a station input `{name}`; its station inputs: {}",
                known.join(", ")
            ),
            Self::NotFinite { name } => write!(f, "station input `{name}` is not a finite number"),
            Self::OutOfRange { name, value, quantity, min, max } => {
                write!(f, "station input `{name}` = {value} is outside {min} to {max}, the range `{quantity}` takes")
            }
        }
    }
}

impl std::error::Error for StationInputError {}

/// Checks that `sensor` takes a station input `name` and that `value` is
/// within the range of every quantity that takes it.
///
/// # Errors
///
/// The name is not a station input of the sensor, or the value is not
/// finite or out of a declared range.
pub fn check_station_input(sensor: &Sensor, name: &str, value: f64) -> Result<(), StationInputError> {
    let inputs = station_inputs(sensor);
    let Some(input) = inputs.iter().find(|s| s.name == name) else {
        return Err(StationInputError::Unknown {
            sensor: sensor.name.clone(),
            name: name.to_owned(),
            known: inputs.iter().map(StationInput::describe).collect(),
        });
    };
    if !value.is_finite() {
        return Err(StationInputError::NotFinite { name: name.to_owned() });
    }
    for (d, i) in &input.uses {
        if let Some((min, max)) = i.range
            && !(min..=max).contains(&value)
        {
            return Err(StationInputError::OutOfRange {
                name: name.to_owned(),
                value,
                quantity: d.name.clone(),
                min,
                max,
            });
        }
    }
    Ok(())
}

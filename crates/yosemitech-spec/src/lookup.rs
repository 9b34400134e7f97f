//! A sensor found by what a person types: its name (`ph_orp`, `ph-orp`),
//! a model on its label (`Y504`, in any case: the sensor's or an alias's),
//! or an unambiguous prefix (`cond`). The CLI's arguments and the station
//! file take the same words, so both ask here.
//!
//! ```
//! use yosemitech_spec::lookup::{By, Lookup, find_sensor};
//! # let spec = yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()])?;
//! let sensors: Vec<&yosemitech_spec::Sensor> = spec.sensors.iter().collect();
//! let Lookup::Found { index, by: By::Name } = find_sensor(&sensors, &sensors[0].name) else { panic!() };
//! assert_eq!(index, 0);
//! assert!(matches!(find_sensor(&sensors, "no-such-probe"), Lookup::Unknown { .. }));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::Sensor;
use crate::suggest::closest;

/// How a word named its sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum By {
    /// The sensor's name, `-` standing for `_`.
    Name,
    /// A model name of the sensor or of one of its aliases, in any case.
    Model,
    /// The start of exactly one sensor's name.
    Prefix,
}

/// What a word names among the sensors.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Lookup {
    /// One sensor, by its index.
    Found {
        /// Its index in the slice searched.
        index: usize,
        /// How the word named it.
        by: By,
    },
    /// A model name that several sensors answer to (their indices): the
    /// word cannot choose.
    SameModel(Vec<usize>),
    /// No sensor; the closest name when the word looks like a typo of one.
    Unknown {
        /// A sensor name within a few edits of the word.
        closest: Option<String>,
    },
}

/// The sensor `word` names among `sensors` (see the module's rules, in
/// that order: name, model, prefix).
pub fn find_sensor(sensors: &[&Sensor], word: &str) -> Lookup {
    let wanted = word.trim().replace('-', "_");
    if let Some(index) = sensors.iter().position(|s| s.name == wanted) {
        return Lookup::Found { index, by: By::Name };
    }
    let word = word.trim();
    let by_model: Vec<usize> = sensors
        .iter()
        .enumerate()
        .filter(|(_, s)| {
            s.model.as_deref().is_some_and(|m| m.eq_ignore_ascii_case(word))
                || s.aliases.iter().any(|a| a.model.eq_ignore_ascii_case(word))
        })
        .map(|(i, _)| i)
        .collect();
    match by_model.as_slice() {
        [index] => return Lookup::Found { index: *index, by: By::Model },
        [] => {}
        _ => return Lookup::SameModel(by_model),
    }
    let prefixed: Vec<usize> =
        sensors.iter().enumerate().filter(|(_, s)| s.name.starts_with(&wanted)).map(|(i, _)| i).collect();
    if let ([index], false) = (prefixed.as_slice(), wanted.is_empty()) {
        return Lookup::Found { index: *index, by: By::Prefix };
    }
    let names: Vec<&str> = sensors.iter().map(|s| s.name.as_str()).collect();
    Lookup::Unknown { closest: closest(&wanted, &names).map(str::to_owned) }
}

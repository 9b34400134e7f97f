//! A probe's chosen units (`units = { name = "uS/cm" }` in the station
//! file) applied to its readings before they are stored, so that the
//! store, its exports and MQTT all carry the converted value with the
//! chosen unit. The conversion is the spec's unit table's
//! (`yosemitech_spec::units`); nothing here knows a sensor.

use std::collections::BTreeMap;

use yosemitech_spec::units::{self, Conversion};

use crate::store::{Datum, Reading};

/// Converts each value of `reading` that `chosen` names, and gives it the
/// chosen unit. A value is converted only when its unit is the one the
/// conversion starts from (any spelling of it): a value of the same name in
/// another unit is left as read rather than converted wrongly. Text values
/// stay as they are.
pub fn apply(chosen: &BTreeMap<String, Conversion>, reading: &mut Reading) {
    if chosen.is_empty() {
        return;
    }
    for m in &mut reading.values {
        let Some(c) = chosen.get(&m.name) else { continue };
        let from = m.unit.as_deref().and_then(units::lookup);
        if !from.is_some_and(|u| std::ptr::eq(u, c.from)) {
            continue;
        }
        if let Datum::Number(v) = m.value {
            m.value = Datum::Number(c.apply(v));
            m.unit = Some(c.to.symbol.to_owned());
        }
    }
}

//! Every unit the loaded spec declares either converts through the unit
//! table (to every unit of its dimension and back) or is refused with a
//! clear "not convertible" error; nothing in between (a unit that silently
//! converts wrongly, or a refusal that does not say why).

use std::collections::BTreeMap;

use yosemitech_spec::units::{self, ChoiceError, Conversion, Quantity, UnitError};
use yosemitech_tests::{report, spec};

/// Every (name, unit) the spec declares: fields of commands, derived
/// quantities and their station inputs, constants.
fn declared() -> Vec<(String, String)> {
    let mut out = Vec::new();
    for sensor in &spec().sensors {
        for command in &sensor.commands {
            for field in command.named_fields() {
                if let Some(u) = &field.unit {
                    out.push((format!("{}.{}", command.name, field.display_name()), u.clone()));
                }
            }
        }
        for d in &sensor.derived {
            if let Some(u) = &d.unit {
                out.push((d.name.clone(), u.clone()));
            }
            for i in &d.inputs {
                if let Some(u) = &i.unit {
                    out.push((format!("{}.{}", d.name, i.name), u.clone()));
                }
            }
        }
        for c in &sensor.constants {
            if let Some(u) = &c.unit {
                out.push((c.name.clone(), u.clone()));
            }
        }
    }
    out
}

#[test]
fn every_declared_unit_converts_or_says_it_does_not() {
    let mut by_outcome: BTreeMap<&str, Vec<String>> = BTreeMap::new();
    let declared = declared();
    assert!(!declared.is_empty());
    for (name, unit) in &declared {
        let quantity = [Quantity { name, unit: Some(unit) }];
        match units::lookup(unit) {
            Some(def) => {
                // Every other unit of its dimension is reachable by name and by
                // dimension, and a value comes back from the round trip.
                for other in units::UNITS.iter().filter(|u| u.dimension == def.dimension) {
                    let there = units::choose_named(name, other.symbol, &quantity).unwrap();
                    assert_eq!(there.to.symbol, other.symbol);
                    let back = Conversion::new(other.symbol, unit).unwrap();
                    let v = 12.34;
                    assert!((back.apply(there.apply(v)) - v).abs() < 1e-9, "{name}: {unit} -> {}", other.symbol);
                    let all = units::choose_by_dimension(other.symbol, &quantity).unwrap();
                    assert_eq!(all.len(), 1, "{name}");
                }
                // A unit of another dimension is a mismatch that names the ones that fit.
                let foreign = units::UNITS.iter().find(|u| u.dimension != def.dimension).unwrap();
                let e = units::choose_named(name, foreign.symbol, &quantity).unwrap_err();
                assert!(matches!(e, ChoiceError::Mismatch { .. }), "{name}: {e}");
                assert!(e.to_string().contains(def.symbol), "{e}");
                by_outcome.entry("convert").or_default().push(unit.clone());
            }
            None => {
                let to = units::UNITS[0].symbol;
                let e = units::choose_named(name, to, &quantity).unwrap_err();
                assert!(matches!(e, ChoiceError::NotConvertible { .. }), "{name}: {e}");
                assert!(e.to_string().contains("not convertible") && e.to_string().contains(unit.as_str()), "{e}");
                assert_eq!(Conversion::new(unit, to), Err(UnitError::Unknown(unit.clone())));
                by_outcome.entry("do not convert").or_default().push(unit.clone());
            }
        }
    }
    let mut summary = Vec::new();
    for (outcome, mut list) in by_outcome {
        let n = list.len();
        list.sort();
        list.dedup();
        summary.push(format!("{n} {outcome} ({})", list.join(", ")));
    }
    report!("units the spec declares: {}", summary.join("; "));
}

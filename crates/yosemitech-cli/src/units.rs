//! `--unit`: values shown in a unit the user chooses. Every conversion
//! comes from the spec crate's unit table (`yosemitech_spec::units`), so
//! a sensor loaded with `--spec` converts the same way and no command
//! knows a sensor's units.

use std::collections::BTreeMap;

use yosemitech_spec::suggest::closest;
use yosemitech_spec::units::{self, Choice, ChoiceError, Conversion, Quantity};
use yosemitech_spec::{CommandSpec, Derived, Value};

use crate::error::{CliError, Result};

/// The units chosen for the quantities of one command line, by name; a
/// quantity without an entry keeps its spec unit.
#[derive(Debug, Default)]
pub struct Chosen {
    conversions: BTreeMap<String, Conversion>,
}

impl Chosen {
    /// Resolves `--unit` arguments (`UNIT` or `NAME=UNIT`) against the
    /// quantities a command shows (fields and derived quantities with their
    /// spec units). `sensor` names the sensor in hints.
    ///
    /// # Errors
    ///
    /// A usage error: an unknown unit (with the nearest spelling), no
    /// quantity of the unit's dimension, an unknown name, a unit of another
    /// dimension than the named quantity's, or two units for one quantity.
    pub fn resolve(args: &[String], quantities: &[Quantity<'_>], sensor: &str) -> Result<Self> {
        let choices: Vec<Choice> = args.iter().map(|a| Choice::parse(a)).collect();
        let conversions = units::choose(&choices, quantities).map_err(|e| usage(&e, sensor))?;
        Ok(Self { conversions })
    }

    /// The conversion chosen for `name`, if any.
    pub fn conversion(&self, name: &str) -> Option<&Conversion> {
        self.conversions.get(name)
    }

    /// The unit `name` is shown in: the chosen one, else `spec_unit`.
    pub fn unit<'a>(&self, name: &str, spec_unit: Option<&'a str>) -> Option<&'a str> {
        self.conversion(name).map(|c| c.to.symbol).or(spec_unit)
    }

    /// `value` of `name` in its chosen unit: numbers converted (integers
    /// become floats, a scaled integer is a decimal anyway), anything else
    /// as it is.
    pub fn value(&self, name: &str, value: &Value) -> Value {
        let Some(c) = self.conversion(name) else { return value.clone() };
        match value {
            Value::Float(v) => Value::Float(c.apply(f64::from(*v)) as f32),
            Value::Int(v) => Value::Float(c.apply(*v as f64) as f32),
            Value::Bcd(b) => b.value().map_or_else(|| value.clone(), |v| Value::Float(c.apply(f64::from(v)) as f32)),
            other => other.clone(),
        }
    }

    /// A derived quantity's value `v` of `name` in its chosen unit.
    pub fn number(&self, name: &str, v: f32) -> f32 {
        self.conversion(name).map_or(v, |c| c.apply(f64::from(v)) as f32)
    }

    /// `values` (by field name) in their chosen units.
    pub fn values(&self, values: &[(String, Value)]) -> Vec<(String, Value)> {
        values.iter().map(|(n, v)| (n.clone(), self.value(n, v))).collect()
    }

    /// `command` as shown: each converted field with its chosen unit, so
    /// that every formatter that reads a field's unit shows the new one.
    pub fn command(&self, command: &CommandSpec) -> CommandSpec {
        let mut shown = command.clone();
        for field in &mut shown.fields {
            if let Some(c) = field.name.as_deref().and_then(|n| self.conversion(n)) {
                field.unit = Some(c.to.symbol.to_owned());
                // The range was the spec unit's; in another unit it would mislead.
                field.range = field.range.map(|(a, b)| (c.apply(a), c.apply(b)));
            }
        }
        shown
    }

    /// `quantity` as shown: with its chosen unit.
    pub fn derived(&self, quantity: &Derived) -> Derived {
        let mut shown = quantity.clone();
        if let Some(c) = self.conversion(&quantity.name) {
            shown.unit = Some(c.to.symbol.to_owned());
        }
        shown
    }
}

/// The quantities `command` shows (its named fields) and the derived ones beside it.
pub fn quantities<'a>(command: &'a CommandSpec, derived: &[&'a Derived]) -> Vec<Quantity<'a>> {
    command
        .named_fields()
        .map(|f| Quantity { name: f.display_name(), unit: f.unit.as_deref() })
        .chain(derived.iter().map(|d| Quantity { name: &d.name, unit: d.unit.as_deref() }))
        .collect()
}

/// A choice's error as the user sees it, with what would be right.
fn usage(e: &ChoiceError, sensor: &str) -> CliError {
    let error = CliError::usage(format!("--unit: {e}"));
    match e {
        ChoiceError::UnknownUnit { unit } => {
            let spellings: Vec<&str> = units::spellings().collect();
            let symbols: Vec<&str> = units::UNITS.iter().map(|u| u.symbol).collect();
            // Unit symbols are case-sensitive (mS is not MS), so a spelling
            // that differs only in case is the likeliest meaning.
            let same_letters = spellings.iter().copied().find(|s| s.eq_ignore_ascii_case(unit));
            match same_letters.or_else(|| closest(unit, &spellings)) {
                Some(best) => error.hint(format!("did you mean `{best}`? Units that convert: {}", symbols.join(", "))),
                None => error.hint(format!("units that convert: {}", symbols.join(", "))),
            }
        }
        ChoiceError::UnknownName { name, names } => {
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            match closest(name, &names) {
                Some(best) => error.hint(format!("did you mean `{best}`? Write --unit NAME=UNIT or --unit UNIT")),
                None => error.hint(format!("`yosemitech list {sensor}` shows each measurement with its unit")),
            }
        }
        _ => error.hint(format!(
            "--unit UNIT converts every measurement of the unit's dimension, --unit NAME=UNIT one; \
             `yosemitech list {sensor}` shows each measurement with its unit"
        )),
    }
}

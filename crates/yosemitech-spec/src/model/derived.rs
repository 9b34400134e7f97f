//! Quantities computed from a sensor's fields, constants and station
//! inputs, and why one may have no value.

use std::collections::BTreeMap;

use serde::Serialize;

use super::Source;

/// A quantity the probe does not send, computed by a formula from fields of
/// its reads, the sensor's constants and station inputs. Validation
/// guarantees that every name of the formula resolves, that its units agree
/// (where declared) and that every example holds.
#[derive(Debug, Clone, Serialize)]
pub struct Derived {
    /// snake_case identifier: the generated function.
    pub name: String,
    /// Human title (one line).
    pub title: String,
    /// The result's unit, when declared.
    pub unit: Option<String>,
    /// What the quantity is, in prose (never empty).
    pub doc: String,
    /// Where the manual gives the formula.
    pub source: Option<Source>,
    /// The inputs, in parameter order.
    pub inputs: Vec<DerivedInput>,
    /// The formula as written.
    pub expr: String,
    /// The formula, names resolved to inputs and constants.
    #[serde(skip)]
    pub formula: crate::expr::Expr,
    /// Values computed independently, each with its source.
    pub examples: Vec<DerivedExample>,
}

/// Where a derived quantity's input comes from.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum InputSource {
    /// A field of a read of the sensor.
    Field {
        /// The read.
        command: String,
        /// Its field (a number).
        field: String,
    },
    /// A value of the station (salinity, barometric pressure).
    Station(String),
}

/// One input of a derived quantity.
#[derive(Debug, Clone, Serialize)]
pub struct DerivedInput {
    /// snake_case identifier, unique within the quantity.
    pub name: String,
    /// Where the value comes from.
    pub source: InputSource,
    /// Its unit (a field input's is its field's).
    pub unit: Option<String>,
    /// The value taken when a station gives none.
    pub default: Option<f64>,
    /// The values the formula takes, inclusive.
    pub range: Option<(f64, f64)>,
}

/// A value of a derived quantity from another source than its formula.
#[derive(Debug, Clone, Serialize)]
pub struct DerivedExample {
    /// The inputs given, by name (the others take their default).
    pub inputs: BTreeMap<String, f64>,
    /// The value.
    pub value: f64,
    /// How far the formula's value may be from it.
    pub tolerance: f64,
    /// Where the value comes from.
    pub doc: String,
}

impl Derived {
    /// The input called `name`.
    pub fn input(&self, name: &str) -> Option<&DerivedInput> {
        self.inputs.iter().find(|i| i.name == name)
    }

    /// The inputs of `example` in parameter order, station inputs it does
    /// not give at their default; `None` names the input that has none.
    pub fn example_inputs(&self, example: &DerivedExample) -> Result<Vec<f32>, String> {
        self.inputs
            .iter()
            .map(|i| example.inputs.get(&i.name).copied().or(i.default).map(|v| v as f32).ok_or_else(|| i.name.clone()))
            .collect()
    }

    /// The formula's value for `inputs` (in parameter order), as the
    /// generated function computes it: inputs checked (finite, in range),
    /// arithmetic in `f64`, the result an `f32` that must be finite.
    pub fn compute(&self, inputs: &[f32]) -> Result<f32, NotComputable> {
        if inputs.len() != self.inputs.len() {
            return Err(NotComputable::Inputs { expected: self.inputs.len(), given: inputs.len() });
        }
        let mut wide = Vec::with_capacity(inputs.len());
        for (decl, &v) in self.inputs.iter().zip(inputs) {
            if !v.is_finite() {
                return Err(NotComputable::NotFinite { input: decl.name.clone() });
            }
            let w = f64::from(v);
            if let Some((min, max)) = decl.range
                && !(min..=max).contains(&w)
            {
                return Err(NotComputable::OutOfRange { input: decl.name.clone(), value: v, min, max });
            }
            wide.push(w);
        }
        let value = self.formula.eval(&wide).ok_or(NotComputable::Undefined)?;
        let narrow = value as f32;
        if narrow.is_finite() { Ok(narrow) } else { Err(NotComputable::Undefined) }
    }
}

/// Why the interpreter has no value for a derived quantity: the same cases
/// as the runtime's `NotComputable`, with owned names.
#[derive(Debug, Clone, PartialEq)]
pub enum NotComputable {
    /// An input is NaN or infinite.
    NotFinite {
        /// The input.
        input: String,
    },
    /// An input lies outside its declared range.
    OutOfRange {
        /// The input.
        input: String,
        /// The value given.
        value: f32,
        /// Lowest value taken.
        min: f64,
        /// Highest value taken.
        max: f64,
    },
    /// The formula has no finite value for these inputs.
    Undefined,
    /// The wrong number of inputs.
    Inputs {
        /// How many the quantity takes.
        expected: usize,
        /// How many were given.
        given: usize,
    },
}

impl NotComputable {
    /// True when the runtime's error is the same case, for the same input.
    pub fn same_as(&self, other: &yosemitech_rtu::NotComputable) -> bool {
        use yosemitech_rtu::NotComputable as R;
        match (self, other) {
            (Self::NotFinite { input }, R::NotFinite { input: i }) => input == i,
            (Self::OutOfRange { input, .. }, R::OutOfRange { input: i, .. }) => input == i,
            (Self::Undefined, R::Undefined) => true,
            (Self::Inputs { expected, given }, R::Inputs { expected: e, given: g }) => expected == e && given == g,
            _ => false,
        }
    }
}

impl std::fmt::Display for NotComputable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotFinite { input } => write!(f, "input `{input}` is not a finite number"),
            Self::OutOfRange { input, value, min, max } => {
                write!(f, "input `{input}` is {value}, outside {min}..={max}")
            }
            Self::Undefined => f.write_str("the formula has no finite value for these inputs"),
            Self::Inputs { expected, given } => write!(f, "{given} inputs given, {expected} expected"),
        }
    }
}

impl std::error::Error for NotComputable {}

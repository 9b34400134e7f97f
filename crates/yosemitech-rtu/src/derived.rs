//! Derived quantities: measurements a probe does not send, computed from
//! fields of its reads, the spec's constants and per-station inputs
//! (salinity, barometric pressure).
//!
//! Generated sensor modules declare one function per derived quantity of
//! the spec (`pub fn tds_mg_l(conductivity: f32) -> Result<f32, NotComputable>`)
//! and list them as data in `DERIVED` ([`DerivedInfo`]). The functions are
//! built from the helpers here: [`input`] checks an input, [`output`] the
//! result, and [`exp`], [`ln`], [`pow`] and the comparisons are the
//! expression language's operations, `no_std` and without allocation.
//! Arithmetic is carried out in `f64`; inputs and results are `f32`.

/// Why a derived quantity has no value for the inputs given: never a
/// number that is not one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NotComputable {
    /// An input is NaN or infinite.
    NotFinite {
        /// The input's name.
        input: &'static str,
    },
    /// An input lies outside the range the spec declares for it.
    OutOfRange {
        /// The input's name.
        input: &'static str,
        /// The value given.
        value: f32,
        /// The lowest value the formula takes.
        min: f64,
        /// The highest value the formula takes.
        max: f64,
    },
    /// The formula has no finite value for these inputs (a division by
    /// zero, the logarithm of a number that is not positive, an overflow,
    /// a comparison of a NaN).
    Undefined,
    /// A table entry was given the wrong number of inputs.
    Inputs {
        /// How many the quantity takes.
        expected: usize,
        /// How many were given.
        given: usize,
    },
}

impl core::fmt::Display for NotComputable {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
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

#[cfg(feature = "std")]
impl std::error::Error for NotComputable {}

/// Where an input of a derived quantity comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InputSource {
    /// A field of one of the sensor's reads.
    Field {
        /// The read's spec name.
        command: &'static str,
        /// The field's spec name.
        field: &'static str,
    },
    /// A value of the station the probe is installed at, not of the probe.
    Station {
        /// The station input's name (`salinity`, `barometric_pressure`).
        name: &'static str,
    },
}

/// One input of a derived quantity, in parameter order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DerivedInput {
    /// The parameter's name.
    pub name: &'static str,
    /// Where the value comes from.
    pub source: InputSource,
    /// Its unit, when declared (a field input's is its field's).
    pub unit: Option<&'static str>,
    /// The value used when a station does not give one.
    pub default: Option<f64>,
    /// The values the formula takes, inclusive.
    pub range: Option<(f64, f64)>,
}

/// `(inputs in parameter order) -> value`: a derived quantity's function as data.
pub type ComputeFn = fn(&[f32]) -> Result<f32, NotComputable>;

/// A derived quantity as data: generated modules list theirs in `DERIVED`,
/// and [`crate::SensorModule::derived`] points at it.
#[derive(Clone, Copy)]
pub struct DerivedInfo {
    /// The spec's snake_case name (the generated function's).
    pub name: &'static str,
    /// Human title (one line).
    pub title: &'static str,
    /// The result's unit, when declared.
    pub unit: Option<&'static str>,
    /// The formula, as the spec writes it.
    pub expr: &'static str,
    /// The inputs, in parameter order.
    pub inputs: &'static [DerivedInput],
    /// Computes the quantity through the generated function.
    pub compute: ComputeFn,
}

impl DerivedInfo {
    /// The input called `name`.
    pub fn input(&self, name: &str) -> Option<&DerivedInput> {
        self.inputs.iter().find(|i| i.name == name)
    }
}

impl core::fmt::Debug for DerivedInfo {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DerivedInfo")
            .field("name", &self.name)
            .field("unit", &self.unit)
            .field("expr", &self.expr)
            .field("inputs", &self.inputs)
            .finish_non_exhaustive()
    }
}

/// Checks input `name`: finite, and within `range` when one is declared.
pub fn input(name: &'static str, value: f32, range: Option<(f64, f64)>) -> Result<f64, NotComputable> {
    if !value.is_finite() {
        return Err(NotComputable::NotFinite { input: name });
    }
    let v = f64::from(value);
    match range {
        Some((min, max)) if !(min..=max).contains(&v) => {
            Err(NotComputable::OutOfRange { input: name, value, min, max })
        }
        _ => Ok(v),
    }
}

/// The result as an `f32`, if it is a finite one.
pub fn output(value: f64) -> Result<f32, NotComputable> {
    // Narrowing is the point: the quantity is an f32 like the fields it comes from.
    #[allow(clippy::cast_possible_truncation)]
    let narrow = value as f32;
    if narrow.is_finite() { Ok(narrow) } else { Err(NotComputable::Undefined) }
}

/// `e` to the power `x`.
pub fn exp(x: f64) -> f64 {
    libm::exp(x)
}

/// The natural logarithm (NaN for numbers that are not positive, which
/// [`output`] then refuses).
pub fn ln(x: f64) -> f64 {
    libm::log(x)
}

/// `base` to the power `exponent`.
pub fn pow(base: f64, exponent: f64) -> f64 {
    libm::pow(base, exponent)
}

/// A positive `base` to the power `exponent`, given the base's natural
/// logarithm `ln_base`: what a formula's `10^y` becomes, without the
/// general [`pow`] (about 3 KB of firmware flash). A whole exponent of at
/// most 64 is a product ([`powi`]), so `10^2` is exactly 100; any other is
/// `exp(ln_base * exponent)`, within a few units in the last place.
pub fn pow_positive(base: f64, ln_base: f64, exponent: f64) -> f64 {
    // `as` saturates and maps NaN to 0; the comparison refuses both.
    #[allow(clippy::cast_possible_truncation)]
    let whole = exponent as i32;
    if f64::from(whole) == exponent && whole.unsigned_abs() <= 64 { powi(base, whole) } else { exp(ln_base * exponent) }
}

/// `base` to a whole power, by repeated squaring: what a formula's `x^2`
/// becomes, without the general [`pow`] (about 3 KB of firmware flash for
/// a square). `x^2` is `x * x` exactly; a power of at most 64 is within a
/// few units in the last place.
pub fn powi(base: f64, exponent: i32) -> f64 {
    let (mut result, mut square, mut rest) = (1.0, base, exponent.unsigned_abs());
    while rest > 0 {
        if rest & 1 == 1 {
            result *= square;
        }
        rest >>= 1;
        if rest > 0 {
            square *= square;
        }
    }
    if exponent < 0 { 1.0 / result } else { result }
}

/// Both operands of a comparison, if neither is NaN.
fn ordered(a: f64, b: f64) -> Result<(f64, f64), NotComputable> {
    if a.is_nan() || b.is_nan() { Err(NotComputable::Undefined) } else { Ok((a, b)) }
}

/// `a < b`; a NaN operand makes the formula undefined.
pub fn lt(a: f64, b: f64) -> Result<bool, NotComputable> {
    ordered(a, b).map(|(a, b)| a < b)
}

/// `a <= b`; a NaN operand makes the formula undefined.
pub fn le(a: f64, b: f64) -> Result<bool, NotComputable> {
    ordered(a, b).map(|(a, b)| a <= b)
}

/// `a > b`; a NaN operand makes the formula undefined.
pub fn gt(a: f64, b: f64) -> Result<bool, NotComputable> {
    ordered(a, b).map(|(a, b)| a > b)
}

/// `a >= b`; a NaN operand makes the formula undefined.
pub fn ge(a: f64, b: f64) -> Result<bool, NotComputable> {
    ordered(a, b).map(|(a, b)| a >= b)
}

/// `a == b`; a NaN operand makes the formula undefined.
#[allow(clippy::float_cmp)]
pub fn eq(a: f64, b: f64) -> Result<bool, NotComputable> {
    ordered(a, b).map(|(a, b)| a == b)
}

/// `a != b`; a NaN operand makes the formula undefined.
#[allow(clippy::float_cmp)]
pub fn ne(a: f64, b: f64) -> Result<bool, NotComputable> {
    ordered(a, b).map(|(a, b)| a != b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_and_outputs() {
        assert_eq!(input("x", 1.5, Some((0.0, 2.0))), Ok(1.5));
        assert_eq!(input("x", f32::NAN, None), Err(NotComputable::NotFinite { input: "x" }));
        assert_eq!(input("x", f32::INFINITY, None), Err(NotComputable::NotFinite { input: "x" }));
        assert!(matches!(input("x", 3.0, Some((0.0, 2.0))), Err(NotComputable::OutOfRange { .. })));
        assert_eq!(output(2.0), Ok(2.0));
        assert_eq!(output(f64::NAN), Err(NotComputable::Undefined));
        assert_eq!(output(1e300), Err(NotComputable::Undefined));
        assert_eq!(lt(1.0, f64::NAN), Err(NotComputable::Undefined));
        assert_eq!(le(1.0, 1.0), Ok(true));
        assert!((exp(ln(5.0)) - 5.0).abs() < 1e-12);
        assert!((pow(10.0, 2.0) - 100.0).abs() < 1e-12);
    }

    #[test]
    fn whole_powers_agree_with_the_general_power() {
        for base in [-3.7, -1.0, -0.5, 0.0, 0.25, 1.0, 2.0, 3.15, 298.15 / 100.0, 1e3] {
            for exponent in -64..=64 {
                let (whole, general) = (powi(base, exponent), pow(base, f64::from(exponent)));
                if general.is_finite() && general != 0.0 {
                    let error = ((whole - general) / general).abs();
                    assert!(error < 1e-13, "{base}^{exponent}: {whole} against {general}");
                } else {
                    assert_eq!(whole.is_finite(), general.is_finite(), "{base}^{exponent}");
                }
            }
            assert_eq!(powi(base, 2), base * base, "a square is one multiplication");
        }
        assert!(powi(f64::NAN, 0) == 1.0 && powi(f64::NAN, 1).is_nan());
    }

    #[test]
    fn powers_of_a_positive_number_agree_with_the_general_power() {
        for base in [0.5, 2.0, 10.0, 273.15] {
            let ln_base = libm::log(base);
            for tenth in -700..=700 {
                let exponent = f64::from(tenth) / 10.0;
                let (ours, general) = (pow_positive(base, ln_base, exponent), pow(base, exponent));
                if general.is_finite() && general != 0.0 {
                    assert!(((ours - general) / general).abs() < 1e-12, "{base}^{exponent}: {ours} against {general}");
                }
                if exponent.fract() == 0.0 && exponent.abs() <= 64.0 {
                    assert_eq!(ours, powi(base, exponent as i32), "{base}^{exponent} is a product");
                }
            }
        }
        assert_eq!(pow_positive(10.0, core::f64::consts::LN_10, 2.0), 100.0);
        assert_eq!(pow_positive(2.0, core::f64::consts::LN_2, 9.0), 512.0);
        assert!(pow_positive(10.0, core::f64::consts::LN_10, f64::NAN).is_nan());
    }
}

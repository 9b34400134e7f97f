//! The one table of units a user may ask a measurement in, and the
//! conversions between units of one dimension.
//!
//! Every tool that shows a value in another unit than the spec's (`read
//! --unit`, `poll --unit`, a station probe's `units`) converts through
//! [`Conversion`], built from [`UNITS`]; no sensor has conversion code of
//! its own. A unit the table does not know (`NTU`, `pH`, `%`, `ppt`)
//! simply does not convert: [`Conversion::new`] says so
//! ([`UnitError::Unknown`]), and `validate` accepts such units all the
//! same (a spec may use any unit; only conversion needs the table).
//!
//! Each unit converts to its dimension's base unit by an affine formula,
//! `base = (value + offset) * num / den`, with `num` and `den` exact where
//! the definition is a ratio of small numbers (`degF`: offset -32, 5/9), so
//! fixed points come out exact (0 degC is 32 degF, 100 degC is 212 degF).
//! The base of each dimension is its smallest unit, so scale factors are
//! whole numbers and a conversion to a smaller unit only multiplies.
//!
//! Parts per million (`ppm`, `ppb`, `ppt`) are left out on purpose: they
//! are mass fractions, equal to mg/L (µg/L, g/L) only for water of density
//! 1 kg/L, and the specs' `ppt` is salinity (practical salinity, g/kg),
//! where a g/L conversion would be wrong. `mmH2O` is a level (the spec's
//! submersible level reads millimetres of water above the sensor), so it is
//! a length here: one millimetre of water column is one millimetre.
//!
//! The table and [`Conversion`] use only `core`; the choosing of units for
//! named quantities ([`choose`]) needs `alloc` for its answers.

use core::fmt;
use std::collections::BTreeMap;

/// What a unit measures; units convert only within one dimension.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Dimension {
    /// Electrical conductivity, as water-quality work calls it: specific conductance (base µS/cm).
    SpecificConductance,
    /// Temperature (base degC).
    Temperature,
    /// Mass concentration (base µg/L).
    Concentration,
    /// Pressure (base Pa).
    Pressure,
    /// Length, and levels as a water column (base mm).
    Length,
    /// Electrical potential (base mV).
    Potential,
    /// Duration (base ms).
    Time,
}

impl Dimension {
    /// Its name in messages (`temperature`).
    pub fn name(self) -> &'static str {
        match self {
            Dimension::SpecificConductance => "specific conductance",
            Dimension::Temperature => "temperature",
            Dimension::Concentration => "concentration",
            Dimension::Pressure => "pressure",
            Dimension::Length => "length",
            Dimension::Potential => "potential",
            Dimension::Time => "time",
        }
    }
}

impl fmt::Display for Dimension {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One unit of the table.
#[derive(Debug, PartialEq)]
pub struct UnitDef {
    /// Its spelling in output (`uS/cm`, `degF`): ASCII, as the specs write units.
    pub symbol: &'static str,
    /// Other spellings it is recognised by (`µS/cm`, `°F`).
    pub aliases: &'static [&'static str],
    /// What it measures.
    pub dimension: Dimension,
    /// Added to a value before scaling to the base unit.
    pub offset: f64,
    /// Numerator of the scale to the base unit.
    pub num: f64,
    /// Denominator of the scale to the base unit.
    pub den: f64,
}

impl UnitDef {
    /// `value` (in this unit) in the dimension's base unit.
    pub fn to_base(&self, value: f64) -> f64 {
        (value + self.offset) * self.num / self.den
    }

    /// `base` (in the dimension's base unit) in this unit.
    pub fn from_base(&self, base: f64) -> f64 {
        base * self.den / self.num - self.offset
    }

    /// True when `spelling` names this unit.
    pub fn is_spelled(&self, spelling: &str) -> bool {
        self.symbol == spelling || self.aliases.contains(&spelling)
    }
}

const fn unit(
    symbol: &'static str,
    aliases: &'static [&'static str],
    dimension: Dimension,
    num: f64,
    den: f64,
) -> UnitDef {
    UnitDef { symbol, aliases, dimension, offset: 0.0, num, den }
}

/// Every unit that converts. Spellings are case-sensitive (`mS` is not `MS`);
/// the lower-case `l` of litres and the two micro signs are listed as aliases.
pub static UNITS: &[UnitDef] = &[
    // Conductivity; base µS/cm. 1 S/m = 10 mS/cm.
    unit("uS/cm", &["µS/cm", "μS/cm"], Dimension::SpecificConductance, 1.0, 1.0),
    unit("mS/cm", &[], Dimension::SpecificConductance, 1000.0, 1.0),
    unit("mS/m", &[], Dimension::SpecificConductance, 10.0, 1.0),
    unit("S/m", &[], Dimension::SpecificConductance, 10_000.0, 1.0),
    // Temperature; base degC.
    unit("degC", &["°C", "℃"], Dimension::Temperature, 1.0, 1.0),
    UnitDef {
        symbol: "degF",
        aliases: &["°F", "℉"],
        dimension: Dimension::Temperature,
        offset: -32.0,
        num: 5.0,
        den: 9.0,
    },
    UnitDef { symbol: "K", aliases: &[], dimension: Dimension::Temperature, offset: -273.15, num: 1.0, den: 1.0 },
    // Mass concentration; base µg/L. 1 mg/mL = 1 g/L.
    unit("ug/L", &["µg/L", "μg/L", "ug/l", "µg/l", "μg/l"], Dimension::Concentration, 1.0, 1.0),
    unit("mg/L", &["mg/l"], Dimension::Concentration, 1000.0, 1.0),
    unit("g/L", &["g/l"], Dimension::Concentration, 1_000_000.0, 1.0),
    unit("mg/mL", &["mg/ml"], Dimension::Concentration, 1_000_000.0, 1.0),
    // Pressure; base Pa. mmHg is the conventional millimetre of mercury
    // (13.5951 g/cm³ x 9.80665 m/s², exactly 133.322387415 Pa); psi is the
    // pound-force (0.45359237 kg x 9.80665 m/s²) per square inch (0.0254² m²).
    unit("Pa", &[], Dimension::Pressure, 1.0, 1.0),
    unit("hPa", &["mbar"], Dimension::Pressure, 100.0, 1.0),
    unit("kPa", &[], Dimension::Pressure, 1000.0, 1.0),
    unit("bar", &[], Dimension::Pressure, 100_000.0, 1.0),
    unit("mmHg", &[], Dimension::Pressure, 133.322_387_415, 1.0),
    unit("psi", &[], Dimension::Pressure, 0.453_592_37 * 9.806_65, 0.0254 * 0.0254),
    // Length and water column; base mm.
    unit("mm", &[], Dimension::Length, 1.0, 1.0),
    unit("mmH2O", &["mm H2O", "mmH₂O"], Dimension::Length, 1.0, 1.0),
    unit("cm", &[], Dimension::Length, 10.0, 1.0),
    unit("cmH2O", &["cm H2O", "cmH₂O"], Dimension::Length, 10.0, 1.0),
    unit("m", &[], Dimension::Length, 1000.0, 1.0),
    unit("mH2O", &["m H2O", "mH₂O"], Dimension::Length, 1000.0, 1.0),
    unit("in", &[], Dimension::Length, 25.4, 1.0),
    unit("ft", &[], Dimension::Length, 304.8, 1.0),
    // Potential; base mV.
    unit("mV", &[], Dimension::Potential, 1.0, 1.0),
    unit("V", &[], Dimension::Potential, 1000.0, 1.0),
    // Time; base ms.
    unit("ms", &[], Dimension::Time, 1.0, 1.0),
    unit("s", &[], Dimension::Time, 1000.0, 1.0),
    unit("min", &[], Dimension::Time, 60_000.0, 1.0),
    unit("h", &[], Dimension::Time, 3_600_000.0, 1.0),
];

/// The unit spelled `spelling` (its symbol or an alias), if the table has it.
pub fn lookup(spelling: &str) -> Option<&'static UnitDef> {
    let spelling = spelling.trim();
    UNITS.iter().find(|u| u.is_spelled(spelling))
}

/// Every spelling the table knows, symbols first: for suggestions.
pub fn spellings() -> impl Iterator<Item = &'static str> {
    UNITS.iter().map(|u| u.symbol).chain(UNITS.iter().flat_map(|u| u.aliases.iter().copied()))
}

/// The symbols of the units of `dimension`, in table order.
pub fn symbols_of(dimension: Dimension) -> impl Iterator<Item = &'static str> {
    UNITS.iter().filter(move |u| u.dimension == dimension).map(|u| u.symbol)
}

/// Why a value cannot be shown in a unit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum UnitError {
    /// The table does not know this spelling.
    Unknown(String),
    /// The two units measure different things.
    Mismatch {
        /// The unit converted from.
        from: &'static str,
        /// Its dimension.
        from_dimension: Dimension,
        /// The unit asked for.
        to: &'static str,
        /// Its dimension.
        to_dimension: Dimension,
    },
}

impl fmt::Display for UnitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnitError::Unknown(u) => write!(f, "`{u}` is not a unit that converts (the unit table does not know it)"),
            UnitError::Mismatch { from, from_dimension, to, to_dimension } => {
                write!(f, "{from} is a {from_dimension} and {to} a {to_dimension}: they do not convert")
            }
        }
    }
}

impl std::error::Error for UnitError {}

/// A conversion between two units of one dimension.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conversion {
    /// The unit of the values given.
    pub from: &'static UnitDef,
    /// The unit of the values returned.
    pub to: &'static UnitDef,
}

impl Conversion {
    /// The conversion from the unit spelled `from` to the one spelled `to`.
    ///
    /// # Errors
    ///
    /// Either spelling is not in the table (the first unknown one is
    /// named), or the units' dimensions differ.
    pub fn new(from: &str, to: &str) -> Result<Self, UnitError> {
        let from_def = lookup(from).ok_or_else(|| UnitError::Unknown(from.to_owned()))?;
        let to_def = lookup(to).ok_or_else(|| UnitError::Unknown(to.to_owned()))?;
        Self::between(from_def, to_def)
    }

    /// The conversion between two units of the table.
    ///
    /// # Errors
    ///
    /// The units' dimensions differ.
    pub fn between(from: &'static UnitDef, to: &'static UnitDef) -> Result<Self, UnitError> {
        if from.dimension != to.dimension {
            return Err(UnitError::Mismatch {
                from: from.symbol,
                from_dimension: from.dimension,
                to: to.symbol,
                to_dimension: to.dimension,
            });
        }
        Ok(Self { from, to })
    }

    /// `value` in `from`, in `to`. The same unit (also spelled otherwise)
    /// returns `value` itself, untouched by rounding.
    pub fn apply(&self, value: f64) -> f64 {
        if core::ptr::eq(self.from, self.to) { value } else { self.to.from_base(self.from.to_base(value)) }
    }
}

/// A quantity a value may be shown for: a field or a derived quantity,
/// with its unit in the spec.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Quantity<'a> {
    /// Its name (a field's or a derived quantity's).
    pub name: &'a str,
    /// Its unit in the spec, if it has one.
    pub unit: Option<&'a str>,
}

/// A unit asked for: for one quantity by name, or for every quantity of its dimension.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Choice {
    /// The quantity, or `None` for every quantity of the unit's dimension.
    pub name: Option<String>,
    /// The unit, as written.
    pub unit: String,
}

impl Choice {
    /// Parses `NAME=UNIT` or `UNIT`.
    pub fn parse(text: &str) -> Self {
        match text.split_once('=') {
            Some((name, unit)) => Self { name: Some(name.trim().to_owned()), unit: unit.trim().to_owned() },
            None => Self { name: None, unit: text.trim().to_owned() },
        }
    }
}

impl fmt::Display for Choice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.name {
            Some(n) => write!(f, "{n}={}", self.unit),
            None => f.write_str(&self.unit),
        }
    }
}

/// Why a unit asked for cannot be given.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ChoiceError {
    /// The unit is not in the table.
    UnknownUnit {
        /// The unit as written.
        unit: String,
    },
    /// No quantity has that name.
    UnknownName {
        /// The name as written.
        name: String,
        /// The names there are.
        names: Vec<String>,
    },
    /// The quantity's own unit is not in the table (or it has none).
    NotConvertible {
        /// The quantity.
        name: String,
        /// Its unit in the spec.
        unit: Option<String>,
        /// The unit asked for.
        to: &'static str,
    },
    /// The quantity's unit and the one asked for measure different things.
    Mismatch {
        /// The quantity.
        name: String,
        /// Its unit in the spec.
        unit: &'static str,
        /// Its unit's dimension.
        dimension: Dimension,
        /// The unit asked for.
        to: &'static str,
        /// That unit's dimension.
        to_dimension: Dimension,
    },
    /// A unit for every quantity of a dimension, and none has it.
    NoneOfDimension {
        /// The unit asked for.
        to: &'static str,
        /// Its dimension.
        dimension: Dimension,
        /// The units the quantities have, that do convert.
        have: Vec<String>,
    },
    /// Two units asked for the same quantity (or the same dimension).
    Twice {
        /// The quantity or the dimension.
        what: String,
        /// The first unit.
        first: String,
        /// The second unit.
        second: String,
    },
}

impl fmt::Display for ChoiceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChoiceError::UnknownUnit { unit } => write!(f, "unknown unit `{unit}`: the unit table does not know it"),
            ChoiceError::UnknownName { name, names } => {
                write!(f, "no measurement or derived quantity `{name}`; there are: {}", names.join(", "))
            }
            ChoiceError::NotConvertible { name, unit: Some(unit), to } => {
                write!(f, "`{name}` is in {unit}, which is not convertible (the unit table does not know it) to {to}")
            }
            ChoiceError::NotConvertible { name, unit: None, to } => {
                write!(f, "`{name}` has no unit, so it is not convertible to {to}")
            }
            ChoiceError::Mismatch { name, unit, dimension, to, to_dimension } => write!(
                f,
                "`{name}` is a {dimension} (in {unit}) and {to} a {to_dimension}: choose one of {}",
                symbols_of(*dimension).collect::<Vec<_>>().join(", ")
            ),
            ChoiceError::NoneOfDimension { to, dimension, have } => {
                write!(f, "no measurement here is a {dimension} to show in {to}")?;
                if have.is_empty() { Ok(()) } else { write!(f, "; the units that convert here: {}", have.join(", ")) }
            }
            ChoiceError::Twice { what, first, second } => write!(f, "two units for {what}: {first} and {second}"),
        }
    }
}

impl std::error::Error for ChoiceError {}

/// The conversion of one quantity to the unit spelled `to`.
///
/// # Errors
///
/// The unit is unknown, no quantity is called `name`, its unit does not
/// convert, or measures something else.
pub fn choose_named(name: &str, to: &str, quantities: &[Quantity<'_>]) -> Result<Conversion, ChoiceError> {
    let target = lookup(to).ok_or_else(|| ChoiceError::UnknownUnit { unit: to.to_owned() })?;
    let Some(q) = quantities.iter().find(|q| q.name == name) else {
        return Err(ChoiceError::UnknownName {
            name: name.to_owned(),
            names: quantities.iter().map(|q| q.name.to_owned()).collect(),
        });
    };
    let not_convertible =
        || ChoiceError::NotConvertible { name: name.to_owned(), unit: q.unit.map(str::to_owned), to: target.symbol };
    let from = q.unit.and_then(lookup).ok_or_else(not_convertible)?;
    Conversion::between(from, target).map_err(|_| ChoiceError::Mismatch {
        name: name.to_owned(),
        unit: from.symbol,
        dimension: from.dimension,
        to: target.symbol,
        to_dimension: target.dimension,
    })
}

/// The conversions of every quantity whose unit has the dimension of the
/// unit spelled `to`, by name.
///
/// # Errors
///
/// The unit is unknown, or no quantity's unit has its dimension.
pub fn choose_by_dimension<'a>(
    to: &str,
    quantities: &[Quantity<'a>],
) -> Result<Vec<(&'a str, Conversion)>, ChoiceError> {
    let target = lookup(to).ok_or_else(|| ChoiceError::UnknownUnit { unit: to.to_owned() })?;
    let chosen: Vec<(&str, Conversion)> = quantities
        .iter()
        .filter_map(|q| {
            let from = q.unit.and_then(lookup)?;
            Conversion::between(from, target).ok().map(|c| (q.name, c))
        })
        .collect();
    if chosen.is_empty() {
        let mut have: Vec<String> =
            quantities.iter().filter_map(|q| q.unit.and_then(lookup)).map(|u| u.symbol.to_owned()).collect();
        have.sort();
        have.dedup();
        return Err(ChoiceError::NoneOfDimension { to: target.symbol, dimension: target.dimension, have });
    }
    Ok(chosen)
}

/// The conversion of each quantity `choices` ask for, by name: a named
/// choice wins over a unit for its dimension; the others keep their unit.
///
/// # Errors
///
/// The first choice that cannot be given, or two choices for one quantity
/// (or one dimension).
pub fn choose(choices: &[Choice], quantities: &[Quantity<'_>]) -> Result<BTreeMap<String, Conversion>, ChoiceError> {
    let mut named: BTreeMap<String, (Conversion, &str)> = BTreeMap::new();
    // Per dimension: the conversions of its quantities, and the unit as written.
    type ByDimension<'c> = BTreeMap<Dimension, (Vec<(String, Conversion)>, &'c str)>;
    let mut by_dimension: ByDimension<'_> = BTreeMap::new();
    for choice in choices {
        match &choice.name {
            Some(name) => {
                let c = choose_named(name, &choice.unit, quantities)?;
                if let Some((_, first)) = named.get(name) {
                    return Err(ChoiceError::Twice {
                        what: format!("`{name}`"),
                        first: (*first).to_owned(),
                        second: choice.unit.clone(),
                    });
                }
                named.insert(name.clone(), (c, &choice.unit));
            }
            None => {
                let all = choose_by_dimension(&choice.unit, quantities)?;
                let dimension = all.first().map_or(Dimension::Time, |(_, c)| c.to.dimension);
                if let Some((_, first)) = by_dimension.get(&dimension) {
                    return Err(ChoiceError::Twice {
                        what: format!("every {dimension}"),
                        first: (*first).to_owned(),
                        second: choice.unit.clone(),
                    });
                }
                let all = all.into_iter().map(|(n, c)| (n.to_owned(), c)).collect();
                by_dimension.insert(dimension, (all, &choice.unit));
            }
        }
    }
    let mut out: BTreeMap<String, Conversion> = by_dimension.into_values().flat_map(|(all, _)| all).collect();
    out.extend(named.into_iter().map(|(n, (c, _))| (n, c)));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn convert(v: f64, from: &str, to: &str) -> f64 {
        Conversion::new(from, to).unwrap().apply(v)
    }

    fn close(a: f64, b: f64, tolerance: f64) -> bool {
        (a - b).abs() <= tolerance
    }

    #[test]
    fn fixed_points() {
        assert_eq!(convert(0.0, "degC", "degF"), 32.0);
        assert_eq!(convert(100.0, "degC", "degF"), 212.0);
        assert_eq!(convert(-40.0, "degC", "degF"), -40.0);
        assert_eq!(convert(32.0, "degF", "degC"), 0.0);
        assert_eq!(convert(212.0, "degF", "degC"), 100.0);
        assert!(close(convert(0.0, "degC", "K"), 273.15, 1e-12));
        assert!(close(convert(0.0, "K", "degF"), -459.67, 1e-9));
        assert_eq!(convert(1.0, "mS/cm", "uS/cm"), 1000.0);
        assert_eq!(convert(1000.0, "uS/cm", "mS/cm"), 1.0);
        assert_eq!(convert(1.0, "S/m", "mS/cm"), 10.0);
        assert_eq!(convert(1.0, "mg/L", "ug/L"), 1000.0);
        assert_eq!(convert(1.0, "mg/mL", "g/L"), 1.0);
        assert!(close(convert(101.325, "kPa", "mmHg"), 760.0, 1e-3));
        // The conventional mmHg is not the torr (101.325/760 kPa): 760 of them are 101.3250144 kPa.
        assert!(close(convert(760.0, "mmHg", "kPa"), 101.325, 1e-4));
        assert!(!close(convert(760.0, "mmHg", "kPa"), 101.325, 1e-6));
        assert!(close(convert(1.0, "psi", "Pa"), 6_894.757_293_168, 1e-6));
        assert_eq!(convert(1013.25, "hPa", "kPa"), 101.325);
        assert_eq!(convert(1.0, "bar", "kPa"), 100.0);
        assert_eq!(convert(1500.0, "mmH2O", "m"), 1.5);
        assert!(close(convert(1.0, "ft", "in"), 12.0, 1e-12));
        assert_eq!(convert(1.0, "V", "mV"), 1000.0);
        assert_eq!(convert(2.0, "min", "s"), 120.0);
    }

    #[test]
    fn tenths_of_a_degree_convert_by_the_formula() {
        // 0.1 degF steps: (F - 32) * 5 / 9, not a rounded factor.
        for tenths in -400..=2120 {
            let f = f64::from(tenths) / 10.0;
            let c = convert(f, "degF", "degC");
            assert!(close(c, (f - 32.0) * 5.0 / 9.0, 1e-12), "{f}");
            assert!(close(convert(c, "degC", "degF"), f, 1e-12), "{f}");
        }
    }

    #[test]
    fn every_pair_of_a_dimension_round_trips() {
        let mut pairs = 0;
        for a in UNITS {
            for b in UNITS.iter().filter(|b| b.dimension == a.dimension) {
                let c = Conversion::between(a, b).unwrap();
                let back = Conversion::between(b, a).unwrap();
                for v in [-12.5, 0.0, 0.001, 1.0, 7.25, 1234.5678] {
                    let there = c.apply(v);
                    assert!(close(back.apply(there), v, 1e-9 * v.abs().max(1.0)), "{v} {} -> {}", a.symbol, b.symbol);
                }
                pairs += 1;
            }
        }
        assert!(pairs > UNITS.len());
    }

    #[test]
    fn spellings_are_unique_and_aliases_find_their_unit() {
        let all: Vec<&str> = spellings().collect();
        for s in &all {
            assert_eq!(all.iter().filter(|o| *o == s).count(), 1, "{s} twice");
            assert!(lookup(s).is_some());
        }
        assert_eq!(lookup("µS/cm").map(|u| u.symbol), Some("uS/cm"));
        assert_eq!(lookup("°F").map(|u| u.symbol), Some("degF"));
        // An alias is the same unit: the value passes untouched.
        assert_eq!(convert(0.1, "µS/cm", "uS/cm").to_bits(), 0.1f64.to_bits());
    }

    #[test]
    fn what_does_not_convert_says_so() {
        assert_eq!(Conversion::new("NTU", "mg/L"), Err(UnitError::Unknown("NTU".into())));
        assert_eq!(Conversion::new("mg/L", "ppm"), Err(UnitError::Unknown("ppm".into())));
        let e = Conversion::new("degC", "kPa").unwrap_err();
        assert!(matches!(e, UnitError::Mismatch { .. }));
        assert!(e.to_string().contains("do not convert"), "{e}");
        assert!(lookup("MS/cm").is_none(), "spellings are case-sensitive");
    }

    fn quantities() -> Vec<Quantity<'static>> {
        vec![
            Quantity { name: "a", unit: Some("mS/cm") },
            Quantity { name: "b", unit: Some("degC") },
            Quantity { name: "c", unit: Some("degC") },
            Quantity { name: "d", unit: Some("NTU") },
            Quantity { name: "e", unit: None },
        ]
    }

    #[test]
    fn choices_by_dimension_and_by_name() {
        let q = quantities();
        let parse = |texts: &[&str]| texts.iter().map(|t| Choice::parse(t)).collect::<Vec<_>>();
        let chosen = choose(&parse(&["degF", "c=K", "a=uS/cm"]), &q).unwrap();
        let symbols: Vec<(&str, &str)> = chosen.iter().map(|(n, c)| (n.as_str(), c.to.symbol)).collect();
        assert_eq!(symbols, [("a", "uS/cm"), ("b", "degF"), ("c", "K")]);

        let err = |texts: &[&str]| choose(&parse(texts), &q).unwrap_err();
        assert!(matches!(err(&["furlong"]), ChoiceError::UnknownUnit { .. }));
        assert!(matches!(err(&["kPa"]), ChoiceError::NoneOfDimension { .. }));
        assert!(err(&["kPa"]).to_string().contains("degC, mS/cm"), "{}", err(&["kPa"]));
        assert!(matches!(err(&["z=degF"]), ChoiceError::UnknownName { .. }));
        assert!(matches!(err(&["a=degF"]), ChoiceError::Mismatch { .. }));
        assert!(err(&["a=degF"]).to_string().contains("uS/cm"), "{}", err(&["a=degF"]));
        assert!(matches!(err(&["d=mg/L"]), ChoiceError::NotConvertible { .. }));
        assert!(err(&["d=mg/L"]).to_string().contains("not convertible"));
        assert!(matches!(err(&["e=mg/L"]), ChoiceError::NotConvertible { unit: None, .. }));
        assert!(matches!(err(&["degF", "K"]), ChoiceError::Twice { .. }));
        assert!(matches!(err(&["b=degF", "b=K"]), ChoiceError::Twice { .. }));
        assert_eq!(Choice::parse(" a = uS/cm "), Choice { name: Some("a".into()), unit: "uS/cm".into() });
    }
}

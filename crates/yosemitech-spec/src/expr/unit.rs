//! Units as products of opaque symbols with integer powers, as a formula's
//! unit check sees them.

use std::collections::BTreeMap;
use std::fmt;

/// A unit: symbols with their (non-zero) integer powers; empty is dimensionless.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Unit(pub BTreeMap<String, i32>);

impl Unit {
    /// True for a unit without symbols.
    pub fn is_dimensionless(&self) -> bool {
        self.0.is_empty()
    }

    pub(super) fn times(&self, other: &Unit, sign: i32) -> Unit {
        let mut out = self.0.clone();
        for (s, p) in &other.0 {
            let e = out.entry(s.clone()).or_insert(0);
            *e += sign * p;
            if *e == 0 {
                out.remove(s);
            }
        }
        Unit(out)
    }

    pub(super) fn power(&self, n: i32) -> Unit {
        if n == 0 {
            return Unit::default();
        }
        Unit(self.0.iter().map(|(s, p)| (s.clone(), p * n)).collect())
    }

    /// Parses a unit as the spec writes it: symbols joined by `*`, `·` or
    /// spaces, `/` dividing by the symbol after it, ` per ` dividing by
    /// everything after it, `^n` (or `^-n`) powers; `1` or nothing for
    /// dimensionless.
    pub fn parse(text: &str) -> Result<Unit, String> {
        let text = text.trim();
        let (num, den) = match text.split_once(" per ") {
            Some((n, d)) => (n, Some(d)),
            None => (text, None),
        };
        let mut unit = parse_product(num)?;
        if let Some(d) = den {
            unit = unit.times(&parse_product(d)?, -1);
        }
        Ok(unit)
    }
}

fn parse_product(text: &str) -> Result<Unit, String> {
    let mut unit = Unit::default();
    let chars: Vec<char> = text.chars().collect();
    let mut i = 0;
    let mut sign = 1;
    let mut expect_factor = true;
    while i < chars.len() {
        let c = chars[i];
        if c == ' ' || c == '*' || c == '·' {
            i += 1;
            continue;
        }
        if c == '/' {
            if expect_factor && i > 0 {
                return Err(format!("`{text}`: `/` follows no symbol"));
            }
            sign = -1;
            expect_factor = true;
            i += 1;
            continue;
        }
        let start = i;
        while i < chars.len() && (chars[i].is_alphanumeric() || matches!(chars[i], '%' | '°' | 'µ' | '_')) {
            i += 1;
        }
        if i == start {
            return Err(format!("`{text}`: `{c}` is not part of a unit symbol"));
        }
        let symbol: String = chars[start..i].iter().collect();
        let mut power = 1i32;
        if chars.get(i) == Some(&'^') {
            i += 1;
            let from = i;
            if chars.get(i) == Some(&'-') {
                i += 1;
            }
            while i < chars.len() && chars[i].is_ascii_digit() {
                i += 1;
            }
            let digits: String = chars[from..i].iter().collect();
            power = digits.parse().map_err(|_| format!("`{text}`: `^` takes a whole number"))?;
        }
        if symbol != "1" {
            if symbol.starts_with(|c: char| c.is_ascii_digit()) {
                return Err(format!("`{text}`: `{symbol}` is not a unit symbol"));
            }
            unit = unit.times(&Unit(BTreeMap::from([(symbol, power)])), sign);
        }
        sign = 1;
        expect_factor = false;
    }
    if expect_factor && !chars.is_empty() && text.trim_end().ends_with('/') {
        return Err(format!("`{text}`: `/` is followed by no symbol"));
    }
    Ok(unit)
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return f.write_str("1 (dimensionless)");
        }
        let mut first = true;
        for (s, p) in self.0.iter().filter(|(_, p)| **p > 0) {
            if !first {
                f.write_str("*")?;
            }
            first = false;
            if *p == 1 { write!(f, "{s}")? } else { write!(f, "{s}^{p}")? }
        }
        if first {
            f.write_str("1")?;
        }
        for (s, p) in self.0.iter().filter(|(_, p)| **p < 0) {
            if *p == -1 { write!(f, "/{s}")? } else { write!(f, "/{s}^{}", -p)? }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::unit;
    use super::*;

    #[test]
    fn units_parse() {
        assert_eq!(unit("mg/L"), Unit(BTreeMap::from([("mg".into(), 1), ("L".into(), -1)])));
        assert_eq!(unit("mg/L per uS/cm"), unit("mg*cm/L/uS"));
        assert_eq!(unit("m^2/s"), unit("m m / s"));
        assert!(unit("1").is_dimensionless());
        assert!(unit("").is_dimensionless());
        assert_eq!(unit("%").to_string(), "%");
        assert_eq!(unit("kPa^-1").to_string(), "1/kPa");
        assert!(Unit::parse("mg/").is_err());
        assert!(Unit::parse("m^x").is_err());
        assert!(Unit::parse("a+b").is_err());
    }
}

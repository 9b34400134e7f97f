//! What a scalar means, read as the type the document asks for (YAML 1.2's
//! core schema): `0x1C00` is a number where a number is asked for and text
//! where text is; `yes` is never a boolean.
//!
//! A number or a boolean is read from a scalar's text whether it is quoted
//! or not (`"12"` is 12 where a number is asked for), unless it is tagged
//! `!!str`. Read as any value (an untagged enum), only a plain scalar is
//! null, a boolean or a number.

use super::load::Scalar;

/// A scalar read as any value.
pub(super) enum Resolved<'a> {
    Null,
    Bool(bool),
    Unsigned(u64),
    Signed(i64),
    Float(f64),
    Text(&'a str),
}

impl Scalar {
    /// Written as null: `~`, `null` or nothing, plain.
    pub(super) fn is_null(&self) -> bool {
        match self.tag.as_deref() {
            Some("null") => true,
            Some(_) => false,
            None => self.plain && matches!(self.text.as_str(), "" | "~" | "null" | "Null" | "NULL"),
        }
    }

    /// The scalar as any value; `Err` names the type a tag asks for that
    /// the text is not.
    pub(super) fn resolve(&self) -> Result<Resolved<'_>, &'static str> {
        let text = self.text.as_str();
        match self.tag.as_deref() {
            Some("str") => return Ok(Resolved::Text(text)),
            Some("null") => return Ok(Resolved::Null),
            Some("bool") => return self.boolean().map(Resolved::Bool).ok_or("bool"),
            Some("int") => return self.integer().ok_or("int"),
            Some("float") => return self.float().map(Resolved::Float).ok_or("floating point"),
            Some(_) => return Ok(Resolved::Text(text)),
            None if !self.plain => return Ok(Resolved::Text(text)),
            None => {}
        }
        if self.is_null() {
            return Ok(Resolved::Null);
        }
        if let Some(b) = self.boolean() {
            return Ok(Resolved::Bool(b));
        }
        if let Some(n) = self.integer() {
            return Ok(n);
        }
        Ok(self.float().map_or(Resolved::Text(text), Resolved::Float))
    }

    /// `true` or `false` (also capitalised, or in capitals).
    pub(super) fn boolean(&self) -> Option<bool> {
        if self.tag.as_deref().is_some_and(|t| t != "bool") {
            return None;
        }
        match self.text.trim() {
            "true" | "True" | "TRUE" => Some(true),
            "false" | "False" | "FALSE" => Some(false),
            _ => None,
        }
    }

    /// A whole number: decimal (no leading zero), `0x` hex, `0o` octal or
    /// `0b` binary, signed, with `_` between digits.
    pub(super) fn whole(&self) -> Option<i128> {
        if self.tag.as_deref().is_some_and(|t| t != "int") {
            return None;
        }
        whole(self.text.trim())
    }

    fn integer(&self) -> Option<Resolved<'_>> {
        let n = self.whole()?;
        Some(match u64::try_from(n) {
            Ok(n) => Resolved::Unsigned(n),
            Err(_) => Resolved::Signed(i64::try_from(n).ok()?),
        })
    }

    /// A number: a whole number, a decimal with optional exponent, or
    /// `.inf`, `-.inf`, `.nan`.
    pub(super) fn float(&self) -> Option<f64> {
        if self.tag.as_deref().is_some_and(|t| t != "float" && t != "int") {
            return None;
        }
        let text = self.text.trim();
        if let Some(n) = whole(text) {
            // Exact up to 2^53; a spec's whole numbers are far smaller.
            #[allow(clippy::cast_precision_loss)]
            return Some(n as f64);
        }
        let (sign, unsigned) = match text.strip_prefix('-') {
            Some(rest) => (-1.0, rest),
            None => (1.0, text.strip_prefix('+').unwrap_or(text)),
        };
        match unsigned {
            ".inf" | ".Inf" | ".INF" => return Some(sign * f64::INFINITY),
            ".nan" | ".NaN" | ".NAN" if unsigned.len() == text.len() => return Some(f64::NAN),
            _ => {}
        }
        decimal(unsigned).then(|| text.parse::<f64>().ok()).flatten()
    }
}

/// `[0-9]*(\.[0-9]*)?([eE][-+]?[0-9]+)?` with at least one digit before the exponent.
fn decimal(text: &str) -> bool {
    let (mantissa, exponent) = match text.find(['e', 'E']) {
        Some(i) => (&text[..i], Some(&text[i + 1..])),
        None => (text, None),
    };
    let (whole, fraction) = mantissa.split_once('.').unwrap_or((mantissa, ""));
    let digits = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    let exponent_ok = exponent.is_none_or(|e| {
        let e = e.strip_prefix(['-', '+']).unwrap_or(e);
        !e.is_empty() && digits(e)
    });
    digits(whole) && digits(fraction) && whole.len() + fraction.len() > 0 && exponent_ok
}

/// The whole number `text` is, by the rules of [`Scalar::whole`]; also how
/// an error tells a negative or too large number from text.
pub(super) fn whole(text: &str) -> Option<i128> {
    let (negative, unsigned) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text.strip_prefix('+').unwrap_or(text)),
    };
    let (radix, digits) = match unsigned.get(..2) {
        Some("0x" | "0X") => (16, &unsigned[2..]),
        Some("0o" | "0O") => (8, &unsigned[2..]),
        Some("0b" | "0B") => (2, &unsigned[2..]),
        _ if unsigned.len() > 1 && unsigned.starts_with('0') => return None,
        _ => (10, unsigned),
    };
    let digits = digits.strip_prefix('_').filter(|_| radix != 10).unwrap_or(digits);
    if digits.is_empty() || digits.starts_with('_') || digits.ends_with('_') || digits.contains("__") {
        return None;
    }
    let mut value: i128 = 0;
    for c in digits.chars().filter(|c| *c != '_') {
        let digit = c.to_digit(radix)?;
        value = value.checked_mul(i128::from(radix))?.checked_add(i128::from(digit))?;
    }
    Some(if negative { -value } else { value })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plain(text: &str) -> Scalar {
        Scalar { text: text.into(), plain: true, tag: None }
    }

    #[test]
    fn whole_numbers() {
        for (text, value) in [("0", 0), ("12", 12), ("+12", 12), ("-5", -5), ("1_000", 1000), ("0x1C00", 0x1C00)] {
            assert_eq!(whole(text), Some(value), "{text}");
        }
        assert_eq!(whole("0o17"), Some(15));
        assert_eq!(whole("0b101"), Some(5));
        for text in ["012", "", "-", "1__0", "_1", "1_", "0x", "1.5", "twelve", "0xG"] {
            assert_eq!(whole(text), None, "{text}");
        }
    }

    #[test]
    fn floats() {
        for (text, value) in [("1e3", 1e3), ("-0.5", -0.5), (".5", 0.5), ("5", 5.0), ("1.", 1.0), ("+2E-1", 0.2)] {
            assert_eq!(plain(text).float(), Some(value), "{text}");
        }
        assert_eq!(plain("-.inf").float(), Some(f64::NEG_INFINITY));
        assert!(plain(".nan").float().is_some_and(f64::is_nan));
        for text in ["inf", "nan", "infinity", "1e", "e3", ".", "-.nan", "1.2.3", "0x1p3"] {
            assert_eq!(plain(text).float(), None, "{text}");
        }
    }

    #[test]
    fn any_value() {
        assert!(matches!(plain("~").resolve(), Ok(Resolved::Null)));
        assert!(matches!(plain("yes").resolve(), Ok(Resolved::Text("yes"))));
        assert!(matches!(plain("TRUE").resolve(), Ok(Resolved::Bool(true))));
        assert!(matches!(plain("-3").resolve(), Ok(Resolved::Signed(-3))));
        let quoted = Scalar { plain: false, ..plain("7") };
        assert!(matches!(quoted.resolve(), Ok(Resolved::Text("7"))));
        let tagged = Scalar { tag: Some("str".into()), ..plain("7") };
        assert!(matches!(tagged.resolve(), Ok(Resolved::Text("7"))));
        assert_eq!(tagged.whole(), None);
    }
}

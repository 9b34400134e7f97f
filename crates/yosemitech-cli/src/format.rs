//! Showing values, units, frames and durations; parsing what the user types.

use std::collections::BTreeMap;
use std::time::Duration;

use serde_json::{Map, Value as Json, json};
use yosemitech_spec::{CommandSpec, Field, FieldKind, Value};

use crate::error::{CliError, Result};

/// A unit as shown to people (`degC` is `°C`).
pub fn unit(unit: &str) -> &str {
    match unit {
        "degC" => "°C",
        "degF" => "°F",
        other => other,
    }
}

/// A value as text, without its unit.
pub fn value_text(value: &Value) -> String {
    match value {
        Value::Text(t) => t.clone(),
        other => other.to_string(),
    }
}

/// A value as text for its field: enums by name (`unknown (255)` when
/// the code has none), flag fields by the names of the bits set (`none`
/// for 0, unnamed bits in hex), every other value as [`value_text`] shows it.
pub fn field_value_text(field: &Field, value: &Value) -> String {
    match (&field.kind, value) {
        (_, Value::Enum { name: Some(name), .. }) => name.clone(),
        (FieldKind::Flags { flags, .. }, Value::Int(raw)) => {
            if *raw == 0 {
                return "none".to_owned();
            }
            let mut names: Vec<String> =
                flags.iter().filter(|f| raw & i64::from(f.mask) != 0).map(|f| f.name.clone()).collect();
            let known: i64 = flags.iter().map(|f| i64::from(f.mask)).fold(0, |a, m| a | m);
            if raw & !known != 0 {
                names.push(format!("0x{:X}", raw & !known));
            }
            names.join("|")
        }
        _ => value_text(value),
    }
}

/// A value with its unit, if it has one.
pub fn value_with_unit(value: &Value, field: Option<&Field>) -> String {
    match field.and_then(|f| f.unit.as_deref()) {
        Some(u) => format!("{} {}", value_text(value), unit(u)),
        None => value_text(value),
    }
}

/// An f32 as a JSON number written the shortest way that reads back to the
/// same f32 (`6.86`, not `6.860000133514404`); not-finite values as strings.
pub fn f32_json(v: f32) -> Json {
    if v.is_finite() {
        // Display writes the shortest round-tripping decimal; as f64 it prints the same.
        v.to_string().parse::<f64>().ok().and_then(serde_json::Number::from_f64).map_or(Json::Null, Json::Number)
    } else if v.is_nan() {
        Json::String("NaN".into())
    } else if v > 0.0 {
        Json::String("inf".into())
    } else {
        Json::String("-inf".into())
    }
}

/// An f32 back from [`f32_json`] (or any JSON number), bit-exact for what
/// [`f32_json`] wrote.
pub fn json_f32(v: &Json) -> Option<f32> {
    match v {
        Json::Number(n) => n.to_string().parse().ok(),
        Json::String(s) => match s.as_str() {
            "NaN" | "nan" => Some(f32::NAN),
            "inf" | "+inf" | "Infinity" => Some(f32::INFINITY),
            "-inf" | "-Infinity" => Some(f32::NEG_INFINITY),
            _ => None,
        },
        _ => None,
    }
}

/// A decoded value as JSON: numbers, text, versions as `"1.1"`, enums as
/// `{"raw": 0, "name": "ok"}`.
pub fn value_json(value: &Value) -> Json {
    match value {
        Value::Float(v) => f32_json(*v),
        Value::Int(v) => json!(v),
        Value::Text(t) => json!(t),
        Value::Version(v) => json!(v.to_string()),
        Value::Bcd(v) => v.value().map_or(Json::Null, |n| json!(n)),
        Value::Enum { raw, name } => json!({ "raw": raw, "name": name }),
    }
}

/// Values as a JSON object, by field name.
pub fn values_json(values: &[(String, Value)]) -> Json {
    Json::Object(values.iter().map(|(k, v)| (k.clone(), value_json(v))).collect::<Map<_, _>>())
}

/// Decoded fields with their units and layout, as JSON.
pub fn fields_json(command: &CommandSpec, values: &[(String, Value)]) -> Json {
    Json::Array(
        values
            .iter()
            .map(|(name, value)| {
                let field = command.field(name);
                json!({
                    "name": name,
                    "value": value_json(value),
                    "unit": field.and_then(|f| f.unit.clone()),
                    "type": field.map(|f| f.kind.type_name()),
                    "text": value_with_unit(value, field),
                })
            })
            .collect(),
    )
}

/// A CSV field, quoted when it needs to be (RFC 4180).
pub fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) { format!("\"{}\"", text.replace('"', "\"\"")) } else { text.to_owned() }
}

/// Bytes as `01 03 28 00`.
pub fn hex(bytes: &[u8]) -> String {
    yosemitech_rtu::Hex(bytes).to_string()
}

/// A frame typed by a person: hex with or without spaces, `0x` prefixes,
/// commas, colons or dashes between bytes.
pub fn parse_frame(text: &str) -> Result<Vec<u8>> {
    let hint = "give the frame as hex bytes, e.g. `01 03 28 00 00 02 CD AB`, `010328000002CDAB` or `0x01 0x03 ...`";
    yosemitech_explain::parse_frame(text)
        .map_err(|e| CliError::usage(format!("invalid frame `{}`: {e}", text.trim())).hint(hint))
}

/// Parses `100ms`, `3s`, `1.5s`, `2m`, `1h`, `250us` or a plain number of seconds.
pub fn parse_duration(text: &str) -> std::result::Result<Duration, String> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, suffix) = t.split_at(split);
    let value: f64 =
        number.parse().map_err(|_| format!("`{text}` is not a duration; write it like 500ms, 3s, 1.5s or 2m"))?;
    let scale = match suffix.trim() {
        "" | "s" | "sec" | "secs" => 1.0,
        "ms" => 1e-3,
        "us" | "µs" => 1e-6,
        "m" | "min" => 60.0,
        "h" => 3600.0,
        other => return Err(format!("unknown unit `{other}` in `{text}`; use ms, s, m or h")),
    };
    Duration::try_from_secs_f64(value * scale).map_err(|_| format!("`{text}` is out of range"))
}

/// Largest chart side, in pixels.
pub const MAX_SIDE: u32 = 10_000;
/// Smallest chart side, in pixels.
pub const MIN_SIDE: u32 = 100;

/// Parses a picture size, `WIDTHxHEIGHT` in pixels, each side within
/// [`MIN_SIDE`]..=[`MAX_SIDE`].
pub fn parse_size(text: &str) -> std::result::Result<(u32, u32), String> {
    let bad = || format!("`{text}` is not a size; write it as WIDTHxHEIGHT in pixels, e.g. 1200x800");
    let (w, h) = text.trim().split_once(['x', 'X']).ok_or_else(bad)?;
    let side = |s: &str| s.trim().parse::<u32>().map_err(|_| bad());
    let (w, h) = (side(w)?, side(h)?);
    for (name, n) in [("width", w), ("height", h)] {
        if !(MIN_SIDE..=MAX_SIDE).contains(&n) {
            return Err(format!("the {name} {n} is outside {MIN_SIDE} to {MAX_SIDE} pixels"));
        }
    }
    Ok((w, h))
}

/// Parses the values of a write (or of a read's reply, for `encode
/// --response`): `field=value` pairs, or values in field order.
pub fn parse_values(command: &CommandSpec, args: &[String]) -> Result<BTreeMap<String, Value>> {
    let fields: Vec<&Field> = command.named_fields().collect();
    let names: Vec<&str> = fields.iter().map(|f| f.display_name()).collect();
    let mut out = BTreeMap::new();
    let mut position = 0;
    for arg in args {
        let named = arg.split_once('=').and_then(|(k, v)| command.field(k).map(|f| (f, v)));
        let (field, text) = match named {
            Some(pair) => pair,
            None => {
                if let Some((k, _)) = arg.split_once('=').filter(|(k, _)| is_identifier(k)) {
                    let e = CliError::usage(format!("`{}` has no field `{k}`", command.name));
                    return Err(match yosemitech_spec::suggest::closest(k, &names) {
                        Some(best) => e.hint(format!("did you mean `{best}`? Its fields: {}", names.join(", "))),
                        None => e.hint(format!("its fields: {}", fields_hint(command))),
                    });
                }
                let Some(f) = fields.get(position) else {
                    return Err(CliError::usage(format!(
                        "too many values: `{}` takes {} ({})",
                        command.name,
                        fields.len(),
                        names.join(", ")
                    ))
                    .hint(format!("give each value once, in order or as field=value: {}", fields_hint(command))));
                };
                position += 1;
                (*f, arg.as_str())
            }
        };
        let name = field.display_name().to_owned();
        if out.contains_key(&name) {
            return Err(
                CliError::usage(format!("`{name}` is given twice")).hint(format!("fields: {}", fields_hint(command)))
            );
        }
        out.insert(name, parse_value(field, text, !command.is_read())?);
    }
    if let Some(missing) = fields.iter().find(|f| !out.contains_key(f.display_name())) {
        return Err(CliError::usage(format!("no value for `{}` of `{}`", missing.display_name(), command.name))
            .hint(format!("give every field, in order or as field=value: {}", fields_hint(command))));
    }
    Ok(out)
}

fn is_identifier(text: &str) -> bool {
    text.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && text.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// `name (type, unit, range)` for every field, for hints.
pub fn fields_hint(command: &CommandSpec) -> String {
    command
        .named_fields()
        .map(|f| {
            let mut about = vec![f.kind.type_name().to_owned()];
            if let Some(u) = &f.unit {
                about.push(unit(u).to_owned());
            }
            if let Some((min, max)) = f.range {
                about.push(format!("{min} to {max}"));
            }
            if let FieldKind::Enum { variants, .. } = &f.kind {
                about.push(variants.iter().map(|v| v.name.as_str()).collect::<Vec<_>>().join("|"));
            }
            format!("{}=<{}>", f.display_name(), about.join(", "))
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Parses one field's value. `bounded`: the value is a write's, which must
/// lie in the field's `range`; a read's range is the measuring range, which
/// a probe may leave (a reply encoded with `encode --response` may carry a
/// value outside it, such as an `absent` sentinel), so it bounds nothing.
pub fn parse_value(field: &Field, text: &str, bounded: bool) -> Result<Value> {
    let name = field.display_name();
    let range = field.range.filter(|_| bounded);
    let bad = |what: &str| {
        CliError::usage(format!("`{text}` is not {what} (field `{name}`)")).hint(format!(
            "`{name}` is a {}{}",
            field.kind.type_name(),
            range.map(|(a, b)| format!(" in {a} to {b}")).unwrap_or_default()
        ))
    };
    let value = match &field.kind {
        FieldKind::F32 { .. } => {
            let v: f32 = text.trim().parse().map_err(|_| bad("a number"))?;
            if !v.is_finite() {
                return Err(bad("a finite number"));
            }
            Value::Float(v)
        }
        FieldKind::U8
        | FieldKind::I8
        | FieldKind::U16 { .. }
        | FieldKind::I16 { .. }
        | FieldKind::U32 { .. }
        | FieldKind::I32 { .. } => Value::Int(parse_int(text).ok_or_else(|| bad("a whole number"))?),
        FieldKind::Ascii { .. } => Value::Text(text.to_owned()),
        FieldKind::Version => Value::Text(text.trim().to_owned()),
        FieldKind::Enum { variants, .. } => match variants.iter().find(|v| v.name == text.trim()) {
            Some(v) => Value::Enum { raw: v.value, name: Some(v.name.clone()) },
            None => Value::Int(parse_int(text).ok_or_else(|| {
                let names: Vec<&str> = variants.iter().map(|v| v.name.as_str()).collect();
                CliError::usage(format!("`{text}` is not a variant of `{name}`"))
                    .hint(format!("one of: {} (or a number)", names.join(", ")))
            })?),
        },
        FieldKind::Reserved { .. } => Value::Int(0),
        FieldKind::Bcd => {
            let v = parse_int(text).ok_or_else(|| bad("a whole number"))?;
            let digits = u8::try_from(v)
                .ok()
                .and_then(yosemitech_rtu::Bcd::from_value)
                .ok_or_else(|| bad("a number 0 to 99"))?;
            Value::Bcd(digits)
        }
        FieldKind::Flags { flags, .. } => {
            let mut raw = 0i64;
            for part in text.split(['|', ',', '+']).map(str::trim).filter(|p| !p.is_empty() && *p != "none") {
                match flags.iter().find(|f| f.name == part) {
                    Some(f) => raw |= i64::from(f.mask),
                    None => {
                        raw |= parse_int(part).ok_or_else(|| {
                            let names: Vec<&str> = flags.iter().map(|f| f.name.as_str()).collect();
                            CliError::usage(format!("`{part}` is not a flag of `{name}`"))
                                .hint(format!("flags joined by `|`: {} (or a number)", names.join(", ")))
                        })?
                    }
                }
            }
            Value::Int(raw)
        }
    };
    // Check a write's range here too, for a message that names the range.
    if let (Some((min, max)), Some(v)) = (range, value.number())
        && !(min..=max).contains(&v)
    {
        return Err(CliError::usage(format!("{name} = {text} is outside the valid range {min} to {max}"))
            .hint(format!("the spec allows `{name}` from {min} to {max}; nothing was sent")));
    }
    Ok(value)
}

/// A whole number, decimal or `0x` hex, possibly negative.
pub fn parse_int(text: &str) -> Option<i64> {
    let t = text.trim();
    let (negative, digits) = match t.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, t),
    };
    let v = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        Some(h) => i64::from_str_radix(h, 16).ok()?,
        None => digits.parse::<i64>().ok()?,
    };
    Some(if negative { -v } else { v })
}

/// A derived quantity's value as shown after its name: `9.1 mg/L  (derived)`
/// (`origin` says from what when not the reads, e.g. "from the means"), or
/// why it has none.
pub fn derived_text(d: &yosemitech_spec::beside::DerivedValue<'_>, origin: Option<&str>) -> String {
    match &d.value {
        Ok(v) => {
            let u = d.quantity.unit.as_deref().map(|u| format!(" {}", unit(u))).unwrap_or_default();
            let origin = origin.map(|o| format!(" {o}")).unwrap_or_default();
            format!("{v}{u}  (derived{origin})")
        }
        Err(why) => format!("not computable: {why}  (derived)"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_within_bounds() {
        assert_eq!(parse_size("1200x800"), Ok((1200, 800)));
        assert_eq!(parse_size(" 100X10000 "), Ok((100, 10_000)));
        for bad in ["", "1200", "x800", "1200x", "99x800", "1200x10001", "-1x5", "axb", "1200x800x3"] {
            assert!(parse_size(bad).is_err(), "{bad:?} was accepted");
        }
    }

    #[test]
    fn f32_json_round_trips_bit_exactly() {
        for v in [6.86f32, -6.72, 0.04, -1.04, 1.0, 0.0, 17.625, 1e-20, 3.4028235e38, f32::MIN_POSITIVE] {
            let j = f32_json(v);
            let text = serde_json::to_string(&j).unwrap();
            let back: Json = serde_json::from_str(&text).unwrap();
            assert_eq!(json_f32(&back).unwrap().to_bits(), v.to_bits(), "{v} as {text}");
        }
        assert_eq!(serde_json::to_string(&f32_json(6.86)).unwrap(), "6.86");
        assert!(json_f32(&f32_json(f32::NAN)).unwrap().is_nan());
    }

    #[test]
    fn parses_frames_as_people_type_them() {
        let want = vec![0x01, 0x03, 0x28, 0x00];
        for text in
            ["01 03 28 00", "01032800", "0x01 0x03 0x28 0x00", "01:03:28:00", "0x01,0x03,0x28,0x00", " 0103 2800 "]
        {
            assert_eq!(parse_frame(text).unwrap(), want, "{text}");
        }
        assert!(parse_frame("01 0").unwrap_err().message.contains("odd"));
        assert!(parse_frame("zz").is_err());
        assert!(parse_frame("").is_err());
    }

    #[test]
    fn parses_durations() {
        assert_eq!(parse_duration("100ms"), Ok(Duration::from_millis(100)));
        assert_eq!(parse_duration("3s"), Ok(Duration::from_secs(3)));
        assert_eq!(parse_duration("1.5s"), Ok(Duration::from_millis(1500)));
        assert_eq!(parse_duration("0"), Ok(Duration::ZERO));
        assert_eq!(parse_duration("2m"), Ok(Duration::from_secs(120)));
        assert!(parse_duration("fast").is_err());
        assert!(parse_duration("3 parsecs").is_err());
    }

    #[test]
    fn parses_ints() {
        assert_eq!(parse_int("20"), Some(20));
        assert_eq!(parse_int("0x14"), Some(20));
        assert_eq!(parse_int("-3"), Some(-3));
        assert_eq!(parse_int("x"), None);
    }
}

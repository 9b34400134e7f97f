//! Values for any command of any spec `validate` accepts, so that a test
//! that must send or serve a command never depends on what one manual
//! happens to print: the values of an example where one states them all,
//! otherwise each field's stated value, otherwise one its type and range
//! allow.

use std::collections::BTreeMap;

use yosemitech_rtu::{Bcd, Version};
use yosemitech_spec::{CommandSpec, Field, FieldKind, Value};

/// A value for every named field of `command` that its encoder takes: an
/// example's where one names every field, then, field by field, the value
/// some example states, then [`typical`].
pub fn sample_values(command: &CommandSpec) -> BTreeMap<String, Value> {
    let names: Vec<&str> = command.named_fields().map(Field::display_name).collect();
    if let Some(example) =
        command.examples.iter().find(|e| !names.is_empty() && names.iter().all(|n| e.values.contains_key(*n)))
    {
        return example.values.clone();
    }
    command
        .named_fields()
        .map(|field| {
            let name = field.display_name();
            let stated = command.examples.iter().find_map(|e| e.values.get(name)).cloned();
            (name.to_owned(), stated.unwrap_or_else(|| typical(field)))
        })
        .collect()
}

/// A value of `field`'s type inside its range (away from its `absent`
/// sentinel), for a field no example states.
pub fn typical(field: &Field) -> Value {
    varied(field, 0)
}

/// The `i`-th of several distinct values of `field`'s type inside its range
/// (a float or integer field; other types repeat [`typical`]'s kind of value).
pub fn varied(field: &Field, i: usize) -> Value {
    let step = (i % 7) as f64 + 1.0;
    let number = match field.range {
        // Inside the range, never on an end: an eighth of it per step.
        Some((min, max)) => min + (max - min) * step / 8.0,
        None => step,
    };
    let number = if field.absent == Some(number) { number + 0.5 } else { number };
    match &field.kind {
        FieldKind::F32 { .. } => Value::Float(number as f32),
        FieldKind::U8 | FieldKind::I8 | FieldKind::U16 { .. } | FieldKind::I16 { .. } => {
            Value::Int(number.round() as i64)
        }
        FieldKind::U32 { .. } | FieldKind::I32 { .. } => Value::Int(number.round() as i64),
        FieldKind::Bcd => Value::Bcd(Bcd::from_value((number.round() as u8).min(99)).unwrap_or(Bcd(0))),
        FieldKind::Ascii { len, .. } => Value::Text("T".repeat((*len).min(8))),
        FieldKind::Version => Value::Version(Version::new(1, (i % 10) as u8)),
        FieldKind::Enum { variants, .. } => {
            let v = &variants[i % variants.len()];
            Value::Enum { raw: v.value, name: Some(v.name.clone()) }
        }
        FieldKind::Flags { flags, .. } => Value::Int(i64::from(flags[i % flags.len()].mask)),
        FieldKind::Reserved { .. } => Value::Int(0),
    }
}

/// The `i`-th distinct float inside the range of the f32 `field`.
pub fn varied_float(field: &Field, i: usize) -> f32 {
    match varied(field, i) {
        Value::Float(f) => f,
        other => panic!("{}: not an f32 field ({other:?})", field.display_name()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every command of the spec encodes its sample values, request and reply.
    #[test]
    fn every_command_of_the_spec_encodes_its_sample_values() {
        let mut checked = 0;
        for sensor in &crate::spec().sensors {
            for command in &sensor.commands {
                let values = sample_values(command);
                let slave = command.fixed_slave.unwrap_or(sensor.default_address);
                if command.is_read() {
                    let reply = command.encode_response(slave, &values);
                    assert!(reply.is_ok(), "{}.{}: {reply:?}", sensor.name, command.name);
                    let frame = reply.unwrap_or_default();
                    let decoded = command.decode_response(slave, &frame);
                    assert!(decoded.is_ok(), "{}.{}: {decoded:?}", sensor.name, command.name);
                } else {
                    let request = command.encode_request(slave, &values);
                    assert!(request.is_ok(), "{}.{}: {request:?}", sensor.name, command.name);
                }
                checked += 1;
            }
        }
        assert!(checked > 0, "the spec has commands");
        crate::report!("sample values: {checked} commands encoded");
    }
}

//! The reference interpreter: every printed example replays, and every
//! command's values survive encode -> decode.

use std::collections::BTreeMap;
use std::sync::OnceLock;

use proptest::prelude::*;
use yosemitech_spec::{CommandSpec, FieldKind, Spec, Value};

use yosemitech_tests::spec;

fn commands(spec: &Spec) -> Vec<CommandSpec> {
    spec.sensors.iter().flat_map(|s| s.commands.iter().cloned()).collect()
}

#[test]
fn examples_replay_through_the_interpreter() {
    let spec = spec();
    let mut replayed = 0;
    let mut complete = 0;
    for cmd in commands(spec) {
        for ex in &cmd.examples {
            let Some((true_request, true_response)) = ex.true_pair() else { continue };
            complete += 1;
            let slave = ex.slave();
            let request_values = if cmd.is_read() { BTreeMap::new() } else { ex.values.clone() };
            assert_eq!(cmd.encode_request(slave, &request_values).expect("encodes"), true_request, "{}", cmd.name);
            let (decoded_slave, written) = cmd.decode_request(true_request).expect("request decodes");
            assert_eq!(decoded_slave, slave);
            let decoded = cmd.decode_response(slave, true_response).expect("reply decodes");
            let values = if cmd.is_read() { decoded } else { written };
            for (name, value) in &values {
                assert!(value.same_as(&ex.values[name]), "{}.{name}: {value} vs {}", cmd.name, ex.values[name]);
            }
            let map: BTreeMap<String, Value> =
                if cmd.is_read() { values.into_iter().collect() } else { BTreeMap::new() };
            if !cmd.trigger {
                assert_eq!(cmd.encode_response(slave, &map).expect("encodes"), true_response, "{}", cmd.name);
            }
            replayed += 1;
        }
    }
    assert_eq!(replayed, complete);
    assert!(replayed > 0);
}

#[test]
fn printed_frames_behave_as_the_errata_say() {
    let spec = spec();
    let mut checked = 0;
    for cmd in commands(spec) {
        for ex in &cmd.examples {
            let Some(err) = &ex.erratum else { continue };
            let printed = if err.corrected_response.is_some() { &ex.response } else { &ex.request };
            let Some(frame) = printed.as_ref().and_then(|f| f.complete.as_deref()) else { continue };
            let decodes = if err.corrected_response.is_some() {
                cmd.decode_response(ex.slave(), frame).is_ok()
            } else {
                cmd.decode_request(frame).is_ok()
            };
            assert_eq!(decodes, err.printed_decodes, "{} erratum {}", cmd.name, err.id);
            checked += 1;
        }
    }
    println!("{checked} printed frames with errata behave as their errata say");
}

#[test]
fn decoding_never_panics_on_garbage() {
    let spec = spec();
    for cmd in commands(spec) {
        for len in 0..40 {
            let frame: Vec<u8> = (0..len).map(|i| (i * 37 + 11) as u8).collect();
            let _ = cmd.decode_response(1, &frame);
            let _ = cmd.decode_request(&frame);
        }
    }
}

/// A value of the field's type, from random bits.
fn value_for(kind: &FieldKind, bits: u64) -> Option<Value> {
    Some(match kind {
        FieldKind::F32 { .. } => Value::Float(f32::from_bits(bits as u32)),
        FieldKind::U8 => Value::Int((bits & 0xFF) as i64),
        FieldKind::I8 => Value::Int(i64::from(bits as u8 as i8)),
        FieldKind::U16 { .. } => Value::Int((bits & 0xFFFF) as i64),
        FieldKind::I16 { .. } => Value::Int(i64::from(bits as u16 as i16)),
        FieldKind::U32 { .. } => Value::Int((bits & 0xFFFF_FFFF) as i64),
        FieldKind::I32 { .. } => Value::Int(i64::from(bits as u32 as i32)),
        FieldKind::Ascii { len, padding } => {
            let n = (bits as usize) % (len + 1);
            let text: String = (0..n).map(|i| char::from(b'A' + ((bits >> (i % 8)) as u8 % 26))).collect();
            // Trailing padding is stripped on decode, so the text must not end in it.
            if text.ends_with(char::from(*padding)) {
                return None;
            }
            Value::Text(text)
        }
        FieldKind::Version => Value::Version(yosemitech_rtu::Version::new(bits as u8, (bits >> 8) as u8)),
        FieldKind::Enum { variants, .. } => {
            let v = &variants[(bits as usize) % variants.len()];
            Value::Enum { raw: v.value, name: Some(v.name.clone()) }
        }
        FieldKind::Reserved { .. } => return None,
        FieldKind::Bcd => Value::Bcd(yosemitech_rtu::Bcd::from_value((bits % 100) as u8)?),
        FieldKind::Flags { flags, .. } => {
            Value::Int(flags.iter().filter(|f| bits & u64::from(f.mask) != 0).map(|f| i64::from(f.mask)).sum())
        }
    })
}

proptest! {
    #[test]
    fn values_survive_encode_and_decode(seeds in proptest::collection::vec(any::<u64>(), 12)) {
        static COMMANDS: OnceLock<Vec<CommandSpec>> = OnceLock::new();
        for cmd in COMMANDS.get_or_init(|| commands(spec())) {
            let mut values = BTreeMap::new();
            let mut ok = true;
            for (i, field) in cmd.named_fields().enumerate() {
                match value_for(&field.kind, seeds[i % seeds.len()].rotate_left(i as u32)) {
                    // Writes check `range`; skip values a write may not send.
                    Some(v) => {
                        if let (Some((min, max)), Value::Float(f)) = (field.range, &v)
                            && !(f64::from(*f) >= min && f64::from(*f) <= max)
                        {
                            ok = false;
                        }
                        if let (Some((min, max)), Value::Int(n)) = (field.range, &v)
                            && !((*n as f64) >= min && (*n as f64) <= max)
                        {
                            ok = false;
                        }
                        if let (Some((min, max)), Value::Bcd(b)) = (field.range, &v)
                            && !b.value().is_some_and(|n| f64::from(n) >= min && f64::from(n) <= max)
                        {
                            ok = false;
                        }
                        values.insert(field.name.clone().expect("named"), v);
                    }
                    None => ok = false,
                }
            }
            if !ok {
                continue;
            }
            let decoded = if cmd.is_read() {
                let frame = cmd.encode_response(7, &values).expect("encodes");
                cmd.decode_response(7, &frame).expect("decodes")
            } else {
                let frame = cmd.encode_request(7, &values).expect("encodes");
                let (slave, decoded) = cmd.decode_request(&frame).expect("decodes");
                prop_assert_eq!(slave, 7);
                decoded
            };
            prop_assert_eq!(decoded.len(), values.len());
            for (name, got) in decoded {
                prop_assert!(got.same_as(&values[&name]), "{}.{}: {} vs {}", cmd.name, name, got, values[&name]);
            }
        }
    }
}

//! Fields: their types and byte orders, enums and their variants, flags and
//! their masks, and the field examples the manual prints.
//!
//! Fields follow each other without gaps or overlaps and together fill the
//! command's registers exactly; a key that does not apply to a field's type
//! is refused rather than ignored. Names, variant codes and flag masks are
//! unique within their field (variants also as Rust names), codes fit the
//! enum's size, and every field example decodes to the value it states and
//! encodes back to its bytes.

use std::collections::{BTreeMap, BTreeSet};

use crate::Spanned;
use yosemitech_rtu::{ByteOrder2, ByteOrder4, Hex};

use crate::check::{check_name, check_text, parse_hex, resolve_figures, stated_value};
use crate::diag::{Pos, Reporter};
use crate::document::{ByteOrderDoc, CommandDoc, FieldDoc, FieldTypeDoc, PaddingDoc};
use crate::model::{EnumRepr, Field, FieldExample, FieldKind, Flag, Variant};
use crate::names::{camel, check_snake};

/// The key of a field entry: `<command>.fields[0] (ph)`.
fn field_key(command: &str, j: usize, f: &FieldDoc) -> String {
    match &f.name {
        Some(n) if check_snake(&n.value).is_none() => format!("{command}.fields[{j}] ({})", n.value),
        _ => format!("{command}.fields[{j}]"),
    }
}

fn order2(o: Option<&Spanned<ByteOrderDoc>>, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<ByteOrder2> {
    match o.map(|o| (o.value, Pos::at(o))) {
        Some((order, pos)) => order.two().or_else(|| {
            r.error(
                pos,
                key,
                format!("`{}` is a 4-byte order but the value has 2 bytes", order.name()),
                Some("use `ab` (big-endian) or `ba`".into()),
            );
            None
        }),
        None => {
            r.error(at, key, "missing `byte_order` for a 2-byte value", Some("use `ab` (big-endian) or `ba`".into()));
            None
        }
    }
}

fn order4(o: Option<&Spanned<ByteOrderDoc>>, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<ByteOrder4> {
    let help = "use `abcd` (big-endian), `dcba` (little-endian image), `cdab` or `badc`";
    match o.map(|o| (o.value, Pos::at(o))) {
        Some((order, pos)) => order.four().or_else(|| {
            r.error(
                pos,
                key,
                format!("`{}` is a 2-byte order but the value has 4 bytes", order.name()),
                Some(help.into()),
            );
            None
        }),
        None => {
            r.error(at, key, "missing `byte_order` for a 4-byte value", Some(help.into()));
            None
        }
    }
}

pub(super) fn resolve_fields(
    c: &CommandDoc,
    key: &str,
    count: Option<u16>,
    trigger: bool,
    at: Pos,
    r: &mut Reporter<'_>,
) -> Option<Vec<Field>> {
    let docs: &[FieldDoc] = c.fields.as_ref().map(|f| f.value.as_slice()).unwrap_or(&[]);
    if trigger {
        if let Some(f) = &c.fields
            && !f.value.is_empty()
        {
            r.error(
                Pos::at(f),
                format!("{key}.fields"),
                "a trigger carries no fields",
                Some("remove `fields`, or remove `trigger` and describe the data".into()),
            );
            return None;
        }
        return Some(Vec::new());
    }
    if docs.is_empty() {
        if c.count.as_ref().is_some_and(|n| n.value == 0) {
            return None; // `count: 0` without `trigger` is reported; no fields follows from it.
        }
        let pos = c.fields.as_ref().map(Pos::at).unwrap_or(at);
        r.error(
            pos,
            format!("{key}.fields"),
            "the command has no fields",
            Some("describe the register data, using `reserved` for unused bytes".into()),
        );
        return None;
    }
    let mut ok = true;
    let mut fields = Vec::new();
    let mut names: BTreeMap<String, Pos> = BTreeMap::new();
    let mut offset = 0usize;
    for (j, f) in docs.iter().enumerate() {
        let fk = field_key(key, j, f);
        let fat = Pos::at(&f.ty);
        match resolve_field(f, &fk, fat, offset, r) {
            Some(field) => {
                let pos = f.name.as_ref().map(Pos::at).unwrap_or(fat);
                if let Some(n) = &field.name
                    && let Some(first) = names.insert(n.clone(), pos)
                {
                    r.error(
                        pos,
                        format!("{fk}.name"),
                        format!("two fields of this command are called `{n}`"),
                        Some(format!(
                            "the first is at line {}, column {}; rename one of them",
                            first.line, first.column
                        )),
                    );
                    ok = false;
                }
                offset = field.offset + field.size();
                fields.push(field);
            }
            None => ok = false,
        }
    }
    if ok && let Some(count) = count {
        let want = 2 * usize::from(count);
        let pos = c.count.as_ref().map(Pos::at).unwrap_or(at);
        if offset < want {
            r.error(
                pos,
                format!("{key}.fields"),
                format!("the fields cover {offset} bytes but {count} registers hold {want}"),
                Some(format!("add a `reserved` field of {} bytes or fix `count`", want - offset)),
            );
            ok = false;
        } else if offset > want {
            r.error(
                pos,
                format!("{key}.fields"),
                format!("the fields need {offset} bytes but {count} registers hold only {want}"),
                Some(format!("`count` should be {}", offset.div_ceil(2))),
            );
            ok = false;
        }
    }
    ok.then_some(fields)
}

fn forbid<T>(v: &Option<Spanned<T>>, what: &str, ty: &str, key: &str, r: &mut Reporter<'_>) -> bool {
    match v {
        Some(v) => {
            r.error(
                Pos::at(v),
                format!("{key}.{what}"),
                format!("`{what}` does not apply to a `{ty}` field"),
                Some(format!("remove `{what}`")),
            );
            false
        }
        None => true,
    }
}

fn resolve_field(f: &FieldDoc, key: &str, at: Pos, offset: usize, r: &mut Reporter<'_>) -> Option<Field> {
    let ty = f.ty.value;
    let ty_name = type_name(ty);
    let mut ok = true;
    let name = match (&f.name, ty) {
        (Some(n), _) => {
            ok &= check_name(n, &format!("{key}.name"), r);
            Some(n.value.clone())
        }
        (None, FieldTypeDoc::Reserved) => None,
        (None, _) => {
            r.error(
                at,
                format!("{key}.name"),
                format!("a `{ty_name}` field needs a `name`"),
                Some("add `name:`, or use `type: reserved` for bytes without meaning".into()),
            );
            ok = false;
            None
        }
    };
    let size = f.size.as_ref().map(|s| (s.value, Pos::at(s)));
    let needs_size = |r: &mut Reporter<'_>| -> Option<usize> {
        match size {
            Some((s, pos)) if s == 0 || s > 250 => {
                r.error(
                    pos,
                    format!("{key}.size"),
                    format!("size {s} is not between 1 and 250 bytes"),
                    Some("a field fits in one frame: at most 250 bytes (125 registers)".into()),
                );
                None
            }
            Some((s, _)) => Some(s as usize),
            None => {
                r.error(
                    at,
                    format!("{key}.size"),
                    format!("a `{ty_name}` field needs a `size` in bytes"),
                    Some("add `size:`".into()),
                );
                None
            }
        }
    };
    let kind = match ty {
        FieldTypeDoc::F32 => {
            order4(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::F32 { order })
        }
        FieldTypeDoc::U32 => {
            order4(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::U32 { order })
        }
        FieldTypeDoc::I32 => {
            order4(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::I32 { order })
        }
        FieldTypeDoc::U16 => {
            order2(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::U16 { order })
        }
        FieldTypeDoc::I16 => {
            order2(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::I16 { order })
        }
        FieldTypeDoc::U8 => Some(FieldKind::U8),
        FieldTypeDoc::I8 => Some(FieldKind::I8),
        FieldTypeDoc::Version => Some(FieldKind::Version),
        FieldTypeDoc::Ascii => {
            let padding = match f.padding.as_ref().map(|p| p.value) {
                None | Some(PaddingDoc::Nul) => 0u8,
                Some(PaddingDoc::Space) => b' ',
            };
            needs_size(r).map(|len| FieldKind::Ascii { len, padding })
        }
        FieldTypeDoc::Reserved => {
            let fill = match &f.fill {
                Some(v) if v.value > 255 => {
                    r.error(
                        Pos::at(v),
                        format!("{key}.fill"),
                        format!("fill {} does not fit in a byte", v.value),
                        None,
                    );
                    None
                }
                Some(v) => Some(v.value as u8),
                None => Some(0),
            };
            match (needs_size(r), fill) {
                (Some(len), Some(fill)) => Some(FieldKind::Reserved { len, fill }),
                _ => None,
            }
        }
        FieldTypeDoc::Enum => resolve_enum(f, key, at, r),
        FieldTypeDoc::Bcd => Some(FieldKind::Bcd),
        FieldTypeDoc::Flags => resolve_flags(f, key, at, r),
    };
    // Keys that do not apply to this type.
    let multi_byte =
        matches!(ty, FieldTypeDoc::F32 | FieldTypeDoc::U16 | FieldTypeDoc::I16 | FieldTypeDoc::U32 | FieldTypeDoc::I32)
            || (matches!(ty, FieldTypeDoc::Enum | FieldTypeDoc::Flags) && size.is_some_and(|(s, _)| s == 2));
    if !multi_byte {
        ok &= forbid(&f.byte_order, "byte_order", ty_name, key, r);
    }
    if !matches!(ty, FieldTypeDoc::Ascii | FieldTypeDoc::Reserved | FieldTypeDoc::Enum | FieldTypeDoc::Flags) {
        ok &= forbid(&f.size, "size", ty_name, key, r);
    }
    if ty != FieldTypeDoc::Ascii {
        ok &= forbid(&f.padding, "padding", ty_name, key, r);
    }
    if ty != FieldTypeDoc::Reserved {
        ok &= forbid(&f.fill, "fill", ty_name, key, r);
    }
    if ty != FieldTypeDoc::Enum {
        ok &= forbid(&f.variants, "variants", ty_name, key, r);
    }
    if ty != FieldTypeDoc::Flags {
        ok &= forbid(&f.flags, "flags", ty_name, key, r);
    }
    let numeric = matches!(
        ty,
        FieldTypeDoc::F32
            | FieldTypeDoc::U8
            | FieldTypeDoc::I8
            | FieldTypeDoc::U16
            | FieldTypeDoc::I16
            | FieldTypeDoc::U32
            | FieldTypeDoc::I32
            | FieldTypeDoc::Bcd
    );
    if !numeric {
        ok &= forbid(&f.absent, "absent", ty_name, key, r);
    }
    let absent = match &f.absent {
        Some(a) if !a.value.is_finite() => {
            r.error(Pos::at(a), format!("{key}.absent"), format!("{} is not a finite number", a.value), None);
            ok = false;
            None
        }
        Some(a) => Some(a.value),
        None => None,
    };
    let range = match &f.range {
        Some(rg) if !numeric => {
            r.error(
                Pos::at(rg),
                format!("{key}.range"),
                format!("`range` does not apply to a `{ty_name}` field"),
                None,
            );
            ok = false;
            None
        }
        Some(rg) if !(rg.value.min.is_finite() && rg.value.max.is_finite() && rg.value.min <= rg.value.max) => {
            r.error(
                Pos::at(rg),
                format!("{key}.range"),
                format!("range {}..={} is empty or not finite", rg.value.min, rg.value.max),
                None,
            );
            ok = false;
            None
        }
        Some(rg) => Some((rg.value.min, rg.value.max)),
        None => None,
    };
    let typical = match &f.typical {
        Some(t) if !numeric => {
            r.error(
                Pos::at(t),
                format!("{key}.typical"),
                format!("`typical` does not apply to a `{ty_name}` field"),
                None,
            );
            ok = false;
            None
        }
        Some(t) if !t.value.is_finite() || range.is_some_and(|(min, max)| t.value < min || t.value > max) => {
            r.error(
                Pos::at(t),
                format!("{key}.typical"),
                format!("typical value {} is not a finite number within the field's range", t.value),
                range.map(|(min, max)| format!("use a value in {min}..={max}")),
            );
            ok = false;
            None
        }
        Some(t) => Some(t.value),
        None => None,
    };
    let unit = f.unit.as_ref().map(|u| check_text(u, &format!("{key}.unit"), r));
    let doc = f.doc.as_ref().map(|d| check_text(d, &format!("{key}.doc"), r));
    let kind = kind?;
    if let Some(o) = &f.offset {
        let want = o.value as usize;
        if want < offset {
            r.error(
                Pos::at(o),
                format!("{key}.offset"),
                format!("field starts at byte {want} but the previous field ends at byte {offset}: they overlap"),
                Some(format!("use `offset: {offset}` or remove `offset`")),
            );
            ok = false;
        } else if want > offset {
            r.error(
                Pos::at(o),
                format!("{key}.offset"),
                format!("bytes {offset}..{want} are not covered by any field"),
                Some(format!("add a `reserved` field of {} bytes before this one", want - offset)),
            );
            ok = false;
        }
    }
    if ty == FieldTypeDoc::Bcd
        && let Some((min, max)) = range
        && (min < 0.0 || max > 99.0)
    {
        let pos = f.range.as_ref().map(Pos::at).unwrap_or(at);
        r.error(pos, format!("{key}.range"), format!("a `bcd` byte holds 0..=99, not {min}..={max}"), None);
        ok = false;
    }
    let mut field = Field { name, kind, offset, unit, doc, range, typical, absent, examples: Vec::new() };
    for (j, e) in f.examples.iter().enumerate() {
        let ek = format!("{key}.examples[{j}]");
        let figures = resolve_figures(&e.figures, &format!("{ek}.figures"), Pos::at(&e.bytes), r);
        let bytes = match parse_hex(&e.bytes.value) {
            Ok(b) => b,
            Err(why) => {
                r.error(Pos::at(&e.bytes), format!("{ek}.bytes"), format!("invalid hex: {why}"), None);
                ok = false;
                continue;
            }
        };
        if bytes.len() != field.size() {
            r.error(
                Pos::at(&e.bytes),
                format!("{ek}.bytes"),
                format!("{} bytes, but the field takes {}", bytes.len(), field.size()),
                None,
            );
            ok = false;
            continue;
        }
        let value = match stated_value(&field, &e.value.value) {
            Ok(v) => v,
            Err(why) => {
                r.error(Pos::at(&e.value), format!("{ek}.value"), why, None);
                ok = false;
                continue;
            }
        };
        let decoded = crate::interp::decode_field(&field, &bytes);
        if !decoded.same_as(&value) {
            r.error(
                Pos::at(&e.value),
                format!("{ek}.value"),
                format!("the bytes decode to {decoded}, but the example states {value}"),
                Some("check the value against the bytes the manual prints".into()),
            );
            ok = false;
            continue;
        }
        match crate::interp::encode_field(&field, &value) {
            Ok(again) if again == bytes => {}
            Ok(again) => {
                r.error(
                    Pos::at(&e.bytes),
                    format!("{ek}.bytes"),
                    format!("the value encodes as {}", Hex(&again)),
                    Some("the value and the bytes must match both ways".into()),
                );
                ok = false;
                continue;
            }
            Err(err) => {
                r.error(Pos::at(&e.value), format!("{ek}.value"), format!("the value does not encode: {err}"), None);
                ok = false;
                continue;
            }
        }
        field.examples.push(FieldExample { bytes, value, figures });
    }
    ok.then_some(field)
}

/// The size (and order) of an enum or flags code: 1 byte, or 2 with a `byte_order`.
fn code_repr(f: &FieldDoc, what: &str, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<EnumRepr> {
    match f.size.as_ref().map(|s| (s.value, Pos::at(s))) {
        None | Some((1, _)) => Some(EnumRepr::U8),
        Some((2, _)) => order2(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(EnumRepr::U16),
        Some((s, pos)) => {
            r.error(
                pos,
                format!("{key}.size"),
                format!("{what} is 1 or 2 bytes, not {s}"),
                Some("use `size: 1`, or `size: 2` with a `byte_order`".into()),
            );
            None
        }
    }
}

fn resolve_flags(f: &FieldDoc, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<FieldKind> {
    let repr = code_repr(f, "a flags field", key, at, r);
    let Some(flags) = &f.flags else {
        r.error(
            at,
            format!("{key}.flags"),
            "a `flags` field needs `flags`",
            Some("list `- {name: ..., mask: 0x01}` entries".into()),
        );
        return None;
    };
    if flags.value.is_empty() {
        r.error(Pos::at(flags), format!("{key}.flags"), "a `flags` field needs at least one flag", None);
        return None;
    }
    let max: u32 = if repr == Some(EnumRepr::U8) { 0xFF } else { 0xFFFF };
    let mut ok = true;
    let mut seen_names = BTreeSet::new();
    let mut seen_masks = BTreeSet::new();
    let mut out = Vec::new();
    for (j, fl) in flags.value.iter().enumerate() {
        let fk = format!("{key}.flags[{j}]");
        ok &= check_name(&fl.name, &format!("{fk}.name"), r);
        if !seen_names.insert(fl.name.value.clone()) {
            r.error(Pos::at(&fl.name), format!("{fk}.name"), format!("two flags are called `{}`", fl.name.value), None);
            ok = false;
        }
        let m = fl.mask.value;
        if m == 0 || m > max || !m.is_power_of_two() {
            r.error(
                Pos::at(&fl.mask),
                format!("{fk}.mask"),
                format!("mask 0x{m:X} is not one bit of the field"),
                Some(format!("a flag is one bit: 0x01, 0x02, 0x04 ... up to 0x{:X}", max.div_ceil(2))),
            );
            ok = false;
        } else if !seen_masks.insert(m) {
            r.error(Pos::at(&fl.mask), format!("{fk}.mask"), format!("mask 0x{m:X} is used twice"), None);
            ok = false;
        }
        let doc = fl.doc.as_ref().map(|d| check_text(d, &format!("{fk}.doc"), r));
        out.push(Flag { name: fl.name.value.clone(), mask: m as u16, doc });
    }
    let repr = repr?;
    ok.then_some(FieldKind::Flags { repr, flags: out })
}

fn type_name(ty: FieldTypeDoc) -> &'static str {
    match ty {
        FieldTypeDoc::F32 => "f32",
        FieldTypeDoc::U8 => "u8",
        FieldTypeDoc::I8 => "i8",
        FieldTypeDoc::U16 => "u16",
        FieldTypeDoc::I16 => "i16",
        FieldTypeDoc::U32 => "u32",
        FieldTypeDoc::I32 => "i32",
        FieldTypeDoc::Ascii => "ascii",
        FieldTypeDoc::Version => "version",
        FieldTypeDoc::Enum => "enum",
        FieldTypeDoc::Reserved => "reserved",
        FieldTypeDoc::Bcd => "bcd",
        FieldTypeDoc::Flags => "flags",
    }
}

fn resolve_enum(f: &FieldDoc, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<FieldKind> {
    let repr = code_repr(f, "an enum code", key, at, r);
    let Some(variants) = &f.variants else {
        r.error(
            at,
            format!("{key}.variants"),
            "an `enum` field needs `variants`",
            Some("list `- {name: ..., value: ...}` entries".into()),
        );
        return None;
    };
    if variants.value.is_empty() {
        r.error(
            Pos::at(variants),
            format!("{key}.variants"),
            "an `enum` needs at least one variant",
            Some("list `- {name: ..., value: ...}` entries".into()),
        );
        return None;
    }
    let max = if repr == Some(EnumRepr::U8) { 0xFF } else { 0xFFFF };
    let mut ok = true;
    let mut names: BTreeMap<String, Pos> = BTreeMap::new();
    let mut types: BTreeMap<String, String> = BTreeMap::new();
    let mut values = BTreeMap::new();
    let mut out = Vec::new();
    for (j, v) in variants.value.iter().enumerate() {
        let vk = match check_snake(&v.name.value) {
            None => format!("{key}.variants[{j}] ({})", v.name.value),
            Some(_) => format!("{key}.variants[{j}]"),
        };
        let name_ok = check_name(&v.name, &format!("{vk}.name"), r);
        ok &= name_ok;
        if let Some(first) = names.insert(v.name.value.clone(), Pos::at(&v.name)) {
            r.error(
                Pos::at(&v.name),
                format!("{vk}.name"),
                format!("two variants are called `{}`", v.name.value),
                Some(format!("the first is at line {}, column {}; rename one of them", first.line, first.column)),
            );
            ok = false;
        } else if name_ok {
            let ty = camel(&v.name.value);
            if let Some(other) = types.insert(ty.clone(), v.name.value.clone()) {
                r.error(
                    Pos::at(&v.name),
                    format!("{vk}.name"),
                    format!("variants `{other}` and `{}` both become the Rust variant `{ty}`", v.name.value),
                    Some("rename one of them".into()),
                );
                ok = false;
            }
        }
        if v.value.value > max {
            let (bytes, help) = if max == 0xFF {
                (1, "a 1-byte enum takes codes 0..=255; for larger codes use `size: 2` with a `byte_order`")
            } else {
                (2, "a 2-byte enum takes codes 0..=65535")
            };
            r.error(
                Pos::at(&v.value),
                format!("{vk}.value"),
                format!("code {} does not fit the enum's {bytes}-byte size", v.value.value),
                Some(help.into()),
            );
            ok = false;
        } else if let Some(other) = values.insert(v.value.value, v.name.value.clone()) {
            r.error(
                Pos::at(&v.value),
                format!("{vk}.value"),
                format!("code {} is used by `{other}` and `{}`", v.value.value, v.name.value),
                Some("enum codes must be unique; each code names one variant".into()),
            );
            ok = false;
        }
        let doc = v.doc.as_ref().map(|d| check_text(d, &format!("{vk}.doc"), r));
        out.push(Variant { name: v.name.value.clone(), value: v.value.value as u16, doc });
    }
    let repr = repr?;
    ok.then_some(FieldKind::Enum { repr, variants: out })
}

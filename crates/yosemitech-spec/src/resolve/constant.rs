//! Constants: the numbers a manual gives outside any register (calibration
//! defaults, limits), single values or lists.
//!
//! A constant is kept only when its name is valid and unique (also as the
//! Rust constant it becomes), it has exactly one of `value` and `values`
//! (a list of 1 to 64), and every value fits its type: finite for `f32`,
//! whole and in range for the unsigned types.

use std::collections::BTreeMap;

use crate::check::{check_name, check_text};
use crate::diag::{Pos, Reporter};
use crate::document::{ConstantDoc, ConstantTypeDoc};
use crate::model::{Constant, ConstantType};
use crate::names::{check_constant_name, check_snake, shouty};

use super::sensor::resolve_source;

pub(super) fn resolve_constants(docs: &[ConstantDoc], r: &mut Reporter<'_>) -> Vec<Constant> {
    let mut out = Vec::new();
    let mut names: BTreeMap<String, Pos> = BTreeMap::new();
    let mut consts: BTreeMap<String, String> = BTreeMap::new();
    for (i, c) in docs.iter().enumerate() {
        let key = match check_snake(&c.name.value) {
            None => format!("constants[{i}] ({})", c.name.value),
            Some(_) => format!("constants[{i}]"),
        };
        let mut name_ok = check_name(&c.name, &format!("{key}.name"), r);
        if name_ok && let Some(why) = check_constant_name(&c.name.value) {
            r.error(Pos::at(&c.name), format!("{key}.name"), why, Some("rename the constant".into()));
            name_ok = false;
        }
        let mut ok = name_ok;
        if let Some(first) = names.insert(c.name.value.clone(), Pos::at(&c.name)) {
            r.error(
                Pos::at(&c.name),
                format!("{key}.name"),
                format!("two constants are called `{}`", c.name.value),
                Some(format!("the first is at line {}, column {}; rename one of them", first.line, first.column)),
            );
            ok = false;
        } else if name_ok {
            let upper = shouty(&c.name.value);
            if let Some(other) = consts.insert(upper.clone(), c.name.value.clone()) {
                r.error(
                    Pos::at(&c.name),
                    format!("{key}.name"),
                    format!("constants `{other}` and `{}` both become the Rust constant `{upper}`", c.name.value),
                    Some("rename one of them".into()),
                );
                ok = false;
            }
        }
        let doc = check_text(&c.doc, &format!("{key}.doc"), r);
        let unit = c.unit.as_ref().map(|u| check_text(u, &format!("{key}.unit"), r));
        let source = c.source.as_ref().map(|s| resolve_source(s, &format!("{key}.source"), r));
        let (values, is_list, pos) = match (&c.value, &c.values) {
            (Some(v), None) => (vec![v.value], false, Pos::at(v)),
            (None, Some(vs)) if !vs.value.is_empty() && vs.value.len() <= 64 => (vs.value.clone(), true, Pos::at(vs)),
            (None, Some(vs)) => {
                r.error(
                    Pos::at(vs),
                    format!("{key}.values"),
                    "a list constant holds 1 to 64 values",
                    Some("use `value:` for a single number".into()),
                );
                continue;
            }
            _ => {
                r.error(
                    Pos::at(&c.name),
                    &key,
                    "a constant has exactly one of `value` and `values`",
                    Some("use `value: 1.0` for a number or `values: [1.0, 2.0]` for a list".into()),
                );
                continue;
            }
        };
        let ty = match c.ty.value {
            ConstantTypeDoc::F32 => ConstantType::F32,
            ConstantTypeDoc::U8 => ConstantType::U8,
            ConstantTypeDoc::U16 => ConstantType::U16,
            ConstantTypeDoc::U32 => ConstantType::U32,
        };
        let max = match ty {
            ConstantType::F32 => f64::from(f32::MAX),
            ConstantType::U8 => 255.0,
            ConstantType::U16 => 65535.0,
            ConstantType::U32 => 4294967295.0,
        };
        for v in &values {
            let integral = ty == ConstantType::F32 || (v.fract() == 0.0 && *v >= 0.0);
            if !v.is_finite() || !integral || v.abs() > max {
                r.error(
                    pos,
                    format!("{key}.value"),
                    format!("{v} is not a valid `{}`", type_name_const(ty)),
                    Some(format!(
                        "a `{}` holds {}",
                        type_name_const(ty),
                        match ty {
                            ConstantType::F32 => "finite numbers that fit an f32",
                            ConstantType::U8 => "whole numbers 0..=255",
                            ConstantType::U16 => "whole numbers 0..=65535",
                            ConstantType::U32 => "whole numbers 0..=4294967295",
                        }
                    )),
                );
                ok = false;
            }
        }
        if ok {
            out.push(Constant { name: c.name.value.clone(), ty, values, is_list, unit, doc, source });
        }
    }
    out
}

fn type_name_const(t: ConstantType) -> &'static str {
    match t {
        ConstantType::F32 => "f32",
        ConstantType::U8 => "u8",
        ConstantType::U16 => "u16",
        ConstantType::U32 => "u32",
    }
}

//! Derived quantities: formulas over fields of the sensor's reads, its
//! constants and station inputs.
//!
//! A quantity is kept only when its name is valid and unique (and not a
//! function the generated module declares), its inputs are unique names
//! each with exactly one of `field` (a number field of a read) and
//! `station`, its formula parses, names only its inputs and the sensor's
//! scalar constants, and its units agree where declared; every example
//! must then hold within its tolerance. Formula errors point at the
//! offending token inside the YAML scalar.

use std::collections::BTreeMap;

use crate::Spanned;

use crate::check::{check_name, check_text};
use crate::diag::{Pos, Reporter};
use crate::document::{DerivedDoc, DerivedInputDoc};
use crate::expr::{self, Binding, Name, Unit};
use crate::model::{CommandSpec, Constant, ConstantType, Derived, DerivedExample, DerivedInput, InputSource};
use crate::names::{check_derived_name, check_input_name, check_snake, escape};
use crate::suggest::closest;

use super::sensor::resolve_source;

pub(super) fn resolve_derived(
    docs: &[DerivedDoc],
    commands: &[CommandSpec],
    constants: &[Constant],
    r: &mut Reporter<'_>,
) -> Vec<Derived> {
    let mut out = Vec::new();
    let mut names: BTreeMap<String, Pos> = BTreeMap::new();
    for (i, d) in docs.iter().enumerate() {
        let key = match check_snake(&d.name.value) {
            None => format!("derived[{i}] ({})", d.name.value),
            Some(_) => format!("derived[{i}]"),
        };
        let mut ok = check_name(&d.name, &format!("{key}.name"), r);
        if ok && let Some(why) = check_derived_name(&d.name.value) {
            r.error(Pos::at(&d.name), format!("{key}.name"), why, Some("rename the quantity".into()));
            ok = false;
        }
        if let Some(first) = names.insert(d.name.value.clone(), Pos::at(&d.name)) {
            r.error(
                Pos::at(&d.name),
                format!("{key}.name"),
                format!("two derived quantities are called `{}`", d.name.value),
                Some(format!("the first is at line {}, column {}; rename one of them", first.line, first.column)),
            );
            ok = false;
        }
        let title = check_text(&d.title, &format!("{key}.title"), r);
        let doc = check_text(&d.doc, &format!("{key}.doc"), r);
        let source = d.source.as_ref().map(|s| resolve_source(s, &format!("{key}.source"), r));
        let unit_text = d.unit.as_ref().map(|u| check_text(u, &format!("{key}.unit"), r));
        let unit = match (&d.unit, &unit_text) {
            (Some(at), Some(text)) => match Unit::parse(text) {
                Ok(u) => Some(u),
                Err(why) => {
                    r.error(Pos::at(at), format!("{key}.unit"), format!("not a unit: {why}"), Some(UNIT_HELP.into()));
                    ok = false;
                    None
                }
            },
            _ => None,
        };

        let mut inputs = Vec::new();
        let mut scope = Vec::new();
        for (k, input) in d.inputs.value.iter().enumerate() {
            let ikey = format!("{key}.inputs[{k}]");
            match resolve_input(input, &ikey, commands, constants, &inputs, r) {
                Some((resolved, unit)) => {
                    scope.push(Name { name: resolved.name.clone(), binding: Binding::Input(k), unit });
                    inputs.push(resolved);
                }
                None => ok = false,
            }
        }
        for c in constants.iter().filter(|c| !c.is_list) {
            let value = c.values.first().copied().unwrap_or_default();
            // The value the generated constant holds (an f32 rounds).
            let value = if c.ty == ConstantType::F32 { f64::from(value as f32) } else { value };
            let unit = c.unit.as_deref().and_then(|u| Unit::parse(u).ok());
            if !scope.iter().any(|n: &Name| n.name == c.name) {
                scope.push(Name { name: c.name.clone(), binding: Binding::Const(value), unit });
            }
        }
        if !ok {
            continue;
        }
        let expr_text = check_text(&d.expr, &format!("{key}.expr"), r);
        let parsed = expr::parse(&d.expr.value).and_then(|e| expr::check(&e, &scope, unit.as_ref()));
        let formula = match parsed {
            Ok((formula, _)) => formula,
            Err(e) => {
                let at = pos_in_scalar(r.text, Pos::at(&d.expr), e.span.start);
                let help = match (e.help, e.related) {
                    (Some(help), Some(related)) => {
                        let p = pos_in_scalar(r.text, Pos::at(&d.expr), related.start);
                        Some(format!("{help} at line {}, column {}", p.line, p.column))
                    }
                    (help, _) => help,
                };
                r.error(at, format!("{key}.expr"), e.message, help);
                continue;
            }
        };
        let used = expr::names_used(&formula);
        let mut unused = false;
        for (input, doc) in derived_inputs(&scope).zip(d.inputs.value.iter()) {
            if !used.contains(&input) {
                r.error(
                    Pos::at(&doc.name),
                    format!("{key}.inputs"),
                    format!("the formula does not use the input `{input}`"),
                    Some("use it in `expr`, or remove the input".into()),
                );
                unused = true;
            }
        }
        if unused {
            continue;
        }
        let mut derived = Derived {
            name: d.name.value.clone(),
            title,
            unit: unit_text,
            doc,
            source,
            inputs,
            expr: expr_text,
            formula,
            examples: Vec::new(),
        };
        let mut examples_ok = true;
        for (k, ex) in d.examples.iter().enumerate() {
            let ekey = format!("{key}.examples[{k}]");
            let doc = check_text(&ex.doc, &format!("{ekey}.doc"), r);
            let mut given = BTreeMap::new();
            for (name, value) in &ex.inputs.value {
                if derived.input(name).is_none() {
                    let all: Vec<&str> = derived.inputs.iter().map(|i| i.name.as_str()).collect();
                    let help = match closest(name, &all) {
                        Some(best) => format!("did you mean `{best}`? inputs: {}", all.join(", ")),
                        None => format!("inputs: {}", all.join(", ")),
                    };
                    r.error(
                        Pos::at(value),
                        format!("{ekey}.inputs"),
                        format!("`{}` is not an input of `{}`", escape(name), derived.name),
                        Some(help),
                    );
                    examples_ok = false;
                } else {
                    given.insert(name.clone(), value.value);
                }
            }
            let tolerance = ex.tolerance.as_ref().map_or(0.0, |t| t.value);
            if !(tolerance.is_finite() && tolerance >= 0.0) {
                r.error(
                    ex.tolerance.as_ref().map(Pos::at).unwrap_or_default(),
                    format!("{ekey}.tolerance"),
                    "a tolerance is a finite number, 0 or more",
                    None,
                );
                examples_ok = false;
                continue;
            }
            let example = DerivedExample { inputs: given, value: ex.value.value, tolerance, doc };
            let values = match derived.example_inputs(&example) {
                Ok(v) => v,
                Err(missing) => {
                    r.error(
                        Pos::at(&ex.inputs),
                        format!("{ekey}.inputs"),
                        format!("the example gives no value for `{missing}`, which has no `default`"),
                        Some(format!("add `{missing}: <value>` to the example's `inputs`")),
                    );
                    examples_ok = false;
                    continue;
                }
            };
            match derived.compute(&values) {
                Ok(got) => {
                    let diff = (f64::from(got) - example.value).abs();
                    // Without a tolerance the value must match to f32 precision.
                    let allowed = tolerance.max(example.value.abs().max(1.0) * 4.0 * f64::from(f32::EPSILON));
                    if diff.is_nan() || diff > allowed {
                        r.error(
                            Pos::at(&ex.value),
                            format!("{ekey}.value"),
                            format!("the formula gives {got} here, {diff:.6} away from {}", example.value),
                            Some(if tolerance > 0.0 {
                                format!("the tolerance is {tolerance}; check the formula, its constants and the value's source")
                            } else {
                                "without `tolerance` the value must match to f32 precision; add the source's tolerance".into()
                            }),
                        );
                        examples_ok = false;
                    }
                }
                Err(e) => {
                    r.error(
                        Pos::at(&ex.value),
                        format!("{ekey}.value"),
                        format!("`{}` is not computable for the example's inputs: {e}", derived.name),
                        Some("an example gives inputs the formula takes, within their ranges".into()),
                    );
                    examples_ok = false;
                }
            }
            derived.examples.push(example);
        }
        if examples_ok {
            out.push(derived);
        }
    }
    out
}

/// The names of the inputs in `scope`, in parameter order.
fn derived_inputs(scope: &[Name]) -> impl Iterator<Item = String> + '_ {
    scope.iter().filter(|n| matches!(n.binding, Binding::Input(_))).map(|n| n.name.clone())
}

const UNIT_HELP: &str =
    "a unit is symbols with integer powers: `mg/L`, `mS/cm`, `kPa`, `m^2/s`, `mg/L per uS/cm`; `1` for none";

fn resolve_input(
    input: &DerivedInputDoc,
    key: &str,
    commands: &[CommandSpec],
    constants: &[Constant],
    before: &[DerivedInput],
    r: &mut Reporter<'_>,
) -> Option<(DerivedInput, Option<Unit>)> {
    let mut ok = check_name(&input.name, &format!("{key}.name"), r);
    let name = &input.name.value;
    if ok && let Some(why) = check_input_name(name) {
        r.error(Pos::at(&input.name), format!("{key}.name"), why, Some("rename the input".into()));
        ok = false;
    }
    if before.iter().any(|b| &b.name == name) {
        r.error(
            Pos::at(&input.name),
            format!("{key}.name"),
            format!("two inputs are called `{name}`"),
            Some("rename one of them".into()),
        );
        ok = false;
    }
    if constants.iter().any(|c| &c.name == name) {
        r.error(
            Pos::at(&input.name),
            format!("{key}.name"),
            format!("the input `{name}` has the name of a constant of the sensor"),
            Some("rename the input: the formula names both".into()),
        );
        ok = false;
    }
    let range = match &input.range {
        Some(range) => {
            let (min, max) = (range.value.min, range.value.max);
            if !(min.is_finite() && max.is_finite() && min <= max) {
                r.error(
                    Pos::at(range),
                    format!("{key}.range"),
                    format!("`{min}..={max}` is not a range"),
                    Some("write `range: {min: 0, max: 40}` with finite bounds, min <= max".into()),
                );
                ok = false;
            }
            Some((min, max))
        }
        None => None,
    };
    let default = input.default.as_ref().map(|d| d.value);
    if let (Some(d), Some(at)) = (default, &input.default)
        && (!d.is_finite() || range.is_some_and(|(min, max)| !(min..=max).contains(&d)))
    {
        r.error(
            Pos::at(at),
            format!("{key}.default"),
            format!("the default {d} is not a finite number within the input's range"),
            None,
        );
        ok = false;
    }
    let (source, unit_text) = match (&input.field, &input.station) {
        (Some(field), None) => {
            if let Some(u) = &input.unit {
                r.error(
                    Pos::at(u),
                    format!("{key}.unit"),
                    "a field input has its field's unit",
                    Some("remove `unit`; declare it on the field".into()),
                );
                ok = false;
            }
            let (command, field_name, unit) = resolve_field(field, key, commands, r)?;
            (InputSource::Field { command, field: field_name }, unit)
        }
        (None, Some(station)) => {
            if let Some(why) = check_snake(&station.value) {
                r.error(
                    Pos::at(station),
                    format!("{key}.station"),
                    format!("invalid station input name: {why}"),
                    Some("name it in snake_case, like `salinity` or `barometric_pressure`".into()),
                );
                ok = false;
            }
            let unit = input.unit.as_ref().map(|u| check_text(u, &format!("{key}.unit"), r));
            (InputSource::Station(station.value.clone()), unit)
        }
        (Some(_), Some(station)) => {
            r.error(
                Pos::at(station),
                format!("{key}.station"),
                "an input has `field` or `station`, not both",
                Some("keep `field: command.field` for a reading, `station: name` for a value of the station".into()),
            );
            return None;
        }
        (None, None) => {
            r.error(
                Pos::at(&input.name),
                format!("{key}.field"),
                format!("the input `{name}` needs `field` or `station`"),
                Some(
                    "add `field: <command>.<field>` (a read's number) or `station: <name>` (salinity, pressure)".into(),
                ),
            );
            return None;
        }
    };
    let unit = match &unit_text {
        Some(text) => match Unit::parse(text) {
            Ok(u) => Some(u),
            Err(why) => {
                let at = input.unit.as_ref().map_or(Pos::at(&input.name), Pos::at);
                r.error(at, format!("{key}.unit"), format!("not a unit: {why}"), Some(UNIT_HELP.into()));
                ok = false;
                None
            }
        },
        None => None,
    };
    ok.then(|| (DerivedInput { name: name.clone(), source, unit: unit_text, default, range }, unit))
}

/// `command.field` of a number field of a read: the names and the field's unit.
fn resolve_field(
    at: &Spanned<String>,
    key: &str,
    commands: &[CommandSpec],
    r: &mut Reporter<'_>,
) -> Option<(String, String, Option<String>)> {
    let fkey = format!("{key}.field");
    let Some((command, field)) = at.value.split_once('.') else {
        r.error(
            Pos::at(at),
            fkey,
            format!("`{}` is not `command.field`", escape(&at.value)),
            Some("name a read and its field, like `get_reading.value_mg_l`".into()),
        );
        return None;
    };
    let reads: Vec<&str> =
        commands.iter().filter(|c| c.is_read() && !c.fields.is_empty()).map(|c| c.name.as_str()).collect();
    let Some(cmd) = commands.iter().find(|c| c.name == command && c.is_read()) else {
        let help = match closest(command, &reads) {
            Some(best) => format!("did you mean `{best}`? reads: {}", reads.join(", ")),
            None => format!("reads: {}", reads.join(", ")),
        };
        r.error(Pos::at(at), fkey, format!("the sensor has no read called `{}`", escape(command)), Some(help));
        return None;
    };
    let numbers: Vec<&str> =
        cmd.fields.iter().filter(|f| f.kind.is_number()).filter_map(|f| f.name.as_deref()).collect();
    let Some(f) = cmd.field(field).filter(|f| f.name.as_deref().is_some_and(|n| numbers.contains(&n))) else {
        let help = match closest(field, &numbers) {
            Some(best) => format!("did you mean `{command}.{best}`? number fields: {}", numbers.join(", ")),
            None => format!("number fields of `{command}`: {}", numbers.join(", ")),
        };
        let what = if cmd.field(field).is_some() { "is not a number field of" } else { "is not a field of" };
        r.error(Pos::at(at), fkey, format!("`{}` {what} `{command}`", escape(field)), Some(help));
        return None;
    };
    Some((command.to_string(), field.to_string(), f.unit.clone()))
}

/// Where byte `offset` of the scalar written at `at` lies in the file:
/// plain, quoted and block scalars, on one line or folded over several.
pub(crate) fn pos_in_scalar(text: &str, at: Pos, offset: usize) -> Pos {
    let lines: Vec<&str> = text.lines().collect();
    let Some(first) = lines.get((at.line as usize).wrapping_sub(1)) else { return at };
    let chars: Vec<char> = first.chars().collect();
    let col = (at.column as usize).saturating_sub(1);
    let Some(&open) = chars.get(col) else { return at };
    // Walk the raw text, one value character at a time.
    let mut remaining = offset;
    let to_pos = |line: usize, column: usize| Pos { line: line as u32 + 1, column: column as u32 + 1 };
    // A block scalar (`|`, `>-`, ...) is located at its header or at its first content line.
    let header = |l: &str| {
        let t = l.trim_end();
        let t = t.strip_suffix(['-', '+']).unwrap_or(t);
        t.ends_with(" |")
            || t.ends_with(" >")
            || t.ends_with(":|")
            || t.ends_with(":>")
            || t.ends_with("- |")
            || t == "|"
            || t == ">"
    };
    let starts_line = chars[..col.min(chars.len())].iter().all(|c| *c == ' ');
    let after_header = starts_line
        && (0..(at.line as usize).saturating_sub(1))
            .rev()
            .map(|i| lines[i])
            .find(|l| !l.trim().is_empty())
            .is_some_and(header);
    if open == '|' || open == '>' || after_header {
        // A block scalar: its lines start at the first content line's indentation.
        let mut line = if after_header { at.line as usize - 1 } else { at.line as usize };
        let indent = lines.get(line).map_or(0, |l| l.len() - l.trim_start().len());
        while let Some(l) = lines.get(line) {
            let content: Vec<char> = l.chars().skip(indent).collect();
            if remaining <= content.len() {
                return to_pos(line, indent + remaining);
            }
            remaining -= content.len() + 1;
            line += 1;
        }
        return at;
    }
    let (mut line, mut column, quote) = match open {
        '"' | '\'' => (at.line as usize - 1, col + 1, Some(open)),
        _ => (at.line as usize - 1, col, None),
    };
    loop {
        let Some(l) = lines.get(line) else { return at };
        let cs: Vec<char> = l.chars().collect();
        while column < cs.len() {
            if remaining == 0 {
                return to_pos(line, column);
            }
            let c = cs[column];
            let step = match (quote, c) {
                (Some('"'), '\\') => 2,
                (Some('\''), '\'') if cs.get(column + 1) == Some(&'\'') => 2,
                _ => 1,
            };
            remaining = remaining.saturating_sub(c.len_utf8().max(1));
            column += step;
        }
        if remaining == 0 {
            return to_pos(line, column);
        }
        // Folded onto the next line: the line break is one space.
        remaining = remaining.saturating_sub(1);
        line += 1;
        column = lines.get(line).map_or(0, |l| l.len() - l.trim_start().len());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(text: &str, line: u32, column: u32, offset: usize) -> (u32, u32) {
        let p = pos_in_scalar(text, Pos { line, column }, offset);
        (p.line, p.column)
    }

    #[test]
    fn positions_inside_scalars() {
        let text =
            "a:\n  expr: x + yy\n  q: \"x + yy\"\n  s: 'it''s + yy'\n  b: |\n    x +\n    yy\n  f: x +\n    yy\n";
        assert_eq!(at(text, 2, 9, 4), (2, 13));
        assert_eq!(at(text, 3, 6, 4), (3, 11));
        assert_eq!(at(text, 4, 6, 7), (4, 15));
        assert_eq!(at(text, 5, 6, 4), (7, 5));
        assert_eq!(at(text, 8, 6, 4), (9, 5));
        // Located at the first content line, as the YAML parser does for block scalars.
        assert_eq!(at(text, 6, 5, 4), (7, 5));
        let folded = "e: >-\n  a /\n    b + c\n  d\n";
        assert_eq!(at(folded, 2, 3, 8), (3, 7));
    }
}

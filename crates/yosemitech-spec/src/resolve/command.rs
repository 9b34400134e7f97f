//! Commands: a definition's function, address, count and fields turned into
//! a [`CommandSpec`], its role, the `use` entries that refine an included one, and
//! its examples and table errata.
//!
//! A command resolves only when all of it is valid: the function, address
//! and count are stated, the count is within Modbus limits
//! ([`MAX_READ_COUNT`], [`MAX_WRITE_COUNT`]; zero only for a trigger write),
//! the fields fill the registers exactly, a role fits the command's shape,
//! and a table erratum corrects something the command does differently. A
//! `use` entry changes only what a manual may add (title, doc, `since`,
//! units, what a calibration block calibrates, source, examples, errata),
//! never the wire format.

use std::collections::BTreeSet;

use crate::Spanned;
use yosemitech_rtu::Function;

use crate::check::{check_erratum_id, check_name, check_role, check_text, resolve_figure};
use crate::diag::{Pos, Reporter};
use crate::document::{CalibratesDoc, CommandDoc, FunctionDoc};
use crate::model::{Calibrates, CommandErratum, CommandSpec, Field, FieldKind, Role};
use crate::names::check_snake;

use super::field::resolve_fields;
use super::sensor::{resolve_provenance, resolve_source};
use super::{MAX_READ_COUNT, MAX_WRITE_COUNT};

/// The key of a command entry: `commands[3] (get_ph)`, the name only when it is valid.
pub(super) fn command_key(i: usize, c: &CommandDoc) -> String {
    match c.name.as_ref().or(c.uses.as_ref()) {
        Some(n) if check_snake(&n.value).is_none() => format!("commands[{i}] ({})", n.value),
        _ => format!("commands[{i}]"),
    }
}

/// A `use:` entry may only add this manual's source, examples and errata.
pub(super) fn check_use_entry(c: &CommandDoc, i: usize, r: &mut Reporter<'_>) {
    let extra: Vec<(&str, Pos)> = [
        ("role", c.role.as_ref().map(Pos::at)),
        ("function", c.function.as_ref().map(Pos::at)),
        ("address", c.address.as_ref().map(Pos::at)),
        ("count", c.count.as_ref().map(Pos::at)),
        ("trigger", c.trigger.as_ref().map(Pos::at)),
        ("fixed_slave", c.fixed_slave.as_ref().map(Pos::at)),
        ("fields", c.fields.as_ref().map(Pos::at)),
        ("extra_byte_counts", c.extra_byte_counts.first().map(Pos::at)),
        ("provenance", c.provenance.as_ref().and_then(|p| p.sources.first()).map(Pos::at)),
    ]
    .into_iter()
    .filter_map(|(k, p)| p.map(|p| (k, p)))
    .collect();
    for (key, pos) in extra {
        r.error(
            pos,
            format!("{}.{key}", command_key(i, c)),
            format!("`{key}` cannot be changed by a `use` entry"),
            Some("a `use` entry takes `title`, `doc`, `since`, `units`, `calibrates`, `source`, `examples` and `errata`; change the definition in the fragment".into()),
        );
    }
}

fn require<'a, T>(
    v: &'a Option<Spanned<T>>,
    at: Pos,
    key: &str,
    what: &str,
    r: &mut Reporter<'_>,
) -> Option<&'a Spanned<T>> {
    if v.is_none() {
        let help = match what {
            "function" => "add `function: read` (0x03) or `function: write` (0x10)",
            "address" => "add `address:`, the first register as sent on the wire, like `0x2800`",
            "count" => "add `count:`, the number of registers",
            _ => "see spec/schema.json",
        };
        r.error(at, key, format!("missing `{what}`"), Some(help.into()));
    }
    v.as_ref()
}

/// Turns a command definition into the model, reporting every problem.
pub(super) fn resolve_command(
    c: &CommandDoc,
    _prefix: Option<&str>,
    i: usize,
    fragment: Option<String>,
    r: &mut Reporter<'_>,
) -> Option<CommandSpec> {
    let key = command_key(i, c);
    let name = c.name.as_ref()?;
    let name_ok = check_name(name, &format!("{key}.name"), r)
        && check_role(
            name,
            &format!("{key}.name"),
            crate::names::check_command_name,
            "rename the command, e.g. `get_<name>`",
            r,
        );
    let at = Pos::at(name);
    let title = c.title.as_ref().map(|t| check_text(t, &format!("{key}.title"), r));
    let doc = c.doc.as_ref().map(|t| check_text(t, &format!("{key}.doc"), r));
    let source = c.source.as_ref().map(|s| resolve_source(s, &format!("{key}.source"), r)).unwrap_or_default();
    let provenance = c.provenance.as_ref().map(|p| resolve_provenance(p, &format!("{key}.provenance"), at, r));
    let function = require(&c.function, at, &format!("{key}.function"), "function", r).map(|f| match f.value {
        FunctionDoc::Read => Function::Read,
        FunctionDoc::Write => Function::Write,
    });
    let address = require(&c.address, at, &format!("{key}.address"), "address", r).and_then(|a| {
        u16::try_from(a.value).ok().or_else(|| {
            r.error(
                Pos::at(a),
                format!("{key}.address"),
                format!("register address {} does not fit in 16 bits", a.value),
                Some("addresses are 0x0000..=0xFFFF, as sent on the wire".into()),
            );
            None
        })
    });
    let trigger = c.trigger.as_ref().is_some_and(|t| t.value);
    let since = c.since.as_ref().map(|s| check_text(s, &format!("{key}.since"), r));
    if let Some(units) = &c.units {
        r.error(
            Pos::at(units),
            format!("{key}.units"),
            "`units` belongs in a `use` entry",
            Some("give each field its `unit` in `fields`".into()),
        );
    }
    let count = require(&c.count, at, &format!("{key}.count"), "count", r);
    let count = match (function, count) {
        (Some(f), Some(n)) => check_count(f, n, trigger, &key, r),
        _ => None,
    };
    let fixed_slave = c.fixed_slave.as_ref().and_then(|s| {
        u8::try_from(s.value).ok().or_else(|| {
            r.error(
                Pos::at(s),
                format!("{key}.fixed_slave"),
                format!("slave address {} does not fit in a byte", s.value),
                Some("a fixed slave address is 0..=255, like `0xFF` for a wildcard".into()),
            );
            None
        })
    });
    let mut extra_byte_counts = Vec::new();
    for (j, b) in c.extra_byte_counts.iter().enumerate() {
        let k = format!("{key}.extra_byte_counts[{j}]");
        if function != Some(Function::Read) {
            r.error(
                Pos::at(b),
                &k,
                "extra byte counts apply to read replies only",
                Some("remove `extra_byte_counts` from this write".into()),
            );
        } else if b.value > 250 || count.is_some_and(|n| b.value == 2 * u32::from(n)) {
            r.error(
                Pos::at(b),
                &k,
                format!("byte count {} is not an alternative to the normal one", b.value),
                Some("list only counts other than 2 * count, at most 250".into()),
            );
        } else {
            extra_byte_counts.push(b.value as u8);
        }
    }
    let fields = resolve_fields(c, &key, count, trigger, at, r);

    let mut cmd = CommandSpec {
        name: name.value.clone(),
        title: title.unwrap_or_else(|| name.value.replace('_', " ")),
        doc: doc.unwrap_or_default(),
        source,
        provenance,
        function: function?,
        address: address?,
        count: count?,
        trigger,
        since,
        role: c.role.as_ref().map(|r| r.value),
        fixed_slave,
        extra_byte_counts,
        fields: fields?,
        examples: Vec::new(),
        errata: Vec::new(),
        shared_from: fragment,
        calibrates: c.calibrates.as_ref().map(|doc| resolve_calibrates(doc, &key, r)),
    };
    if !name_ok {
        return None;
    }
    if let Some(role) = &c.role
        && let Err(why) = check_role_shape(role.value, &cmd)
    {
        r.error(
            Pos::at(role),
            format!("{key}.role"),
            format!("`{}` cannot have role `{}`: {why}", cmd.name, role.value.name()),
            Some("see the roles in docs/spec-language.md".into()),
        );
        return None;
    }
    resolve_command_extras(c, i, &mut cmd, r);
    Some(cmd)
}

/// What a command with `role` must look like for the simulator and the CLI to use it.
fn check_role_shape(role: Role, cmd: &CommandSpec) -> Result<(), String> {
    let named: Vec<&Field> = cmd.named_fields().collect();
    let one = |pred: fn(&FieldKind) -> bool, what: &str| -> Result<(), String> {
        match named.as_slice() {
            [f] if pred(&f.kind) => Ok(()),
            _ => Err(format!("it needs exactly one named field, {what}")),
        }
    };
    let read = |ok: bool| if ok { Ok(()) } else { Err("it must be a read".to_string()) };
    let write = |ok: bool| if ok { Ok(()) } else { Err("it must be a write".to_string()) };
    match role {
        Role::SetSlaveAddress => write(!cmd.is_read()).and_then(|()| one(|k| matches!(k, FieldKind::U8), "a `u8`")),
        Role::GetSlaveAddress => read(cmd.is_read()).and_then(|()| one(|k| matches!(k, FieldKind::U8), "a `u8`")),
        Role::SerialNumber => {
            read(cmd.is_read()).and_then(|()| one(|k| matches!(k, FieldKind::Ascii { .. }), "an `ascii`"))
        }
        Role::Version => {
            read(cmd.is_read())?;
            if !named.is_empty() && named.iter().all(|f| matches!(f.kind, FieldKind::Version)) {
                Ok(())
            } else {
                Err("its fields must be `version` fields".into())
            }
        }
        Role::StartMeasurement | Role::StopMeasurement | Role::Wipe => {
            if cmd.trigger {
                Ok(())
            } else {
                Err("it must be a `trigger`".into())
            }
        }
        Role::CalibrationPoint => write(!cmd.is_read()).and_then(|()| {
            one(|k| matches!(k, FieldKind::F32 { .. } | FieldKind::U16 { .. } | FieldKind::I16 { .. }), "a number")
        }),
        Role::CalibrationStatus => {
            read(cmd.is_read()).and_then(|()| one(|k| matches!(k, FieldKind::Enum { .. }), "an `enum`"))
        }
        Role::UserCalibration => write(!cmd.is_read()).and_then(|()| match named.as_slice() {
            [k, b] if [k, b].iter().all(|f| matches!(f.kind, FieldKind::F32 { .. })) => Ok(()),
            _ => Err("it needs exactly two named fields, `f32` slope K then `f32` offset B".into()),
        }),
    }
}

/// A block's `calibrates`: the field is checked against the sensor's
/// measurement reads once every command is known.
pub(super) fn resolve_calibrates(doc: &CalibratesDoc, key: &str, r: &mut Reporter<'_>) -> Calibrates {
    let key = format!("{key}.calibrates");
    let mut standards = Vec::new();
    for (j, s) in doc.standards.iter().enumerate() {
        if s.value.is_finite() {
            standards.push(s.value);
        } else {
            r.error(Pos::at(s), format!("{key}.standards[{j}]"), "a standard must be a finite number", None);
        }
    }
    Calibrates {
        field: check_text(&doc.field, &format!("{key}.field"), r),
        standards,
        settle_ms: doc.settle_ms.as_ref().map(|m| m.value),
    }
}

fn check_count(f: Function, n: &Spanned<u32>, trigger: bool, key: &str, r: &mut Reporter<'_>) -> Option<u16> {
    let v = n.value;
    let k = format!("{key}.count");
    if trigger && f == Function::Read {
        // A read used as a command: it asks for registers whose reply it ignores.
        if v == 0 || v > MAX_READ_COUNT {
            r.error(
                Pos::at(n),
                k,
                format!("a trigger read asks for 1..={MAX_READ_COUNT} registers, not {v}"),
                Some("use the count the manual's request sends, like `count: 1`".into()),
            );
            return None;
        }
        return Some(v as u16);
    }
    if trigger {
        if v != 0 {
            r.error(Pos::at(n), k, format!("a trigger writes 0 registers, not {v}"), Some("use `count: 0`".into()));
            return None;
        }
        return Some(0);
    }
    let max = if f == Function::Read { MAX_READ_COUNT } else { MAX_WRITE_COUNT };
    if v == 0 {
        r.error(
            Pos::at(n),
            k,
            "register count 0 is only valid for a trigger write".to_string(),
            Some("declare `trigger: true` on a write that sends no data (like a start-measurement trigger)".into()),
        );
        return None;
    }
    if v > max {
        let what = if f == Function::Read { "read" } else { "write" };
        r.error(
            Pos::at(n),
            k,
            format!("register count {v} is out of range for a {what}"),
            Some(format!("a {what} covers 1..={max} registers")),
        );
        return None;
    }
    Some(v as u16)
}

/// Examples and table errata; needs the resolved command.
pub(super) fn resolve_command_extras(c: &CommandDoc, i: usize, cmd: &mut CommandSpec, r: &mut Reporter<'_>) {
    let key = command_key(i, c);
    let mut ids = BTreeSet::new();
    for (j, e) in c.errata.iter().enumerate() {
        let ek = format!("{key}.errata[{j}]");
        check_erratum_id(&e.id, &format!("{ek}.id"), &mut ids, r);
        let note = check_text(&e.note, &format!("{ek}.note"), r);
        let t = &e.table;
        let mut differs = false;
        if let Some(a) = &t.address {
            if a.value == u32::from(cmd.address) {
                r.error(
                    Pos::at(a),
                    format!("{ek}.table.address"),
                    format!("the table's address 0x{:04X} is the command's own: nothing to correct", a.value),
                    Some("remove `address` from `table`".into()),
                );
            } else if a.value > 0xFFFF {
                r.error(
                    Pos::at(a),
                    format!("{ek}.table.address"),
                    format!("address {} does not fit in 16 bits", a.value),
                    Some("addresses are 0x0000..=0xFFFF".into()),
                );
            }
            differs = true;
        }
        if let Some(n) = &t.count {
            if n.value == u32::from(cmd.count) {
                r.error(
                    Pos::at(n),
                    format!("{ek}.table.count"),
                    format!("the table's count {} is the command's own: nothing to correct", n.value),
                    Some("remove `count` from `table`".into()),
                );
            } else if n.value > 0xFFFF {
                r.error(
                    Pos::at(n),
                    format!("{ek}.table.count"),
                    format!("count {} does not fit in 16 bits", n.value),
                    Some("counts are 0..=65535".into()),
                );
            }
            differs = true;
        }
        let table_function = t.function.as_ref().map(|f| {
            let func = match f.value {
                FunctionDoc::Read => Function::Read,
                FunctionDoc::Write => Function::Write,
            };
            if func == cmd.function {
                r.error(
                    Pos::at(f),
                    format!("{ek}.table.function"),
                    "the table's function is the command's own: nothing to correct",
                    Some("remove `function` from `table`".into()),
                );
            }
            func
        });
        if t.function.is_some() {
            differs = true;
        }
        if !differs {
            r.error(
                Pos::at(&e.id),
                format!("{ek}.table"),
                "a table erratum names what the table prints: `address`, `count` or `function`",
                Some("add `table: {address: 0x1100}` (or `count`, `function`) as the table prints it".into()),
            );
        }
        let figure = match &e.figure {
            Some(f) => match resolve_figure(&f.value, &format!("{ek}.figure"), Pos::at(f), r) {
                Some(figure) => Some(figure),
                None => continue,
            },
            None => None,
        };
        cmd.errata.push(CommandErratum {
            id: e.id.value.clone(),
            figure,
            manual: e.manual.as_ref().map(|m| check_text(m, &format!("{ek}.manual"), r)),
            table_address: t.address.as_ref().map(|a| a.value as u16),
            table_count: t.count.as_ref().map(|n| n.value as u16),
            table_function,
            note,
        });
    }
    for (j, e) in c.examples.iter().enumerate() {
        if let Some(ex) = crate::examples::check_example(cmd, e, &format!("{key}.examples[{j}]"), &mut ids, r) {
            cmd.examples.push(ex);
        }
    }
}

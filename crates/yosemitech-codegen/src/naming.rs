//! The names of everything generated for one sensor, decided up front so
//! that collisions are errors here rather than compile errors downstream.

use std::collections::BTreeMap;

use heck::{ToShoutySnakeCase, ToUpperCamelCase};
use yosemitech_spec::names::{
    DEVICE_METHODS, MODULE_CONSTS, MODULE_FUNCTIONS, MODULE_TYPES, PRELUDE_NAMES, check_snake,
};
use yosemitech_spec::{CommandSpec, EnumRepr, FieldKind, Sensor, Variant};

use crate::Error;

/// Names of one command's items.
#[derive(Debug, Clone)]
pub struct CommandNames {
    /// The request type and the `CommandId`/`Request`/`Response` variant.
    pub ty: String,
    /// The reply type of a read.
    pub response: String,
    /// The `Device` method.
    pub method: String,
}

/// One generated enum type, shared by every field with the same name and codes.
#[derive(Debug, Clone)]
pub struct EnumDef {
    /// The type.
    pub ty: String,
    /// The code size.
    pub repr: EnumRepr,
    /// The named codes.
    pub variants: Vec<Variant>,
    /// The first field's doc.
    pub doc: Option<String>,
    /// `command.field` of every field using it.
    pub used_by: Vec<String>,
}

/// Every generated name of one sensor.
#[derive(Debug, Clone)]
pub struct Names {
    /// Per command, in spec order.
    pub commands: Vec<CommandNames>,
    /// Enum types, in order of first use.
    pub enums: Vec<EnumDef>,
    /// (command index, field index) -> index into `enums`.
    pub enum_of: BTreeMap<(usize, usize), usize>,
    /// Per constant, in spec order.
    pub constants: Vec<String>,
}

impl Names {
    /// Decides every name of `sensor`'s module.
    pub fn plan(sensor: &Sensor) -> Result<Self, Error> {
        let collision = |detail: String| Error::NameCollision { sensor: sensor.name.clone(), detail };
        let mut types: BTreeMap<String, String> =
            MODULE_TYPES.iter().map(|t| ((*t).to_owned(), "the generated module".to_owned())).collect();
        // The module relies on the prelude (`Option`, `Some`, `From`, `Iterator`, ...):
        // an enum type falls back to another name, a command is refused.
        for name in PRELUDE_NAMES {
            types.insert((*name).to_owned(), "a name of the Rust prelude".to_owned());
        }
        let claim_type = |types: &mut BTreeMap<String, String>, name: &str, owner: String| match types.get(name) {
            Some(other) => Err(collision(format!("type `{name}` of {owner} is also {other}"))),
            None => {
                types.insert(name.to_owned(), owner);
                Ok(())
            }
        };

        let mut commands = Vec::new();
        for c in &sensor.commands {
            let ty = c.name.to_upper_camel_case();
            claim_type(&mut types, &ty, format!("command `{}`", c.name))?;
            let response = format!("{ty}Response");
            if c.is_read() {
                claim_type(&mut types, &response, format!("the reply of `{}`", c.name))?;
            }
            commands.push(CommandNames { ty, response, method: String::new() });
        }

        // Device methods: reads drop a leading `get_`; anything that would
        // collide or not be an identifier keeps the command's full name.
        let mut methods: BTreeMap<String, usize> = BTreeMap::new();
        let preferred: Vec<String> = sensor.commands.iter().map(preferred_method).collect();
        for (i, c) in sensor.commands.iter().enumerate() {
            let short = &preferred[i];
            let taken_by_other = preferred.iter().enumerate().any(|(j, p)| j != i && p == short)
                || sensor.commands.iter().enumerate().any(|(j, o)| j != i && &o.name == short);
            let method =
                if DEVICE_METHODS.contains(&short.as_str()) || taken_by_other { c.name.clone() } else { short.clone() };
            if DEVICE_METHODS.contains(&method.as_str()) {
                return Err(collision(format!("command `{}` would shadow `Device::{method}`", c.name)));
            }
            if let Some(other) = methods.insert(method.clone(), i) {
                return Err(collision(format!(
                    "`Device::{method}` for both `{}` and `{}`",
                    sensor.commands[other].name, c.name
                )));
            }
            commands[i].method = method;
        }

        // Enum types.
        let mut enums: Vec<EnumDef> = Vec::new();
        let mut enum_of = BTreeMap::new();
        for (ci, c) in sensor.commands.iter().enumerate() {
            for (fi, f) in c.fields.iter().enumerate() {
                let (FieldKind::Enum { repr, variants }, Some(name)) = (&f.kind, &f.name) else { continue };
                let candidates = enum_type_candidates(c, name);
                let same = |e: &EnumDef| e.repr == *repr && e.variants == *variants;
                let mut chosen = None;
                for candidate in &candidates {
                    if let Some(k) = enums.iter().position(|e| &e.ty == candidate) {
                        if same(&enums[k]) {
                            chosen = Some(k);
                            break;
                        }
                        continue;
                    }
                    if types.contains_key(candidate) {
                        continue;
                    }
                    types.insert(candidate.clone(), format!("the enum of `{}.{name}`", c.name));
                    enums.push(EnumDef {
                        ty: candidate.clone(),
                        repr: *repr,
                        variants: variants.clone(),
                        doc: f.doc.clone(),
                        used_by: Vec::new(),
                    });
                    chosen = Some(enums.len() - 1);
                    break;
                }
                let Some(k) = chosen else {
                    return Err(collision(format!(
                        "no free type name for the enum of `{}.{name}` (tried {})",
                        c.name,
                        candidates.join(", ")
                    )));
                };
                enums[k].used_by.push(format!("{}.{name}", c.name));
                enum_of.insert((ci, fi), k);
            }
        }

        let mut consts: BTreeMap<String, String> =
            MODULE_CONSTS.iter().map(|c| ((*c).to_owned(), "the generated module".to_owned())).collect();
        let mut constants = Vec::new();
        for c in &sensor.constants {
            let name = c.name.to_shouty_snake_case();
            if let Some(other) = consts.insert(name.clone(), format!("constant `{}`", c.name)) {
                return Err(collision(format!("constant `{name}` of `{}` is also {other}", c.name)));
            }
            constants.push(name);
        }

        // One function per derived quantity, beside the module's own.
        let mut functions: BTreeMap<&str, &str> =
            MODULE_FUNCTIONS.iter().map(|f| (*f, "the generated module")).collect();
        for d in &sensor.derived {
            if let Some(other) = functions.insert(&d.name, "another derived quantity") {
                return Err(collision(format!("the function `{}` of a derived quantity is also {other}", d.name)));
            }
        }

        Ok(Self { commands, enums, enum_of, constants })
    }
}

/// `get_ph` -> `ph`; everything else keeps its name.
fn preferred_method(c: &CommandSpec) -> String {
    match c.name.strip_prefix("get_") {
        Some(short) if c.is_read() && check_snake(short).is_none() => short.to_owned(),
        _ => c.name.clone(),
    }
}

/// Type names to try for the enum of field `field` of command `c`, best first:
/// the command without its verb when the field is its subject
/// (`get_calibration_status.status` -> `CalibrationStatus`), the field's
/// name (`range_status` -> `RangeStatus`), then command + field.
fn enum_type_candidates(c: &CommandSpec, field: &str) -> Vec<String> {
    let subject = c.name.split_once('_').map_or(c.name.as_str(), |(_, rest)| rest);
    let mut out = Vec::new();
    if subject.ends_with(field) {
        out.push(subject.to_upper_camel_case());
    }
    out.push(field.to_upper_camel_case());
    out.push(format!("{}{}", c.name.to_upper_camel_case(), field.to_upper_camel_case()));
    out.dedup();
    out
}

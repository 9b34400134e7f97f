//! Rules for names: they become Rust identifiers in generated code.

use heck::{ToShoutySnakeCase, ToUpperCamelCase};

/// Longest name accepted.
pub const MAX_NAME_LEN: usize = 64;

const KEYWORDS: &[&str] = &[
    "as", "async", "await", "break", "const", "continue", "crate", "dyn", "else", "enum", "extern", "false", "fn",
    "for", "gen", "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return", "self",
    "Self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use", "where", "while", "abstract",
    "become", "box", "do", "final", "macro", "override", "priv", "try", "typeof", "unsized", "virtual", "yield",
];

/// Words that are keywords only in some positions (`union`, `&raw const`,
/// `safe fn`); legal identifiers, but refused to keep generated code plain.
const CONTEXTUAL_KEYWORDS: &[&str] = &["union", "raw", "safe", "macro_rules"];

/// Types every generated sensor module declares itself. The generator
/// declares exactly these (`yosemitech_codegen` takes them from here), so a
/// spec that validates cannot collide with them.
pub const MODULE_TYPES: &[&str] = &["CommandId", "Request", "Response", "Device", "AsyncDevice"];

/// Constants every generated sensor module declares itself.
pub const MODULE_CONSTS: &[&str] = &["SENSOR", "MODULE", "COMMANDS", "DERIVED"];

/// Functions every generated sensor module declares itself, besides one per
/// derived quantity (whose names must avoid these), and `rtu`, the module's
/// alias of the runtime.
pub const MODULE_FUNCTIONS: &[&str] = &["decode_response", "identify_request", "rtu"];

/// Methods of the generated `Device` and `AsyncDevice` that are not
/// commands (`set_slave_address` only for sensors with the roles it needs,
/// reserved for all). A command's method is its name or, for a read, its
/// name without `get_`; the full name must be free.
pub const DEVICE_METHODS: &[&str] = &["new", "address", "set_address", "client", "call", "set_slave_address"];

/// Other type names the generated code uses (traits and variants it names).
const TAKEN_TYPE_NAMES: &[&str] = &["Command", "Unknown", "Error", "Result"];

/// Why `name` cannot be used, or `None` if it can.
///
/// A usable name is snake_case ASCII starting with a letter, at most
/// [`MAX_NAME_LEN`] long, without doubled or trailing underscores, not a
/// Rust keyword, and not a keyword or a name the generated code reserves
/// once converted to UpperCamelCase.
pub fn check_snake(name: &str) -> Option<String> {
    if name.is_empty() {
        return Some("the name is empty".into());
    }
    if name.len() > MAX_NAME_LEN {
        return Some(format!("the name is {} characters long; at most {MAX_NAME_LEN} are allowed", name.len()));
    }
    let mut chars = name.chars();
    let first_ok = chars.next().is_some_and(|c| c.is_ascii_lowercase());
    let rest_ok = chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    if !first_ok || !rest_ok {
        return Some(format!("`{}` is not a snake_case identifier", escape(name)));
    }
    if name.contains("__") || name.ends_with('_') {
        return Some(format!("`{name}` has a doubled or trailing underscore"));
    }
    if KEYWORDS.contains(&name) {
        return Some(format!("`{name}` is a Rust keyword"));
    }
    if CONTEXTUAL_KEYWORDS.contains(&name) {
        return Some(format!("`{name}` is a contextual Rust keyword"));
    }
    let camel = name.to_upper_camel_case();
    if KEYWORDS.contains(&camel.as_str())
        || TAKEN_TYPE_NAMES.contains(&camel.as_str())
        || MODULE_TYPES.contains(&camel.as_str())
    {
        return Some(format!("`{name}` becomes `{camel}`, which the generated code reserves"));
    }
    None
}

/// The UpperCamelCase form (types, enum variants).
pub fn camel(name: &str) -> String {
    name.to_upper_camel_case()
}

/// The SHOUTY_SNAKE form (constants).
pub fn shouty(name: &str) -> String {
    name.to_shouty_snake_case()
}

/// Crates that generated code, or the crate including it, names by path:
/// a sensor module of the same name, declared at that crate's root, would
/// shadow them (`std::time::Duration` in the `yosemitech` crate would look
/// into the module; `rtu` is how the `yosemitech` crate re-exports the
/// runtime, and the generated code's own alias for it).
pub const RESERVED_SENSOR_NAMES: &[&str] = &["core", "alloc", "std", "rtu", "yosemitech_rtu"];

/// Type, trait and variant names of the Rust 2024 prelude. A command's
/// request type must not take one: generated code relies on `Option`,
/// `Some`, `None`, `Ok`, `Err`, `From` and `Iterator` from the prelude, and
/// a module that shadows the others breaks the code that glob-imports it.
pub const PRELUDE_NAMES: &[&str] = &[
    "AsMut",
    "AsRef",
    "AsyncFn",
    "AsyncFnMut",
    "AsyncFnOnce",
    "Box",
    "Clone",
    "Copy",
    "Default",
    "DoubleEndedIterator",
    "Drop",
    "Eq",
    "Err",
    "ExactSizeIterator",
    "Extend",
    "Fn",
    "FnMut",
    "FnOnce",
    "From",
    "FromIterator",
    "Future",
    "Into",
    "IntoFuture",
    "IntoIterator",
    "Iterator",
    "None",
    "Ok",
    "Option",
    "Ord",
    "PartialEq",
    "PartialOrd",
    "Result",
    "Send",
    "Sized",
    "Some",
    "String",
    "Sync",
    "ToOwned",
    "ToString",
    "TryFrom",
    "TryInto",
    "Unpin",
    "Vec",
];

/// Why `name` (already a valid [`check_snake`] name) cannot name a sensor,
/// or `None` if it can: the sensor's module must not shadow a crate.
pub fn check_sensor_name(name: &str) -> Option<String> {
    RESERVED_SENSOR_NAMES.contains(&name).then(|| {
        format!(
            "a sensor module called `{name}` would shadow the crate `{name}` \
             that generated code and the crate including it use"
        )
    })
}

/// Why `name` (already a valid [`check_snake`] name) cannot name a
/// command, or `None` if it can: its request type must not shadow a name
/// of the Rust prelude.
pub fn check_command_name(name: &str) -> Option<String> {
    let camel = camel(name);
    if DEVICE_METHODS.contains(&name) {
        return Some(format!("`{name}` would take `Device::{name}`, a method every generated `Device` has"));
    }
    PRELUDE_NAMES
        .contains(&camel.as_str())
        .then(|| format!("`{name}` becomes the type `{camel}`, which would shadow the Rust prelude's `{camel}`"))
}

/// Why `name` (already a valid [`check_snake`] name) cannot name a
/// constant, or `None` if it can: its constant must not be one the module
/// declares itself.
pub fn check_constant_name(name: &str) -> Option<String> {
    let upper = shouty(name);
    MODULE_CONSTS
        .contains(&upper.as_str())
        .then(|| format!("`{name}` becomes the constant `{upper}`, which every generated module declares itself"))
}

/// Why `name` (already a valid [`check_snake`] name) cannot name a derived
/// quantity, or `None` if it can: its function must not be one the module
/// declares itself.
pub fn check_derived_name(name: &str) -> Option<String> {
    MODULE_FUNCTIONS
        .contains(&name)
        .then(|| format!("`{name}` would take the function `{name}`, which every generated module declares itself"))
}

/// Why `name` (already a valid [`check_snake`] name) cannot name an input of
/// a derived quantity, or `None` if it can: the formula's functions are
/// taken.
pub fn check_input_name(name: &str) -> Option<String> {
    crate::expr::FUNCTION_NAMES.contains(&name).then(|| format!("`{name}` is a function of the formula language"))
}

/// `name` with control and bidi-override characters escaped, shortened to
/// 80 characters, for messages.
pub fn escape(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars().take(80) {
        if c.is_control() || ('\u{202A}'..='\u{202E}').contains(&c) || ('\u{2066}'..='\u{2069}').contains(&c) {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules() {
        assert_eq!(check_snake("get_value"), None);
        assert!(check_snake("type").is_some());
        assert!(check_snake("self").is_some());
        assert!(check_snake("Get").is_some());
        assert!(check_snake("a-b").is_some());
        assert!(check_snake("x\"]; fn evil() {").is_some());
        assert!(check_snake("unknown").is_some());
        assert!(check_snake(&"a".repeat(65)).is_some());
    }

    #[test]
    fn sensor_and_command_roles() {
        for crate_name in ["core", "std", "alloc", "rtu", "yosemitech_rtu"] {
            assert!(check_sensor_name(crate_name).is_some(), "{crate_name}");
            assert_eq!(check_command_name(crate_name), None, "{crate_name}");
        }
        for shadowing in ["option", "some", "none", "ok", "err", "from", "iterator", "try_from", "string", "vec"] {
            assert!(check_command_name(shadowing).is_some(), "{shadowing}");
            assert_eq!(check_sensor_name(shadowing), None, "{shadowing}");
        }
        assert_eq!(check_command_name("get_option"), None);
        for method in DEVICE_METHODS {
            assert!(check_command_name(method).is_some(), "{method}");
        }
        for ty in MODULE_TYPES {
            let snake = heck::ToSnakeCase::to_snake_case(*ty);
            assert!(check_snake(&snake).is_some(), "{snake}");
        }
        for constant in MODULE_CONSTS {
            assert!(check_constant_name(&constant.to_lowercase()).is_some(), "{constant}");
        }
        assert_eq!(check_constant_name("module_count"), None);
        for f in MODULE_FUNCTIONS {
            assert!(check_derived_name(f).is_some(), "{f}");
        }
        assert_eq!(check_derived_name("tds_mg_l"), None);
        assert!(check_input_name("exp").is_some());
        assert_eq!(check_input_name("salinity"), None);
        assert_eq!(check_sensor_name("probe_x"), None);
    }
}

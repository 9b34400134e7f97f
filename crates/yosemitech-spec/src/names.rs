//! Rules for names: they become Rust identifiers in generated code.

use heck::{ToShoutySnakeCase, ToUpperCamelCase};

/// Longest name accepted.
pub const MAX_NAME_LEN: usize = 64;

const KEYWORDS: &[&str] = &[
    "as", "async", "await", "break", "const", "continue", "crate", "dyn", "else", "enum", "extern", "false", "fn",
    "for", "gen", "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return", "self",
    "Self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use", "where", "while", "abstract",
    "become", "box", "do", "final", "macro", "override", "priv", "try", "typeof", "unsized", "virtual", "yield",
    "union", "raw", "safe",
];

/// Names the generated code uses itself.
const TAKEN_TYPE_NAMES: &[&str] = &["Command", "Response", "Request", "Unknown", "Device", "Error", "Result"];

/// Why `name` cannot be used, or `None` if it can. `what` says what it names.
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
    let camel = name.to_upper_camel_case();
    if KEYWORDS.contains(&camel.as_str()) || TAKEN_TYPE_NAMES.contains(&camel.as_str()) {
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

/// `name` with control characters escaped, for messages.
pub fn escape(name: &str) -> String {
    name.chars().flat_map(char::escape_debug).take(80).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules() {
        assert_eq!(check_snake("get_ph"), None);
        assert!(check_snake("type").is_some());
        assert!(check_snake("self").is_some());
        assert!(check_snake("Get").is_some());
        assert!(check_snake("a-b").is_some());
        assert!(check_snake("x\"]; fn evil() {").is_some());
        assert!(check_snake("unknown").is_some());
        assert!(check_snake(&"a".repeat(65)).is_some());
    }
}

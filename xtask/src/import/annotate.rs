//! A serialized document made readable for the person who finishes it: each
//! TODO as a `# TODO(import)` comment above the key it concerns (where
//! `cargo xtask validate` reports it by line and column), a blank line
//! between top-level sections and between commands, and register addresses,
//! slave addresses and codes in hex as the manuals print them, and short
//! lists of numbers on one line (`figures: [5, 6]`).
//!
//! It reads only the block-style YAML the serializer writes (one key or item
//! per line, nested by indentation), not YAML in general.

use yosemitech_spec::IMPORT_TODO;

use super::document::Todo;

/// The serializer's settings for drafts: items indented under their key, as
/// the reviewed specs write them.
pub(super) fn yaml_of<T: serde::Serialize>(value: &T) -> Result<String, serde_saphyr::SerializeError> {
    let options = serde_saphyr::ser_options! { compact_list_indent: false };
    serde_saphyr::to_string_with_options(value, options)
}

/// The key paths each line starts (`sensor.serial`, `commands[2]`,
/// `commands[2].name`): an item line starts its item and its first key.
pub(super) fn key_paths(yaml: &str) -> Vec<Vec<String>> {
    // (indent, path, items seen so far under it)
    let mut stack: Vec<(usize, String, usize)> = Vec::new();
    let mut block_scalar_under: Option<usize> = None;
    let mut out = Vec::new();
    for line in yaml.lines() {
        let indent = line.len() - line.trim_start().len();
        let rest = line.trim_start();
        if let Some(key_indent) = block_scalar_under {
            if rest.is_empty() || indent > key_indent {
                out.push(Vec::new());
                continue;
            }
            block_scalar_under = None;
        }
        if rest.is_empty() || rest.starts_with('#') {
            out.push(Vec::new());
            continue;
        }
        while stack.last().is_some_and(|(i, _, _)| *i >= indent) {
            stack.pop();
        }
        let mut starts = Vec::new();
        let (mut indent, mut rest) = (indent, rest);
        if let Some(item) = rest.strip_prefix("- ").or(if rest == "-" { Some("") } else { None }) {
            let parent = stack.last_mut();
            let (parent_path, index) = match parent {
                Some((_, path, items)) => {
                    *items += 1;
                    (path.clone(), *items - 1)
                }
                None => (String::new(), 0),
            };
            let path = format!("{parent_path}[{index}]");
            starts.push(path.clone());
            stack.push((indent, path, 0));
            indent += 2;
            rest = item;
        }
        if let Some((key, value)) = split_key(rest) {
            let parent = stack.last().map_or("", |(_, p, _)| p.as_str());
            let path = if parent.is_empty() { key.to_string() } else { format!("{parent}.{key}") };
            starts.push(path.clone());
            stack.push((indent, path, 0));
            if value.starts_with('|') || value.starts_with('>') {
                block_scalar_under = Some(indent);
            }
        }
        out.push(starts);
    }
    out
}

/// A line's key (unquoted) and value, when it is `key: value` or `key:`.
fn split_key(rest: &str) -> Option<(&str, &str)> {
    let (key, value) = match rest.find(": ") {
        Some(at) => (&rest[..at], rest[at + 2..].trim()),
        None => (rest.strip_suffix(':')?, ""),
    };
    let key = key.trim_matches(|c| c == '"' || c == '\'');
    (!key.is_empty()).then_some((key, value))
}

/// The digits a number at `path` is written with in hex, if it is an address
/// or a code.
fn hex_digits(path: &str) -> Option<usize> {
    let names: Vec<&str> = path.split('.').map(|s| s.split('[').next().unwrap_or(s)).collect();
    match names.as_slice() {
        [.., "values" | "units" | "inputs", _] => None,
        [.., "address"] => Some(4),
        [.., "fixed_slave"] => Some(2),
        [.., "flags", "mask"] | [.., "variants", "value"] => Some(2),
        _ => None,
    }
}

/// `yaml` with the TODO comments, blank lines and hex numbers. A TODO whose
/// key is not in the text is written at the top, so none is lost.
pub(super) fn annotate(yaml: &str, todos: &[Todo]) -> String {
    let paths = key_paths(yaml);
    let first_line_of = |at: &str| paths.iter().position(|starts| starts.iter().any(|p| p == at));
    let mut above: Vec<Vec<&str>> = vec![Vec::new(); paths.len().max(1)];
    for t in todos {
        let line = first_line_of(&t.at).unwrap_or(0);
        above[line].push(&t.text);
    }
    let lines: Vec<&str> = yaml.lines().collect();
    let mut out = String::new();
    let mut folded = 0..0;
    for (k, &line) in lines.iter().enumerate() {
        if folded.contains(&k) {
            continue;
        }
        let starts = paths.get(k).map_or(&[][..], Vec::as_slice);
        let indent = line.len() - line.trim_start().len();
        let top_level = indent == 0 && !line.starts_with('-') && !line.starts_with('#') && !line.is_empty();
        let command_item = starts.first().is_some_and(|p| is_later_command(p));
        if k > 0 && (top_level || command_item) {
            out.push('\n');
        }
        for text in above.get(k).into_iter().flatten() {
            out.push_str(&format!("{}# {IMPORT_TODO}: {text}\n", " ".repeat(indent)));
        }
        match number_list(&lines, k, &above) {
            Some((numbers, end)) => {
                out.push_str(&format!("{line} [{}]", numbers.join(", ")));
                folded = k + 1..end;
            }
            None => out.push_str(&in_hex(line, starts.last().map(String::as_str))),
        }
        out.push('\n');
    }
    out
}

/// A key whose value is a block list of plain numbers with no TODO among
/// them (`figures:` then `- 5`, `- 6`): the numbers and the line after the
/// list, to write it as the reviewed specs do (`figures: [5, 6]`).
fn number_list(lines: &[&str], key: usize, above: &[Vec<&str>]) -> Option<(Vec<String>, usize)> {
    let line = lines[key];
    let rest = line.trim_start();
    // `- figures:` starts an item: its key is two columns in.
    let indent = line.len() - rest.len() + if rest.starts_with("- ") { 2 } else { 0 };
    if !line.ends_with(':') || rest.starts_with('#') {
        return None;
    }
    let dash = format!("{}- ", " ".repeat(indent + 2));
    let mut numbers = Vec::new();
    let mut end = key + 1;
    while let Some(item) = lines.get(end).and_then(|l| l.strip_prefix(&dash)) {
        if item.parse::<f64>().is_err() || above.get(end).is_some_and(|t| !t.is_empty()) {
            return None;
        }
        numbers.push(item.to_owned());
        end += 1;
    }
    (!numbers.is_empty()).then_some((numbers, end))
}

/// `commands[N]`, N > 0: a command after the file's first.
fn is_later_command(path: &str) -> bool {
    path.strip_prefix("commands[")
        .and_then(|r| r.strip_suffix(']'))
        .is_some_and(|n| n.parse::<usize>().is_ok_and(|n| n > 0))
}

fn in_hex(line: &str, path: Option<&str>) -> String {
    let Some(digits) = path.and_then(hex_digits) else { return line.to_string() };
    let Some((head, number)) = line.rsplit_once(": ") else { return line.to_string() };
    match number.parse::<u32>() {
        Ok(n) => format!("{head}: 0x{n:0digits$X}"),
        Err(_) => line.to_string(),
    }
}

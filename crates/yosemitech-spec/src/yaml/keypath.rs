//! The key path (`commands[0] (get_ph).count`) of a position, from any
//! well-formed YAML, for errors the typed parse reports without one.

use super::load::{Duplicates, Node, Value, parse};
use crate::diag::Pos;
use crate::names::{check_snake, escape};

/// Every key and value of a document with its position and key path.
pub(super) struct KeyPaths(Vec<(Pos, String)>);

impl KeyPaths {
    /// The key paths of `text`, if it is well-formed YAML (within the limits).
    pub(super) fn of(text: &str) -> Option<Self> {
        let root = parse(text, Duplicates::LastWins).ok()?;
        let mut out = Vec::new();
        walk(&root, String::new(), &mut out);
        out.sort_by_key(|(pos, _)| *pos);
        Some(Self(out))
    }

    /// The key path of the key or value written exactly at `pos`.
    pub(super) fn exact(&self, pos: Pos) -> Option<String> {
        self.0.iter().rev().find(|(p, _)| *p == pos).map(|(_, path)| path.clone())
    }

    /// The key path at `pos` (the last key or value starting at or before
    /// it). With `parent`, the path of the mapping holding that key instead,
    /// and where that mapping's key is written.
    pub(super) fn at(&self, pos: Pos, parent: bool) -> Option<(Pos, String)> {
        let (at, path) = self.0.iter().rev().find(|(p, _)| *p <= pos)?;
        if !parent {
            return Some((*at, path.clone()));
        }
        let up = parent_path(path)?;
        let start = self.0.iter().find(|(_, p)| *p == up).map_or(*at, |(p, _)| *p);
        Some((start, up))
    }
}

/// `a.b[2] (x).c` -> `a.b[2] (x)`; `a.b[2] (x)` -> `a.b`.
pub(super) fn parent_path(path: &str) -> Option<String> {
    match path.rfind(['.', '[']) {
        Some(i) => path.get(..i).map(str::to_string),
        None if path.is_empty() => None,
        None => Some(String::new()),
    }
}

fn walk(node: &Node, path: String, out: &mut Vec<(Pos, String)>) {
    out.push((node.referenced, path.clone()));
    match &node.value {
        Value::List(items) => {
            for (i, item) in items.iter().enumerate() {
                // Entries with a valid `name` (or `use`) are shown by it: `commands[3] (get_ph)`.
                let name = match &item.value {
                    Value::Map(entries) => entries.iter().find_map(|(k, v)| {
                        let (key, name) = (k.name()?, v.name()?);
                        ((key == "name" || key == "use") && check_snake(name).is_none()).then(|| name.to_owned())
                    }),
                    _ => None,
                };
                let item_path = match name {
                    Some(n) => format!("{path}[{i}] ({n})"),
                    None => format!("{path}[{i}]"),
                };
                walk(item, item_path, out);
            }
        }
        Value::Map(entries) => {
            for (k, v) in entries {
                let key = escape(k.name().unwrap_or_default());
                let key_path = if path.is_empty() { key } else { format!("{path}.{key}") };
                out.push((k.referenced, key_path.clone()));
                walk(v, key_path, out);
            }
        }
        Value::Scalar(_) => {}
    }
}

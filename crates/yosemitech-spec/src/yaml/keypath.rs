//! The key path (`commands[0] (get_ph).count`) of a position, from any
//! well-formed YAML, for errors the typed parse reports without one.

use std::fmt;

use serde::Deserialize;
use serde::de::{self, MapAccess, SeqAccess, Visitor};
use serde_saphyr::DuplicateKeyPolicy;

use super::limits::options;
use crate::Spanned;
use crate::diag::Pos;
use crate::names::{check_snake, escape};

/// Any YAML node, with positions: used to tell the key path of a position
/// when the typed parse fails.
enum Node {
    Map(Vec<(Spanned<Scalar>, Spanned<Node>)>),
    Seq(Vec<Spanned<Node>>),
    Scalar(String),
}

/// A scalar of any type, as text.
struct Scalar(String);

struct ScalarVisitor;

impl Visitor<'_> for ScalarVisitor {
    type Value = Scalar;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a scalar")
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Scalar, E> {
        Ok(Scalar(v.to_owned()))
    }
    fn visit_bool<E: de::Error>(self, v: bool) -> Result<Scalar, E> {
        Ok(Scalar(v.to_string()))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Scalar, E> {
        Ok(Scalar(v.to_string()))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Scalar, E> {
        Ok(Scalar(v.to_string()))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Scalar, E> {
        Ok(Scalar(v.to_string()))
    }
    fn visit_unit<E: de::Error>(self) -> Result<Scalar, E> {
        Ok(Scalar(String::new()))
    }
}

impl<'de> Deserialize<'de> for Scalar {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ScalarVisitor)
    }
}

struct NodeVisitor;

impl<'de> Visitor<'de> for NodeVisitor {
    type Value = Node;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("any YAML node")
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_owned()))
    }
    fn visit_bool<E: de::Error>(self, v: bool) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_string()))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_string()))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_string()))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Node, E> {
        Ok(Node::Scalar(v.to_string()))
    }
    fn visit_unit<E: de::Error>(self) -> Result<Node, E> {
        Ok(Node::Scalar(String::new()))
    }
    fn visit_none<E: de::Error>(self) -> Result<Node, E> {
        Ok(Node::Scalar(String::new()))
    }
    fn visit_some<D: de::Deserializer<'de>>(self, d: D) -> Result<Node, D::Error> {
        Node::deserialize(d)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Node, A::Error> {
        let mut items = Vec::new();
        while let Some(item) = seq.next_element()? {
            items.push(item);
        }
        Ok(Node::Seq(items))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Node, A::Error> {
        let mut entries = Vec::new();
        while let Some(entry) = map.next_entry()? {
            entries.push(entry);
        }
        Ok(Node::Map(entries))
    }
}

impl<'de> Deserialize<'de> for Node {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(NodeVisitor)
    }
}

/// Every key and value of a document with its position and key path.
pub(super) struct KeyPaths(Vec<(Pos, String)>);

impl KeyPaths {
    /// The key paths of `text`, if it is well-formed YAML (within the limits).
    pub(super) fn of(text: &str) -> Option<Self> {
        let mut options = options();
        options.duplicate_keys = DuplicateKeyPolicy::LastWins;
        options.non_finite_float_policy = serde_saphyr::NonFiniteFloatPolicy::PassThrough;
        let root = serde_saphyr::from_str_with_options::<Spanned<Node>>(text, options).ok()?;
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

fn walk(node: &Spanned<Node>, path: String, out: &mut Vec<(Pos, String)>) {
    out.push((Pos::at(node), path.clone()));
    match &node.value {
        Node::Scalar(_) => {}
        Node::Seq(items) => {
            for (i, item) in items.iter().enumerate() {
                // Entries with a valid `name` (or `use`) are shown by it: `commands[3] (get_ph)`.
                let name = match &item.value {
                    Node::Map(entries) => entries.iter().find_map(|(k, v)| match &v.value {
                        Node::Scalar(s) if (k.value.0 == "name" || k.value.0 == "use") && check_snake(s).is_none() => {
                            Some(s.clone())
                        }
                        _ => None,
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
        Node::Map(entries) => {
            for (k, v) in entries {
                let key = escape(&k.value.0);
                let key_path = if path.is_empty() { key } else { format!("{path}.{key}") };
                out.push((Pos::at(k), key_path.clone()));
                walk(v, key_path, out);
            }
        }
    }
}

//! A spec file's YAML as a tree of located nodes, built from the parser's
//! events under the limits of [`super::limits`].
//!
//! Scalars are kept as written (text, plain or quoted, tag): what a scalar
//! means depends on what the document asks of it (`scalar`), as in YAML
//! 1.2's core schema read by type.

use std::collections::HashMap;

use granit_parser::{ErrorKind, Event, Parser, ScalarStyle, ScanError, Span};

use super::error::{Error, Kind, Limit};
use super::limits::{MAX_ALIAS_REPLAY, MAX_YAML_ALIASES, MAX_YAML_DEPTH, MAX_YAML_NODES};
use crate::diag::Pos;

/// A YAML node, where it is used (an alias's place, or its own) and where
/// it is written.
#[derive(Clone, Debug)]
pub(super) struct Node {
    pub value: Value,
    pub referenced: Pos,
    pub defined: Pos,
}

#[derive(Clone, Debug)]
pub(super) enum Value {
    Scalar(Scalar),
    List(Vec<Node>),
    Map(Vec<(Node, Node)>),
}

/// A scalar as written.
#[derive(Clone, Debug)]
pub(super) struct Scalar {
    /// The text, quotes and escapes resolved.
    pub text: String,
    /// Written without quotes or block indicator: only a plain scalar can
    /// mean null, a boolean or a number when read as any value.
    pub plain: bool,
    /// The tag: a core-schema suffix (`str`, `int`, ...) or the tag as written.
    pub tag: Option<String>,
}

/// Whether a key written twice in one mapping is an error or the last wins
/// (for finding key paths in a file whose error is elsewhere).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Duplicates {
    Refuse,
    LastWins,
}

/// The tree of `text`: its one document, or an empty scalar (null) for none.
pub(super) fn parse(text: &str, duplicates: Duplicates) -> Result<Node, Error> {
    let options = granit_parser::options! {
        flow_nesting_limit: MAX_YAML_DEPTH,
        block_nesting_limit: MAX_YAML_DEPTH,
    };
    let mut builder =
        Builder { duplicates, stack: Vec::new(), anchors: HashMap::new(), root: None, counts: Counts::default() };
    let mut documents = 0;
    for event in Parser::new_from_str_with_options(text, options) {
        let (event, span) = event.map_err(syntax)?;
        let at = pos(&span);
        match event {
            Event::DocumentStart(..) => {
                documents += 1;
                if documents > 1 {
                    return Err(Error::new(Kind::MultipleDocuments, at));
                }
            }
            Event::Scalar(text, style, anchor, tag) => {
                let tag = tag.map(|tag| tag.core_suffix().map_or_else(|| tag.original(), str::to_owned));
                let scalar = Scalar { text: text.into_owned(), plain: matches!(style, ScalarStyle::Plain), tag };
                builder.count(at)?;
                builder.complete(Node { value: Value::Scalar(scalar), referenced: at, defined: at }, anchor)?;
            }
            Event::SequenceStart(_, anchor, _) => builder.open(Open::List(Vec::new()), anchor, at)?,
            Event::MappingStart(_, anchor, _) => builder.open(Open::Map(OpenMap::default()), anchor, at)?,
            Event::SequenceEnd | Event::MappingEnd => builder.close()?,
            Event::Alias(id) => builder.alias(id, at)?,
            Event::UnresolvedAlias(_) => return Err(Error::new(Kind::UnknownAnchor, at)),
            _ => {}
        }
    }
    Ok(builder.root.unwrap_or(Node {
        value: Value::Scalar(Scalar { text: String::new(), plain: true, tag: None }),
        referenced: Pos { line: 1, column: 1 },
        defined: Pos { line: 1, column: 1 },
    }))
}

impl Node {
    pub(super) fn scalar(&self) -> Option<&Scalar> {
        match &self.value {
            Value::Scalar(s) => Some(s),
            Value::List(_) | Value::Map(_) => None,
        }
    }

    pub(super) fn is_null(&self) -> bool {
        self.scalar().is_some_and(Scalar::is_null)
    }

    /// The text of a scalar, as a key or a variant name is read.
    pub(super) fn name(&self) -> Option<&str> {
        self.scalar().map(|s| s.text.as_str())
    }
}

fn pos(span: &Span) -> Pos {
    place(span.start.line(), span.start.col())
}

/// The 1-based place of the parser's line (1-based) and column (0-based).
fn place(line: usize, column: usize) -> Pos {
    let number = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    Pos { line: number(line), column: number(column.saturating_add(1)) }
}

fn syntax(e: ScanError) -> Error {
    let at = place(e.marker().line(), e.marker().col());
    match e.kind() {
        ErrorKind::UnknownAnchor => Error::new(Kind::UnknownAnchor, at),
        ErrorKind::MultipleDocumentsUnsupported => Error::new(Kind::MultipleDocuments, at),
        _ => Error::new(Kind::Syntax { msg: e.info() }, at),
    }
}

/// A collection being read.
enum Open {
    List(Vec<Node>),
    Map(OpenMap),
}

/// A mapping being read: its entries, where each scalar key's entry is (so
/// that a mapping of many keys costs no quadratic search), and a key
/// waiting for its value.
#[derive(Default)]
struct OpenMap {
    entries: Vec<(Node, Node)>,
    index: HashMap<String, usize>,
    key: Option<Node>,
}

struct Frame {
    open: Open,
    anchor: usize,
    at: Pos,
}

#[derive(Default)]
struct Counts {
    nodes: usize,
    aliases: usize,
    replayed: usize,
}

struct Builder {
    duplicates: Duplicates,
    stack: Vec<Frame>,
    /// Each anchored node, and how many nodes it holds.
    anchors: HashMap<usize, (Node, usize)>,
    root: Option<Node>,
    counts: Counts,
}

impl Builder {
    fn count(&mut self, at: Pos) -> Result<(), Error> {
        self.counts.nodes += 1;
        if self.counts.nodes > MAX_YAML_NODES {
            return Err(Error::new(Kind::Limit { limit: Limit::Nodes }, at));
        }
        Ok(())
    }

    fn open(&mut self, open: Open, anchor: usize, at: Pos) -> Result<(), Error> {
        self.count(at)?;
        if self.stack.len() >= MAX_YAML_DEPTH {
            return Err(Error::new(Kind::Limit { limit: Limit::Depth }, at));
        }
        self.stack.push(Frame { open, anchor, at });
        Ok(())
    }

    fn close(&mut self) -> Result<(), Error> {
        let Some(Frame { open, anchor, at }) = self.stack.pop() else { return Ok(()) };
        let value = match open {
            Open::List(items) => Value::List(items),
            Open::Map(map) => Value::Map(map.entries),
        };
        self.complete(Node { value, referenced: at, defined: at }, anchor)
    }

    /// A copy of an anchored node, used at `at`: every node in it is used there.
    fn alias(&mut self, id: usize, at: Pos) -> Result<(), Error> {
        self.counts.aliases += 1;
        if self.counts.aliases > MAX_YAML_ALIASES {
            return Err(Error::new(Kind::Limit { limit: Limit::Aliases }, at));
        }
        let Some((node, size)) = self.anchors.get(&id) else { return Err(Error::new(Kind::UnknownAnchor, at)) };
        let size = *size;
        self.counts.replayed = self.counts.replayed.saturating_add(size);
        if self.counts.replayed > MAX_ALIAS_REPLAY {
            return Err(Error::new(Kind::Limit { limit: Limit::AliasReplay }, at));
        }
        self.counts.nodes = self.counts.nodes.saturating_add(size);
        if self.counts.nodes > MAX_YAML_NODES {
            return Err(Error::new(Kind::Limit { limit: Limit::Nodes }, at));
        }
        let mut copy = node.clone();
        used_at(&mut copy, at);
        self.complete(copy, 0)
    }

    /// A node read whole: into its collection, or the document's root.
    fn complete(&mut self, node: Node, anchor: usize) -> Result<(), Error> {
        if anchor != 0 {
            if self.anchors.len() >= MAX_YAML_ALIASES {
                return Err(Error::new(Kind::Limit { limit: Limit::Anchors }, node.defined));
            }
            self.anchors.insert(anchor, (node.clone(), size(&node)));
        }
        let Some(frame) = self.stack.last_mut() else {
            self.root = Some(node);
            return Ok(());
        };
        match &mut frame.open {
            Open::List(items) => items.push(node),
            Open::Map(OpenMap { key: key @ None, .. }) => *key = Some(node),
            Open::Map(OpenMap { entries, index, key }) => {
                let Some(key) = key.take() else { return Ok(()) };
                // Only a scalar key can be written twice: a collection as a
                // key is refused by every document type.
                let Some(name) = key.name().map(str::to_owned) else {
                    entries.push((key, node));
                    return Ok(());
                };
                match index.get(&name) {
                    Some(_) if self.duplicates == Duplicates::Refuse => {
                        return Err(Error::new(Kind::DuplicateKey { key: name }, key.referenced));
                    }
                    Some(&i) => {
                        if let Some(entry) = entries.get_mut(i) {
                            *entry = (key, node);
                        }
                    }
                    None => {
                        index.insert(name, entries.len());
                        entries.push((key, node));
                    }
                }
            }
        }
        Ok(())
    }
}

fn size(node: &Node) -> usize {
    1 + match &node.value {
        Value::Scalar(_) => 0,
        Value::List(items) => items.iter().map(size).sum(),
        Value::Map(entries) => entries.iter().map(|(k, v)| size(k) + size(v)).sum(),
    }
}

fn used_at(node: &mut Node, at: Pos) {
    node.referenced = at;
    match &mut node.value {
        Value::Scalar(_) => {}
        Value::List(items) => items.iter_mut().for_each(|item| used_at(item, at)),
        Value::Map(entries) => entries.iter_mut().for_each(|(k, v)| {
            used_at(k, at);
            used_at(v, at);
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(node: &Node) -> Vec<(String, String)> {
        let Value::Map(entries) = &node.value else { panic!("not a mapping: {node:?}") };
        let text = |n: &Node| n.name().unwrap_or("?").to_owned();
        entries.iter().map(|(k, v)| (text(k), text(v))).collect()
    }

    #[test]
    fn a_key_written_twice_is_refused_where_it_is_written_again_or_the_last_wins() {
        let text = "a: 1\nb: 2\na: 3\n";
        match parse(text, Duplicates::Refuse) {
            Err(Error { kind: Kind::DuplicateKey { key }, at }) => {
                assert_eq!((key.as_str(), at), ("a", Pos { line: 3, column: 1 }));
            }
            other => panic!("{other:?}"),
        }
        let Ok(root) = parse(text, Duplicates::LastWins) else { panic!("no tree") };
        assert_eq!(entries(&root), [("a".into(), "3".into()), ("b".into(), "2".into())]);
    }

    #[test]
    fn a_mapping_of_many_keys_is_read_whole() {
        // Near the node limit: a quadratic duplicate search would not finish.
        let keys = MAX_YAML_NODES / 2 - 1;
        let text: String = (0..keys).map(|i| format!("k{i}: {i}\n")).collect();
        let Ok(root) = parse(&text, Duplicates::Refuse) else { panic!("refused") };
        assert_eq!(entries(&root).len(), keys);
        let over: String = format!("{text}x: 1\ny: 2\n");
        assert!(matches!(
            parse(&over, Duplicates::Refuse),
            Err(Error { kind: Kind::Limit { limit: Limit::Nodes }, .. })
        ));
    }

    #[test]
    fn every_node_of_an_aliased_value_is_used_at_the_alias() {
        let Ok(root) = parse("a: &x {b: [1]}\nc: *x\n", Duplicates::Refuse) else { panic!("refused") };
        let Value::Map(top) = &root.value else { panic!("not a mapping") };
        let Some((_, used)) = top.last() else { panic!("empty") };
        let Value::Map(inner) = &used.value else { panic!("not a mapping") };
        let Some((key, list)) = inner.first() else { panic!("empty") };
        let Value::List(items) = &list.value else { panic!("not a list") };
        let alias = Pos { line: 2, column: 4 };
        for node in [used, key, list].into_iter().chain(items) {
            assert_eq!(node.referenced, alias, "{node:?}");
            assert_eq!(node.defined.line, 1, "{node:?}");
        }
    }
}

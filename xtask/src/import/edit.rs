//! The text of a spec file, edited in place: `--into` keeps every line of
//! the original (comments, anchors, flow mappings, the author's order) and
//! only inserts or replaces lines, so that the merge reads as a short diff.
//!
//! Spec files are block-style YAML with flow mappings for small values
//! (`source: {section: ..}`), as `docs/spec-language.md` writes them. This
//! module finds keys and list items by indentation; a value it cannot find
//! in that shape is reported, never guessed at.

use std::collections::{BTreeMap, BTreeSet};

/// Lines of a block: `start..end` (0-based, end exclusive, trailing blank
/// and comment lines excluded), whose keys sit at `indent`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Span {
    /// First line (a list item's dash line, or the first line of a mapping's body).
    pub start: usize,
    /// One past the last line.
    pub end: usize,
    /// Indentation of the block's keys.
    pub indent: usize,
}

/// A key of a block mapping.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Key {
    /// Its line.
    pub line: usize,
    /// Its indentation.
    pub indent: usize,
    /// One past the last line of its value.
    pub end: usize,
    /// The text after `key:` on its line, trimmed (empty for a block value).
    pub inline: String,
}

impl Key {
    /// The block under the key (for a nested mapping), with its indentation.
    pub fn body(&self, lines: &[String]) -> Span {
        let indent =
            (self.line + 1..self.end).find(|&i| !filler(&lines[i])).map_or(self.indent + 2, |i| indent_of(&lines[i]));
        Span { start: self.line + 1, end: self.end, indent }
    }
}

/// Leading spaces.
pub(crate) fn indent_of(line: &str) -> usize {
    line.len() - line.trim_start_matches(' ').len()
}

/// A blank or comment-only line.
pub(crate) fn filler(line: &str) -> bool {
    let t = line.trim();
    t.is_empty() || t.starts_with('#')
}

/// The key written at `indent` on `line` (`key: ...`, or `- key: ...` with
/// the dash two columns left of it), and the text after the colon.
fn key_on(line: &str, indent: usize) -> Option<(&str, &str)> {
    let lead = indent_of(line);
    let rest = if lead == indent {
        &line[lead..]
    } else if lead + 2 == indent && line[lead..].starts_with("- ") {
        &line[lead + 2..]
    } else {
        return None;
    };
    let end = rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))?;
    let (name, after) = rest.split_at(end);
    let after = after.strip_prefix(':')?;
    if !name.is_empty() && (after.is_empty() || after.starts_with(' ')) { Some((name, after.trim())) } else { None }
}

/// The end of the value of the key on line `at` (keys at `indent`): the
/// lines below that are deeper, or a block list written at the key's own
/// indentation, trailing filler excluded.
fn value_end(lines: &[String], at: usize, indent: usize, limit: usize) -> usize {
    let mut end = at + 1;
    let mut i = at + 1;
    while i < limit {
        let l = &lines[i];
        if filler(l) {
            // A comment as deep as the key or shallower ends nothing, but
            // does not belong to this value if nothing deeper follows.
            i += 1;
            continue;
        }
        let lead = indent_of(l);
        let dash_at_key = lead == indent && l[lead..].starts_with('-');
        if lead > indent || dash_at_key {
            i += 1;
            end = i;
        } else {
            break;
        }
    }
    end
}

/// The key `name` of the mapping `within`.
pub(crate) fn find_key(lines: &[String], within: Span, name: &str) -> Option<Key> {
    for i in within.start..within.end {
        if let Some((k, inline)) = key_on(&lines[i], within.indent)
            && k == name
        {
            let end = value_end(lines, i, within.indent, within.end);
            return Some(Key { line: i, indent: within.indent, end, inline: inline.to_string() });
        }
    }
    None
}

/// The whole file as a mapping.
pub(crate) fn root(lines: &[String]) -> Span {
    Span { start: 0, end: lines.len(), indent: 0 }
}

/// The items of the block list under `key`, each a mapping span.
pub(crate) fn items(lines: &[String], key: &Key) -> Vec<Span> {
    let Some(dash) = (key.line + 1..key.end).find(|&i| !filler(&lines[i])).map(|i| indent_of(&lines[i])) else {
        return Vec::new();
    };
    let starts: Vec<usize> = (key.line + 1..key.end)
        .filter(|&i| indent_of(&lines[i]) == dash && lines[i][dash..].starts_with('-') && !filler(&lines[i]))
        .collect();
    let mut out = Vec::new();
    for (k, &s) in starts.iter().enumerate() {
        let next = starts.get(k + 1).copied().unwrap_or(key.end);
        let mut end = next;
        while end > s + 1 && filler(&lines[end - 1]) {
            end -= 1;
        }
        out.push(Span { start: s, end, indent: dash + 2 });
    }
    out
}

/// The value of a scalar key on one line, unquoted (`name: get_ph`, `since: "1.8"`).
pub(crate) fn scalar(key: &Key) -> String {
    let v = key.inline.split(" #").next().unwrap_or("").trim();
    v.trim_matches('"').trim_matches('\'').to_string()
}

/// The name of a `commands:` item: its `name:` or `use:`.
pub(crate) fn item_name(lines: &[String], item: Span) -> Option<String> {
    find_key(lines, item, "name").or_else(|| find_key(lines, item, "use")).map(|k| scalar(&k))
}

/// Insertions and replacements, applied together so that line numbers
/// stay those of the original while they are planned.
#[derive(Debug, Default)]
pub(crate) struct Edits {
    /// Lines to insert before a line.
    before: BTreeMap<usize, Vec<(usize, Vec<String>)>>,
    /// Blocks to insert after a line: (depth, lines), deeper ones first.
    after: BTreeMap<usize, Vec<(usize, usize, Vec<String>)>>,
    /// Replaced lines.
    replace: BTreeMap<usize, String>,
    /// Removed lines.
    remove: BTreeSet<usize>,
    /// Insertion order, to keep blocks of the same depth in the order planned.
    seq: usize,
}

/// An inserted block, located in the output.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Placed {
    /// The block's tag (what it is, for messages).
    pub tag: usize,
    /// Its first line in the output (0-based).
    pub start: usize,
    /// One past its last line.
    pub end: usize,
}

impl Edits {
    /// Inserts `block` (already indented) after line `at`; among blocks
    /// after the same line, deeper ones (`depth`, the indentation) go first,
    /// so that a key appended to a list's last item stays inside it.
    pub fn after(&mut self, at: usize, depth: usize, block: Vec<String>) -> usize {
        self.seq += 1;
        self.after.entry(at).or_default().push((depth, self.seq, block));
        self.seq
    }

    /// Inserts `block` before line `at`.
    pub fn before(&mut self, at: usize, block: Vec<String>) -> usize {
        self.seq += 1;
        self.before.entry(at).or_default().push((self.seq, block));
        self.seq
    }

    /// Replaces line `at`.
    pub fn replace(&mut self, at: usize, line: String) {
        self.replace.insert(at, line);
    }

    /// Removes lines `start..end` (the tests take revisions out of a spec with it).
    #[cfg(test)]
    pub fn remove(&mut self, start: usize, end: usize) {
        self.remove.extend(start..end);
    }

    /// True when nothing is planned.
    pub fn is_empty(&self) -> bool {
        self.before.is_empty() && self.after.is_empty() && self.replace.is_empty() && self.remove.is_empty()
    }

    /// The edited lines, and where each inserted block (by the number its
    /// insertion returned) and each replaced line landed.
    pub fn apply(&self, lines: &[String]) -> (Vec<String>, Vec<Placed>) {
        let mut out = Vec::with_capacity(lines.len() + 64);
        let mut placed = Vec::new();
        let mut put = |out: &mut Vec<String>, tag: usize, block: &[String]| {
            let start = out.len();
            out.extend(block.iter().cloned());
            placed.push(Placed { tag, start, end: out.len() });
        };
        let last = lines.len().saturating_sub(1);
        for (i, line) in lines.iter().enumerate() {
            if let Some(blocks) = self.before.get(&i) {
                for (tag, b) in blocks {
                    put(&mut out, *tag, b);
                }
            }
            if !self.remove.contains(&i) {
                match self.replace.get(&i) {
                    Some(r) => put(&mut out, 0, std::slice::from_ref(r)),
                    None => out.push(line.clone()),
                }
            }
            self.put_after(i, &mut out, &mut put);
        }
        if lines.is_empty() {
            self.put_after(last, &mut out, &mut put);
        }
        (out, placed)
    }

    fn put_after(&self, i: usize, out: &mut Vec<String>, put: &mut impl FnMut(&mut Vec<String>, usize, &[String])) {
        if let Some(blocks) = self.after.get(&i) {
            let mut sorted: Vec<&(usize, usize, Vec<String>)> = blocks.iter().collect();
            sorted.sort_by_key(|(depth, seq, _)| (std::cmp::Reverse(*depth), *seq));
            for (_, seq, b) in sorted {
                put(out, *seq, b);
            }
        }
    }
}

/// `text` as lines.
pub(crate) fn lines_of(text: &str) -> Vec<String> {
    text.lines().map(str::to_owned).collect()
}

/// Lines back to text, with a final newline.
pub(crate) fn text_of(lines: &[String]) -> String {
    let mut s = lines.join("\n");
    s.push('\n');
    s
}

/// `block` (lines written at indent 0 for a list item `- ...`) moved to `indent`.
pub(crate) fn indented(block: &str, indent: usize) -> Vec<String> {
    let pad = " ".repeat(indent);
    block.lines().map(|l| if l.is_empty() { String::new() } else { format!("{pad}{l}") }).collect()
}

/// A TODO comment line at `indent`.
pub(crate) fn todo_line(indent: usize, text: &str) -> String {
    format!("{}# {}: {}", " ".repeat(indent), yosemitech_spec::IMPORT_TODO, super::one_line_text(text))
}

/// The `commands:` items by name.
fn command_items(lines: &[String]) -> Vec<(String, Span)> {
    let Some(commands) = find_key(lines, root(lines), "commands") else { return Vec::new() };
    items(lines, &commands).into_iter().filter_map(|it| Some((item_name(lines, it)?, it))).collect()
}

/// Whether a list item opens a flow mapping (`- {..}`), which this module does not edit inside.
fn flow_item(lines: &[String], item: Span) -> bool {
    lines[item.start].trim_start().trim_start_matches('-').trim_start().starts_with('{')
}

/// Appends `item` (YAML at indent 0) to the block list under the key `name`
/// of the mapping `within`, creating the key after `anchor_end` when absent.
fn append_item(
    lines: &[String],
    e: &mut Edits,
    within: Span,
    name: &str,
    item: &str,
    anchor_end: usize,
) -> Result<(), String> {
    match find_key(lines, within, name) {
        Some(k) if k.inline.is_empty() => {
            let its = items(lines, &k);
            let Some(last) = its.last() else {
                e.after(k.line, within.indent + 2, indented(item, within.indent + 2));
                return Ok(());
            };
            let dash = last.indent - 2;
            e.after(last.end - 1, dash + 1, indented(item, dash));
            Ok(())
        }
        Some(k) if k.inline == "[]" => {
            e.replace(k.line, format!("{}{name}:", " ".repeat(within.indent)));
            e.after(k.line, within.indent + 2, indented(item, within.indent + 2));
            Ok(())
        }
        Some(k) => Err(format!("`{name}` at line {} is written in flow style (`{}`)", k.line + 1, k.inline)),
        None => {
            let mut block = vec![format!("{}{name}:", " ".repeat(within.indent))];
            block.extend(indented(item, within.indent + 2));
            e.after(anchor_end.saturating_sub(1), within.indent, block);
            Ok(())
        }
    }
}

/// Plans the text edits of a merge; what cannot be placed in the text is
/// returned as TODOs about the file.
pub(crate) fn apply_plan(lines: &[String], plan: &super::merge::Plan) -> (Edits, Vec<String>) {
    let mut e = Edits::default();
    let mut todos: Vec<String> = Vec::new();
    let r = root(lines);
    let Some(sensor) = find_key(lines, r, "sensor") else {
        todos.push("the spec has no `sensor:` block to merge into".into());
        return (e, todos);
    };
    let body = sensor.body(lines);
    let manual_key = find_key(lines, body, "manual");
    // The revision entry.
    if let Some(rev) = &plan.revision {
        let anchor = manual_key.as_ref().map_or(body.end, |m| m.end);
        if let Err(why) = append_item(lines, &mut e, body, "revisions", rev, anchor) {
            todos.push(format!("add this manual to `sensor.revisions` by hand: {why}"));
        }
    }
    // A claim on a recorded manual.
    if let Some((which, item)) = &plan.claim {
        let target = match which {
            None => manual_key.clone(),
            Some(i) => find_key(lines, body, "revisions")
                .and_then(|k| items(lines, &k).get(*i).copied())
                .and_then(|it| find_key(lines, it, "manual")),
        };
        match target {
            Some(m) if m.inline.is_empty() => {
                if let Err(why) = append_item(lines, &mut e, m.body(lines), "serial_claims", item, m.end) {
                    todos.push(format!("add the serial claim by hand: {why}"));
                }
            }
            _ => todos
                .push(format!("add `serial_claims: [{}]` to the manual by hand", item.trim().trim_start_matches("- "))),
        }
    }
    let cmds = command_items(lines);
    let find = |name: &str| cmds.iter().find(|(n, _)| n == name).map(|(_, s)| *s);
    for (name, edit) in &plan.commands {
        let Some(item) = find(name) else {
            todos.push(format!(
                "`{name}` comes from an included fragment without a `use: {name}` entry here; add one for SW {}'s changes: {}",
                plan.software,
                [
                    edit.since.as_ref().map(|s| format!("since \"{s}\"")),
                    (!edit.citations.is_empty()).then(|| format!("{} citations", edit.citations.len())),
                    (!edit.examples.is_empty()).then(|| format!("{} examples", edit.examples.len())),
                ]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>()
                .join(", ")
            ));
            todos.extend(edit.todos.iter().map(|t| format!("{name}: {t}")));
            continue;
        };
        let pad = item.indent;
        for t in &edit.todos {
            e.before(item.start, vec![todo_line(pad - 2, t)]);
        }
        if flow_item(lines, item) {
            if edit.since.is_some()
                || !edit.citations.is_empty()
                || !edit.examples.is_empty()
                || !edit.errata.is_empty()
            {
                e.before(
                    item.start,
                    vec![todo_line(
                        pad - 2,
                        &format!("merge SW {}'s changes into this flow-style entry by hand", plan.software),
                    )],
                );
            }
            continue;
        }
        if let Some(since) = &edit.since {
            let line = format!("{}since: {}", " ".repeat(pad), super::q(since));
            match find_key(lines, item, "since") {
                Some(k) => e.replace(k.line, line),
                None => {
                    e.after(item.start, pad, vec![line]);
                }
            }
        }
        let examples = find_key(lines, item, "examples");
        if !edit.citations.is_empty() {
            let ex_items = examples.as_ref().map(|k| items(lines, k)).unwrap_or_default();
            for (j, figures) in &edit.citations {
                let cite = super::merge::citation_item(&plan.software, figures);
                match ex_items.get(*j) {
                    Some(x) if !flow_item(lines, *x) => {
                        if let Err(why) = append_item(lines, &mut e, *x, "also_in", &cite, x.end) {
                            e.before(
                                item.start,
                                vec![todo_line(
                                    pad - 2,
                                    &format!(
                                        "cite SW {}'s figures {} by hand: {why}",
                                        plan.software,
                                        figures.join(", ")
                                    ),
                                )],
                            );
                        }
                    }
                    _ => {
                        e.before(
                            item.start,
                            vec![todo_line(
                                pad - 2,
                                &format!(
                                    "example {} is not a block entry: cite SW {}'s figures {} by hand",
                                    j + 1,
                                    plan.software,
                                    figures.join(", ")
                                ),
                            )],
                        );
                    }
                }
            }
        }
        for x in &edit.examples {
            if let Err(why) = append_item(lines, &mut e, item, "examples", x, item.end) {
                e.before(
                    item.start,
                    vec![todo_line(pad - 2, &format!("add SW {}'s example by hand: {why}", plan.software))],
                );
            }
        }
        for x in &edit.errata {
            if let Err(why) = append_item(lines, &mut e, item, "errata", x, item.end) {
                e.before(
                    item.start,
                    vec![todo_line(pad - 2, &format!("add SW {}'s erratum by hand: {why}", plan.software))],
                );
            }
        }
    }
    // Commands added.
    let commands_key = find_key(lines, r, "commands");
    let dash = cmds.first().map_or(2, |(_, s)| s.indent - 2);
    let mut includes: Vec<(String, String)> = Vec::new();
    for nc in &plan.new_commands {
        let block: Vec<String> = nc
            .text
            .lines()
            .map(|l| {
                if l.is_empty() {
                    String::new()
                } else {
                    format!("{}{}", " ".repeat(dash), l.strip_prefix("  ").unwrap_or(l))
                }
            })
            .collect();
        let at = nc.after.as_deref().and_then(find);
        match (at, &commands_key, cmds.first()) {
            (Some(span), _, _) => {
                e.after(span.end - 1, dash, block);
            }
            (None, _, Some((_, first))) if nc.after.is_none() => {
                e.before(first.start, block.into_iter().skip_while(String::is_empty).chain([String::new()]).collect());
            }
            (None, Some(k), _) => {
                e.after(k.end.saturating_sub(1), dash, block);
            }
            (None, None, _) => {
                let mut b = vec![String::new(), "commands:".to_string()];
                b.extend(block);
                e.after(lines.len().saturating_sub(1), 0, b);
            }
        }
        if let Some(u) = &nc.uses {
            includes.push(u.clone());
        }
    }
    // Includes the added `use:` entries need.
    if !includes.is_empty() {
        let include_key = find_key(lines, r, "include");
        let inc_items = include_key.as_ref().map(|k| items(lines, k)).unwrap_or_default();
        let mut fresh: Vec<(String, Vec<String>)> = Vec::new();
        for (file, name) in includes {
            let entry = inc_items.iter().find(|it| {
                let l = lines[it.start].trim_start().trim_start_matches('-').trim();
                l == file
                    || l.contains(&format!("file: {file}"))
                    || find_key(lines, **it, "file").is_some_and(|k| scalar(&k) == file)
            });
            match entry {
                Some(it) => {
                    let l = &lines[it.start];
                    let whole = l.trim_start().trim_start_matches('-').trim() == file;
                    if whole {
                        continue;
                    }
                    if let Some(close) = l.rfind(']').filter(|_| l.contains("only: [")) {
                        let mut new = l.clone();
                        new.insert_str(close, &format!(", {name}"));
                        e.replace(it.start, new);
                    } else if let Some(only) = find_key(lines, *it, "only") {
                        let last = items(lines, &only).last().copied();
                        match last {
                            Some(last) => {
                                e.after(
                                    last.end - 1,
                                    last.indent,
                                    vec![format!("{}- {name}", " ".repeat(last.indent - 2))],
                                );
                            }
                            None => todos.push(format!("add `{name}` to the `only:` of the include of {file} by hand")),
                        }
                    } else {
                        todos.push(format!("add `{name}` to the include of {file} by hand"));
                    }
                }
                None => match fresh.iter_mut().find(|(f, _)| *f == file) {
                    Some((_, names)) => names.push(name),
                    None => fresh.push((file, vec![name])),
                },
            }
        }
        for (file, names) in fresh {
            let item = format!("- {{file: {file}, only: [{}]}}", names.join(", "));
            match &include_key {
                Some(k) => {
                    if let Err(why) = append_item(lines, &mut e, r, "include", &item, k.end) {
                        todos.push(format!("include {file} (only: {}) by hand: {why}", names.join(", ")));
                    }
                }
                None => {
                    let at = commands_key.as_ref().map_or(lines.len(), |k| k.line);
                    e.before(at, vec!["include:".into(), format!("  {item}"), String::new()]);
                }
            }
        }
    }
    // TODOs about the file, before `sensor:`.
    for t in plan.file_todos.iter().chain(&todos) {
        e.before(sensor.line, vec![todo_line(0, t)]);
    }
    (e, todos)
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str = "# head\nsensor:\n  name: p\n  manual:\n    title: T\n  serial: {baud: 9600}\n\ncommands:\n  - name: a\n    doc: |\n      text\n      # not a comment\n    examples:\n      - figures: [1]\n        request: \"01\"\n\n  # TODO(import): before b\n  - use: b\n    since: \"1.8\"\nerrata:\n- id: E1\n  note: x\n";

    #[test]
    fn keys_items_and_edits() {
        let lines = lines_of(DOC);
        let r = root(&lines);
        let sensor = find_key(&lines, r, "sensor").expect("sensor");
        let manual = find_key(&lines, sensor.body(&lines), "manual").expect("manual");
        assert_eq!((manual.line, manual.end), (3, 5));
        let serial = find_key(&lines, sensor.body(&lines), "serial").expect("serial");
        assert_eq!(serial.inline, "{baud: 9600}");
        let commands = find_key(&lines, r, "commands").expect("commands");
        let cmds = items(&lines, &commands);
        assert_eq!(cmds.len(), 2);
        assert_eq!((cmds[0].start, cmds[0].end, cmds[0].indent), (8, 15, 4));
        assert_eq!(item_name(&lines, cmds[1]).as_deref(), Some("b"));
        let since = find_key(&lines, cmds[1], "since").expect("since");
        assert_eq!(scalar(&since), "1.8");
        let examples = find_key(&lines, cmds[0], "examples").expect("examples");
        let ex = items(&lines, &examples);
        assert_eq!((ex[0].start, ex[0].end, ex[0].indent), (13, 15, 8));
        let errata = find_key(&lines, r, "errata").expect("errata");
        assert_eq!(items(&lines, &errata).len(), 1, "a list at the key's own indentation");

        let mut e = Edits::default();
        e.after(cmds[0].end - 1, 4, vec!["    since: \"2\"".into()]);
        e.after(ex[0].end - 1, 8, vec!["        also_in: []".into()]);
        e.replace(since.line, "    since: \"1.9\"".into());
        let (out, placed) = e.apply(&lines);
        assert_eq!(out[15], "        also_in: []", "the deeper block first");
        assert_eq!(out[16], "    since: \"2\"");
        assert!(out.contains(&"    since: \"1.9\"".to_string()));
        assert_eq!(placed.len(), 3);
    }
}

//! The commonest slip in a spec's flow mappings: an unquoted comma that
//! ends a value early, making the rest of the text a key of its own.

use super::lexer::unclosed_flow;
use crate::diag::Pos;

/// An unquoted comma that ended a value inside a flow mapping, making the
/// rest of the text a key of its own: `{doc: Slope K, the gain.}`.
#[derive(Debug, PartialEq, Eq)]
pub(super) struct Comma {
    /// The comma.
    pub(super) pos: Pos,
    /// The key whose value it ended, and where that is written.
    pub(super) key: String,
    pub(super) key_pos: Pos,
    /// The value as meant: `Slope K, the gain.`.
    pub(super) value: String,
    /// The text read as a key: `the gain.`.
    pub(super) stray: String,
}

/// The unquoted comma that made the entry at `pos` of a flow mapping: the
/// entry has no value (or a key with a space, which no spec key has) and
/// follows a `key: plain text` entry.
pub(super) fn unquoted_comma(text: &str, pos: Pos) -> Option<Comma> {
    let line: Vec<char> = text.lines().nth((pos.line as usize).checked_sub(1)?)?.chars().collect();
    let column = (pos.column as usize).checked_sub(1)?;
    // A flow mapping opened on an earlier line continues on this one.
    let continued = unclosed_flow(text, Pos { line: pos.line, column: 1 }).is_some_and(|(_, _, c)| c == '{');
    let (entries, at) = flow_entries(&line, column, continued)?;
    // An entry's characters without the blanks around it, and where they start.
    let trimmed = |&(start, end): &(usize, usize)| -> (usize, &[char]) {
        let chars = line.get(start..end).unwrap_or(&[]);
        let lead = chars.iter().take_while(|c| c.is_whitespace()).count();
        let trail = chars.iter().rev().take_while(|c| c.is_whitespace()).count();
        (start + lead, chars.get(lead..chars.len().saturating_sub(trail)).unwrap_or(&[]))
    };
    let plain = |t: &[char]| t.first().is_some_and(|c| !"\"'[]{}&*!|>%@`#?:-".contains(*c));
    let valueless = |e: &(usize, usize)| {
        let (_, t) = trimmed(e);
        plain(t) && entry_colon(t).is_none()
    };
    let (_, stray) = trimmed(entries.get(at)?);
    let spaced_key =
        entry_colon(stray).is_some_and(|c| plain(stray) && stray.get(..c).is_some_and(|k| k.contains(&' ')));
    if !valueless(entries.get(at)?) && !spaced_key {
        return None;
    }
    // Back over earlier valueless entries to the one whose value the comma ended.
    let mut first = at;
    while first > 0 && entries.get(first - 1).is_some_and(valueless) {
        first -= 1;
    }
    let owner = entries.get(first.checked_sub(1)?)?;
    let (key_column, owner_text) = trimmed(owner);
    let colon = entry_colon(owner_text)?;
    let key: String = owner_text.get(..colon)?.iter().collect();
    let value = owner_text.get(colon + 1..)?;
    let value_column = key_column + colon + 1 + value.iter().take_while(|c| c.is_whitespace()).count();
    if !plain(owner_text) || !plain(line.get(value_column..)?) || key.trim().is_empty() {
        return None;
    }
    // Forward over later valueless entries: the rest of the text meant.
    let mut last = at;
    while entries.get(last + 1).is_some_and(valueless) {
        last += 1;
    }
    let (_, meant) = trimmed(&(value_column, entries.get(last)?.1));
    Some(Comma {
        pos: Pos { line: pos.line, column: owner.1 as u32 + 1 },
        key: key.trim().to_string(),
        key_pos: Pos { line: pos.line, column: key_column as u32 + 1 },
        value: meant.iter().collect(),
        stray: stray.iter().collect(),
    })
}

/// Where the colon of a `key: value` (or `key:`) entry is.
fn entry_colon(entry: &[char]) -> Option<usize> {
    (0..entry.len()).find(|&i| entry.get(i) == Some(&':') && entry.get(i + 1).is_none_or(|n| *n == ' ' || *n == '\t'))
}

/// A flow collection open on a line, for [`flow_entries`].
struct Flow {
    /// `[` or `{`, and its column.
    opener: char,
    column: usize,
    /// Where the entry being read starts.
    entry: usize,
    /// The entries read: character ranges, between commas.
    entries: Vec<(usize, usize)>,
}

impl Flow {
    /// Its entries, the last ending at `end`, and which holds `column`, if
    /// it is a mapping.
    fn holding(mut self, end: usize, column: usize) -> Option<(Vec<(usize, usize)>, usize)> {
        self.entries.push((self.entry, end));
        let at = self.entries.iter().position(|&(s, e)| s <= column && column <= e)?;
        (self.opener == '{').then_some((self.entries, at))
    }
}

/// The entries (character ranges, between commas) of the innermost flow
/// collection of `line` holding character `column`, if it is a mapping,
/// and which entry holds it. With `continued`, the line starts inside a
/// flow mapping.
fn flow_entries(line: &[char], column: usize, continued: bool) -> Option<(Vec<(usize, usize)>, usize)> {
    let mut open: Vec<Flow> = Vec::new();
    if continued {
        open.push(Flow { opener: '{', column: 0, entry: 0, entries: Vec::new() });
    }
    let mut quote: Option<char> = None;
    let mut prev: Option<char> = None;
    let mut after_blank = true;
    let mut end = line.len();
    let mut i = 0;
    while let Some(&c) = line.get(i) {
        match quote {
            Some('"') if c == '\\' => i += 1,
            Some('\'') if c == '\'' && line.get(i + 1) == Some(&'\'') => i += 1,
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None => {
                let value_start = (matches!(prev, None | Some(':' | '-' | '?')) && after_blank)
                    || (!open.is_empty() && matches!(prev, Some('[' | '{' | ',' | ':')));
                match c {
                    '#' if after_blank => {
                        end = i;
                        break;
                    }
                    '"' | '\'' if value_start => quote = Some(c),
                    '[' | '{' if value_start => {
                        open.push(Flow { opener: c, column: i, entry: i + 1, entries: Vec::new() })
                    }
                    ',' => {
                        if let Some(top) = open.last_mut() {
                            top.entries.push((top.entry, i));
                            top.entry = i + 1;
                        }
                    }
                    ']' | '}' => {
                        // The innermost collection holding `column` closes here.
                        if let Some(flow) = open.pop()
                            && flow.column <= column
                            && column <= i
                        {
                            return flow.holding(i, column);
                        }
                    }
                    _ => {}
                }
            }
        }
        after_blank = c == ' ' || c == '\t';
        if !after_blank {
            prev = Some(c);
        }
        i += 1;
    }
    // Still open at the end of the line: a flow mapping running over lines.
    open.pop().filter(|flow| flow.column <= column)?.holding(end, column)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::yaml::parse;
    use crate::yaml::tests::{problems, spec};

    #[test]
    fn unquoted_comma_in_a_flow_mapping() {
        let text = spec("  - name: k\n    fields:\n      - {name: k, type: f32, doc: Slope K, the gain.}\n");
        let Err(found) = parse(&text) else { panic!("expected an error") };
        assert_eq!(found.len(), 1);
        let p = &found[0];
        assert_eq!(p.message, "an unquoted comma ends the value inside `{...}`");
        assert_eq!((p.pos.line, p.pos.column), (12, 42));
        assert_eq!(p.key, "commands[0] (k).fields[0] (k).doc");
        let help = p.help.as_deref().unwrap_or_default();
        assert!(help.ends_with("quote the text: doc: \"Slope K, the gain.\""), "{help}");
        assert!(help.contains("`the gain.` is read as a key of its own"), "{help}");

        let comma = |line: &str, column| unquoted_comma(line, Pos { line: 1, column });
        // Several commas; the error may point at a later stray part.
        let c = comma("{note: a, b, c, name: x}", 14).expect("a comma");
        assert_eq!((c.pos, c.key.as_str(), c.value.as_str()), (Pos { line: 1, column: 9 }, "note", "a, b, c"));
        // A stray part with `: ` in it.
        let c = comma("{doc: Range 0, the max: 14}", 16).expect("a comma");
        assert_eq!((c.value.as_str(), c.stray.as_str()), ("Range 0, the max: 14", "the max: 14"));
        // A flow mapping over two lines.
        let c = unquoted_comma("- {name: k,\n   doc: a, b}", Pos { line: 2, column: 12 }).expect("a comma");
        assert_eq!((c.pos, c.value.as_str()), (Pos { line: 2, column: 10 }, "a, b"));
        // Not a comma slip: a misspelt key, a quoted value, a list.
        assert_eq!(comma("{name: k, dox: 1}", 11), None);
        assert_eq!(
            comma("{name: k, dox}", 11),
            Some(Comma {
                pos: Pos { line: 1, column: 9 },
                key: "name".into(),
                key_pos: Pos { line: 1, column: 2 },
                value: "k, dox".into(),
                stray: "dox".into(),
            })
        );
        assert_eq!(comma("{doc: \"a\", b}", 12), None);
        assert_eq!(comma("[doc: a, b]", 10), None);
        assert_eq!(comma("{a: [x, y], b}", 13), None);
        // Quoted, the comma is fine.
        assert!(parse(&spec("  - {name: k, doc: \"Slope K, the gain.\"}\n")).is_ok());
        // A genuine unknown key keeps its message.
        let found = problems(&spec("  - {name: k, dox: 1}\n"));
        assert_eq!(found, [(10, 15, "unknown key `dox`".to_string())]);
    }
}

//! Where parsing may resume after an error, so that one run reports the
//! mistakes of separate entries of a file, not only the first.

use super::lexer::{fresh_starts, indentation, is_blank_or_comment, is_directive, is_item, is_list_header, top_key};

/// Where parsing may resume after an error: top-level keys and the items
/// of top-level block lists, found by indentation.
///
/// A line only counts where no quoted text or flow collection (`[...]`,
/// `{...}`) is open, or where every one open there is never closed (an
/// error that would swallow the rest of the file): YAML lets both run over
/// lines, even unindented ones.
pub(super) struct Layout {
    /// The lines (comments, directives) before the first key, kept when parsing from a resume point.
    pub(super) preamble: usize,
    /// What each line is.
    lines: Vec<Line>,
    /// For each line, whether parsing may start afresh there (see [`fresh_starts`]).
    fresh: Vec<bool>,
    /// In line order.
    resumes: Vec<Resume>,
}

/// What a line is, for [`Layout`].
#[derive(Debug, Clone, PartialEq, Eq)]
enum Line {
    /// Blank, or only a comment.
    Blank,
    /// A directive (`%YAML`) or a document start (`---`).
    Directive,
    /// `key: ...` at column 0; `list` when nothing follows the colon, so
    /// that a block list may.
    Key { key: String, list: bool },
    /// `- ...`, indented this much.
    Item(usize),
    /// Anything else.
    Other,
}

impl Line {
    fn of(line: &str) -> Self {
        if is_blank_or_comment(line) {
            Line::Blank
        } else if is_directive(line) {
            Line::Directive
        } else if let Some(key) = top_key(line) {
            Line::Key { key: key.to_string(), list: is_list_header(line) }
        } else if is_item(line) {
            Line::Item(indentation(line))
        } else {
            Line::Other
        }
    }
}

/// A line (0-based) where parsing may resume.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Resume {
    pub(super) line: usize,
    /// For an item of a top-level list: the list.
    pub(super) list: Option<List>,
}

/// The top-level list an item belongs to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct List {
    /// The line (0-based) of the list's key, kept when parsing from the item.
    pub(super) header: usize,
    key: String,
    /// The item's index in the list.
    index: usize,
}

impl List {
    /// A key path of the text parsed from this item (where it is item 0)
    /// as a path of the file: `commands[1] (x)` -> `commands[4] (x)`.
    pub(super) fn shift(&self, path: &str) -> String {
        let shifted = path.strip_prefix(self.key.as_str()).and_then(|r| r.strip_prefix('[')).and_then(|r| {
            let digits = r.find(']')?;
            let n: usize = r.get(..digits)?.parse().ok()?;
            Some(format!("{}[{}{}", self.key, n + self.index, r.get(digits..)?))
        });
        shifted.unwrap_or_else(|| path.to_string())
    }
}

impl Layout {
    /// The resume points of `text`, if it has the usual shape: a mapping of
    /// block keys at column 0, after nothing but comments and directives.
    pub(super) fn of(text: &str) -> Option<Self> {
        // A lone `\r` ends a line for YAML but not for `str::lines`.
        if text.match_indices('\r').any(|(i, _)| text.as_bytes().get(i + 1) != Some(&b'\n')) {
            return None;
        }
        let lines: Vec<&str> = text.lines().collect();
        let mut layout = Self {
            lines: lines
                .iter()
                .enumerate()
                .map(|(i, l)| Line::of(if i == 0 { l.trim_start_matches('\u{feff}') } else { l }))
                .collect(),
            fresh: fresh_starts(&lines),
            preamble: 0,
            resumes: Vec::new(),
        };
        layout.preamble = layout.lines.iter().take_while(|l| matches!(l, Line::Blank | Line::Directive)).count();
        layout.resumes = layout.resumes()?;
        Some(layout)
    }

    /// After an error found a quote or bracket at line `line` (1-based) that
    /// closes only further down, reads the lines after as if it closed at
    /// the end of its line. False if nothing changes.
    pub(super) fn reset(&mut self, text: &str, line: usize) -> bool {
        if self.fresh.get(line).is_none_or(|&f| f) {
            // Nothing open after that line closes again: nothing to reset.
            return false;
        }
        let after: Vec<&str> = text.lines().skip(line).collect();
        let fresh = fresh_starts(&after);
        self.fresh.truncate(line);
        self.fresh.extend(fresh);
        self.resumes = self.resumes().unwrap_or_default();
        true
    }

    /// The resume points, if the file is a mapping of block keys.
    fn resumes(&self) -> Option<Vec<Resume>> {
        let fresh = |i: usize| self.fresh.get(i).copied().unwrap_or(false);
        let tops: Vec<usize> =
            (0..self.lines.len()).filter(|&i| fresh(i) && matches!(self.lines[i], Line::Key { .. })).collect();
        if tops.first() != Some(&self.preamble) {
            return None;
        }
        let mut resumes = Vec::new();
        for (n, &top) in tops.iter().enumerate() {
            resumes.push(Resume { line: top, list: None });
            let Line::Key { key, list: true } = &self.lines[top] else { continue };
            let end = tops.get(n + 1).copied().unwrap_or(self.lines.len());
            let mut body = (top + 1..end).filter(|&i| self.lines[i] != Line::Blank).peekable();
            let Some(&Line::Item(indent)) = body.peek().map(|&i| &self.lines[i]) else { continue };
            let items = body.filter(|&i| self.lines[i] == Line::Item(indent));
            for (index, line) in items.enumerate() {
                if fresh(line) {
                    resumes.push(Resume { line, list: Some(List { header: top, key: key.clone(), index }) });
                }
            }
        }
        Some(resumes)
    }

    /// Where to resume after an error that stopped the parser at `stop`
    /// (1-based line), having parsed from `from`: after both, and past the
    /// list whose key line `stop` is on.
    pub(super) fn resume_after(&self, stop: usize, from: Option<&Resume>) -> Option<Resume> {
        let after = stop.max(from.map_or(0, |r| r.line + 1));
        let bad_header = from.and_then(|r| r.list.as_ref()).filter(|l| l.header + 1 == stop).map(|l| l.header);
        self.resumes
            .iter()
            .find(|r| r.line + 1 > after && (bad_header.is_none() || r.list.as_ref().map(|l| l.header) != bad_header))
            .cloned()
    }

    /// The first resume line (0-based) after line `line` (1-based): where
    /// the entry holding `line` ends.
    pub(super) fn next_start_after(&self, line: usize) -> Option<usize> {
        self.resumes.iter().map(|r| r.line).find(|&l| l + 1 > line)
    }
}

/// `text` with the lines (0-based) that `keep` refuses emptied, their line
/// breaks kept, so that positions stay those of `text`.
pub(super) fn keep_lines(text: &str, keep: impl Fn(usize) -> bool) -> String {
    let mut out = String::with_capacity(text.len());
    for (i, line) in text.split_inclusive('\n').enumerate() {
        if keep(i) {
            out.push_str(line);
        } else {
            out.extend(line.chars().filter(|c| matches!(c, '\r' | '\n')));
        }
    }
    out
}

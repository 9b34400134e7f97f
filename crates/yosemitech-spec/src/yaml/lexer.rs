//! YAML read line by line, as far as finding errors needs: what a line
//! is, and which quotes and flow collections are open where.

use crate::diag::Pos;

pub(super) fn indentation(line: &str) -> usize {
    line.len() - line.trim_start_matches(' ').len()
}

pub(super) fn is_blank_or_comment(line: &str) -> bool {
    let t = line.trim();
    t.is_empty() || t.starts_with('#')
}

/// A directive (`%YAML 1.2`) or a document start (`---`), which may come before the first key.
pub(super) fn is_directive(line: &str) -> bool {
    let t = line.trim_end();
    t.starts_with('%')
        || t.strip_prefix("---")
            .is_some_and(|r| r.is_empty() || r.starts_with([' ', '\t']) && r.trim_start().starts_with('#'))
}

/// A list item's line: `- ...` or a lone `-`.
pub(super) fn is_item(line: &str) -> bool {
    let t = line.trim_start_matches(' ');
    t == "-" || t.starts_with("- ") || t.starts_with("-\t")
}

/// The key of a line `key: ...` at column 0 with a plain key, if it is one.
pub(super) fn top_key(line: &str) -> Option<&str> {
    let first = line.chars().next()?;
    if !(first.is_alphanumeric() || first == '_') {
        return None;
    }
    let colon = line.char_indices().find(|&(i, c)| {
        c == ':' && line.get(i + 1..).and_then(|r| r.chars().next()).is_none_or(|n| n == ' ' || n == '\t')
    })?;
    let key = line.get(..colon.0)?;
    (!key.contains(|c: char| "#[]{},\"'&*!|>%@`".contains(c) || c.is_control())).then(|| key.trim_end())
}

/// A key line with nothing after the colon but a comment: `commands:`.
pub(super) fn is_list_header(line: &str) -> bool {
    let Some(colon) = line.find(':') else { return false };
    let rest = line.get(colon + 1..).unwrap_or("");
    let t = rest.trim_start();
    t.is_empty() || t.starts_with('#') && rest.starts_with([' ', '\t'])
}

/// Quoted scalars and flow collections opened and closed line by line, as
/// YAML's scanner sees them (block scalars skipped, comments ignored).
#[derive(Default)]
struct Lexer {
    /// What is open (`"`, `'`, `[` or `{`) and where (0-based line and character).
    open: Vec<(char, usize, usize)>,
    /// Inside a block scalar: lines indented more than this belong to it.
    block: Option<usize>,
}

impl Lexer {
    /// Lexes line `n`, calling `closed(kind, opened at, closed at column, depth after)`
    /// for each quoted scalar or collection it closes.
    fn line(&mut self, n: usize, line: &str, mut closed: impl FnMut(char, (usize, usize), usize, usize)) {
        if let Some(parent) = self.block {
            if line.trim().is_empty() || indentation(line) > parent {
                return;
            }
            self.block = None;
        }
        // The last non-blank character before this one on the line.
        let mut prev: Option<char> = None;
        let mut after_blank = true;
        let mut chars = line.char_indices().enumerate().peekable();
        while let Some((i, (byte, c))) = chars.next() {
            let top = self.open.last().map(|o| o.0);
            let next = chars.peek().map(|(_, (_, c))| *c);
            let mut close = false;
            match top {
                Some('"') if c == '\\' => {
                    chars.next();
                }
                Some('"') if c == '"' => close = true,
                Some('\'') if c == '\'' && next == Some('\'') => {
                    chars.next();
                }
                Some('\'') if c == '\'' => close = true,
                Some('"' | '\'') => {}
                _ => {
                    let in_flow = top.is_some();
                    // A value starts at the line's start, after `: `, `- `, `? `, or in a flow after `[`, `{`, `,`, `:`.
                    let value_start = (matches!(prev, None | Some(':' | '-' | '?')) && after_blank)
                        || (in_flow && matches!(prev, Some('[' | '{' | ',' | ':')));
                    match c {
                        '#' if after_blank => break,
                        '"' | '\'' | '[' | '{' if value_start => self.open.push((c, n, i)),
                        ']' | '}' if in_flow => close = true,
                        '|' | '>' if !in_flow && value_start && is_block_header(line.get(byte + 1..).unwrap_or("")) => {
                            self.block = Some(block_parent(line));
                            break;
                        }
                        _ => {}
                    }
                }
            }
            if close && let Some((kind, line, column)) = self.open.pop() {
                closed(kind, (line, column), i, self.open.len());
            }
            after_blank = c == ' ' || c == '\t';
            if !after_blank {
                prev = Some(c);
            }
        }
    }
}

/// For each line, whether parsing may start afresh there: no quoted scalar
/// or flow collection is open at its start, or every one open there stays
/// open to the end of the file.
pub(super) fn fresh_starts(lines: &[&str]) -> Vec<bool> {
    let mut lexer = Lexer::default();
    let mut depth_at_start = Vec::with_capacity(lines.len());
    let mut least_depth = Vec::with_capacity(lines.len());
    for (n, line) in lines.iter().enumerate() {
        let depth = lexer.open.len();
        let mut least = depth;
        lexer.line(n, line, |_, _, _, after| least = least.min(after));
        depth_at_start.push(depth);
        least_depth.push(least);
    }
    let mut fresh = vec![false; lines.len()];
    let mut least_after = lexer.open.len();
    for n in (0..lines.len()).rev() {
        least_after = least_after.min(least_depth[n]);
        fresh[n] = least_after >= depth_at_start[n];
    }
    fresh
}

/// Where the quoted scalar starts that is open at `pos`, or that closed on
/// its line just before it, if it starts on an earlier line: a quote never
/// closed on its own line runs on until the next quote.
pub(super) fn quote_start(text: &str, pos: Pos) -> Option<Pos> {
    let target = (pos.line as usize).checked_sub(1)?;
    let column = (pos.column as usize).saturating_sub(1);
    let mut lexer = Lexer::default();
    let mut start = None;
    for (n, line) in text.lines().enumerate().take(target + 1) {
        lexer.line(n, line, |kind, from, at, _| {
            if n == target && at < column && matches!(kind, '"' | '\'') {
                start = Some(from);
            }
        });
    }
    let open = lexer.open.iter().find(|o| matches!(o.0, '"' | '\'')).map(|o| (o.1, o.2));
    let (line, column) = open.or(start).filter(|(line, _)| *line < target)?;
    Some(Pos { line: line as u32 + 1, column: column as u32 + 1 })
}

/// What may follow `|` or `>` to start a block scalar: chomping and
/// indentation indicators, then nothing or a comment.
fn is_block_header(rest: &str) -> bool {
    let indicators = rest.chars().take(2).take_while(|c| matches!(c, '-' | '+' | '1'..='9')).count();
    let tail = rest.get(indicators..).unwrap_or("");
    let comment = tail.trim_start_matches([' ', '\t']);
    comment.is_empty() || comment.starts_with('#') && comment.len() < tail.len()
}

/// The indentation a block scalar started on `line` must exceed: the
/// column of its key, or of its `-` in a list.
fn block_parent(line: &str) -> usize {
    let mut column = indentation(line);
    let mut dash = None;
    let mut rest = line.get(column..).unwrap_or("");
    while is_item(rest) {
        dash = Some(column);
        let after = rest.get(1..).unwrap_or("");
        let skipped = after.len() - after.trim_start_matches([' ', '\t']).len();
        column += 1 + skipped;
        rest = after.get(skipped..).unwrap_or("");
    }
    if rest.starts_with(['|', '>']) {
        // `- |`: the list's column; `|` alone on a line: its parent's, at most.
        return dash.unwrap_or(column.saturating_sub(1));
    }
    column
}

/// The innermost flow collection opened before `pos` and still open there.
pub(super) fn unclosed_flow(text: &str, pos: Pos) -> Option<(u32, u32, char)> {
    let mut stack: Vec<(u32, u32, char)> = Vec::new();
    for (i, line) in text.lines().enumerate().take(pos.line as usize) {
        let line_no = i as u32 + 1;
        let mut quote: Option<char> = None;
        // The last non-blank character before this one on the line.
        let mut prev: Option<char> = None;
        let mut after_blank = true;
        for (j, c) in line.chars().enumerate() {
            let col = j as u32 + 1;
            if line_no == pos.line && col >= pos.column {
                break;
            }
            // A value starts at the line's start, after `: `, `- `, `, ` or an opener.
            let value_start =
                (matches!(prev, None | Some(':' | ',' | '-')) && after_blank) || matches!(prev, Some('[' | '{'));
            match quote {
                Some(q) if c == q => quote = None,
                Some(_) => {}
                None => match c {
                    '#' if after_blank => break,
                    '"' | '\'' if value_start => quote = Some(c),
                    '[' | '{' if value_start => stack.push((line_no, col, c)),
                    ']' | '}' if !stack.is_empty() => {
                        stack.pop();
                    }
                    _ => {}
                },
            }
            after_blank = c == ' ' || c == '\t';
            if !after_blank {
                prev = Some(c);
            }
        }
    }
    stack.pop()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unclosed() {
        let text = "a:\n  b: [1, 2\n  c: 3\n";
        assert_eq!(unclosed_flow(text, Pos { line: 3, column: 4 }), Some((2, 6, '[')));
        assert_eq!(unclosed_flow("a: [1, 2]\nb: x[y\n", Pos { line: 2, column: 5 }), None);
    }

    #[test]
    fn lines_where_parsing_may_start_afresh() {
        let fresh = |text: &str| fresh_starts(&text.lines().collect::<Vec<_>>());
        assert_eq!(fresh("a: [1,\n2]\nb: 3"), [true, false, true]);
        assert_eq!(fresh("a: \"x\nb: y\"\nc: 'it''s\nd'"), [true, false, true, false]);
        // Never closed: the rest of the file would be swallowed, so start afresh.
        assert_eq!(fresh("a: [1\nb: 2\nc: 3"), [true, true, true]);
        assert_eq!(fresh("a: |\n  \"x [\nb: 2 # ]\n"), [true, true, true]);
        assert_eq!(fresh("a: x'y\nb: [1] # \"\nc: 3"), [true, true, true]);
    }

    #[test]
    fn quotes_left_open_are_found_where_they_start() {
        let text = "a:\n  b: \"x\n  c: y\n  d: \"z\"\n";
        assert_eq!(quote_start(text, Pos { line: 4, column: 9 }), Some(Pos { line: 2, column: 6 }));
        assert_eq!(quote_start(text, Pos { line: 4, column: 7 }), Some(Pos { line: 2, column: 6 }));
        assert_eq!(quote_start("a: \"x\"\nb: \"y", Pos { line: 2, column: 4 }), None);
    }
}

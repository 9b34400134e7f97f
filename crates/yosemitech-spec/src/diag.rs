//! Diagnostics in the manner of rustc: what is wrong, where, and what would be valid.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::Spanned;

/// A position in a spec file (1-based; 0 when unknown).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Pos {
    /// Line.
    pub line: u32,
    /// Column.
    pub column: u32,
}

impl Pos {
    /// Where a spanned value is written.
    pub fn at<T>(spanned: &Spanned<T>) -> Self {
        spanned.referenced
    }
}

/// One problem in a spec file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Diagnostic {
    /// The file.
    pub file: PathBuf,
    /// Where in it.
    pub pos: Pos,
    /// The offending key, as a path (`commands[2].count`).
    pub key: String,
    /// What is wrong.
    pub message: String,
    /// What would be valid.
    pub help: Option<String>,
    /// The source line, for display.
    pub source_line: Option<String>,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "error: {}", self.message)?;
        let file = self.file.display();
        if self.pos.line > 0 {
            writeln!(f, "  --> {file}:{}:{}", self.pos.line, self.pos.column)?;
        } else {
            writeln!(f, "  --> {file}")?;
        }
        if let Some(line) = &self.source_line {
            let number = self.pos.line.to_string();
            let pad = " ".repeat(number.len());
            let (shown, caret_at) = window(line, (self.pos.column as usize).saturating_sub(1));
            writeln!(f, "{pad} |")?;
            writeln!(f, "{number} | {shown}")?;
            writeln!(f, "{pad} | {}^", " ".repeat(caret_at))?;
        }
        if !self.key.is_empty() {
            writeln!(f, "  = key: {}", self.key)?;
        }
        if let Some(help) = &self.help {
            writeln!(f, "  = help: {help}")?;
        }
        Ok(())
    }
}

/// Widest source excerpt shown, in characters.
const SHOWN_WIDTH: usize = 100;

/// Characters that would change how the rest of a terminal line reads:
/// bidi embeddings, overrides, isolates and marks, line and paragraph
/// separators (the diagnostic's message names them; the excerpt blanks them).
fn is_invisible_format(c: char) -> bool {
    matches!(
        c,
        '\u{200E}' | '\u{200F}' | '\u{061C}' | '\u{2028}' | '\u{2029}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}'
    )
}

/// The part of `line` to show around character `column` (0-based), with
/// control and bidi characters blanked, and the caret's offset in it.
fn window(line: &str, column: usize) -> (String, usize) {
    let chars: Vec<char> =
        line.chars().map(|c| if c.is_control() || is_invisible_format(c) { ' ' } else { c }).collect();
    let column = column.min(chars.len());
    if chars.len() <= SHOWN_WIDTH {
        return (chars.into_iter().collect::<String>().trim_end().to_string(), column);
    }
    let start = if column < SHOWN_WIDTH * 3 / 4 { 0 } else { column - SHOWN_WIDTH / 2 };
    let end = (start + SHOWN_WIDTH).min(chars.len());
    let mut shown = String::new();
    let mut caret = column - start;
    if start > 0 {
        shown.push_str("...");
        caret += 3;
    }
    shown.extend(&chars[start..end]);
    if end < chars.len() {
        shown.push_str("...");
    }
    (shown, caret)
}

/// All problems found in a set of spec files.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Diagnostics(pub Vec<Diagnostic>);

impl Diagnostics {
    /// True when nothing is wrong.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Number of problems.
    pub fn len(&self) -> usize {
        self.0.len()
    }
}

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for d in &self.0 {
            writeln!(f, "{d}")?;
        }
        let n = self.0.len();
        write!(f, "error: could not load the spec due to {n} previous error{}", if n == 1 { "" } else { "s" })
    }
}

impl std::error::Error for Diagnostics {}

/// Collects diagnostics for one file.
pub(crate) struct Reporter<'a> {
    pub file: &'a Path,
    pub text: &'a str,
    pub out: &'a mut Vec<Diagnostic>,
}

impl Reporter<'_> {
    pub fn error(&mut self, pos: Pos, key: impl Into<String>, message: impl Into<String>, help: Option<String>) {
        let source_line = if pos.line > 0 {
            self.text.lines().nth(pos.line as usize - 1).map(|l| l.chars().take(4096).collect())
        } else {
            None
        };
        self.out.push(Diagnostic {
            file: self.file.to_path_buf(),
            pos,
            key: key.into(),
            message: message.into(),
            help,
            source_line,
        });
    }
}

//! The draft: frames, fields, examples and commands as the manual prints them.

use std::fmt::Write as _;

use super::header::Header;

/// A frame as printed: bytes (`None`: a placeholder), open-ended, CRC state.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DraftFrame {
    /// Bytes before the CRC.
    pub bytes: Vec<Option<u8>>,
    /// Bytes of unknown number follow.
    pub open_ended: bool,
    /// The CRC printed, if any.
    pub crc: Option<[u8; 2]>,
}

impl DraftFrame {
    /// The correct CRC, when every byte is known.
    pub fn computed_crc(&self) -> Option<[u8; 2]> {
        if self.open_ended {
            return None;
        }
        let bytes: Option<Vec<u8>> = self.bytes.iter().copied().collect();
        bytes.map(|b| yosemitech_rtu::crc16(&b).to_le_bytes())
    }

    /// The printed CRC is right.
    pub fn crc_verified(&self) -> bool {
        self.crc.is_some() && self.crc == self.computed_crc()
    }

    /// The printed CRC is wrong (provably).
    pub fn crc_wrong(&self) -> bool {
        self.crc.is_some() && self.computed_crc().is_some_and(|c| Some(c) != self.crc)
    }

    pub(super) fn spec_text(&self, with_crc: Option<[u8; 2]>) -> String {
        let mut parts: Vec<String> =
            self.bytes.iter().map(|b| b.map_or_else(|| "??".to_string(), |b| format!("{b:02X}"))).collect();
        if let Some(c) = with_crc {
            parts.extend(c.iter().map(|b| format!("{b:02X}")));
        }
        if self.open_ended {
            parts.push("...".into());
        }
        parts.join(" ")
    }

    /// As the spec writes it (printed CRC included).
    pub fn text(&self) -> String {
        self.spec_text(self.crc)
    }
}

/// A drafted field.
#[derive(Debug, Clone, PartialEq)]
pub struct DField {
    /// Name (`None`: reserved).
    pub name: Option<String>,
    /// The spec's type name.
    pub ty: &'static str,
    /// Byte order key, when the type has one.
    pub order: Option<&'static str>,
    /// Byte offset in the register data.
    pub offset: usize,
    /// Bytes.
    pub size: usize,
    /// Enum variants or flags: (value, label).
    pub codes: Vec<(u16, String)>,
}

impl DField {
    /// A field without enum variants or flags.
    pub(super) fn plain(
        name: Option<String>,
        ty: &'static str,
        order: Option<&'static str>,
        offset: usize,
        size: usize,
    ) -> Self {
        DField { name, ty, order, offset, size, codes: Vec::new() }
    }
}

/// A drafted example.
#[derive(Debug, Clone)]
pub struct DExample {
    /// Figure labels (`16`, `T3`).
    pub figures: Vec<String>,
    /// Request as printed.
    pub request: Option<DraftFrame>,
    /// Response as printed.
    pub response: Option<DraftFrame>,
    /// Values the manual states, by data offset: (offset, YAML value).
    pub values: Vec<(usize, String)>,
}

/// A drafted command.
#[derive(Debug, Clone)]
pub struct DCommand {
    /// snake_case name.
    pub name: String,
    /// The manual's heading.
    pub title: String,
    /// Section number.
    pub section: String,
    /// Figures of the section.
    pub figures: Vec<String>,
    /// 0x03 or 0x10 (`None`: undecided).
    pub function: Option<u8>,
    /// Start address.
    pub address: Option<u16>,
    /// Registers.
    pub count: Option<u16>,
    /// Fields (empty: none or undecided).
    pub fields: Vec<DField>,
    /// The shared fragment command it equals: (file, command).
    pub uses: Option<(String, String)>,
    /// Examples.
    pub examples: Vec<DExample>,
    /// What a person must resolve.
    pub todos: Vec<String>,
    /// Table contradictions: (figure, key, table value, note).
    pub table_errata: Vec<(String, &'static str, String)>,
    /// The page the section starts on, when the text keeps page breaks.
    pub page: Option<u32>,
}

/// A drafted spec.
#[derive(Debug, Clone)]
pub struct Draft {
    /// The YAML text.
    pub yaml: String,
    /// Commands.
    pub commands: Vec<DCommand>,
    /// Manual-wide TODOs.
    pub todos: Vec<String>,
    /// The manual's header (cover, scope line, serial settings).
    pub(crate) header: Header,
    /// The manual's lines (cleaned) and where the command chapter ends.
    pub(crate) lines: Vec<String>,
    /// The first line after the command chapter (the procedure chapter).
    pub(crate) chapter_end: usize,
}

impl Draft {
    pub(super) fn frames(&self) -> impl Iterator<Item = &DraftFrame> {
        self.commands.iter().flat_map(|c| c.examples.iter()).flat_map(|e| [&e.request, &e.response]).flatten()
    }

    /// TODOs in the draft.
    pub fn todo_count(&self) -> usize {
        self.todos.len() + self.commands.iter().map(|c| c.todos.len()).sum::<usize>()
    }

    /// The import report.
    pub fn report(&self) -> String {
        let frames: Vec<&DraftFrame> = self.frames().collect();
        let verified = frames.iter().filter(|f| f.crc_verified()).count();
        let wrong = frames.iter().filter(|f| f.crc_wrong()).count();
        let without = frames.iter().filter(|f| f.crc.is_none()).count();
        let mut s = String::new();
        let shared = self.commands.iter().filter(|c| c.uses.is_some()).count();
        let _ = writeln!(s, "commands found: {} ({} taken from shared fragments)", self.commands.len(), shared);
        let _ = writeln!(
            s,
            "frames found: {}; CRC verified: {verified}; CRC wrong: {wrong} (drafted as errata); without CRC: {without}",
            frames.len()
        );
        let _ = writeln!(s, "TODOs: {}", self.todo_count());
        for t in &self.todos {
            let _ = writeln!(s, "  TODO(import): {t}");
        }
        for c in &self.commands {
            for t in &c.todos {
                let _ = writeln!(s, "  TODO(import): section {} ({}): {t}", c.section, c.title);
            }
        }
        s
    }
}

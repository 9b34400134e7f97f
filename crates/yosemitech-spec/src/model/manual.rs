//! Where a spec's facts come from: the manuals, their sections and
//! figures, and the sources that stand in for a manual.

use serde::Serialize;
use yosemitech_rtu::LineSettings;

use super::ser_line;

/// Where facts come from when no Modbus manual states them.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Provenance {
    /// Each source (a driver and its version, an issue), never empty.
    pub sources: Vec<String>,
    /// What the sources say and leave open.
    pub doc: Option<String>,
}

impl Provenance {
    /// `no manual: from A; B`, as `list`, the docs and the register maps show it.
    pub fn summary(&self) -> String {
        format!("no manual: from {}", self.sources.join("; "))
    }
}

/// The manual a sensor's spec transcribes.
#[derive(Debug, Clone, Serialize)]
pub struct Manual {
    /// The manual's title, one line, as printed on its cover.
    pub title: String,
    /// Revisions covered, as the manual's scope line states them.
    pub revision: String,
    /// The software revision it documents (`"1.7"`), when stated.
    pub software: Option<String>,
    /// The text extraction used.
    pub file: Option<String>,
    /// The serial settings the manual's builds state (claims, as printed;
    /// a client uses the sensor's or the revision's `serial`).
    pub serial_claims: Vec<SerialClaim>,
}

/// Serial settings a build of a manual states.
#[derive(Debug, Clone, Serialize)]
pub struct SerialClaim {
    /// The settings as printed.
    #[serde(serialize_with = "ser_line")]
    pub serial: LineSettings,
    /// The text extraction of the build, when not the manual's `file`.
    pub file: Option<String>,
    /// What is known about the build.
    pub doc: Option<String>,
}

/// Where the manual documents something.
#[derive(Debug, Clone, Serialize, PartialEq, Eq, Default)]
pub struct Source {
    /// Section, e.g. "2.2.3".
    pub section: String,
    /// Figures and tables cited, in the order written; may be empty.
    pub figures: Vec<Figure>,
    /// The manual's software revision when not the sensor's `manual`.
    pub manual: Option<String>,
}

/// A figure or table of a manual.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Figure {
    /// Figure `number`; `occurrence` 2 for the second figure a manual gives that number.
    Figure {
        /// The number printed under the figure (1 or more).
        number: u32,
        /// 1, or 2 and more for a number the manual repeats.
        occurrence: u8,
    },
    /// Table `number`, as printed (1 or more).
    Table(u32),
}

impl Figure {
    /// Figure `number` (its first occurrence).
    pub const fn number(number: u32) -> Self {
        Figure::Figure { number, occurrence: 1 }
    }

    /// Parses the spec's form: `23`, `"T4"` (Table 4), `"43b"` (the second figure 43).
    pub fn parse(text: &str) -> Result<Self, String> {
        let t = text.trim();
        let bad = || {
            format!(
                "`{}` is not a figure: use a number (23), `T<n>` for a table, `<n>b` for a repeated number",
                crate::names::escape(t)
            )
        };
        if let Some(n) = t.strip_prefix('T').or_else(|| t.strip_prefix("Table ")) {
            return n.parse::<u32>().map(Figure::Table).map_err(|_| bad());
        }
        let digits = t.trim_end_matches(|c: char| c.is_ascii_lowercase());
        let suffix = &t[digits.len()..];
        let number = digits.parse::<u32>().map_err(|_| bad())?;
        let occurrence = match suffix {
            "" => 1,
            s if s.len() == 1 => s.as_bytes()[0] - b'a' + 1,
            _ => return Err(bad()),
        };
        Ok(Figure::Figure { number, occurrence })
    }
}

impl std::fmt::Display for Figure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Figure::Figure { number, occurrence: 1 } => write!(f, "{number}"),
            Figure::Figure { number, occurrence } => {
                write!(f, "{number}{}", char::from(b'a' + occurrence.saturating_sub(1)))
            }
            Figure::Table(n) => write!(f, "T{n}"),
        }
    }
}

impl Serialize for Figure {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Figure::Figure { number, occurrence: 1 } => s.serialize_u32(*number),
            other => s.collect_str(other),
        }
    }
}

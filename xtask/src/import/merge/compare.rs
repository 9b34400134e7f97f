//! The review's rows and differences: commands, frames and the draft's TODOs.

use yosemitech_spec::CommandSpec;

use super::super::review::CommandRow;
use super::super::{DCommand, DraftFrame};
use super::recorded::figs;

/// The figure a frame-level TODO of the draft names (`Fig 34: ...`).
pub(super) fn todo_figure(t: &str) -> Option<&str> {
    t.strip_prefix("Fig ")?.split(':').next()
}

pub(super) fn is_table_todo(t: &str) -> bool {
    t.contains("contradicts the printed frames: check the drafted table errata")
}

/// Byte positions where two frames differ (and a length difference).
pub(super) fn differing_bytes(a: &DraftFrame, b: &DraftFrame) -> String {
    let mut at: Vec<String> = Vec::new();
    let n = a.bytes.len().max(b.bytes.len());
    for i in 0..n {
        if a.bytes.get(i) != b.bytes.get(i) {
            at.push(i.to_string());
        }
    }
    let mut s = if at.is_empty() { String::new() } else { format!("bytes {}", at.join(", ")) };
    if a.crc != b.crc {
        s.push_str(if s.is_empty() { "CRC" } else { ", CRC" });
    }
    if a.open_ended != b.open_ended {
        s.push_str(if s.is_empty() { "open end" } else { ", open end" });
    }
    s
}

pub(super) fn function_name(f: Option<u8>) -> String {
    match f {
        Some(0x03) => "read".into(),
        Some(0x10) => "write".into(),
        Some(f) => format!("0x{f:02X}"),
        None => "?".into(),
    }
}

pub(super) fn row_of_draft(d: &DCommand, name: &str, note: Option<String>) -> CommandRow {
    CommandRow {
        name: name.to_string(),
        function: function_name(d.function),
        address: d.address.map(|a| format!("0x{a:04X}")).unwrap_or_else(|| "?".into()),
        count: d.count.map(u32::from),
        section: d.section.clone(),
        title: d.title.clone(),
        figures: d.figures.clone(),
        page: d.page,
        note,
    }
}

pub(super) fn row_of_spec(c: &CommandSpec, note: Option<String>) -> CommandRow {
    CommandRow {
        name: c.name.clone(),
        function: function_name(Some(c.function.code())),
        address: format!("0x{:04X}", c.address),
        count: Some(u32::from(c.count)),
        section: c.source.section.clone(),
        title: c.title.clone(),
        figures: figs(&c.source.figures),
        page: None,
        note,
    }
}

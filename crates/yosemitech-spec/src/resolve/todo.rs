//! Points `cargo xtask import` left to a person: every `TODO(import)` in a
//! spec file is an error at its line and column until someone resolves the
//! point and deletes the marker.

use crate::diag::{Pos, Reporter};

/// The marker the importer writes (in a comment) where it could not decide.
pub const IMPORT_TODO: &str = "TODO(import)";

/// Most markers reported one by one in a file; the rest are counted.
const MAX_REPORTED: usize = 20;

/// Reports every `TODO(import)` of `text`.
pub(super) fn check_import_todos(text: &str, r: &mut Reporter<'_>) {
    let mut found = 0usize;
    let mut last = Pos::default();
    for (i, line) in text.lines().enumerate() {
        for (at, _) in line.match_indices(IMPORT_TODO) {
            found += 1;
            let column = line[..at].chars().count() as u32 + 1;
            last = Pos { line: i as u32 + 1, column };
            if found > MAX_REPORTED {
                continue;
            }
            let point: String = line[at + IMPORT_TODO.len()..]
                .trim_start_matches(':')
                .trim()
                .chars()
                .filter(|c| !c.is_control())
                .take(160)
                .collect();
            let message = if point.is_empty() {
                "an import TODO is unresolved".to_string()
            } else {
                format!("an import TODO is unresolved: {point}")
            };
            r.error(
                last,
                "",
                message,
                Some(format!(
                    "check the manual where it says, fix the spec, then delete the `{IMPORT_TODO}` comment (docs/importer.md)"
                )),
            );
        }
    }
    if found > MAX_REPORTED {
        r.error(
            last,
            "",
            format!("{} more import TODOs are unresolved (the last is here)", found - MAX_REPORTED),
            Some(format!("resolve every `{IMPORT_TODO}` of the file")),
        );
    }
}

//! A sensor's errata: the mistakes of its manual that are not about one
//! command's table or examples (those are resolved with the command).
//!
//! Every erratum keeps its id, figures, manual, sections and note; ids are
//! short identifiers, unique within the file, and all text is checked like
//! any other.

use std::collections::BTreeSet;

use crate::Spanned;

use crate::check::{check_erratum_id, check_text, resolve_figures};
use crate::diag::{Pos, Reporter};
use crate::document::ErratumDoc;
use crate::model::Erratum;

pub(super) fn resolve_errata(docs: &[ErratumDoc], r: &mut Reporter<'_>) -> Vec<Erratum> {
    let mut ids = BTreeSet::new();
    docs.iter()
        .enumerate()
        .map(|(i, e)| {
            check_erratum_id(&e.id, &format!("errata[{i}].id"), &mut ids, r);
            let sections = e
                .sections
                .iter()
                .enumerate()
                .map(|(j, section)| {
                    // Sections are plain strings (no positions): check them as if written at the id.
                    let spanned = Spanned { value: section.clone(), ..e.id.clone() };
                    check_text(&spanned, &format!("errata[{i}].sections[{j}]"), r)
                })
                .collect();
            Erratum {
                id: e.id.value.clone(),
                figures: resolve_figures(&e.figures, &format!("errata[{i}].figures"), Pos::at(&e.id), r),
                manual: e.manual.as_ref().map(|m| check_text(m, &format!("errata[{i}].manual"), r)),
                sections,
                note: check_text(&e.note, &format!("errata[{i}].note"), r),
            }
        })
        .collect()
}

//! `--into`: a manual compared with the spec of its probe, command by
//! command and frame by frame, and the merge planned.
//!
//! The draft of the manual (the importer's own, see `draft.rs`) is matched
//! with the spec's commands by function and start address. For each pair:
//! a count or a confidently drafted field that differs is a change (left to
//! a person); each printed frame identical to a recorded one is cited (the
//! example gains `also_in` with this manual's figures); any other frame
//! becomes an example of this manual, its values decoded with the spec's
//! fields. Commands only the manual has are added (`since:` when the
//! manual is the newest); commands only the spec has get `since:` (an older
//! manual) or a TODO. What the plan cannot decide is a TODO, never a guess.
//!
//! The plan is here; what the spec records (`recorded`), the review's rows
//! (`compare`) and the YAML the merge adds (`render`) are its helpers.

use std::collections::BTreeMap;

use yosemitech_spec::{CommandSpec, Sensor, Spec};

use super::review::{Changed, ErratumRow, FrameDiff, FrameRow, Renumbered, Review, SerialRow, SinceRow};
use super::{Draft, DraftFrame, file_name, one_line_text, printed_key, q};
use compare::{differing_bytes, function_name, is_table_todo, row_of_draft, row_of_spec, todo_figure};
use recorded::{figs, frames_of, id_generator, known_table_erratum, mapped_figures, same_table};
pub(in crate::import) use render::citation_item;
use render::{example_item, revision_doc, table_erratum_item};

mod compare;
mod recorded;
mod render;

/// Serial settings, comparable and printable as `9600 8N1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Serial {
    baud: u32,
    data_bits: u32,
    parity: &'static str,
    stop_bits: u32,
}

impl Serial {
    fn of(line: &yosemitech_rtu::LineSettings) -> Self {
        Serial {
            baud: line.baud,
            data_bits: line.format.data_bits.bits(),
            parity: line.format.parity.name(),
            stop_bits: line.format.stop_bits.bits(),
        }
    }

    /// As the spec writes it.
    fn yaml(&self) -> String {
        format!(
            "{{baud: {}, data_bits: {}, parity: {}, stop_bits: {}}}",
            self.baud, self.data_bits, self.parity, self.stop_bits
        )
    }
}

impl std::fmt::Display for Serial {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = self.parity.chars().next().map_or('N', |c| c.to_ascii_uppercase());
        write!(f, "{} {}{}{}", self.baud, self.data_bits, p, self.stop_bits)
    }
}

/// Where the manual's software stands among the recorded manuals.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Place {
    /// Newer than every recorded manual.
    Newer,
    /// Older than every recorded manual.
    Older,
    /// Between two recorded manuals.
    Between,
    /// A recorded manual's software: `None` the file's `manual`, `Some(i)` `revisions[i]`.
    Recorded(Option<usize>),
}

/// Changes to one command of the spec.
#[derive(Debug, Default)]
pub(crate) struct CommandEdit {
    /// The `since:` to write (set, or replace).
    pub since: Option<String>,
    /// Citations: (index of the example among the command's, this manual's figures).
    pub citations: Vec<(usize, Vec<String>)>,
    /// New example items, YAML at indent 0.
    pub examples: Vec<String>,
    /// New command errata items, YAML at indent 0.
    pub errata: Vec<String>,
    /// TODOs about the command.
    pub todos: Vec<String>,
}

/// A command the manual adds.
#[derive(Debug)]
pub(crate) struct NewCommand {
    /// The spec command it follows in the manual's order (`None`: first).
    pub after: Option<String>,
    /// The item, as `render_command` writes it (two-space item indent).
    pub text: String,
    /// The fragment command it uses: (fragment file, command).
    pub uses: Option<(String, String)>,
}

/// The merge: what to add to the spec's text.
#[derive(Debug, Default)]
pub(crate) struct Plan {
    /// This manual's software (the `manual:` its additions carry).
    pub software: String,
    /// A new `sensor.revisions` entry, YAML at indent 0 (`- manual: ...`).
    pub revision: Option<String>,
    /// A serial claim for a recorded manual: (`None` the file's `manual`,
    /// `Some(i)` `revisions[i]`), the claim item at indent 0.
    pub claim: Option<(Option<usize>, String)>,
    /// Changes by spec command name.
    pub commands: BTreeMap<String, CommandEdit>,
    /// Commands added, in the manual's order.
    pub new_commands: Vec<NewCommand>,
    /// TODOs about the whole file.
    pub file_todos: Vec<String>,
}

impl Plan {
    /// True when the plan changes nothing.
    pub fn is_empty(&self) -> bool {
        self.revision.is_none()
            && self.claim.is_none()
            && self.new_commands.is_empty()
            && self.file_todos.is_empty()
            && self.commands.values().all(|c| {
                c.since.is_none()
                    && c.citations.is_empty()
                    && c.examples.is_empty()
                    && c.errata.is_empty()
                    && c.todos.is_empty()
            })
    }

    fn edit(&mut self, name: &str) -> &mut CommandEdit {
        self.commands.entry(name.to_string()).or_default()
    }
}

/// The version's numbers, for ordering (`"1.10"` after `"1.9"`).
fn vkey(s: &str) -> Vec<u32> {
    s.split('.').filter_map(|x| x.trim().parse().ok()).collect()
}

/// Where `software` stands among the sensor's manuals.
pub(crate) fn place(sensor: &Sensor, software: &str) -> Result<Place, String> {
    let mut recorded: Vec<(Option<usize>, &str)> = Vec::new();
    if let Some(sw) = sensor.manual.as_ref().and_then(|m| m.software.as_ref()) {
        recorded.push((None, sw));
    }
    for (i, r) in sensor.revisions.iter().enumerate() {
        if let Some(sw) = &r.manual.software {
            recorded.push((Some(i), sw));
        }
    }
    if recorded.is_empty() {
        return Err(format!(
            "{} states no `software` for its manual, so another revision cannot be placed; add `software:` to `sensor.manual` first",
            super::identify::shown(sensor)
        ));
    }
    if let Some((i, _)) = recorded.iter().find(|(_, sw)| vkey(sw) == vkey(software)) {
        return Ok(Place::Recorded(*i));
    }
    let v = vkey(software);
    if recorded.iter().all(|(_, sw)| vkey(sw) < v) {
        Ok(Place::Newer)
    } else if recorded.iter().all(|(_, sw)| vkey(sw) > v) {
        Ok(Place::Older)
    } else {
        Ok(Place::Between)
    }
}

/// Compares the draft with the sensor and plans the merge; fills the review.
pub(crate) fn plan(
    spec: &Spec,
    sensor: &Sensor,
    d: &Draft,
    manual_file: &str,
    software: &str,
    place: &Place,
    review: &mut Review,
) -> Plan {
    let mut plan = Plan { software: software.to_string(), ..Plan::default() };
    let default_sw = sensor.manual.as_ref().and_then(|m| m.software.clone()).unwrap_or_default();
    let mut next_id = id_generator(sensor);
    let recorded_sw: Vec<String> = sensor.manuals().filter_map(|m| m.software.clone()).collect();
    let oldest = recorded_sw.iter().min_by_key(|s| vkey(s)).cloned().unwrap_or_default();
    let newest = recorded_sw.iter().max_by_key(|s| vkey(s)).cloned().unwrap_or_default();
    let present = |c: &CommandSpec, sw: &str| c.since.as_deref().is_none_or(|s| vkey(s) <= vkey(sw));

    // Match the manual's commands with the spec's: function and start address.
    let mut matched: Vec<Option<usize>> = Vec::new();
    let mut taken = vec![false; sensor.commands.len()];
    for dc in &d.commands {
        let m =
            sensor.commands.iter().enumerate().position(|(i, c)| {
                !taken[i] && Some(c.function.code()) == dc.function && Some(c.address) == dc.address
            });
        if let Some(i) = m {
            taken[i] = true;
        }
        matched.push(m);
    }

    // Commands of both.
    for (dc, m) in d.commands.iter().zip(&matched) {
        let Some(i) = *m else { continue };
        let c = &sensor.commands[i];
        let edit_name = c.name.clone();
        // The command's layout.
        if dc.count.is_some_and(|n| n != c.count) {
            let n = dc.count.unwrap_or_default();
            review.commands_changed.push(Changed {
                name: c.name.clone(),
                what: "count".into(),
                spec: c.count.to_string(),
                manual: n.to_string(),
                section: dc.section.clone(),
                figures: dc.figures.clone(),
                page: dc.page,
            });
            plan.edit(&edit_name).todos.push(format!(
                "section {} of SW {software}'s manual gives {} registers where the spec has {}: the spec language has one layout per command",
                dc.section, n, c.count
            ));
        }
        // Fields the draft is sure of (floats, text); a shared command's are the fragment's.
        let shared_layout = dc.uses.is_some() && c.shared_from.is_some();
        let confident: Vec<&super::DField> =
            dc.fields.iter().filter(|f| !shared_layout && matches!(f.ty, "f32" | "ascii")).collect();
        let clash: Vec<String> = confident
            .iter()
            .filter(|f| {
                !c.fields.iter().any(|s| s.offset == f.offset && s.kind.type_name() == f.ty && s.size() == f.size)
            })
            .map(|f| format!("{} at byte {} ({} bytes)", f.ty, f.offset, f.size))
            .collect();
        if !clash.is_empty() && dc.count == Some(c.count) {
            let layout: Vec<String> =
                c.fields.iter().map(|f| format!("{} at byte {}", f.kind.type_name(), f.offset)).collect();
            review.commands_changed.push(Changed {
                name: c.name.clone(),
                what: "fields".into(),
                spec: layout.join(", "),
                manual: clash.join(", "),
                section: dc.section.clone(),
                figures: dc.figures.clone(),
                page: dc.page,
            });
            plan.edit(&edit_name).todos.push(format!(
                "section {}: SW {software}'s frames carry {} where the spec's fields differ: check the layout",
                dc.section,
                clash.join(", ")
            ));
        }
        // Since.
        if let Some(s) = &c.since
            && vkey(software) < vkey(s)
        {
            plan.edit(&edit_name).since = Some(software.to_string());
            review.since.push(SinceRow {
                name: c.name.clone(),
                since: software.to_string(),
                was: Some(s.clone()),
                why: format!("SW {software}'s manual documents it (section {})", dc.section),
            });
        }
        if let Place::Recorded(_) = place
            && !present(c, software)
        {
            plan.edit(&edit_name).todos.push(format!(
                "section {}: this build of SW {software}'s manual documents the command, which the spec gives `since: {}`",
                dc.section,
                c.since.clone().unwrap_or_default()
            ));
        }
        // Renumbered section and figures.
        let old = figs(&c.source.figures);
        let source_sw = c.source.manual.clone().unwrap_or_else(|| default_sw.clone());
        if source_sw != software
            && !c.source.section.is_empty()
            && (c.source.section != dc.section || (old.len() == dc.figures.len() && old != dc.figures))
        {
            review.figures_renumbered.push(Renumbered {
                command: c.name.clone(),
                manual_from: source_sw.clone(),
                section_from: c.source.section.clone(),
                section_to: dc.section.clone(),
                figures_from: old.clone(),
                figures_to: dc.figures.clone(),
                page: dc.page,
            });
        }
        // Frames.
        let frame_todos: Vec<&String> = dc.todos.iter().filter(|t| todo_figure(t).is_some()).collect();
        for de in &dc.examples {
            let key = (de.request.clone(), de.response.clone());
            let hit = c
                .examples
                .iter()
                .enumerate()
                .filter(|(_, x)| frames_of(x) == key)
                .min_by_key(|(_, x)| x.manual.is_some());
            match hit {
                Some((j, x)) => {
                    let x_sw = x.manual.clone().unwrap_or_else(|| default_sw.clone());
                    let has_it = c.examples.iter().any(|y| {
                        frames_of(y) == key
                            && (y.manual.as_deref().unwrap_or(&default_sw) == software
                                || y.also_in.iter().any(|a| a.manual == software))
                    });
                    let mapped = mapped_figures(c, dc, x, &default_sw, de);
                    let edit = plan.edit(&edit_name);
                    if let Some((_, figures)) = edit.citations.iter_mut().find(|(k, _)| *k == j) {
                        // The manual prints the same frames twice: one citation, every figure.
                        for f in mapped {
                            if !figures.contains(&f) {
                                figures.push(f);
                            }
                        }
                        continue;
                    }
                    if has_it {
                        continue;
                    }
                    review.frames_cited.push(FrameRow {
                        command: c.name.clone(),
                        figures: mapped.clone(),
                        recorded_manual: Some(x_sw),
                        recorded_figures: figs(&x.figures),
                        page: dc.page,
                    });
                    plan.edit(&edit_name).citations.push((j, mapped));
                }
                None => {
                    // The nearest recorded example: the source manual's first.
                    let near = c
                        .examples
                        .iter()
                        .find(|x| x.manual.as_deref().unwrap_or(&default_sw) == source_sw)
                        .or(c.examples.first());
                    let figures = match near {
                        Some(x) => mapped_figures(c, dc, x, &default_sw, de),
                        None => de.figures.clone(),
                    };
                    if near.is_none() {
                        review.frames_new.push(FrameRow {
                            command: c.name.clone(),
                            figures: figures.clone(),
                            recorded_manual: None,
                            recorded_figures: Vec::new(),
                            page: dc.page,
                        });
                    }
                    for (side, new, old) in [
                        ("request", &de.request, near.and_then(|x| x.request.as_ref()).map(printed_key)),
                        ("response", &de.response, near.and_then(|x| x.response.as_ref()).map(printed_key)),
                    ] {
                        let Some(new) = new else { continue };
                        if near.is_none() || old.as_ref() == Some(new) {
                            continue;
                        }
                        review.frames_differ.push(FrameDiff {
                            command: c.name.clone(),
                            figures: figures.clone(),
                            page: dc.page,
                            side: side.into(),
                            printed: new.text(),
                            recorded: old.as_ref().map(DraftFrame::text),
                            recorded_manual: near.map(|x| x.manual.clone().unwrap_or_else(|| default_sw.clone())),
                            recorded_figures: near.map(|x| figs(&x.figures)).unwrap_or_default(),
                            bytes: old.as_ref().map(|o| differing_bytes(o, new)).unwrap_or_default(),
                        });
                    }
                    let item = example_item(Some(c), de, &figures, software, &mut next_id);
                    let edit = plan.edit(&edit_name);
                    edit.examples.push(item);
                    for t in
                        frame_todos.iter().filter(|t| todo_figure(t).is_some_and(|f| de.figures.iter().any(|x| x == f)))
                    {
                        edit.todos.push(format!("section {}: {}", dc.section, t));
                    }
                    if let Place::Recorded(_) = place {
                        edit.todos.push(format!(
                            "section {}: SW {software} is recorded, but this build of its manual prints other frames (Figs {}): another build?",
                            dc.section,
                            figures.join(", ")
                        ));
                    }
                }
            }
        }
        // Table errata.
        for (fig, key, val) in &dc.table_errata {
            let recorded_here = c
                .errata
                .iter()
                .any(|e| same_table(e, key, val) && e.manual.as_deref().unwrap_or(&default_sw) == software);
            if recorded_here {
                continue;
            }
            let known = known_table_erratum(spec, sensor, &c.name, c.shared_from.as_deref(), key, val);
            let id = next_id();
            let note = match &known {
                Some(k) => format!(
                    "As {k}: the register table gives {key} {val}; the CRC-valid frames of this section are what the probe sends."
                ),
                None => "The register table disagrees with the printed frames; the frames are used.".to_string(),
            };
            let (item, table_todo) = table_erratum_item(id.clone(), fig, (key, val), software, note);
            review.errata.push(ErratumRow {
                command: c.name.clone(),
                id: id.clone(),
                figure: fig.clone(),
                table: format!("{key}: {val}"),
                known: known.clone(),
                todo: known.is_none(),
            });
            let edit = plan.edit(&edit_name);
            edit.errata.push(item);
            if known.is_none() {
                edit.todos.push(format!(
                    "section {}: the register table (Fig {fig}) gives {key} {val} against the printed frames: check erratum {id}",
                    dc.section
                ));
            }
            if let Some(todo) = table_todo {
                edit.todos.push(format!("section {}: erratum {id}: {todo}", dc.section));
            }
        }
    }

    // A command the manual documents at another address or with another
    // function, by its name or title: a change, not an addition and a removal.
    let mut moved: Vec<Option<usize>> = vec![None; d.commands.len()];
    for (k, (dc, m)) in d.commands.iter().zip(&matched).enumerate() {
        if m.is_some() {
            continue;
        }
        let names = [dc.uses.as_ref().map(|u| u.1.clone()), Some(dc.name.clone()), Some(super::snake(&dc.title))];
        let Some(i) = sensor.commands.iter().enumerate().position(|(i, c)| {
            !taken[i]
                && (names.iter().flatten().any(|n| *n == c.name) || super::snake(&c.title) == super::snake(&dc.title))
        }) else {
            continue;
        };
        let c = &sensor.commands[i];
        taken[i] = true;
        moved[k] = Some(i);
        let mut what = Vec::new();
        if dc.function != Some(c.function.code()) {
            what.push(("function", function_name(Some(c.function.code())), function_name(dc.function)));
        }
        if dc.address != Some(c.address) {
            what.push((
                "address",
                format!("0x{:04X}", c.address),
                dc.address.map(|a| format!("0x{a:04X}")).unwrap_or_else(|| "?".into()),
            ));
        }
        if dc.count.is_some_and(|n| n != c.count) {
            what.push(("count", c.count.to_string(), dc.count.map(|n| n.to_string()).unwrap_or_default()));
        }
        for (key, was, now) in what {
            review.commands_changed.push(Changed {
                name: c.name.clone(),
                what: key.into(),
                spec: was.clone(),
                manual: now.clone(),
                section: dc.section.clone(),
                figures: dc.figures.clone(),
                page: dc.page,
            });
            plan.edit(&c.name).todos.push(format!(
                "section {} (\"{}\") of SW {software}'s manual gives {key} {now} where the spec has {was}: the spec language has one layout per command",
                dc.section, dc.title
            ));
        }
    }

    // Commands only the spec has.
    for (i, c) in sensor.commands.iter().enumerate() {
        if taken[i] {
            continue;
        }
        match place {
            Place::Newer => {
                if present(c, &newest) {
                    review.commands_removed.push(row_of_spec(c, Some(format!("not in SW {software}'s manual"))));
                    plan.edit(&c.name).todos.push(format!(
                        "SW {software}'s manual does not document this command (newer than every recorded manual): removed by that firmware, or missed by the importer? The spec language cannot say a command was removed"
                    ));
                }
            }
            Place::Older => {
                if c.since.is_none() {
                    plan.edit(&c.name).since = Some(oldest.clone());
                    review.since.push(SinceRow {
                        name: c.name.clone(),
                        since: oldest.clone(),
                        was: None,
                        why: format!("SW {software}'s manual (older) does not document it"),
                    });
                }
            }
            Place::Between | Place::Recorded(_) => {
                if present(c, software) {
                    review.commands_removed.push(row_of_spec(c, Some(format!("not in SW {software}'s manual"))));
                    plan.edit(&c.name).todos.push(format!(
                        "SW {software}'s manual does not document this command, which the spec has in that revision: removed, or missed by the importer?"
                    ));
                }
            }
        }
    }

    // Commands only the manual has.
    let fragment_name = |file: &str| spec.fragments.iter().find(|f| file_name(&f.file) == file).map(|f| f.name.clone());
    let mut previous: Option<String> = None;
    let mut names: Vec<String> = sensor.commands.iter().map(|c| c.name.clone()).collect();
    for ((dc, m), moved) in d.commands.iter().zip(&matched).zip(&moved) {
        if let Some(i) = *m {
            previous = Some(sensor.commands[i].name.clone());
            continue;
        }
        if let Some(i) = *moved {
            previous = Some(sensor.commands[i].name.clone());
            continue;
        }
        let mut dc = dc.clone();
        let name = dc.uses.as_ref().map_or_else(|| dc.name.clone(), |(_, n)| n.clone());
        if dc.uses.is_none() {
            let mut n = 2;
            while names.contains(&dc.name) {
                dc.name = format!("{}_{n}", name);
                n += 1;
            }
        }
        names.push(dc.name.clone());
        let shown_name = dc.uses.as_ref().map_or_else(|| dc.name.clone(), |(_, n)| n.clone());
        // What the spec language records as printed, or a fragment defines, needs no person.
        let trigger_read = dc.uses.as_ref().is_some_and(|(file, n)| {
            spec.fragments
                .iter()
                .filter(|f| file_name(&f.file) == *file)
                .flat_map(|f| &f.commands)
                .any(|c| c.name == *n && c.trigger && c.is_read())
        });
        let shared_from = dc.uses.as_ref().and_then(|(file, _)| fragment_name(file));
        let mut table_notes = Vec::new();
        let mut all_known = true;
        for (fig, key, val) in &dc.table_errata {
            let known = known_table_erratum(spec, sensor, &shown_name, shared_from.as_deref(), key, val);
            table_notes.push(match &known {
                Some(k) => format!(
                    "As {k}: the register table gives {key} {val}; the CRC-valid frames of this section are what the probe sends."
                ),
                None => "The register table disagrees with the printed frames; the frames are used.".to_string(),
            });
            all_known &= known.is_some();
            review.errata.push(ErratumRow {
                command: shown_name.clone(),
                id: String::new(),
                figure: fig.clone(),
                table: format!("{key}: {val}"),
                known: known.clone(),
                todo: known.is_none(),
            });
        }
        let mut todos: Vec<String> = dc
            .todos
            .iter()
            .filter(|t| !(trigger_read && t.contains("bytes left open")))
            .filter(|t| !(all_known && is_table_todo(t)))
            .cloned()
            .collect();
        let since = match place {
            Place::Newer => Some(software.to_string()),
            Place::Older | Place::Between => {
                todos.push(format!(
                    "SW {software}'s manual documents this command, the newer recorded manuals do not: the spec language cannot say a command was removed"
                ));
                Some(software.to_string())
            }
            Place::Recorded(_) => {
                todos.push(format!(
                    "SW {software} is recorded, but this build of its manual adds this command: another build?"
                ));
                None
            }
        };
        let mut ids: Vec<String> = Vec::new();
        let mut mint = || {
            let id = next_id();
            ids.push(id.clone());
            id
        };
        let mut text = String::new();
        let mut o = super::CommandRender {
            manual: Some(software),
            since: since.as_deref(),
            todos: Some(&todos),
            table_notes,
            next_id: &mut mint,
        };
        super::render_command(&mut text, &dc, &mut o);
        // The ids the rendering gave, in the review.
        for (e, id) in review.errata.iter_mut().filter(|e| e.command == shown_name && e.id.is_empty()).zip(&ids) {
            e.id = id.clone();
        }
        review.commands_added.push(row_of_draft(&dc, &shown_name, since.as_ref().map(|s| format!("since \"{s}\""))));
        for e in &dc.examples {
            review.frames_new.push(FrameRow {
                command: shown_name.clone(),
                figures: e.figures.clone(),
                recorded_manual: None,
                recorded_figures: Vec::new(),
                page: dc.page,
            });
        }
        plan.new_commands.push(NewCommand { after: previous.clone(), text, uses: dc.uses.clone() });
        previous = Some(shown_name);
    }

    // The draft's manual-wide TODOs (no software revision: refused before;
    // no baud rate: the spec has its serial settings) need nothing here.

    // Serial settings.
    let h = &d.header;
    let manual_serial = h.baud.map(|baud| Serial {
        baud,
        data_bits: u32::from(h.data_bits.unwrap_or(8)),
        parity: h.parity.unwrap_or("none"),
        stop_bits: u32::from(h.stop_bits.unwrap_or(1)),
    });
    let (client, claims, recorded_file) = match place {
        Place::Recorded(Some(i)) => {
            let r = &sensor.revisions[*i];
            (Serial::of(&r.serial), r.manual.serial_claims.clone(), r.manual.file.clone())
        }
        Place::Recorded(None) => {
            let manual = sensor.manual.as_ref();
            (
                Serial::of(&sensor.serial),
                manual.map(|m| m.serial_claims.clone()).unwrap_or_default(),
                manual.and_then(|m| m.file.clone()),
            )
        }
        _ => (Serial::of(&sensor.serial), Vec::new(), None),
    };
    let mut claim_item = None;
    let mut recorded_as = None;
    if let Some(ms) = manual_serial {
        let same_build = recorded_file.as_deref() == Some(manual_file);
        let claimed = claims.iter().any(|c| Serial::of(&c.serial) == ms);
        let agrees = if claims.is_empty() { ms == client } else { claimed };
        if !agrees || (!same_build && !claims.is_empty() && !claimed) {
            let file = match place {
                Place::Recorded(_) if !same_build => format!("\n  file: {}", q(manual_file)),
                _ => String::new(),
            };
            claim_item = Some(format!("- serial: {}{file}\n", ms.yaml()));
            recorded_as = Some(format!(
                "`serial_claims` of SW {software}'s manual; clients keep {client}{}",
                if ms.baud != client.baud || ms.parity != client.parity || ms.data_bits != client.data_bits {
                    " (check which the probes use)"
                } else {
                    ""
                }
            ));
            if ms.baud != client.baud || ms.parity != client.parity || ms.data_bits != client.data_bits {
                plan.file_todos.push(format!(
                    "SW {software}'s manual states {ms} where the spec's probes use {client}: if probes of that firmware really differ (more than the stop bits), give the revision its own `serial:`"
                ));
            }
        }
    } else {
        recorded_as = Some("the manual states no baud rate".into());
    }
    review.serial = SerialRow { manual: manual_serial.map(|s| s.to_string()), spec: client.to_string(), recorded_as };

    // The revision entry, or the claim of a recorded manual.
    match place {
        Place::Recorded(i) => {
            if let Some(item) = claim_item {
                plan.claim = Some((*i, item));
            }
        }
        _ => {
            let mut y = String::new();
            y.push_str("- manual:\n");
            y.push_str(&format!("    title: {}\n", q(&h.manual_title)));
            let revision = h.revision.clone().unwrap_or_else(|| format!("SW Rev{software}"));
            y.push_str(&format!("    revision: {}\n", q(&revision)));
            y.push_str(&format!("    software: {}\n", q(software)));
            y.push_str(&format!("    file: {}\n", q(manual_file)));
            if let Some(item) = &claim_item {
                y.push_str("    serial_claims:\n");
                for l in item.lines() {
                    y.push_str(&format!("      {l}\n"));
                }
            }
            y.push_str(&format!("  doc: {}\n", q(&revision_doc(review, software, place, &newest, &oldest))));
            plan.revision = Some(y);
        }
    }

    // Procedure.
    review.procedure = super::procedure::compare_procedure(sensor, d, software);
    for t in &plan.file_todos {
        review.todos.push(one_line_text(t));
    }
    plan
}

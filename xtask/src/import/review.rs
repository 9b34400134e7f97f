//! The review `--into` prints: what the manual changes against the spec,
//! with the manual's section, figures and page for each point, as text or
//! (`--json`) as the same data.

use std::fmt::Write as _;

use serde::Serialize;

/// How the manual was recognised as one of the spec's probe.
#[derive(Debug, Clone, Default, Serialize)]
pub(crate) struct Identified {
    /// The serial numbers the manual prints.
    pub serial_numbers: Vec<String>,
    /// Their model code (digits 3-4).
    pub model_code: Option<String>,
    /// The spec's `model_code`.
    pub spec_model_code: Option<String>,
    /// Commands the manual documents (with function, address and count).
    pub commands_in_manual: usize,
    /// Commands the spec has.
    pub commands_in_spec: usize,
    /// The manual's commands the spec has (same function, address, count).
    pub shared: usize,
    /// The weighted match of the command sets, 0..1.
    pub score: f64,
    /// A remark (a sibling's serial number).
    pub note: Option<String>,
}

/// A command added or removed.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct CommandRow {
    /// The command's name in the spec.
    pub name: String,
    /// `read` or `write`.
    pub function: String,
    /// Start address, `0x2E00`.
    pub address: String,
    /// Registers.
    pub count: Option<u32>,
    /// The section (the manual's for an added command, the spec's source for a removed one).
    pub section: String,
    /// The heading.
    pub title: String,
    /// Its figures.
    pub figures: Vec<String>,
    /// Its page in the manual, when the text keeps page breaks.
    pub page: Option<u32>,
    /// `since "1.8"`, or why it is listed.
    pub note: Option<String>,
}

/// A command whose layout the manual gives otherwise.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Changed {
    /// The command.
    pub name: String,
    /// `count` or `fields`.
    pub what: String,
    /// The spec's.
    pub spec: String,
    /// The manual's.
    pub manual: String,
    /// The manual's section.
    pub section: String,
    /// Its figures.
    pub figures: Vec<String>,
    /// Its page.
    pub page: Option<u32>,
}

/// A `since:` set or changed.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct SinceRow {
    /// The command.
    pub name: String,
    /// The value written.
    pub since: String,
    /// The value before, if any.
    pub was: Option<String>,
    /// Why.
    pub why: String,
}

/// A frame pair of the manual: cited (identical to a recorded one) or new.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct FrameRow {
    /// The command.
    pub command: String,
    /// The manual's figures.
    pub figures: Vec<String>,
    /// The recorded example's manual (software), for a citation.
    pub recorded_manual: Option<String>,
    /// The recorded example's figures.
    pub recorded_figures: Vec<String>,
    /// The page.
    pub page: Option<u32>,
}

/// A printed frame that differs from the recorded one.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct FrameDiff {
    /// The command.
    pub command: String,
    /// The manual's figures.
    pub figures: Vec<String>,
    /// The page.
    pub page: Option<u32>,
    /// `request` or `response`.
    pub side: String,
    /// As this manual prints it.
    pub printed: String,
    /// As the spec records it (the nearest example), if it records one.
    pub recorded: Option<String>,
    /// That example's manual.
    pub recorded_manual: Option<String>,
    /// That example's figures.
    pub recorded_figures: Vec<String>,
    /// Where they differ.
    pub bytes: String,
}

/// A command whose section or figures the manual numbers otherwise.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Renumbered {
    /// The command.
    pub command: String,
    /// The manual the spec's numbers are of.
    pub manual_from: String,
    /// The spec's section.
    pub section_from: String,
    /// The manual's.
    pub section_to: String,
    /// The spec's figures.
    pub figures_from: Vec<String>,
    /// The manual's.
    pub figures_to: Vec<String>,
    /// The page.
    pub page: Option<u32>,
}

/// The serial settings.
#[derive(Debug, Clone, Default, Serialize)]
pub(crate) struct SerialRow {
    /// As the manual states them.
    pub manual: Option<String>,
    /// What the spec's clients use for this software.
    pub spec: String,
    /// How the difference is recorded, if there is one.
    pub recorded_as: Option<String>,
}

/// A number or command of the manual's procedure chapter.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct ProcedureRow {
    /// The number (`10 s`) or the spec's value (`procedure.readings = 10`).
    pub what: String,
    /// What the manual says of it, when it is the spec's value.
    pub manual: String,
    /// The spec's value it matches (`procedure.warm_up_ms = 10000`).
    pub spec: Option<String>,
    /// The chapter's figure.
    pub figure: Option<String>,
    /// Its page.
    pub page: Option<u32>,
}

/// A table erratum the merge drafted.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct ErratumRow {
    /// The command.
    pub command: String,
    /// The id written.
    pub id: String,
    /// The figure of the register table.
    pub figure: String,
    /// What the table prints.
    pub table: String,
    /// The recorded erratum it repeats, if any.
    pub known: Option<String>,
    /// Left to a person.
    pub todo: bool,
}

/// The review of one merge.
#[derive(Debug, Clone, Default, Serialize)]
pub(crate) struct Review {
    /// The manual's file name.
    pub manual: String,
    /// The spec file merged into.
    pub spec: String,
    /// The sensor.
    pub sensor: String,
    /// The manual's cover title.
    pub title: String,
    /// Its scope line's revisions.
    pub revision: Option<String>,
    /// Its software.
    pub software: String,
    /// How it was recognised.
    pub identified: Identified,
    /// Where it stands among the recorded manuals.
    pub placement: String,
    /// True when the manual adds nothing (no file written).
    pub nothing_new: bool,
    /// Commands the manual adds.
    pub commands_added: Vec<CommandRow>,
    /// Commands of the spec the manual does not document, where that matters.
    pub commands_removed: Vec<CommandRow>,
    /// Layouts the manual gives otherwise.
    pub commands_changed: Vec<Changed>,
    /// `since:` values set on the spec's commands.
    pub since: Vec<SinceRow>,
    /// Frames identical to recorded ones (cited with this manual's figures).
    pub frames_cited: Vec<FrameRow>,
    /// Frames that differ from the recorded ones (recorded as this manual's examples).
    pub frames_differ: Vec<FrameDiff>,
    /// Frames new to the spec: of the added commands, and of commands the spec has no example of.
    pub frames_new: Vec<FrameRow>,
    /// Sections and figures numbered otherwise.
    pub figures_renumbered: Vec<Renumbered>,
    /// Serial settings.
    pub serial: SerialRow,
    /// The procedure chapter against the spec's procedure and constants.
    pub procedure: Vec<ProcedureRow>,
    /// Table errata drafted.
    pub errata: Vec<ErratumRow>,
    /// What is left to a person (`# TODO(import)` in the merged file).
    pub todos: Vec<String>,
    /// The file written.
    pub out: Option<String>,
    /// Time of the merge, in milliseconds.
    pub millis: f64,
}

fn figures(f: &[String]) -> String {
    match f.len() {
        0 => "no figure".into(),
        1 => format!("Fig {}", f[0]),
        _ => format!("Figs {}", f.join(", ")),
    }
}

fn page(p: Option<u32>) -> String {
    p.map(|p| format!(", p. {p}")).unwrap_or_default()
}

fn none_or(n: usize) -> String {
    if n == 0 { ": none".into() } else { format!(" ({n}):") }
}

impl Review {
    /// The review as text.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{} -> {} (sensor {})", self.manual, self.spec, self.sensor);
        let _ = writeln!(
            s,
            "  manual: \"{}\", {} (software {})",
            self.title,
            self.revision.as_deref().unwrap_or("no scope line"),
            self.software
        );
        let id = &self.identified;
        let sn = match (id.serial_numbers.first(), &id.model_code) {
            (Some(sn), Some(code)) => format!(
                "serial number {sn} (model code {code}{})",
                id.spec_model_code.as_ref().map(|c| format!(", the spec's {c}")).unwrap_or_default()
            ),
            _ => "no serial number printed".into(),
        };
        let _ = writeln!(
            s,
            "  identified: {sn}; {} of its {} commands are in the spec (which has {})",
            id.shared, id.commands_in_manual, id.commands_in_spec
        );
        if let Some(n) = &id.note {
            let _ = writeln!(s, "  note: {n}");
        }
        let _ = writeln!(s, "  revision: {}", self.placement);
        if self.nothing_new {
            let _ = writeln!(
                s,
                "nothing new: every command, frame and setting of this manual is recorded; no file written"
            );
            return s;
        }
        let _ = writeln!(s, "commands added{}", none_or(self.commands_added.len()));
        for c in &self.commands_added {
            let _ = writeln!(s, "  + {}", row(c));
        }
        let _ = writeln!(s, "commands removed{}", none_or(self.commands_removed.len()));
        for c in &self.commands_removed {
            let _ = writeln!(s, "  - {}", row(c));
        }
        let _ = writeln!(s, "commands changed{}", none_or(self.commands_changed.len()));
        for c in &self.commands_changed {
            let _ = writeln!(
                s,
                "  ~ {:<32} {}: spec {}, manual {} (section {}, {}{})",
                c.name,
                c.what,
                c.spec,
                c.manual,
                c.section,
                figures(&c.figures),
                page(c.page)
            );
        }
        if !self.since.is_empty() {
            let _ = writeln!(s, "since ({}):", self.since.len());
            for r in &self.since {
                let was = r.was.as_ref().map(|w| format!(" (was \"{w}\")")).unwrap_or_default();
                let _ = writeln!(s, "  {:<34} since \"{}\"{was}: {}", r.name, r.since, r.why);
            }
        }
        let frames = |rows: &[FrameRow]| rows.iter().filter(|_| true).count();
        let _ = writeln!(
            s,
            "frames identical to recorded ones, cited with this manual's figures (`also_in`){}",
            none_or(frames(&self.frames_cited))
        );
        for f in &self.frames_cited {
            let _ = writeln!(
                s,
                "  = {:<32} {}{} (as SW {} {})",
                f.command,
                figures(&f.figures),
                page(f.page),
                f.recorded_manual.as_deref().unwrap_or("?"),
                figures(&f.recorded_figures)
            );
        }
        let _ = writeln!(s, "frames that differ{}", none_or(self.frames_differ.len()));
        for f in &self.frames_differ {
            let _ = writeln!(s, "  ! {:<32} {} {}{}", f.command, f.side, figures(&f.figures), page(f.page));
            let _ = writeln!(s, "      printed:  {}", f.printed);
            match &f.recorded {
                Some(r) => {
                    let _ = writeln!(
                        s,
                        "      recorded: {r} (SW {} {}; {})",
                        f.recorded_manual.as_deref().unwrap_or("?"),
                        figures(&f.recorded_figures),
                        f.bytes
                    );
                }
                None => {
                    let _ = writeln!(s, "      recorded: none");
                }
            }
        }
        if !self.frames_new.is_empty() {
            let _ = writeln!(
                s,
                "frames new to the spec (of added commands, or of commands without an example) ({}):",
                self.frames_new.len()
            );
            for f in &self.frames_new {
                let _ = writeln!(s, "  + {:<32} {}{}", f.command, figures(&f.figures), page(f.page));
            }
        }
        let _ = writeln!(s, "sections and figures renumbered{}", none_or(self.figures_renumbered.len()));
        for r in &self.figures_renumbered {
            let _ = writeln!(
                s,
                "  # {:<32} section {} -> {}, {} -> {}{} (from SW {})",
                r.command,
                r.section_from,
                r.section_to,
                figures(&r.figures_from),
                r.figures_to.join(", "),
                page(r.page),
                r.manual_from
            );
        }
        let sr = &self.serial;
        match (&sr.manual, &sr.recorded_as) {
            (Some(m), None) => {
                let _ = writeln!(s, "serial settings: {m}, as the spec's");
            }
            (Some(m), Some(how)) => {
                let _ = writeln!(s, "serial settings: the manual states {m}, the spec {}: recorded as {how}", sr.spec);
            }
            (None, how) => {
                let _ =
                    writeln!(s, "serial settings: {} (the spec: {})", how.as_deref().unwrap_or("none stated"), sr.spec);
            }
        }
        let proc_figure = self.procedure.first().and_then(|p| p.figure.clone());
        let proc_page = self.procedure.first().and_then(|p| p.page);
        let place = match (proc_figure, proc_page) {
            (Some(f), Some(p)) => format!(" (Fig {f}, p. {p})"),
            (Some(f), None) => format!(" (Fig {f})"),
            (None, Some(p)) => format!(" (p. {p})"),
            (None, None) => String::new(),
        };
        let _ = writeln!(
            s,
            "procedure chapter{place}{}",
            if self.procedure.is_empty() { ": nothing to compare" } else { ":" }
        );
        for p in &self.procedure {
            match (&p.spec, p.manual.is_empty()) {
                (Some(spec), _) => {
                    let _ = writeln!(s, "  {:<34} = {spec}", p.what);
                }
                (None, true) => {
                    let _ = writeln!(s, "  {:<34} not in the spec", p.what);
                }
                (None, false) => {
                    let _ = writeln!(s, "  {:<34} {}", p.what, p.manual);
                }
            }
        }
        let _ = writeln!(s, "errata drafted{}", none_or(self.errata.len()));
        for e in &self.errata {
            let _ = writeln!(
                s,
                "  {:<34} {} Fig {}: the register table gives {}{}",
                e.command,
                e.id,
                e.figure,
                e.table,
                match (&e.known, e.todo) {
                    (Some(k), _) => format!(" (as {k})"),
                    (None, true) => " (TODO: new)".into(),
                    (None, false) => String::new(),
                }
            );
        }
        let _ = writeln!(s, "TODO(import) left in the merged file{}", none_or(self.todos.len()));
        for t in &self.todos {
            let _ = writeln!(s, "  {t}");
        }
        if let Some(out) = &self.out {
            let _ = writeln!(s, "wrote {out} in {:.0} ms", self.millis);
        }
        s
    }

    /// The review as JSON.
    pub fn json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

fn row(c: &CommandRow) -> String {
    format!(
        "{:<32} {:<5} {} x{:<3} section {} \"{}\", {}{}{}",
        c.name,
        c.function,
        c.address,
        c.count.map(|n| n.to_string()).unwrap_or_else(|| "?".into()),
        c.section,
        c.title,
        figures(&c.figures),
        page(c.page),
        c.note.as_ref().map(|n| format!("; {n}")).unwrap_or_default()
    )
}

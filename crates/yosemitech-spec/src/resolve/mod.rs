//! Loading and validation: YAML documents in, a checked [`Spec`] or every
//! problem at once out.
//!
//! This module reads the files (and, recursively, their includes), then
//! resolves each sensor file: its header ([`sensor`]), its included and own
//! commands ([`includes`], [`command`], [`field`]), its procedure
//! ([`procedure`]), constants ([`constant`]) and errata ([`errata`]). It
//! guarantees that command names, the Rust types they become and wire
//! positions are unique within a sensor, that a sensor has at most one
//! command per role, and that sensor names are unique; diagnostics are
//! reported once each, ordered by file and position.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use crate::check::check_text;
use crate::diag::{Diagnostic, Diagnostics, Pos, Reporter};
use crate::document::{CommandDoc, SensorDoc, SpecFile};
use crate::model::{Fragment, Role, Sensor, Spec};
use crate::names::{camel, escape};
use crate::sources::{FsSources, NotUtf8, Sources};

mod command;
mod constant;
mod derived;
mod errata;
mod field;
mod includes;
mod procedure;
mod sensor;
mod todo;

use command::{check_use_entry, command_key, resolve_calibrates, resolve_command, resolve_command_extras};
use constant::resolve_constants;
use derived::resolve_derived;
use errata::resolve_errata;
use includes::{check_fragment, collect_includes, include_target};
use procedure::resolve_procedure;
use sensor::{check_manual_refs, check_unsourced, resolve_sensor_head, resolve_source};
pub use todo::IMPORT_TODO;

pub use crate::check::{MAX_TEXT_LEN, parse_hex};

/// Deepest chain of includes.
pub const MAX_INCLUDE_DEPTH: usize = 8;
/// Most registers a read may cover (Modbus).
pub const MAX_READ_COUNT: u32 = 125;
/// Most registers a write may cover (Modbus).
pub const MAX_WRITE_COUNT: u32 = 123;

/// Loads files and directories (their `*.yaml`) from the file system.
///
/// Every problem in every file is reported at once, each with its file,
/// line and column; the loader never panics, whatever the input.
pub fn load_paths(paths: &[PathBuf]) -> Result<Spec, Diagnostics> {
    load_with(&FsSources, paths)
}

/// Loads files and directories from `sources`.
pub fn load_with(sources: &dyn Sources, paths: &[PathBuf]) -> Result<Spec, Diagnostics> {
    let mut roots: Vec<PathBuf> = Vec::new();
    let mut diags = Vec::new();
    for path in paths {
        if sources.is_dir(path) {
            match sources.yaml_files(path) {
                Ok(files) if files.is_empty() => diags.push(plain(path, "the directory holds no `.yaml` files".into())),
                Ok(files) => roots.extend(files),
                Err(e) => diags.push(plain(path, format!("cannot list the directory: {e}"))),
            }
        } else {
            roots.push(path.clone());
        }
    }
    let mut seen_roots = BTreeSet::new();
    roots.retain(|r| seen_roots.insert(r.clone()));

    let mut loader = Loader { sources, files: BTreeMap::new(), diags, cycles: BTreeSet::new() };
    for root in &roots {
        loader.parse(root, None);
    }
    let mut sensors = Vec::new();
    for root in &roots {
        if let Some(sensor) = loader.resolve_root(root) {
            sensors.push(sensor);
        }
    }
    loader.check_unique_sensors(&sensors);
    let fragments = loader.fragments(&sensors);
    let diags = finish(loader.diags);
    if diags.is_empty() { Ok(Spec { sensors, fragments }) } else { Err(Diagnostics(diags)) }
}

/// Drops repeated diagnostics (a fragment is checked once per including
/// sensor) and orders them by file, then position.
fn finish(diags: Vec<Diagnostic>) -> Vec<Diagnostic> {
    let mut unique: Vec<Diagnostic> = Vec::new();
    for d in diags {
        if !unique.contains(&d) {
            unique.push(d);
        }
    }
    unique.sort_by(|a, b| (&a.file, a.pos).cmp(&(&b.file, b.pos)));
    unique
}

/// Counts of what [`load_paths`] checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Summary {
    /// Sensors.
    pub sensors: usize,
    /// Commands over all sensors.
    pub commands: usize,
    /// Example frame pairs replayed.
    pub examples: usize,
    /// Frames replayed: the printed ones plus the corrections errata give.
    pub frames: usize,
    /// Frames printed in the manuals: a request, a reply, or both per example.
    pub printed_frames: usize,
    /// Printed frames complete with their CRC (replayed byte for byte).
    pub complete_frames: usize,
    /// Errata recorded.
    pub errata: usize,
    /// Derived quantities, their formulas checked.
    pub derived: usize,
    /// Examples of derived quantities computed and compared.
    pub derived_examples: usize,
}

impl Spec {
    /// What the spec holds.
    pub fn summary(&self) -> Summary {
        let mut s = Summary { sensors: self.sensors.len(), ..Summary::default() };
        for sensor in &self.sensors {
            s.commands += sensor.commands.len();
            s.errata += sensor.errata.len();
            s.derived += sensor.derived.len();
            s.derived_examples += sensor.derived.iter().map(|d| d.examples.len()).sum::<usize>();
            for c in &sensor.commands {
                s.errata += c.errata.len();
                for e in &c.examples {
                    s.examples += 1;
                    s.frames += e.frames_printed();
                    s.printed_frames += e.frames_printed();
                    s.complete_frames += e.frames_printed_complete();
                    if let Some(err) = &e.erratum {
                        s.errata += 1;
                        s.frames += usize::from(err.corrected_request.is_some())
                            + usize::from(err.corrected_response.is_some());
                    }
                }
            }
        }
        s
    }
}

/// A problem with a whole file or directory, at no particular place.
fn plain(path: &Path, message: String) -> Diagnostic {
    Diagnostic {
        file: path.to_path_buf(),
        pos: Pos::default(),
        key: String::new(),
        message,
        help: None,
        source_line: None,
    }
}

/// `path` as shown in a message about `from`: relative to `from`'s directory when inside it.
fn shown(path: &Path, from: &Path) -> String {
    let dir = from.parent().unwrap_or(Path::new(""));
    path.strip_prefix(dir).unwrap_or(path).display().to_string()
}

/// A place in another file, for a help text: `line L, column C` in the same file.
fn place(file: &Path, pos: Pos, from: &Path) -> String {
    if file == from {
        format!("line {}, column {}", pos.line, pos.column)
    } else {
        format!("{}:{}:{}", shown(file, from), pos.line, pos.column)
    }
}

/// Where a top-level `key:` is written (block style), or the file's start.
fn top_key_pos(text: &str, key: &str) -> Pos {
    text.lines()
        .position(|l| l.strip_prefix(key).is_some_and(|rest| rest.trim_start().starts_with(':')))
        .map_or(Pos { line: 1, column: 1 }, |i| Pos { line: i as u32 + 1, column: 1 })
}

/// A read error as a reader would say it.
fn io_reason(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "no such file".into(),
        std::io::ErrorKind::PermissionDenied => "permission denied".into(),
        _ => e.to_string(),
    }
}

struct Parsed {
    text: String,
    doc: Option<SpecFile>,
}

struct Loader<'s> {
    sources: &'s dyn Sources,
    files: BTreeMap<PathBuf, Parsed>,
    diags: Vec<Diagnostic>,
    /// Include cycles already reported, by their member files.
    cycles: BTreeSet<BTreeSet<PathBuf>>,
}

/// A command definition with the file it was written in.
struct Def<'d> {
    file: &'d Path,
    doc: &'d CommandDoc,
    index: usize,
    fragment: Option<String>,
}

/// Where a resolved command comes from, for messages about it.
struct Origin<'d> {
    file: &'d Path,
    pos: Pos,
    key: String,
    /// Where the entry states what its calibration block calibrates.
    calibrates_at: Option<Pos>,
}

impl Loader<'_> {
    /// Reports at `pos` in `file` (a file already read).
    fn report(&mut self, file: &Path, pos: Pos, key: String, message: String, help: Option<String>) {
        let text = self.files.get(file).map(|p| p.text.clone()).unwrap_or_default();
        Reporter { file, text: &text, out: &mut self.diags }.error(pos, key, message, help);
    }

    /// Reads and parses `path` once (and, recursively, its includes).
    fn parse(&mut self, path: &Path, included_from: Option<(&Path, Pos, String)>) {
        if self.files.contains_key(path) {
            return;
        }
        let text = match self.sources.read(path) {
            Ok(t) => t,
            Err(e) => {
                self.files.insert(path.to_path_buf(), Parsed { text: String::new(), doc: None });
                self.read_error(path, &e, included_from);
                return;
            }
        };
        todo::check_import_todos(&text, &mut Reporter { file: path, text: &text, out: &mut self.diags });
        let doc = match crate::yaml::parse(&text) {
            Ok(doc) => Some(doc),
            Err(problems) => {
                let mut r = Reporter { file: path, text: &text, out: &mut self.diags };
                for problem in problems {
                    r.error(problem.pos, problem.key, problem.message, problem.help);
                }
                None
            }
        };
        let mut includes = Vec::new();
        if let Some(d) = &doc {
            for (i, inc) in d.include.iter().enumerate() {
                match include_target(path, &inc.value.file) {
                    Ok(target) => includes.push((target, Pos::at(inc), format!("include[{i}]"))),
                    Err(why) => {
                        let mut r = Reporter { file: path, text: &text, out: &mut self.diags };
                        r.error(
                            Pos::at(inc),
                            format!("include[{i}]"),
                            format!("cannot include `{}`: {why}", escape(&inc.value.file)),
                            Some("include fragment files by a path relative to this file, like `common.yaml`".into()),
                        );
                    }
                }
            }
        }
        self.files.insert(path.to_path_buf(), Parsed { text, doc });
        for (inc, pos, key) in includes {
            self.parse(&inc, Some((path, pos, key)));
        }
    }

    /// Reports a file that could not be read: in the file itself when its
    /// content is at fault, at the include (or with no position) otherwise.
    fn read_error(&mut self, path: &Path, e: &std::io::Error, included_from: Option<(&Path, Pos, String)>) {
        let not_utf8 = e.get_ref().and_then(|inner| inner.downcast_ref::<NotUtf8>());
        if let Some(bad) = not_utf8 {
            self.diags.push(Diagnostic {
                file: path.to_path_buf(),
                pos: Pos { line: bad.line, column: bad.column },
                key: String::new(),
                message: "the file is not UTF-8 text".into(),
                help: Some("save the file as UTF-8".into()),
                source_line: Some(bad.text.chars().take(200).collect()),
            });
            return;
        }
        if e.kind() == std::io::ErrorKind::FileTooLarge || e.kind() == std::io::ErrorKind::InvalidData {
            self.diags.push(Diagnostic {
                file: path.to_path_buf(),
                pos: Pos { line: 1, column: 1 },
                key: String::new(),
                message: e.to_string(),
                help: Some("spec files are hand-written and small; check that this is the intended file".into()),
                source_line: None,
            });
            return;
        }
        match included_from {
            Some((from, pos, key)) => self.report(
                from,
                pos,
                key,
                format!("cannot read included file `{}`: {}", shown(path, from), io_reason(e)),
                Some("include paths are relative to the including file's directory".into()),
            ),
            None => self.diags.push(plain(path, format!("cannot read the file: {}", io_reason(e)))),
        }
    }

    fn resolve_root(&mut self, root: &Path) -> Option<Sensor> {
        let parsed = self.files.get(root)?;
        let doc = parsed.doc.as_ref()?;
        let mut diags = Vec::new();
        let sensor = {
            let mut r = Reporter { file: root, text: &parsed.text, out: &mut diags };
            match (&doc.sensor, &doc.fragment) {
                (Some(_), Some(_)) => {
                    r.error(
                        top_key_pos(&parsed.text, "fragment"),
                        "fragment",
                        "a file has `sensor` or `fragment`, not both",
                        Some("move shared commands to a fragment file of their own and `include` it".into()),
                    );
                    None
                }
                (None, None) => {
                    r.error(
                        Pos { line: 1, column: 1 },
                        "",
                        "a spec file needs a `sensor` or a `fragment` section",
                        Some("start the file with `sensor:` (a manual) or `fragment:` (shared commands)".into()),
                    );
                    None
                }
                (None, Some(_)) => {
                    // A fragment on its own: check its commands and stop.
                    let mut defs = Vec::new();
                    let mut stack = vec![root.to_path_buf()];
                    collect_includes(&self.files, root, &mut stack, &mut defs, &mut diags, &mut self.cycles);
                    drop(defs);
                    let parsed = self.files.get(root)?;
                    let doc = parsed.doc.as_ref()?;
                    let mut r = Reporter { file: root, text: &parsed.text, out: &mut diags };
                    check_fragment(doc, &mut r);
                    for (i, c) in doc.commands.iter().enumerate() {
                        let _ = resolve_command(c, None, i, None, &mut r);
                    }
                    None
                }
                (Some(sensor), None) => {
                    let mut cycles = std::mem::take(&mut self.cycles);
                    let sensor = self.resolve_sensor(root, doc, sensor, &mut diags, &mut cycles);
                    self.cycles = cycles;
                    Some(sensor)
                }
            }
        };
        self.diags.extend(diags);
        sensor.flatten()
    }

    /// The fragments some sensor includes, with their own definitions.
    /// (Their problems were reported while resolving the sensors.)
    fn fragments(&self, sensors: &[Sensor]) -> Vec<Fragment> {
        let mut out = Vec::new();
        for (path, parsed) in &self.files {
            let Some(doc) = &parsed.doc else { continue };
            let Some(fragment) = &doc.fragment else { continue };
            if !sensors.iter().any(|s| s.files.contains(path)) {
                continue;
            }
            let mut ignored = Vec::new();
            let mut r = Reporter { file: path, text: &parsed.text, out: &mut ignored };
            let commands = doc
                .commands
                .iter()
                .enumerate()
                .filter_map(|(i, c)| resolve_command(c, None, i, Some(fragment.name.value.clone()), &mut r))
                .collect();
            out.push(Fragment {
                name: fragment.name.value.clone(),
                doc: fragment.doc.value.clone(),
                file: path.clone(),
                commands,
            });
        }
        out
    }

    /// Reports sensors defined twice, at the second definition's name.
    fn check_unique_sensors(&mut self, sensors: &[Sensor]) {
        let mut first: BTreeMap<&str, (&Path, Pos)> = BTreeMap::new();
        for s in sensors {
            let pos = self
                .files
                .get(&s.file)
                .and_then(|p| p.doc.as_ref())
                .and_then(|d| d.sensor.as_ref())
                .map_or(Pos { line: 1, column: 1 }, |d| Pos::at(&d.name));
            match first.get(s.name.as_str()) {
                Some((file, at)) => {
                    let message = format!("a sensor called `{}` is already defined", s.name);
                    let help = format!(
                        "the first is at {}; sensor names become module names and must be unique",
                        place(file, *at, &s.file)
                    );
                    self.report(&s.file, pos, "sensor.name".into(), message, Some(help));
                }
                None => {
                    first.insert(&s.name, (&s.file, pos));
                }
            }
        }
    }

    fn resolve_sensor(
        &self,
        root: &Path,
        doc: &SpecFile,
        sensor_doc: &SensorDoc,
        diags: &mut Vec<Diagnostic>,
        cycles: &mut BTreeSet<BTreeSet<PathBuf>>,
    ) -> Option<Sensor> {
        let text = &self.files.get(root)?.text;
        let mut included = Vec::new();
        let complete = collect_includes(&self.files, root, &mut vec![root.to_path_buf()], &mut included, diags, cycles);

        let mut r = Reporter { file: root, text, out: diags };
        let head = resolve_sensor_head(sensor_doc, &mut r);

        // Which included commands does this file `use`? Only the first `use` of each counts.
        let mut used: BTreeMap<String, usize> = BTreeMap::new();
        for (i, c) in doc.commands.iter().enumerate() {
            let Some(u) = &c.uses else { continue };
            let key = format!("{}.use", command_key(i, c));
            if !included.iter().any(|d| d.doc.name.as_ref().is_some_and(|n| n.value == u.value)) {
                if !complete {
                    continue; // An include failed: its commands are unknown, not missing.
                }
                let names: Vec<&str> =
                    included.iter().filter_map(|d| d.doc.name.as_ref().map(|n| n.value.as_str())).collect();
                let help = if names.is_empty() {
                    "this file includes no commands; add the fragment that defines it to `include`".to_string()
                } else {
                    match crate::suggest::closest(&u.value, &names) {
                        Some(best) => format!("did you mean `{best}`? included commands: {}", names.join(", ")),
                        None => format!("included commands: {}", names.join(", ")),
                    }
                };
                r.error(Pos::at(u), key, format!("no included command is called `{}`", escape(&u.value)), Some(help));
            } else if let Some(&first) = used.get(&u.value) {
                let first_pos = doc.commands.get(first).and_then(|f| f.uses.as_ref()).map(Pos::at).unwrap_or_default();
                r.error(
                    Pos::at(u),
                    key,
                    format!("`{}` is used twice", u.value),
                    Some(format!(
                        "the first `use` is at line {}, column {}; merge the two entries",
                        first_pos.line, first_pos.column
                    )),
                );
            } else {
                used.insert(u.value.clone(), i);
            }
        }

        let mut commands = Vec::new();
        let mut origins: Vec<Origin<'_>> = Vec::new();
        // Included commands nobody refines keep their fragment's examples and source.
        for def in included.iter().filter(|d| d.doc.name.as_ref().is_some_and(|n| !used.contains_key(&n.value))) {
            let Some(parsed) = self.files.get(def.file) else { continue };
            let mut fr = Reporter { file: def.file, text: &parsed.text, out: r.out };
            if let Some(c) = resolve_command(def.doc, None, def.index, def.fragment.clone(), &mut fr) {
                let pos = def.doc.name.as_ref().map(Pos::at).unwrap_or_default();
                origins.push(Origin {
                    file: def.file,
                    pos,
                    key: command_key(def.index, def.doc),
                    calibrates_at: def.doc.calibrates.as_ref().map(|c| Pos::at(&c.field)),
                });
                commands.push(c);
            }
        }
        for (i, c) in doc.commands.iter().enumerate() {
            match (&c.name, &c.uses) {
                (Some(n), Some(_)) => r.error(
                    Pos::at(n),
                    command_key(i, c),
                    "a command has `name` (a new command) or `use` (an included one), not both",
                    Some("keep `name` to define a new command, or `use` to add this manual's examples to an included one".into()),
                ),
                (None, None) => r.error(
                    c.title.as_ref().map(Pos::at).or(c.function.as_ref().map(Pos::at)).unwrap_or_default(),
                    command_key(i, c),
                    "a command needs `name` (a new command) or `use` (an included one)",
                    Some("add `name: <snake_case>` for a new command, or `use: <name>` of an included one".into()),
                ),
                (Some(n), None) => {
                    if let Some(cmd) = resolve_command(c, None, i, None, &mut r) {
                        origins.push(Origin {
                            file: root,
                            pos: Pos::at(n),
                            key: command_key(i, c),
                            calibrates_at: c.calibrates.as_ref().map(|c| Pos::at(&c.field)),
                        });
                        commands.push(cmd);
                    }
                }
                (None, Some(u)) => {
                    if used.get(&u.value) != Some(&i) {
                        continue; // Unknown or repeated: reported above.
                    }
                    let Some(def) = included.iter().find(|d| d.doc.name.as_ref().is_some_and(|n| n.value == u.value))
                    else {
                        continue;
                    };
                    check_use_entry(c, i, &mut r);
                    // The definition's problems belong to its own file.
                    let Some(parsed) = self.files.get(def.file) else { continue };
                    let mut defr = Reporter { file: def.file, text: &parsed.text, out: r.out };
                    let Some(mut cmd) = resolve_command(def.doc, None, def.index, def.fragment.clone(), &mut defr)
                    else {
                        continue;
                    };
                    // This manual's title, doc, units, source, examples and errata.
                    let key = command_key(i, c);
                    if let Some(s) = &c.source {
                        cmd.source = resolve_source(s, &format!("{key}.source"), &mut r);
                    }
                    if let Some(t) = &c.title {
                        cmd.title = check_text(t, &format!("{key}.title"), &mut r);
                    }
                    if let Some(d) = &c.doc {
                        cmd.doc = check_text(d, &format!("{key}.doc"), &mut r);
                    }
                    if let Some(since) = &c.since {
                        cmd.since = Some(check_text(since, &format!("{key}.since"), &mut r));
                    }
                    if let Some(units) = &c.units {
                        for (field, unit) in &units.value {
                            let unit_text = check_text(unit, &format!("{key}.units.{field}"), &mut r);
                            match cmd.fields.iter_mut().find(|f| f.name.as_deref() == Some(field.as_str())) {
                                Some(f) => f.unit = Some(unit_text),
                                None => r.error(
                                    Pos::at(unit),
                                    format!("{key}.units.{field}"),
                                    format!("`{}` has no field called `{}`", cmd.name, escape(field)),
                                    Some(format!(
                                        "fields: {}",
                                        cmd.named_fields().map(|f| f.display_name()).collect::<Vec<_>>().join(", ")
                                    )),
                                ),
                            }
                        }
                    }
                    if let Some(calibrates) = &c.calibrates {
                        cmd.calibrates = Some(resolve_calibrates(calibrates, &key, &mut r));
                    }
                    cmd.examples.clear();
                    cmd.errata.clear();
                    resolve_command_extras(c, i, &mut cmd, &mut r);
                    origins.push(Origin {
                        file: root,
                        pos: Pos::at(u),
                        key: command_key(i, c),
                        calibrates_at: c.calibrates.as_ref().map(|c| Pos::at(&c.field)),
                    });
                    commands.push(cmd);
                }
            }
        }

        // A sensor with no command gives no tool anything to send.
        if head.is_some() && commands.is_empty() && doc.commands.is_empty() && doc.include.is_empty() {
            r.error(
                Pos::at(&sensor_doc.name),
                "commands",
                "the sensor has no command",
                Some("add `commands:` with the manual's commands (definitions, or `use:` of an included one)".into()),
            );
        }

        // Names, the Rust types they become, and wire positions must be unique.
        let mut names: BTreeMap<String, usize> = BTreeMap::new();
        let mut types: BTreeMap<String, usize> = BTreeMap::new();
        let mut wires: BTreeMap<(u8, u16, Option<u8>), usize> = BTreeMap::new();
        for (k, (cmd, origin)) in commands.iter().zip(&origins).enumerate() {
            let mut fr = match self.files.get(origin.file) {
                Some(p) => Reporter { file: origin.file, text: &p.text, out: r.out },
                None => continue,
            };
            if let Some(&j) = names.get(&cmd.name) {
                let first = &origins[j];
                fr.error(
                    origin.pos,
                    format!("{}.name", origin.key),
                    format!("two commands are called `{}`", cmd.name),
                    Some(format!(
                        "the first is at {}; command names must be unique within a sensor, included commands too",
                        place(first.file, first.pos, origin.file)
                    )),
                );
                continue;
            }
            names.insert(cmd.name.clone(), k);
            let ty = camel(&cmd.name);
            if let Some(&j) = types.get(&ty) {
                fr.error(
                    origin.pos,
                    format!("{}.name", origin.key),
                    format!("`{}` and `{}` both become the Rust type `{ty}`", commands[j].name, cmd.name),
                    Some(format!(
                        "rename one of them (the other is at {})",
                        place(origins[j].file, origins[j].pos, origin.file)
                    )),
                );
            } else {
                types.insert(ty, k);
            }
            let wire = (cmd.function.code(), cmd.address, cmd.fixed_slave);
            if let Some(&j) = wires.get(&wire) {
                fr.error(
                    origin.pos,
                    format!("{}.address", origin.key),
                    format!(
                        "`{}` and `{}` both {} register 0x{:04X}",
                        commands[j].name,
                        cmd.name,
                        if cmd.is_read() { "read" } else { "write" },
                        cmd.address
                    ),
                    Some(format!(
                        "a frame must identify one command (the other is at {})",
                        place(origins[j].file, origins[j].pos, origin.file)
                    )),
                );
            } else {
                wires.insert(wire, k);
            }
        }

        // A read's reply type, `<Command>Response`, is a type too.
        for (cmd, origin) in commands.iter().zip(&origins) {
            let reply = format!("{}Response", camel(&cmd.name));
            let Some(&j) = types.get(&reply).filter(|_| cmd.is_read()) else { continue };
            let mut fr = match self.files.get(origin.file) {
                Some(p) => Reporter { file: origin.file, text: &p.text, out: r.out },
                None => continue,
            };
            fr.error(
                origin.pos,
                format!("{}.name", origin.key),
                format!(
                    "the reply of `{}` becomes the Rust type `{reply}`, the type of `{}`",
                    cmd.name, commands[j].name
                ),
                Some(format!(
                    "rename one of them (the other is at {})",
                    place(origins[j].file, origins[j].pos, origin.file)
                )),
            );
        }

        // One command per role (a sensor may have several calibration blocks).
        let mut roles: BTreeMap<Role, usize> = BTreeMap::new();
        for (k, (cmd, origin)) in commands.iter().zip(&origins).enumerate() {
            let Some(role) = cmd.role.filter(|&role| role != Role::UserCalibration) else { continue };
            if let Some(&j) = roles.get(&role) {
                r.error(
                    origin.pos,
                    format!("{}.role", origin.key),
                    format!("`{}` and `{}` both have role `{}`", commands[j].name, cmd.name, role.name()),
                    Some(
                        "a sensor has at most one command per role; include the fragment with `only:` to leave one out"
                            .into(),
                    ),
                );
            } else {
                roles.insert(role, k);
            }
        }
        // A user calibration block: a read of the same registers pairs it,
        // and what it calibrates is a measured field of the sensor.
        for (cmd, origin) in commands.iter().zip(&origins) {
            let mut fr = match self.files.get(origin.file) {
                Some(p) => Reporter { file: origin.file, text: &p.text, out: r.out },
                None => continue,
            };
            let is_block = cmd.role == Some(Role::UserCalibration);
            if is_block && !commands.iter().any(|c| c.is_read() && c.address == cmd.address && c.count == cmd.count) {
                fr.error(
                    origin.pos,
                    format!("{}.role", origin.key),
                    format!(
                        "`{}` cannot have role `user_calibration`: no read of the same registers (0x{:04X} x{}) pairs it",
                        cmd.name, cmd.address, cmd.count
                    ),
                    Some("add the manual's read of the K/B block, or remove the role".into()),
                );
            }
            let Some(calibrates) = &cmd.calibrates else { continue };
            let at = origin.calibrates_at.unwrap_or(origin.pos);
            if !is_block {
                fr.error(
                    at,
                    format!("{}.calibrates", origin.key),
                    format!("`{}` states `calibrates` but is not a `user_calibration` block", cmd.name),
                    Some("`calibrates` belongs to the write with role `user_calibration`".into()),
                );
                continue;
            }
            let probe = Sensor::measured_fields(&commands);
            if !probe.iter().any(|f| *f == calibrates.field) {
                fr.error(
                    at,
                    format!("{}.calibrates.field", origin.key),
                    format!("`{}` is not a named field of a measurement read", escape(&calibrates.field)),
                    Some(format!("measured fields: {}", probe.join(", "))),
                );
            }
        }
        check_manual_refs(sensor_doc, doc, &mut r);
        check_unsourced(sensor_doc, doc, &mut r);
        let procedure = doc.procedure.as_ref().and_then(|p| resolve_procedure(p, &commands, &mut r));
        let constants = resolve_constants(&doc.constants, &mut r);
        let errata = resolve_errata(&doc.errata, &mut r);
        let derived = resolve_derived(&doc.derived, &commands, &constants, &mut r);
        let head = head?;
        let mut files = vec![root.to_path_buf()];
        files.extend(included.iter().map(|d| d.file.to_path_buf()));
        files.sort();
        files.dedup();
        Some(Sensor {
            name: head.name,
            title: head.title,
            doc: head.doc,
            model: head.model,
            model_code: head.model_code,
            also_model_codes: head.also_model_codes,
            aliases: head.aliases,
            manual: head.manual,
            provenance: head.provenance,
            revisions: head.revisions,
            serial: head.serial,
            min_address: head.min_address,
            max_address: head.max_address,
            default_address: head.default_address,
            commands,
            procedure,
            constants,
            errata,
            derived,
            file: root.to_path_buf(),
            files,
        })
    }
}

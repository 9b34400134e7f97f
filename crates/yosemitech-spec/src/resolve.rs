//! Loading and validation: YAML documents in, a checked [`Spec`] or every
//! problem at once out.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde_saphyr::Spanned;
use yosemitech_rtu::{Function, Hex, crc16};

use crate::diag::{Diagnostic, Diagnostics, Pos, Reporter};
use crate::document::*;
use crate::interp::{Value, parse_version};
use crate::model::*;
use crate::names::{camel, check_snake, escape, shouty};
use crate::sources::{FsSources, NotUtf8, Sources, sibling};

/// Deepest chain of includes.
pub const MAX_INCLUDE_DEPTH: usize = 8;
/// Most registers a read may cover (Modbus).
pub const MAX_READ_COUNT: u32 = 125;
/// Most registers a write may cover (Modbus).
pub const MAX_WRITE_COUNT: u32 = 123;
/// Longest text (doc, title, note).
pub const MAX_TEXT_LEN: usize = 4096;

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
}

impl Spec {
    /// What the spec holds.
    pub fn summary(&self) -> Summary {
        let mut s = Summary { sensors: self.sensors.len(), ..Summary::default() };
        for sensor in &self.sensors {
            s.commands += sensor.commands.len();
            s.errata += sensor.errata.len();
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

/// Why an include entry cannot name a fragment file, or the file it names.
fn include_target(file: &Path, include: &str) -> Result<PathBuf, String> {
    let path = Path::new(include);
    if include.trim().is_empty() {
        return Err("the include path is empty".into());
    }
    if path.is_absolute() || include.starts_with('/') || include.starts_with('\\') {
        return Err("it is an absolute path".into());
    }
    if !matches!(path.extension().and_then(|e| e.to_str()), Some("yaml" | "yml")) {
        return Err("it is not a `.yaml` file".into());
    }
    Ok(sibling(file, include))
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
                    match crate::yaml::closest(&u.value, &names) {
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
                origins.push(Origin { file: def.file, pos, key: command_key(def.index, def.doc) });
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
                        origins.push(Origin { file: root, pos: Pos::at(n), key: command_key(i, c) });
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
                    cmd.examples.clear();
                    cmd.errata.clear();
                    resolve_command_extras(c, i, &mut cmd, &mut r);
                    origins.push(Origin { file: root, pos: Pos::at(u), key: command_key(i, c) });
                    commands.push(cmd);
                }
            }
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

        // One command per role.
        let mut roles: BTreeMap<Role, usize> = BTreeMap::new();
        for (k, (cmd, origin)) in commands.iter().zip(&origins).enumerate() {
            let Some(role) = cmd.role else { continue };
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
        check_manual_refs(sensor_doc, doc, &mut r);
        let procedure = doc.procedure.as_ref().and_then(|p| resolve_procedure(p, &commands, &mut r));
        let constants = resolve_constants(&doc.constants, &mut r);
        let errata = resolve_errata(&doc.errata, &mut r);
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
            manual: head.manual,
            revisions: head.revisions,
            serial: head.serial,
            min_address: head.min_address,
            max_address: head.max_address,
            default_address: head.default_address,
            commands,
            procedure,
            constants,
            errata,
            file: root.to_path_buf(),
            files,
        })
    }
}

/// Every `since` and `manual` of a sensor file names one of its manuals' `software`.
fn check_manual_refs(sensor: &SensorDoc, doc: &SpecFile, r: &mut Reporter<'_>) {
    let known: Vec<&str> = std::iter::once(&sensor.manual)
        .chain(sensor.revisions.iter().map(|rev| &rev.manual))
        .filter_map(|m| m.software.as_ref().map(|s| s.value.as_str()))
        .collect();
    let check = |value: &Spanned<String>, key: String, r: &mut Reporter<'_>| {
        if !known.contains(&value.value.as_str()) {
            let help = if known.is_empty() {
                "state the manuals' software revisions: `sensor.manual.software` and `sensor.revisions`".to_string()
            } else {
                format!("the file's manuals document software {}", known.join(", "))
            };
            r.error(
                Pos::at(value),
                key,
                format!("no manual of this sensor documents software `{}`", escape(&value.value)),
                Some(help),
            );
        }
    };
    for (i, c) in doc.commands.iter().enumerate() {
        let key = command_key(i, c);
        if let Some(since) = &c.since {
            check(since, format!("{key}.since"), r);
        }
        if let Some(m) = c.source.as_ref().and_then(|s| s.manual.as_ref()) {
            check(m, format!("{key}.source.manual"), r);
        }
        for (j, e) in c.examples.iter().enumerate() {
            if let Some(m) = &e.manual {
                check(m, format!("{key}.examples[{j}].manual"), r);
            }
        }
        for (j, e) in c.errata.iter().enumerate() {
            if let Some(m) = &e.manual {
                check(m, format!("{key}.errata[{j}].manual"), r);
            }
        }
    }
    for (i, e) in doc.errata.iter().enumerate() {
        if let Some(m) = &e.manual {
            check(m, format!("errata[{i}].manual"), r);
        }
    }
    if let Some(m) = doc.procedure.as_ref().and_then(|p| p.source.as_ref()).and_then(|s| s.manual.as_ref()) {
        check(m, "procedure.source.manual".into(), r);
    }
}

/// The procedure, with every command it names checked against the sensor's.
fn resolve_procedure(p: &ProcedureDoc, commands: &[Command], r: &mut Reporter<'_>) -> Option<Procedure> {
    let mut ok = true;
    let names: Vec<&str> = commands.iter().map(|c| c.name.as_str()).collect();
    let steps = |list: &[Spanned<String>], what: &str, r: &mut Reporter<'_>, ok: &mut bool| -> Vec<String> {
        let mut out = Vec::new();
        for (i, name) in list.iter().enumerate() {
            let key = format!("procedure.{what}[{i}]");
            match commands.iter().find(|c| c.name == name.value) {
                None => {
                    let help = match crate::yaml::closest(&name.value, &names) {
                        Some(best) => format!("did you mean `{best}`?"),
                        None => format!("commands: {}", names.join(", ")),
                    };
                    r.error(
                        Pos::at(name),
                        key,
                        format!("the sensor has no command called `{}`", escape(&name.value)),
                        Some(help),
                    );
                    *ok = false;
                }
                Some(c) if what == "read" && !(c.is_read() && c.named_fields().next().is_some()) => {
                    r.error(
                        Pos::at(name),
                        key,
                        format!("`{}` is not a read that gives values", c.name),
                        Some("`read` lists the reads whose values the procedure averages".into()),
                    );
                    *ok = false;
                }
                Some(c) if what != "read" && !c.takes_no_values() => {
                    r.error(
                        Pos::at(name),
                        key,
                        format!("`{}` needs values to send", c.name),
                        Some(format!("`{what}` lists commands sent without values: triggers and reads")),
                    );
                    *ok = false;
                }
                Some(c) => out.push(c.name.clone()),
            }
        }
        out
    };
    let before = steps(&p.before, "before", r, &mut ok);
    let read = steps(&p.read.value, "read", r, &mut ok);
    let after = steps(&p.after, "after", r, &mut ok);
    if p.read.value.is_empty() {
        r.error(Pos::at(&p.read), "procedure.read", "a procedure reads at least one command", None);
        ok = false;
    }
    let readings = p.readings.as_ref().map_or(1, |n| n.value);
    if let Some(n) = &p.readings
        && !(1..=1000).contains(&n.value)
    {
        r.error(Pos::at(n), "procedure.readings", format!("{} readings: use 1..=1000", n.value), None);
        ok = false;
    }
    const DAY_MS: u32 = 86_400_000;
    for (value, key) in [(&p.warm_up_ms, "procedure.warm_up_ms"), (&p.interval_ms, "procedure.interval_ms")] {
        if let Some(v) = value
            && v.value > DAY_MS
        {
            r.error(Pos::at(v), key, format!("{} ms is longer than a day", v.value), None);
            ok = false;
        }
    }
    let source = p.source.as_ref().map(|s| resolve_source(s, "procedure.source", r));
    let doc = p.doc.as_ref().map(|d| check_text(d, "procedure.doc", r));
    ok.then(|| Procedure {
        source,
        doc,
        before,
        warm_up_ms: p.warm_up_ms.as_ref().map_or(0, |v| v.value),
        read,
        readings,
        interval_ms: p.interval_ms.as_ref().map_or(0, |v| v.value),
        after,
    })
}

/// The key of a command entry: `commands[3] (get_ph)`, the name only when it is valid.
fn command_key(i: usize, c: &CommandDoc) -> String {
    match c.name.as_ref().or(c.uses.as_ref()) {
        Some(n) if check_snake(&n.value).is_none() => format!("commands[{i}] ({})", n.value),
        _ => format!("commands[{i}]"),
    }
}

/// The key of a field entry: `<command>.fields[0] (ph)`.
fn field_key(command: &str, j: usize, f: &FieldDoc) -> String {
    match &f.name {
        Some(n) if check_snake(&n.value).is_none() => format!("{command}.fields[{j}] ({})", n.value),
        _ => format!("{command}.fields[{j}]"),
    }
}

/// A sensor's header, checked.
struct Head {
    name: String,
    title: String,
    doc: String,
    model: Option<String>,
    model_code: Option<String>,
    manual: Manual,
    revisions: Vec<Revision>,
    serial: Serial,
    min_address: u8,
    max_address: u8,
    default_address: u8,
}

/// Characters that reorder text on screen (Trojan Source, CVE-2021-42574):
/// rustc refuses them in comments and literals, and a reader cannot see them.
const BIDI_CONTROLS: &[char] =
    &['\u{202A}', '\u{202B}', '\u{202C}', '\u{202D}', '\u{202E}', '\u{2066}', '\u{2067}', '\u{2068}', '\u{2069}'];

/// Name of a control character, for messages.
fn char_name(c: char) -> String {
    let name = match c {
        '\0' => " (NUL)",
        '\u{7}' => " (BEL)",
        '\u{8}' => " (backspace)",
        '\r' => " (carriage return)",
        '\u{b}' => " (vertical tab)",
        '\u{c}' => " (form feed)",
        '\u{1b}' => " (ESC)",
        '\u{7f}' => " (DEL)",
        c if BIDI_CONTROLS.contains(&c) => " (bidi override)",
        _ => "",
    };
    format!("U+{:04X}{name}", u32::from(c))
}

pub(crate) fn check_text(value: &Spanned<String>, key: &str, r: &mut Reporter<'_>) -> String {
    let text = &value.value;
    let mut bad: Vec<char> = Vec::new();
    for c in text.chars() {
        let control = c.is_control() && c != '\n' && c != '\t';
        if (control || BIDI_CONTROLS.contains(&c)) && !bad.contains(&c) {
            bad.push(c);
        }
    }
    if !bad.is_empty() {
        let names: Vec<String> = bad.iter().take(8).map(|c| char_name(*c)).collect();
        let what = if names.len() == 1 { "an invisible control character" } else { "invisible control characters" };
        r.error(
            Pos::at(value),
            key,
            format!("text contains {what}: {}", names.join(", ")),
            Some(
                "remove them; text may hold newlines and tabs, but no other control or bidi-override characters".into(),
            ),
        );
    }
    if text.len() > MAX_TEXT_LEN {
        r.error(
            Pos::at(value),
            key,
            format!("text is {} bytes long; at most {MAX_TEXT_LEN} are allowed", text.len()),
            Some("shorten it; long explanations belong in docs/".into()),
        );
    }
    text.trim().to_string()
}

fn check_name(value: &Spanned<String>, key: &str, r: &mut Reporter<'_>) -> bool {
    match check_snake(&value.value) {
        None => true,
        Some(why) => {
            r.error(
                Pos::at(value),
                key,
                format!("invalid name: {why}"),
                Some("names are snake_case ASCII (a-z, 0-9, _), start with a letter, and are not Rust keywords".into()),
            );
            false
        }
    }
}

/// A name valid as such that cannot name this kind of item (`rule`), reported with `help`.
fn check_role(
    value: &Spanned<String>,
    key: &str,
    rule: fn(&str) -> Option<String>,
    help: &str,
    r: &mut Reporter<'_>,
) -> bool {
    match rule(&value.value) {
        None => true,
        Some(why) => {
            r.error(Pos::at(value), key, format!("invalid name: {why}"), Some(help.replace("<name>", &value.value)));
            false
        }
    }
}

fn check_fragment(doc: &SpecFile, r: &mut Reporter<'_>) {
    if let Some(f) = &doc.fragment {
        check_name(&f.name, "fragment.name", r);
        check_text(&f.doc, "fragment.doc", r);
    }
    for (key, present) in [
        ("constants", !doc.constants.is_empty()),
        ("errata", !doc.errata.is_empty()),
        ("procedure", doc.procedure.is_some()),
    ] {
        if present {
            r.error(
                top_key_pos(r.text, key),
                key,
                format!("a fragment cannot hold `{key}`"),
                Some("a fragment holds only `commands` and `include`; move this to the sensor files".into()),
            );
        }
    }
    for (i, c) in doc.commands.iter().enumerate() {
        if let Some(u) = &c.uses {
            r.error(
                Pos::at(u),
                format!("{}.use", command_key(i, c)),
                "`use` belongs in sensor files, not fragments",
                Some("a fragment defines commands with `name`; sensor files `use` them".into()),
            );
        }
        if let Some(since) = &c.since {
            r.error(
                Pos::at(since),
                format!("{}.since", command_key(i, c)),
                "`since` belongs in sensor files: firmware revisions are a probe's own",
                Some("give `since` in the sensor file's `use` entry".into()),
            );
        }
    }
}

fn resolve_sensor_head(s: &SensorDoc, r: &mut Reporter<'_>) -> Option<Head> {
    let name_ok = check_name(&s.name, "sensor.name", r)
        && check_role(
            &s.name,
            "sensor.name",
            crate::names::check_sensor_name,
            "rename the sensor, e.g. `<name>_probe`",
            r,
        );
    let title = check_text(&s.title, "sensor.title", r);
    let doc = check_text(&s.doc, "sensor.doc", r);
    let manual = resolve_manual(&s.manual, "sensor.manual", r);
    let model = s.model.as_ref().map(|m| check_text(m, "sensor.model", r));
    let model_code = s.model_code.as_ref().map(|m| {
        let code = m.value.trim();
        if code.len() != 2 || !code.chars().all(|c| c.is_ascii_digit()) {
            r.error(
                Pos::at(m),
                "sensor.model_code",
                format!("model code `{}` is not two digits", escape(&m.value)),
                Some("write the two digits after `YL` in the serial number, quoted: `model_code: \"09\"`".into()),
            );
        }
        code.to_string()
    });
    let mut ok = name_ok;
    let serial = resolve_serial(&s.serial, "sensor.serial", r);
    ok &= serial.is_some();
    let mut revisions = Vec::new();
    let mut softwares: BTreeMap<String, Pos> = BTreeMap::new();
    if let Some(sw) = &s.manual.software {
        softwares.insert(sw.value.clone(), Pos::at(sw));
    }
    for (i, rev) in s.revisions.iter().enumerate() {
        let key = format!("sensor.revisions[{i}]");
        let rev_manual = resolve_manual(&rev.manual, &format!("{key}.manual"), r);
        match &rev.manual.software {
            None => {
                r.error(
                    Pos::at(&rev.manual.title),
                    format!("{key}.manual.software"),
                    "a revision's manual needs `software`, the firmware revision it documents",
                    Some("add `software: \"1.8\"` as the manual's scope line states it".into()),
                );
                ok = false;
            }
            Some(sw) => {
                if s.manual.software.is_none() {
                    r.error(
                        Pos::at(&s.manual.title),
                        "sensor.manual.software",
                        "a sensor with `revisions` states the `software` of its `manual` too",
                        Some("add `software:` to `sensor.manual`".into()),
                    );
                    ok = false;
                }
                if let Some(first) = softwares.insert(sw.value.clone(), Pos::at(sw)) {
                    r.error(
                        Pos::at(sw),
                        format!("{key}.manual.software"),
                        format!("software `{}` is already the revision of another manual", escape(&sw.value)),
                        Some(format!(
                            "each manual documents one software revision (the first is at line {})",
                            first.line
                        )),
                    );
                    ok = false;
                }
            }
        }
        let rev_serial = match &rev.serial {
            Some(sd) => resolve_serial(sd, &format!("{key}.serial"), r),
            None => serial,
        };
        let doc = rev.doc.as_ref().map(|d| check_text(d, &format!("{key}.doc"), r));
        match rev_serial {
            Some(serial) => revisions.push(Revision { manual: rev_manual, doc, serial }),
            None => ok = false,
        }
    }
    let min = s.addresses.min.value;
    let max = s.addresses.max.value;
    if !(1..=247).contains(&min) || !(1..=247).contains(&max) || min > max {
        r.error(
            Pos::at(&s.addresses.min),
            "sensor.addresses",
            format!("address range {min}..={max} is not a range of Modbus slave addresses"),
            Some("use min <= max within 1..=247".into()),
        );
        ok = false;
    }
    let default = s.default_address.value;
    if default < min || default > max {
        r.error(
            Pos::at(&s.default_address),
            "sensor.default_address",
            format!("default address {default} is outside {min}..={max}"),
            Some("the factory address must be one of `addresses`".into()),
        );
        ok = false;
    }
    if !ok {
        return None;
    }
    Some(Head {
        name: s.name.value.clone(),
        title,
        doc,
        model,
        model_code,
        manual,
        revisions,
        serial: serial?,
        min_address: min as u8,
        max_address: max as u8,
        default_address: default as u8,
    })
}

fn resolve_manual(m: &ManualDoc, key: &str, r: &mut Reporter<'_>) -> Manual {
    Manual {
        title: check_text(&m.title, &format!("{key}.title"), r),
        revision: check_text(&m.revision, &format!("{key}.revision"), r),
        software: m.software.as_ref().map(|s| check_text(s, &format!("{key}.software"), r)),
        file: m.file.as_ref().map(|f| check_text(f, &format!("{key}.file"), r)),
    }
}

fn resolve_serial(serial: &SerialDoc, key: &str, r: &mut Reporter<'_>) -> Option<Serial> {
    let mut ok = true;
    let baud = serial.baud.value;
    if !(300..=1_000_000).contains(&baud) {
        r.error(
            Pos::at(&serial.baud),
            format!("{key}.baud"),
            format!("baud rate {baud} is not plausible"),
            Some("use 300..=1000000 (the manuals say 9600)".into()),
        );
        ok = false;
    }
    let data_bits = serial.data_bits.value;
    if !(7..=8).contains(&data_bits) {
        r.error(
            Pos::at(&serial.data_bits),
            format!("{key}.data_bits"),
            format!("a serial line has 7 or 8 data bits, not {data_bits}"),
            Some("use 7 or 8 (the manuals say 8)".into()),
        );
        ok = false;
    }
    let stop_bits = serial.stop_bits.value;
    if !(1..=2).contains(&stop_bits) {
        r.error(
            Pos::at(&serial.stop_bits),
            format!("{key}.stop_bits"),
            format!("a serial line has 1 or 2 stop bits, not {stop_bits}"),
            Some("use 1 or 2 (the manuals say 1)".into()),
        );
        ok = false;
    }
    let parity = match serial.parity {
        ParityDoc::None => Parity::None,
        ParityDoc::Even => Parity::Even,
        ParityDoc::Odd => Parity::Odd,
    };
    ok.then_some(Serial { baud, data_bits: data_bits as u8, parity, stop_bits: stop_bits as u8 })
}

/// Depth-first over includes, collecting fragment commands; reports cycles
/// (each once) and includes of files that are not fragments. Returns false
/// when some included file could not be used, so that its commands are
/// unknown rather than missing.
fn collect_includes<'d>(
    files: &'d BTreeMap<PathBuf, Parsed>,
    file: &Path,
    stack: &mut Vec<PathBuf>,
    out: &mut Vec<Def<'d>>,
    diags: &mut Vec<Diagnostic>,
    cycles: &mut BTreeSet<BTreeSet<PathBuf>>,
) -> bool {
    let Some(parsed) = files.get(file) else { return false };
    let Some(doc) = &parsed.doc else { return false };
    let mut complete = true;
    for (i, inc) in doc.include.iter().enumerate() {
        // Invalid include paths were reported while parsing.
        let Ok(path) = include_target(file, &inc.value.file) else {
            complete = false;
            continue;
        };
        let mut r = Reporter { file, text: &parsed.text, out: diags };
        if let Some(start) = stack.iter().position(|p| *p == path) {
            let members: BTreeSet<PathBuf> = stack[start..].iter().cloned().collect();
            if cycles.insert(members) {
                let chain: Vec<String> = stack[start..].iter().chain([&path]).map(|p| shown(p, file)).collect();
                r.error(
                    Pos::at(inc),
                    format!("include[{i}]"),
                    format!("include cycle: {}", chain.join(" -> ")),
                    Some("a fragment may not include itself, directly or through others; remove this include".into()),
                );
            }
            continue;
        }
        if stack.len() >= MAX_INCLUDE_DEPTH {
            r.error(
                Pos::at(inc),
                format!("include[{i}]"),
                format!("includes nest deeper than {MAX_INCLUDE_DEPTH} files"),
                Some("include the fragments from the sensor file directly".into()),
            );
            complete = false;
            continue;
        }

        // Unreadable or broken files were reported where they are.
        let Some(inc_doc) = files.get(&path).and_then(|p| p.doc.as_ref()) else {
            complete = false;
            continue;
        };
        let Some(fragment) = &inc_doc.fragment else {
            let what = match &inc_doc.sensor {
                Some(s) => format!("it describes the sensor `{}`", escape(&s.name.value)),
                None => "it has no `fragment:` section".into(),
            };
            r.error(
                Pos::at(inc),
                format!("include[{i}]"),
                format!("`{}` is not a fragment: {what}", escape(&inc.value.file)),
                Some("only files with a `fragment:` section can be included".into()),
            );
            complete = false;
            continue;
        };
        stack.push(path.clone());
        complete &= collect_includes(files, &path, stack, out, diags, cycles);
        stack.pop();
        let Some((path_ref, _)) = files.get_key_value(&path) else { continue };
        let mut r = Reporter { file, text: &parsed.text, out: diags };
        let defined: Vec<&str> =
            inc_doc.commands.iter().filter_map(|c| c.name.as_ref().map(|n| n.value.as_str())).collect();
        if let Some(only) = &inc.value.only {
            for (j, name) in only.iter().enumerate() {
                if !defined.contains(&name.value.as_str()) {
                    let help = match crate::yaml::closest(&name.value, &defined) {
                        Some(best) => {
                            format!("did you mean `{best}`? `{}` defines: {}", inc.value.file, defined.join(", "))
                        }
                        None => format!("`{}` defines: {}", inc.value.file, defined.join(", ")),
                    };
                    r.error(
                        Pos::at(name),
                        format!("include[{i}].only[{j}]"),
                        format!("`{}` defines no command called `{}`", escape(&inc.value.file), escape(&name.value)),
                        Some(help),
                    );
                }
            }
        }
        for (index, c) in inc_doc.commands.iter().enumerate() {
            let Some(name) = &c.name else { continue };
            let taken = inc.value.only.as_ref().is_none_or(|only| only.iter().any(|o| o.value == name.value));
            if taken && !out.iter().any(|d| d.file == path_ref.as_path() && d.index == index) {
                out.push(Def { file: path_ref.as_path(), doc: c, index, fragment: Some(fragment.name.value.clone()) });
            }
        }
    }
    complete
}

/// A `use:` entry may only add this manual's source, examples and errata.
fn check_use_entry(c: &CommandDoc, i: usize, r: &mut Reporter<'_>) {
    let extra: Vec<(&str, Pos)> = [
        ("role", c.role.as_ref().map(Pos::at)),
        ("function", c.function.as_ref().map(Pos::at)),
        ("address", c.address.as_ref().map(Pos::at)),
        ("count", c.count.as_ref().map(Pos::at)),
        ("trigger", c.trigger.as_ref().map(Pos::at)),
        ("fixed_slave", c.fixed_slave.as_ref().map(Pos::at)),
        ("fields", c.fields.as_ref().map(Pos::at)),
        ("extra_byte_counts", c.extra_byte_counts.first().map(Pos::at)),
    ]
    .into_iter()
    .filter_map(|(k, p)| p.map(|p| (k, p)))
    .collect();
    for (key, pos) in extra {
        r.error(
            pos,
            format!("{}.{key}", command_key(i, c)),
            format!("`{key}` cannot be changed by a `use` entry"),
            Some("a `use` entry takes `title`, `doc`, `since`, `units`, `source`, `examples` and `errata`; change the definition in the fragment".into()),
        );
    }
}

fn resolve_source(s: &SourceDoc, key: &str, r: &mut Reporter<'_>) -> Source {
    let at = Pos::at(&s.section);
    Source {
        section: check_text(&s.section, &format!("{key}.section"), r),
        figures: resolve_figures(&s.figures, &format!("{key}.figures"), at, r),
        manual: s.manual.as_ref().map(|m| check_text(m, &format!("{key}.manual"), r)),
    }
}

/// Figure references: numbers, `T<n>` tables, `<n>b` repeated numbers.
pub(crate) fn resolve_figures(docs: &[FigureDoc], key: &str, at: Pos, r: &mut Reporter<'_>) -> Vec<Figure> {
    docs.iter().enumerate().filter_map(|(i, f)| resolve_figure(f, &format!("{key}[{i}]"), at, r)).collect()
}

pub(crate) fn resolve_figure(doc: &FigureDoc, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<Figure> {
    let parsed = match doc {
        FigureDoc::Number(n) => Ok(Figure::number(*n)),
        FigureDoc::Text(t) => Figure::parse(t),
    };
    match parsed {
        Ok(f) => Some(f),
        Err(why) => {
            r.error(
                at,
                key,
                why,
                Some("figures are `23`, `\"T4\"` (Table 4) or `\"43b\"` (the second figure 43)".into()),
            );
            None
        }
    }
}

fn require<'a, T>(
    v: &'a Option<Spanned<T>>,
    at: Pos,
    key: &str,
    what: &str,
    r: &mut Reporter<'_>,
) -> Option<&'a Spanned<T>> {
    if v.is_none() {
        let help = match what {
            "function" => "add `function: read` (0x03) or `function: write` (0x10)",
            "address" => "add `address:`, the first register as sent on the wire, like `0x2800`",
            "count" => "add `count:`, the number of registers",
            _ => "see spec/schema.json",
        };
        r.error(at, key, format!("missing `{what}`"), Some(help.into()));
    }
    v.as_ref()
}

/// Turns a command definition into the model, reporting every problem.
fn resolve_command(
    c: &CommandDoc,
    _prefix: Option<&str>,
    i: usize,
    fragment: Option<String>,
    r: &mut Reporter<'_>,
) -> Option<Command> {
    let key = command_key(i, c);
    let name = c.name.as_ref()?;
    let name_ok = check_name(name, &format!("{key}.name"), r)
        && check_role(
            name,
            &format!("{key}.name"),
            crate::names::check_command_name,
            "rename the command, e.g. `get_<name>`",
            r,
        );
    let at = Pos::at(name);
    let title = c.title.as_ref().map(|t| check_text(t, &format!("{key}.title"), r));
    let doc = c.doc.as_ref().map(|t| check_text(t, &format!("{key}.doc"), r));
    let source = c.source.as_ref().map(|s| resolve_source(s, &format!("{key}.source"), r)).unwrap_or_default();
    let function = require(&c.function, at, &format!("{key}.function"), "function", r).map(|f| match f.value {
        FunctionDoc::Read => Function::Read,
        FunctionDoc::Write => Function::Write,
    });
    let address = require(&c.address, at, &format!("{key}.address"), "address", r).and_then(|a| {
        u16::try_from(a.value).ok().or_else(|| {
            r.error(
                Pos::at(a),
                format!("{key}.address"),
                format!("register address {} does not fit in 16 bits", a.value),
                Some("addresses are 0x0000..=0xFFFF, as sent on the wire".into()),
            );
            None
        })
    });
    let trigger = c.trigger.as_ref().is_some_and(|t| t.value);
    let since = c.since.as_ref().map(|s| check_text(s, &format!("{key}.since"), r));
    if let Some(units) = &c.units {
        r.error(
            Pos::at(units),
            format!("{key}.units"),
            "`units` belongs in a `use` entry",
            Some("give each field its `unit` in `fields`".into()),
        );
    }
    let count = require(&c.count, at, &format!("{key}.count"), "count", r);
    let count = match (function, count) {
        (Some(f), Some(n)) => check_count(f, n, trigger, &key, r),
        _ => None,
    };
    let fixed_slave = c.fixed_slave.as_ref().and_then(|s| {
        u8::try_from(s.value).ok().or_else(|| {
            r.error(
                Pos::at(s),
                format!("{key}.fixed_slave"),
                format!("slave address {} does not fit in a byte", s.value),
                Some("a fixed slave address is 0..=255, like `0xFF` for a wildcard".into()),
            );
            None
        })
    });
    let mut extra_byte_counts = Vec::new();
    for (j, b) in c.extra_byte_counts.iter().enumerate() {
        let k = format!("{key}.extra_byte_counts[{j}]");
        if function != Some(Function::Read) {
            r.error(
                Pos::at(b),
                &k,
                "extra byte counts apply to read replies only",
                Some("remove `extra_byte_counts` from this write".into()),
            );
        } else if b.value > 250 || count.is_some_and(|n| b.value == 2 * u32::from(n)) {
            r.error(
                Pos::at(b),
                &k,
                format!("byte count {} is not an alternative to the normal one", b.value),
                Some("list only counts other than 2 * count, at most 250".into()),
            );
        } else {
            extra_byte_counts.push(b.value as u8);
        }
    }
    let fields = resolve_fields(c, &key, count, trigger, at, r);

    let mut cmd = Command {
        name: name.value.clone(),
        title: title.unwrap_or_else(|| name.value.replace('_', " ")),
        doc: doc.unwrap_or_default(),
        source,
        function: function?,
        address: address?,
        count: count?,
        trigger,
        since,
        role: c.role.as_ref().map(|r| r.value),
        fixed_slave,
        extra_byte_counts,
        fields: fields?,
        examples: Vec::new(),
        errata: Vec::new(),
        shared_from: fragment,
    };
    if !name_ok {
        return None;
    }
    if let Some(role) = &c.role
        && let Err(why) = check_role_shape(role.value, &cmd)
    {
        r.error(
            Pos::at(role),
            format!("{key}.role"),
            format!("`{}` cannot have role `{}`: {why}", cmd.name, role.value.name()),
            Some("see the roles in docs/spec-language.md".into()),
        );
        return None;
    }
    resolve_command_extras(c, i, &mut cmd, r);
    Some(cmd)
}

/// What a command with `role` must look like for the simulator and the CLI to use it.
fn check_role_shape(role: Role, cmd: &Command) -> Result<(), String> {
    let named: Vec<&Field> = cmd.named_fields().collect();
    let one = |pred: fn(&FieldKind) -> bool, what: &str| -> Result<(), String> {
        match named.as_slice() {
            [f] if pred(&f.kind) => Ok(()),
            _ => Err(format!("it needs exactly one named field, {what}")),
        }
    };
    let read = |ok: bool| if ok { Ok(()) } else { Err("it must be a read".to_string()) };
    let write = |ok: bool| if ok { Ok(()) } else { Err("it must be a write".to_string()) };
    match role {
        Role::SetSlaveAddress => write(!cmd.is_read()).and_then(|()| one(|k| matches!(k, FieldKind::U8), "a `u8`")),
        Role::GetSlaveAddress => read(cmd.is_read()).and_then(|()| one(|k| matches!(k, FieldKind::U8), "a `u8`")),
        Role::SerialNumber => {
            read(cmd.is_read()).and_then(|()| one(|k| matches!(k, FieldKind::Ascii { .. }), "an `ascii`"))
        }
        Role::Version => {
            read(cmd.is_read())?;
            if !named.is_empty() && named.iter().all(|f| matches!(f.kind, FieldKind::Version)) {
                Ok(())
            } else {
                Err("its fields must be `version` fields".into())
            }
        }
        Role::StartMeasurement | Role::StopMeasurement | Role::Wipe => {
            if cmd.trigger {
                Ok(())
            } else {
                Err("it must be a `trigger`".into())
            }
        }
        Role::CalibrationPoint => write(!cmd.is_read()).and_then(|()| {
            one(|k| matches!(k, FieldKind::F32 { .. } | FieldKind::U16 { .. } | FieldKind::I16 { .. }), "a number")
        }),
        Role::CalibrationStatus => {
            read(cmd.is_read()).and_then(|()| one(|k| matches!(k, FieldKind::Enum { .. }), "an `enum`"))
        }
    }
}

fn check_count(f: Function, n: &Spanned<u32>, trigger: bool, key: &str, r: &mut Reporter<'_>) -> Option<u16> {
    let v = n.value;
    let k = format!("{key}.count");
    if trigger && f == Function::Read {
        // A read used as a command: it asks for registers whose reply it ignores.
        if v == 0 || v > MAX_READ_COUNT {
            r.error(
                Pos::at(n),
                k,
                format!("a trigger read asks for 1..={MAX_READ_COUNT} registers, not {v}"),
                Some("use the count the manual's request sends, like `count: 1`".into()),
            );
            return None;
        }
        return Some(v as u16);
    }
    if trigger {
        if v != 0 {
            r.error(Pos::at(n), k, format!("a trigger writes 0 registers, not {v}"), Some("use `count: 0`".into()));
            return None;
        }
        return Some(0);
    }
    let max = if f == Function::Read { MAX_READ_COUNT } else { MAX_WRITE_COUNT };
    if v == 0 {
        r.error(
            Pos::at(n),
            k,
            "register count 0 is only valid for a trigger write".to_string(),
            Some("declare `trigger: true` on a write that sends no data (like conductivity start measurement)".into()),
        );
        return None;
    }
    if v > max {
        let what = if f == Function::Read { "read" } else { "write" };
        r.error(
            Pos::at(n),
            k,
            format!("register count {v} is out of range for a {what}"),
            Some(format!("a {what} covers 1..={max} registers")),
        );
        return None;
    }
    Some(v as u16)
}

fn order2(o: Option<&Spanned<ByteOrderDoc>>, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<Order2> {
    match o.map(|o| (o.value, Pos::at(o))) {
        Some((ByteOrderDoc::Ab, _)) => Some(Order2::Ab),
        Some((ByteOrderDoc::Ba, _)) => Some(Order2::Ba),
        Some((other, pos)) => {
            r.error(
                pos,
                key,
                format!("`{}` is a 4-byte order but the value has 2 bytes", order_name(other)),
                Some("use `ab` (big-endian) or `ba`".into()),
            );
            None
        }
        None => {
            r.error(at, key, "missing `byte_order` for a 2-byte value", Some("use `ab` (big-endian) or `ba`".into()));
            None
        }
    }
}

fn order4(o: Option<&Spanned<ByteOrderDoc>>, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<Order4> {
    let help = "use `abcd` (big-endian), `dcba` (little-endian image), `cdab` or `badc`";
    match o.map(|o| (o.value, Pos::at(o))) {
        Some((ByteOrderDoc::Abcd, _)) => Some(Order4::Abcd),
        Some((ByteOrderDoc::Dcba, _)) => Some(Order4::Dcba),
        Some((ByteOrderDoc::Cdab, _)) => Some(Order4::Cdab),
        Some((ByteOrderDoc::Badc, _)) => Some(Order4::Badc),
        Some((other, pos)) => {
            r.error(
                pos,
                key,
                format!("`{}` is a 2-byte order but the value has 4 bytes", order_name(other)),
                Some(help.into()),
            );
            None
        }
        None => {
            r.error(at, key, "missing `byte_order` for a 4-byte value", Some(help.into()));
            None
        }
    }
}

fn order_name(o: ByteOrderDoc) -> &'static str {
    match o {
        ByteOrderDoc::Ab => "ab",
        ByteOrderDoc::Ba => "ba",
        ByteOrderDoc::Abcd => "abcd",
        ByteOrderDoc::Dcba => "dcba",
        ByteOrderDoc::Cdab => "cdab",
        ByteOrderDoc::Badc => "badc",
    }
}

fn resolve_fields(
    c: &CommandDoc,
    key: &str,
    count: Option<u16>,
    trigger: bool,
    at: Pos,
    r: &mut Reporter<'_>,
) -> Option<Vec<Field>> {
    let docs: &[FieldDoc] = c.fields.as_ref().map(|f| f.value.as_slice()).unwrap_or(&[]);
    if trigger {
        if let Some(f) = &c.fields
            && !f.value.is_empty()
        {
            r.error(
                Pos::at(f),
                format!("{key}.fields"),
                "a trigger carries no fields",
                Some("remove `fields`, or remove `trigger` and describe the data".into()),
            );
            return None;
        }
        return Some(Vec::new());
    }
    if docs.is_empty() {
        if c.count.as_ref().is_some_and(|n| n.value == 0) {
            return None; // `count: 0` without `trigger` is reported; no fields follows from it.
        }
        let pos = c.fields.as_ref().map(Pos::at).unwrap_or(at);
        r.error(
            pos,
            format!("{key}.fields"),
            "the command has no fields",
            Some("describe the register data, using `reserved` for unused bytes".into()),
        );
        return None;
    }
    let mut ok = true;
    let mut fields = Vec::new();
    let mut names: BTreeMap<String, Pos> = BTreeMap::new();
    let mut offset = 0usize;
    for (j, f) in docs.iter().enumerate() {
        let fk = field_key(key, j, f);
        let fat = Pos::at(&f.ty);
        match resolve_field(f, &fk, fat, offset, r) {
            Some(field) => {
                let pos = f.name.as_ref().map(Pos::at).unwrap_or(fat);
                if let Some(n) = &field.name
                    && let Some(first) = names.insert(n.clone(), pos)
                {
                    r.error(
                        pos,
                        format!("{fk}.name"),
                        format!("two fields of this command are called `{n}`"),
                        Some(format!(
                            "the first is at line {}, column {}; rename one of them",
                            first.line, first.column
                        )),
                    );
                    ok = false;
                }
                offset = field.offset + field.size();
                fields.push(field);
            }
            None => ok = false,
        }
    }
    if ok && let Some(count) = count {
        let want = 2 * usize::from(count);
        let pos = c.count.as_ref().map(Pos::at).unwrap_or(at);
        if offset < want {
            r.error(
                pos,
                format!("{key}.fields"),
                format!("the fields cover {offset} bytes but {count} registers hold {want}"),
                Some(format!("add a `reserved` field of {} bytes or fix `count`", want - offset)),
            );
            ok = false;
        } else if offset > want {
            r.error(
                pos,
                format!("{key}.fields"),
                format!("the fields need {offset} bytes but {count} registers hold only {want}"),
                Some(format!("`count` should be {}", offset.div_ceil(2))),
            );
            ok = false;
        }
    }
    ok.then_some(fields)
}

fn forbid<T>(v: &Option<Spanned<T>>, what: &str, ty: &str, key: &str, r: &mut Reporter<'_>) -> bool {
    match v {
        Some(v) => {
            r.error(
                Pos::at(v),
                format!("{key}.{what}"),
                format!("`{what}` does not apply to a `{ty}` field"),
                Some(format!("remove `{what}`")),
            );
            false
        }
        None => true,
    }
}

fn resolve_field(f: &FieldDoc, key: &str, at: Pos, offset: usize, r: &mut Reporter<'_>) -> Option<Field> {
    let ty = f.ty.value;
    let ty_name = type_name(ty);
    let mut ok = true;
    let name = match (&f.name, ty) {
        (Some(n), _) => {
            ok &= check_name(n, &format!("{key}.name"), r);
            Some(n.value.clone())
        }
        (None, FieldTypeDoc::Reserved) => None,
        (None, _) => {
            r.error(
                at,
                format!("{key}.name"),
                format!("a `{ty_name}` field needs a `name`"),
                Some("add `name:`, or use `type: reserved` for bytes without meaning".into()),
            );
            ok = false;
            None
        }
    };
    let size = f.size.as_ref().map(|s| (s.value, Pos::at(s)));
    let needs_size = |r: &mut Reporter<'_>| -> Option<usize> {
        match size {
            Some((s, pos)) if s == 0 || s > 250 => {
                r.error(
                    pos,
                    format!("{key}.size"),
                    format!("size {s} is not between 1 and 250 bytes"),
                    Some("a field fits in one frame: at most 250 bytes (125 registers)".into()),
                );
                None
            }
            Some((s, _)) => Some(s as usize),
            None => {
                r.error(
                    at,
                    format!("{key}.size"),
                    format!("a `{ty_name}` field needs a `size` in bytes"),
                    Some("add `size:`".into()),
                );
                None
            }
        }
    };
    let kind = match ty {
        FieldTypeDoc::F32 => {
            order4(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::F32 { order })
        }
        FieldTypeDoc::U32 => {
            order4(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::U32 { order })
        }
        FieldTypeDoc::I32 => {
            order4(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::I32 { order })
        }
        FieldTypeDoc::U16 => {
            order2(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::U16 { order })
        }
        FieldTypeDoc::I16 => {
            order2(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(|order| FieldKind::I16 { order })
        }
        FieldTypeDoc::U8 => Some(FieldKind::U8),
        FieldTypeDoc::I8 => Some(FieldKind::I8),
        FieldTypeDoc::Version => Some(FieldKind::Version),
        FieldTypeDoc::Ascii => {
            let padding = match f.padding.as_ref().map(|p| p.value) {
                None | Some(PaddingDoc::Nul) => 0u8,
                Some(PaddingDoc::Space) => b' ',
            };
            needs_size(r).map(|len| FieldKind::Ascii { len, padding })
        }
        FieldTypeDoc::Reserved => {
            let fill = match &f.fill {
                Some(v) if v.value > 255 => {
                    r.error(
                        Pos::at(v),
                        format!("{key}.fill"),
                        format!("fill {} does not fit in a byte", v.value),
                        None,
                    );
                    None
                }
                Some(v) => Some(v.value as u8),
                None => Some(0),
            };
            match (needs_size(r), fill) {
                (Some(len), Some(fill)) => Some(FieldKind::Reserved { len, fill }),
                _ => None,
            }
        }
        FieldTypeDoc::Enum => resolve_enum(f, key, at, r),
        FieldTypeDoc::Bcd => Some(FieldKind::Bcd),
        FieldTypeDoc::Flags => resolve_flags(f, key, at, r),
    };
    // Keys that do not apply to this type.
    let multi_byte =
        matches!(ty, FieldTypeDoc::F32 | FieldTypeDoc::U16 | FieldTypeDoc::I16 | FieldTypeDoc::U32 | FieldTypeDoc::I32)
            || (matches!(ty, FieldTypeDoc::Enum | FieldTypeDoc::Flags) && size.is_some_and(|(s, _)| s == 2));
    if !multi_byte {
        ok &= forbid(&f.byte_order, "byte_order", ty_name, key, r);
    }
    if !matches!(ty, FieldTypeDoc::Ascii | FieldTypeDoc::Reserved | FieldTypeDoc::Enum | FieldTypeDoc::Flags) {
        ok &= forbid(&f.size, "size", ty_name, key, r);
    }
    if ty != FieldTypeDoc::Ascii {
        ok &= forbid(&f.padding, "padding", ty_name, key, r);
    }
    if ty != FieldTypeDoc::Reserved {
        ok &= forbid(&f.fill, "fill", ty_name, key, r);
    }
    if ty != FieldTypeDoc::Enum {
        ok &= forbid(&f.variants, "variants", ty_name, key, r);
    }
    if ty != FieldTypeDoc::Flags {
        ok &= forbid(&f.flags, "flags", ty_name, key, r);
    }
    let numeric = matches!(
        ty,
        FieldTypeDoc::F32
            | FieldTypeDoc::U8
            | FieldTypeDoc::I8
            | FieldTypeDoc::U16
            | FieldTypeDoc::I16
            | FieldTypeDoc::U32
            | FieldTypeDoc::I32
            | FieldTypeDoc::Bcd
    );
    if !numeric {
        ok &= forbid(&f.absent, "absent", ty_name, key, r);
    }
    let absent = match &f.absent {
        Some(a) if !a.value.is_finite() => {
            r.error(Pos::at(a), format!("{key}.absent"), format!("{} is not a finite number", a.value), None);
            ok = false;
            None
        }
        Some(a) => Some(a.value),
        None => None,
    };
    let range = match &f.range {
        Some(rg) if !numeric => {
            r.error(
                Pos::at(rg),
                format!("{key}.range"),
                format!("`range` does not apply to a `{ty_name}` field"),
                None,
            );
            ok = false;
            None
        }
        Some(rg) if !(rg.value.min.is_finite() && rg.value.max.is_finite() && rg.value.min <= rg.value.max) => {
            r.error(
                Pos::at(rg),
                format!("{key}.range"),
                format!("range {}..={} is empty or not finite", rg.value.min, rg.value.max),
                None,
            );
            ok = false;
            None
        }
        Some(rg) => Some((rg.value.min, rg.value.max)),
        None => None,
    };
    let unit = f.unit.as_ref().map(|u| check_text(u, &format!("{key}.unit"), r));
    let doc = f.doc.as_ref().map(|d| check_text(d, &format!("{key}.doc"), r));
    let kind = kind?;
    if let Some(o) = &f.offset {
        let want = o.value as usize;
        if want < offset {
            r.error(
                Pos::at(o),
                format!("{key}.offset"),
                format!("field starts at byte {want} but the previous field ends at byte {offset}: they overlap"),
                Some(format!("use `offset: {offset}` or remove `offset`")),
            );
            ok = false;
        } else if want > offset {
            r.error(
                Pos::at(o),
                format!("{key}.offset"),
                format!("bytes {offset}..{want} are not covered by any field"),
                Some(format!("add a `reserved` field of {} bytes before this one", want - offset)),
            );
            ok = false;
        }
    }
    if ty == FieldTypeDoc::Bcd
        && let Some((min, max)) = range
        && (min < 0.0 || max > 99.0)
    {
        let pos = f.range.as_ref().map(Pos::at).unwrap_or(at);
        r.error(pos, format!("{key}.range"), format!("a `bcd` byte holds 0..=99, not {min}..={max}"), None);
        ok = false;
    }
    let mut field = Field { name, kind, offset, unit, doc, range, absent, examples: Vec::new() };
    for (j, e) in f.examples.iter().enumerate() {
        let ek = format!("{key}.examples[{j}]");
        let figures = resolve_figures(&e.figures, &format!("{ek}.figures"), Pos::at(&e.bytes), r);
        let bytes = match parse_hex(&e.bytes.value) {
            Ok(b) => b,
            Err(why) => {
                r.error(Pos::at(&e.bytes), format!("{ek}.bytes"), format!("invalid hex: {why}"), None);
                ok = false;
                continue;
            }
        };
        if bytes.len() != field.size() {
            r.error(
                Pos::at(&e.bytes),
                format!("{ek}.bytes"),
                format!("{} bytes, but the field takes {}", bytes.len(), field.size()),
                None,
            );
            ok = false;
            continue;
        }
        let value = match stated_value(&field, &e.value.value) {
            Ok(v) => v,
            Err(why) => {
                r.error(Pos::at(&e.value), format!("{ek}.value"), why, None);
                ok = false;
                continue;
            }
        };
        let decoded = crate::interp::decode_field(&field, &bytes);
        if !decoded.same_as(&value) {
            r.error(
                Pos::at(&e.value),
                format!("{ek}.value"),
                format!("the bytes decode to {decoded}, but the example states {value}"),
                Some("check the value against the bytes the manual prints".into()),
            );
            ok = false;
            continue;
        }
        match crate::interp::encode_field(&field, &value) {
            Ok(again) if again == bytes => {}
            Ok(again) => {
                r.error(
                    Pos::at(&e.bytes),
                    format!("{ek}.bytes"),
                    format!("the value encodes as {}", Hex(&again)),
                    Some("the value and the bytes must match both ways".into()),
                );
                ok = false;
                continue;
            }
            Err(err) => {
                r.error(Pos::at(&e.value), format!("{ek}.value"), format!("the value does not encode: {err}"), None);
                ok = false;
                continue;
            }
        }
        field.examples.push(FieldExample { bytes, value, figures });
    }
    ok.then_some(field)
}

fn resolve_flags(f: &FieldDoc, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<FieldKind> {
    let repr = match f.size.as_ref().map(|s| (s.value, Pos::at(s))) {
        None | Some((1, _)) => Some(EnumRepr::U8),
        Some((2, _)) => order2(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(EnumRepr::U16),
        Some((s, pos)) => {
            r.error(
                pos,
                format!("{key}.size"),
                format!("a flags field is 1 or 2 bytes, not {s}"),
                Some("use `size: 1`, or `size: 2` with a `byte_order`".into()),
            );
            None
        }
    };
    let Some(flags) = &f.flags else {
        r.error(
            at,
            format!("{key}.flags"),
            "a `flags` field needs `flags`",
            Some("list `- {name: ..., mask: 0x01}` entries".into()),
        );
        return None;
    };
    if flags.value.is_empty() {
        r.error(Pos::at(flags), format!("{key}.flags"), "a `flags` field needs at least one flag", None);
        return None;
    }
    let max: u32 = if repr == Some(EnumRepr::U8) { 0xFF } else { 0xFFFF };
    let mut ok = true;
    let mut seen_names = BTreeSet::new();
    let mut seen_masks = BTreeSet::new();
    let mut out = Vec::new();
    for (j, fl) in flags.value.iter().enumerate() {
        let fk = format!("{key}.flags[{j}]");
        ok &= check_name(&fl.name, &format!("{fk}.name"), r);
        if !seen_names.insert(fl.name.value.clone()) {
            r.error(Pos::at(&fl.name), format!("{fk}.name"), format!("two flags are called `{}`", fl.name.value), None);
            ok = false;
        }
        let m = fl.mask.value;
        if m == 0 || m > max || !m.is_power_of_two() {
            r.error(
                Pos::at(&fl.mask),
                format!("{fk}.mask"),
                format!("mask 0x{m:X} is not one bit of the field"),
                Some(format!("a flag is one bit: 0x01, 0x02, 0x04 ... up to 0x{:X}", max.div_ceil(2))),
            );
            ok = false;
        } else if !seen_masks.insert(m) {
            r.error(Pos::at(&fl.mask), format!("{fk}.mask"), format!("mask 0x{m:X} is used twice"), None);
            ok = false;
        }
        let doc = fl.doc.as_ref().map(|d| check_text(d, &format!("{fk}.doc"), r));
        out.push(Flag { name: fl.name.value.clone(), mask: m as u16, doc });
    }
    let repr = repr?;
    ok.then_some(FieldKind::Flags { repr, flags: out })
}

fn type_name(ty: FieldTypeDoc) -> &'static str {
    match ty {
        FieldTypeDoc::F32 => "f32",
        FieldTypeDoc::U8 => "u8",
        FieldTypeDoc::I8 => "i8",
        FieldTypeDoc::U16 => "u16",
        FieldTypeDoc::I16 => "i16",
        FieldTypeDoc::U32 => "u32",
        FieldTypeDoc::I32 => "i32",
        FieldTypeDoc::Ascii => "ascii",
        FieldTypeDoc::Version => "version",
        FieldTypeDoc::Enum => "enum",
        FieldTypeDoc::Reserved => "reserved",
        FieldTypeDoc::Bcd => "bcd",
        FieldTypeDoc::Flags => "flags",
    }
}

fn resolve_enum(f: &FieldDoc, key: &str, at: Pos, r: &mut Reporter<'_>) -> Option<FieldKind> {
    let repr = match f.size.as_ref().map(|s| (s.value, Pos::at(s))) {
        None | Some((1, _)) => Some(EnumRepr::U8),
        Some((2, _)) => order2(f.byte_order.as_ref(), &format!("{key}.byte_order"), at, r).map(EnumRepr::U16),
        Some((s, pos)) => {
            r.error(
                pos,
                format!("{key}.size"),
                format!("an enum code is 1 or 2 bytes, not {s}"),
                Some("use `size: 1`, or `size: 2` with a `byte_order`".into()),
            );
            None
        }
    };
    let Some(variants) = &f.variants else {
        r.error(
            at,
            format!("{key}.variants"),
            "an `enum` field needs `variants`",
            Some("list `- {name: ..., value: ...}` entries".into()),
        );
        return None;
    };
    if variants.value.is_empty() {
        r.error(
            Pos::at(variants),
            format!("{key}.variants"),
            "an `enum` needs at least one variant",
            Some("list `- {name: ..., value: ...}` entries".into()),
        );
        return None;
    }
    let max = if repr == Some(EnumRepr::U8) { 0xFF } else { 0xFFFF };
    let mut ok = true;
    let mut names: BTreeMap<String, Pos> = BTreeMap::new();
    let mut types: BTreeMap<String, String> = BTreeMap::new();
    let mut values = BTreeMap::new();
    let mut out = Vec::new();
    for (j, v) in variants.value.iter().enumerate() {
        let vk = match check_snake(&v.name.value) {
            None => format!("{key}.variants[{j}] ({})", v.name.value),
            Some(_) => format!("{key}.variants[{j}]"),
        };
        let name_ok = check_name(&v.name, &format!("{vk}.name"), r);
        ok &= name_ok;
        if let Some(first) = names.insert(v.name.value.clone(), Pos::at(&v.name)) {
            r.error(
                Pos::at(&v.name),
                format!("{vk}.name"),
                format!("two variants are called `{}`", v.name.value),
                Some(format!("the first is at line {}, column {}; rename one of them", first.line, first.column)),
            );
            ok = false;
        } else if name_ok {
            let ty = camel(&v.name.value);
            if let Some(other) = types.insert(ty.clone(), v.name.value.clone()) {
                r.error(
                    Pos::at(&v.name),
                    format!("{vk}.name"),
                    format!("variants `{other}` and `{}` both become the Rust variant `{ty}`", v.name.value),
                    Some("rename one of them".into()),
                );
                ok = false;
            }
        }
        if v.value.value > max {
            let (bytes, help) = if max == 0xFF {
                (1, "a 1-byte enum takes codes 0..=255; for larger codes use `size: 2` with a `byte_order`")
            } else {
                (2, "a 2-byte enum takes codes 0..=65535")
            };
            r.error(
                Pos::at(&v.value),
                format!("{vk}.value"),
                format!("code {} does not fit the enum's {bytes}-byte size", v.value.value),
                Some(help.into()),
            );
            ok = false;
        } else if let Some(other) = values.insert(v.value.value, v.name.value.clone()) {
            r.error(
                Pos::at(&v.value),
                format!("{vk}.value"),
                format!("code {} is used by `{other}` and `{}`", v.value.value, v.name.value),
                Some("enum codes must be unique; each code names one variant".into()),
            );
            ok = false;
        }
        let doc = v.doc.as_ref().map(|d| check_text(d, &format!("{vk}.doc"), r));
        out.push(Variant { name: v.name.value.clone(), value: v.value.value as u16, doc });
    }
    let repr = repr?;
    ok.then_some(FieldKind::Enum { repr, variants: out })
}

/// Examples and table errata; needs the resolved command.
fn resolve_command_extras(c: &CommandDoc, i: usize, cmd: &mut Command, r: &mut Reporter<'_>) {
    let key = command_key(i, c);
    let mut ids = BTreeSet::new();
    for (j, e) in c.errata.iter().enumerate() {
        let ek = format!("{key}.errata[{j}]");
        check_erratum_id(&e.id, &format!("{ek}.id"), &mut ids, r);
        let note = check_text(&e.note, &format!("{ek}.note"), r);
        let t = &e.table;
        let mut differs = false;
        if let Some(a) = &t.address {
            if a.value == u32::from(cmd.address) {
                r.error(
                    Pos::at(a),
                    format!("{ek}.table.address"),
                    format!("the table's address 0x{:04X} is the command's own: nothing to correct", a.value),
                    Some("remove `address` from `table`".into()),
                );
            } else if a.value > 0xFFFF {
                r.error(
                    Pos::at(a),
                    format!("{ek}.table.address"),
                    format!("address {} does not fit in 16 bits", a.value),
                    Some("addresses are 0x0000..=0xFFFF".into()),
                );
            }
            differs = true;
        }
        if let Some(n) = &t.count {
            if n.value == u32::from(cmd.count) {
                r.error(
                    Pos::at(n),
                    format!("{ek}.table.count"),
                    format!("the table's count {} is the command's own: nothing to correct", n.value),
                    Some("remove `count` from `table`".into()),
                );
            } else if n.value > 0xFFFF {
                r.error(
                    Pos::at(n),
                    format!("{ek}.table.count"),
                    format!("count {} does not fit in 16 bits", n.value),
                    Some("counts are 0..=65535".into()),
                );
            }
            differs = true;
        }
        let table_function = t.function.as_ref().map(|f| {
            let func = match f.value {
                FunctionDoc::Read => Function::Read,
                FunctionDoc::Write => Function::Write,
            };
            if func == cmd.function {
                r.error(
                    Pos::at(f),
                    format!("{ek}.table.function"),
                    "the table's function is the command's own: nothing to correct",
                    Some("remove `function` from `table`".into()),
                );
            }
            func
        });
        if t.function.is_some() {
            differs = true;
        }
        if !differs {
            r.error(
                Pos::at(&e.id),
                format!("{ek}.table"),
                "a table erratum names what the table prints: `address`, `count` or `function`",
                Some("add `table: {address: 0x1100}` (or `count`, `function`) as the table prints it".into()),
            );
        }
        let figure = match &e.figure {
            Some(f) => match resolve_figure(&f.value, &format!("{ek}.figure"), Pos::at(f), r) {
                Some(figure) => Some(figure),
                None => continue,
            },
            None => None,
        };
        cmd.errata.push(CommandErratum {
            id: e.id.value.clone(),
            figure,
            manual: e.manual.as_ref().map(|m| check_text(m, &format!("{ek}.manual"), r)),
            table_address: t.address.as_ref().map(|a| a.value as u16),
            table_count: t.count.as_ref().map(|n| n.value as u16),
            table_function,
            note,
        });
    }
    for (j, e) in c.examples.iter().enumerate() {
        if let Some(ex) = crate::examples::check_example(cmd, e, &format!("{key}.examples[{j}]"), &mut ids, r) {
            cmd.examples.push(ex);
        }
    }
}

pub(crate) fn check_erratum_id(id: &Spanned<String>, key: &str, ids: &mut BTreeSet<String>, r: &mut Reporter<'_>) {
    let v = &id.value;
    let valid = !v.is_empty() && v.len() <= 16 && v.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !valid {
        r.error(
            Pos::at(id),
            key,
            format!("erratum id `{}` is not a short identifier", escape(v)),
            Some("use the id from datasheet-notes.md, like `E4`".into()),
        );
    } else if !ids.insert(v.clone()) {
        r.error(
            Pos::at(id),
            key,
            format!("erratum `{v}` is recorded twice here"),
            Some("record each erratum once per command".into()),
        );
    }
}

fn resolve_constants(docs: &[ConstantDoc], r: &mut Reporter<'_>) -> Vec<Constant> {
    let mut out = Vec::new();
    let mut names: BTreeMap<String, Pos> = BTreeMap::new();
    let mut consts: BTreeMap<String, String> = BTreeMap::new();
    for (i, c) in docs.iter().enumerate() {
        let key = match check_snake(&c.name.value) {
            None => format!("constants[{i}] ({})", c.name.value),
            Some(_) => format!("constants[{i}]"),
        };
        let name_ok = check_name(&c.name, &format!("{key}.name"), r);
        let mut ok = name_ok;
        if let Some(first) = names.insert(c.name.value.clone(), Pos::at(&c.name)) {
            r.error(
                Pos::at(&c.name),
                format!("{key}.name"),
                format!("two constants are called `{}`", c.name.value),
                Some(format!("the first is at line {}, column {}; rename one of them", first.line, first.column)),
            );
            ok = false;
        } else if name_ok {
            let upper = shouty(&c.name.value);
            if let Some(other) = consts.insert(upper.clone(), c.name.value.clone()) {
                r.error(
                    Pos::at(&c.name),
                    format!("{key}.name"),
                    format!("constants `{other}` and `{}` both become the Rust constant `{upper}`", c.name.value),
                    Some("rename one of them".into()),
                );
                ok = false;
            }
        }
        let doc = check_text(&c.doc, &format!("{key}.doc"), r);
        let unit = c.unit.as_ref().map(|u| check_text(u, &format!("{key}.unit"), r));
        let source = c.source.as_ref().map(|s| resolve_source(s, &format!("{key}.source"), r));
        let (values, is_list, pos) = match (&c.value, &c.values) {
            (Some(v), None) => (vec![v.value], false, Pos::at(v)),
            (None, Some(vs)) if !vs.value.is_empty() && vs.value.len() <= 64 => (vs.value.clone(), true, Pos::at(vs)),
            (None, Some(vs)) => {
                r.error(
                    Pos::at(vs),
                    format!("{key}.values"),
                    "a list constant holds 1 to 64 values",
                    Some("use `value:` for a single number".into()),
                );
                continue;
            }
            _ => {
                r.error(
                    Pos::at(&c.name),
                    &key,
                    "a constant has exactly one of `value` and `values`",
                    Some("use `value: 1.0` for a number or `values: [1.0, 2.0]` for a list".into()),
                );
                continue;
            }
        };
        let ty = match c.ty.value {
            ConstantTypeDoc::F32 => ConstantType::F32,
            ConstantTypeDoc::U8 => ConstantType::U8,
            ConstantTypeDoc::U16 => ConstantType::U16,
            ConstantTypeDoc::U32 => ConstantType::U32,
        };
        let max = match ty {
            ConstantType::F32 => f64::from(f32::MAX),
            ConstantType::U8 => 255.0,
            ConstantType::U16 => 65535.0,
            ConstantType::U32 => 4294967295.0,
        };
        for v in &values {
            let integral = ty == ConstantType::F32 || (v.fract() == 0.0 && *v >= 0.0);
            if !v.is_finite() || !integral || v.abs() > max {
                r.error(
                    pos,
                    format!("{key}.value"),
                    format!("{v} is not a valid `{}`", type_name_const(ty)),
                    Some(format!(
                        "a `{}` holds {}",
                        type_name_const(ty),
                        match ty {
                            ConstantType::F32 => "finite numbers that fit an f32",
                            ConstantType::U8 => "whole numbers 0..=255",
                            ConstantType::U16 => "whole numbers 0..=65535",
                            ConstantType::U32 => "whole numbers 0..=4294967295",
                        }
                    )),
                );
                ok = false;
            }
        }
        if ok {
            out.push(Constant { name: c.name.value.clone(), ty, values, is_list, unit, doc, source });
        }
    }
    out
}

fn type_name_const(t: ConstantType) -> &'static str {
    match t {
        ConstantType::F32 => "f32",
        ConstantType::U8 => "u8",
        ConstantType::U16 => "u16",
        ConstantType::U32 => "u32",
    }
}

fn resolve_errata(docs: &[ErratumDoc], r: &mut Reporter<'_>) -> Vec<Erratum> {
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

/// Parses "01 03 28 00" (spaces optional between bytes).
pub fn parse_hex(text: &str) -> Result<Vec<u8>, String> {
    let compact: String = text.chars().filter(|c| !c.is_whitespace()).collect();
    if compact.is_empty() {
        return Err("the frame is empty".into());
    }
    if let Some(bad) = compact.chars().find(|c| !c.is_ascii_hexdigit()) {
        return Err(format!("{bad:?} is not a hex digit"));
    }
    if !compact.len().is_multiple_of(2) {
        return Err(format!("{} hex digits is an odd number; each byte takes two", compact.len()));
    }
    if compact.len() / 2 > yosemitech_rtu::frame::MAX_ADU {
        return Err(format!("{} bytes is longer than any RTU frame (256)", compact.len() / 2));
    }
    (0..compact.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(compact.get(i..i + 2).unwrap_or("zz"), 16).map_err(|e| e.to_string()))
        .collect()
}

/// The CRC a frame should carry, shown as wire bytes.
pub(crate) fn crc_text(frame: &[u8]) -> String {
    let body = frame.get(..frame.len().saturating_sub(2)).unwrap_or(&[]);
    Hex(&crc16(body).to_le_bytes()).to_string()
}

/// Converts a stated value to the field's value type.
pub(crate) fn stated_value(field: &Field, v: &StatedValue) -> Result<Value, String> {
    let ty = field.kind.type_name();
    match (&field.kind, v) {
        (FieldKind::F32 { .. }, StatedValue::Number(n)) => Ok(Value::Float(*n as f32)),
        (
            FieldKind::U8
            | FieldKind::I8
            | FieldKind::U16 { .. }
            | FieldKind::I16 { .. }
            | FieldKind::U32 { .. }
            | FieldKind::I32 { .. },
            StatedValue::Number(n),
        ) => {
            if n.fract() != 0.0 || !n.is_finite() || n.abs() > 4.3e9 {
                Err(format!("{n} is not a whole number for a `{ty}` field"))
            } else {
                Ok(Value::Int(*n as i64))
            }
        }
        (FieldKind::Bcd, StatedValue::Number(n)) => {
            if n.fract() != 0.0 || !(0.0..=99.0).contains(n) {
                Err(format!("{n} is not a two-digit number for a `bcd` field"))
            } else {
                yosemitech_rtu::Bcd::from_value(*n as u8)
                    .map(Value::Bcd)
                    .ok_or_else(|| format!("{n} is not a two-digit number"))
            }
        }
        (FieldKind::Flags { flags, .. }, StatedValue::Number(n)) => {
            let all: u32 = flags.iter().map(|f| u32::from(f.mask)).sum();
            if n.fract() != 0.0 || *n < 0.0 || *n > f64::from(all) {
                Err(format!("{n} is not a combination of this field's flags"))
            } else {
                Ok(Value::Int(*n as i64))
            }
        }
        (FieldKind::Flags { flags, .. }, StatedValue::Text(t)) => {
            let mut raw = 0i64;
            for part in t.split('|').map(str::trim).filter(|p| !p.is_empty() && *p != "none") {
                match flags.iter().find(|f| f.name == part) {
                    Some(f) => raw |= i64::from(f.mask),
                    None => {
                        return Err(format!(
                            "`{}` is not a flag; flags: {}",
                            escape(part),
                            flags.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(", ")
                        ));
                    }
                }
            }
            Ok(Value::Int(raw))
        }
        (FieldKind::Ascii { .. }, StatedValue::Text(t)) => Ok(Value::Text(t.clone())),
        (FieldKind::Version, StatedValue::Text(t)) => {
            parse_version(t).map(Value::Version).ok_or_else(|| format!("`{t}` is not a version like \"1.1\""))
        }
        (FieldKind::Version, StatedValue::Number(n)) => Err(format!("write the version {n} as text, e.g. \"1.1\"")),
        (FieldKind::Enum { variants, .. }, StatedValue::Text(t)) => variants
            .iter()
            .find(|v| &v.name == t)
            .map(|v| Value::Enum { raw: v.value, name: Some(v.name.clone()) })
            .ok_or_else(|| {
                format!(
                    "`{}` is not a variant; variants: {}",
                    escape(t),
                    variants.iter().map(|v| v.name.as_str()).collect::<Vec<_>>().join(", ")
                )
            }),
        (_, StatedValue::Number(n)) => Err(format!("a `{ty}` field takes text, not the number {n}")),
        (_, StatedValue::Text(t)) => Err(format!("a `{ty}` field takes a number, not the text {:?}", escape(t))),
    }
}

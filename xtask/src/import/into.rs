//! `cargo xtask import MANUAL --into spec/NAME.yaml [--out FILE] [--json]`:
//! another revision of a probe's manual, merged into the probe's spec.
//!
//! The manual is drafted as `import` drafts a new one, recognised as the
//! spec's probe (or refused, naming the spec it seems to belong to),
//! placed among the recorded manuals by its software revision, compared
//! (`merge`) and written into a copy of the spec's text (`edit`). The merged
//! file is loaded before it is written: every problem the loader finds in
//! it becomes a `# TODO(import)`, as does everything the comparison cannot
//! decide, and `cargo xtask validate` rejects the file until each is
//! resolved. The review (`review`) says what changed.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use yosemitech_spec::sources::{MemSources, normalize};
use yosemitech_spec::{Spec, load_paths, load_with};

use super::edit::{self, Edits};
use super::merge::{self, Place};
use super::review::Review;
use super::{BadInput, bad, file_name, import_with, read_manual, shared_from};

/// A merge's outcome.
pub(crate) struct Merged {
    /// The merged spec's text; `None` when the manual adds nothing.
    pub text: Option<String>,
    /// The review.
    pub review: Review,
}

/// Every sensor of `dir` that loads (the directory at once, or file by file
/// when some file does not), and the index of `target` among them.
fn load_dir(dir: &Path, target: &Path) -> Result<(Spec, usize), BadInput> {
    let same = |a: &Path, b: &Path| normalize(a) == normalize(b) || a.canonicalize().ok() == b.canonicalize().ok();
    let find = |spec: &Spec| spec.sensors.iter().position(|s| same(&s.file, target));
    if let Ok(spec) = load_paths(&[dir.to_path_buf()])
        && let Some(i) = find(&spec)
    {
        return Ok((spec, i));
    }
    // Some file of the directory does not load: take every one that does.
    let own = match load_paths(&[target.to_path_buf()]) {
        Ok(spec) => spec,
        Err(diags) => {
            let first =
                diags.0.first().map(|d| format!("{}:{}:{}: {}", d.file.display(), d.pos.line, d.pos.column, d.message));
            return bad(format!(
                "{} does not validate ({}); run `cargo xtask validate` and fix it first",
                target.display(),
                first.unwrap_or_else(|| "no sensor".into())
            ));
        }
    };
    if own.sensors.is_empty() {
        return bad(format!("{} is a fragment, not a sensor's spec", target.display()));
    }
    let mut spec = Spec { sensors: Vec::new(), fragments: own.fragments.clone() };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| rd.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|x| x == "yaml")).collect())
        .unwrap_or_default();
    files.sort();
    for f in files {
        if same(&f, target) {
            continue;
        }
        if let Ok(other) = load_paths(&[f]) {
            for frag in other.fragments {
                if !spec.fragments.iter().any(|x| x.name == frag.name) {
                    spec.fragments.push(frag);
                }
            }
            // A copy of the target (a merge written beside it) is no other probe.
            let name = &own.sensors[0].name;
            spec.sensors.extend(other.sensors.into_iter().filter(|s| s.name != *name));
        }
    }
    spec.sensors.extend(own.sensors);
    let i = spec.sensors.len() - 1;
    Ok((spec, i))
}

/// Merges the manual at `manual` (its text) into the spec file `into`.
pub(crate) fn merge_manual(manual: &Path, into: &Path) -> Result<Merged, BadInput> {
    let text = read_manual(manual)?;
    merge_text(&text, &file_name(manual), into)
}

/// Merges a manual's text (`file`: its file name, as the spec records it).
pub(crate) fn merge_text(text: &str, file: &str, into: &Path) -> Result<Merged, BadInput> {
    let started = Instant::now();
    let meta = match std::fs::metadata(into) {
        Ok(m) => m,
        Err(e) => return bad(format!("--into {}: {e}", into.display())),
    };
    if !meta.is_file() || into.extension().is_none_or(|x| x != "yaml" && x != "yml") {
        return bad(format!("--into {}: not a spec file (`spec/NAME.yaml`)", into.display()));
    }
    let original = match std::fs::read_to_string(into) {
        Ok(t) => t,
        Err(e) => return bad(format!("--into {}: {e}", into.display())),
    };
    let dir = into.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let (spec, target) = load_dir(dir, into)?;
    let sensor = &spec.sensors[target];
    let draft = import_with(text, &sensor.name, file, &shared_from(&spec))?;
    let Some(software) = draft.header.software.clone() else {
        return bad(
            "the manual's scope line names no software revision (\"... software Rev1.8 or later\"), so it cannot be placed among the spec's revisions",
        );
    };
    let identified = super::identify::identify(&spec, target, &draft).map_err(BadInput)?;
    let place = merge::place(sensor, &software).map_err(BadInput)?;
    let recorded: Vec<String> = sensor.manuals().filter_map(|m| m.software.clone()).collect();
    let placement = match &place {
        Place::Newer => format!("SW {software}, newer than every recorded manual ({})", recorded.join(", ")),
        Place::Older => format!("SW {software}, older than every recorded manual ({})", recorded.join(", ")),
        Place::Between => format!("SW {software}, between the recorded manuals ({})", recorded.join(", ")),
        Place::Recorded(_) => format!("SW {software}, a recorded manual"),
    };
    // A cover title that is prose (a text without its cover page) is no title.
    let mut draft = draft;
    let cover = draft.header.manual_title.trim().to_string();
    if (cover.is_empty() || cover.len() > 100 || cover.contains(". "))
        && let Some(m) = &sensor.manual
    {
        draft.header.manual_title = m.title.clone();
    }
    let mut review = Review {
        manual: file.to_string(),
        spec: into.display().to_string(),
        sensor: sensor.name.clone(),
        title: draft.header.manual_title.clone(),
        revision: draft.header.revision.clone(),
        software: software.clone(),
        identified,
        placement,
        ..Review::default()
    };
    let plan = merge::plan(&spec, sensor, &draft, file, &software, &place, &mut review);
    if plan.is_empty() {
        review.nothing_new = true;
        review.todos.clear();
        review.millis = started.elapsed().as_secs_f64() * 1000.0;
        return Ok(Merged { text: None, review });
    }
    let lines = edit::lines_of(&original);
    let (edits, unplaced) = edit::apply_plan(&lines, &plan);
    review.todos.extend(unplaced.iter().map(|t| super::one_line_text(t)));
    for (name, e) in &plan.commands {
        review.todos.extend(e.todos.iter().map(|t| format!("{name}: {}", super::one_line_text(t))));
    }
    for nc in &plan.new_commands {
        review.todos.extend(
            nc.text.lines().filter_map(|l| l.trim().strip_prefix("# TODO(import): ")).map(|t| format!("(added) {t}")),
        );
    }
    let mut seen = Vec::new();
    review.todos.retain(|t| {
        let fresh = !seen.contains(t);
        seen.push(t.clone());
        fresh
    });
    let (merged, _) = edits.apply(&lines);
    // The loader's word on the merged text, placed where the original was
    // (includes resolve the same way); its problems become TODOs.
    let merged = with_loader_todos(dir, into, merged, &mut review);
    review.millis = started.elapsed().as_secs_f64() * 1000.0;
    Ok(Merged { text: Some(edit::text_of(&merged)), review })
}

/// Loads `lines` as the file `into` (its fragments from `dir`) and puts a
/// `# TODO(import)` before the entry holding each problem found (the
/// importer's own TODOs aside).
fn with_loader_todos(dir: &Path, into: &Path, lines: Vec<String>, review: &mut Review) -> Vec<String> {
    let root = normalize(into);
    let mut sources = MemSources::default();
    if let Ok(rd) = std::fs::read_dir(dir) {
        for entry in rd.flatten() {
            let p = entry.path();
            if p.extension().is_some_and(|x| x == "yaml" || x == "yml")
                && let Ok(t) = std::fs::read_to_string(&p)
            {
                sources = sources.with(normalize(&dir.join(entry.file_name())), t);
            }
        }
    }
    sources = sources.with(root.clone(), edit::text_of(&lines));
    let Err(diags) = load_with(&sources, std::slice::from_ref(&root)) else { return lines };
    let mut e = Edits::default();
    let outline_root = edit::root(&lines);
    let commands = edit::find_key(&lines, outline_root, "commands");
    let cmd_items = commands.as_ref().map(|k| edit::items(&lines, k)).unwrap_or_default();
    let sensor = edit::find_key(&lines, outline_root, "sensor");
    for d in &diags.0 {
        if d.file != root || d.source_line.as_deref().is_some_and(|l| l.contains(yosemitech_spec::IMPORT_TODO)) {
            continue;
        }
        let at = (d.pos.line as usize).saturating_sub(1);
        let (anchor, indent) = match cmd_items.iter().find(|s| (s.start..s.end).contains(&at)) {
            Some(item) => (item.start, item.indent - 2),
            None => (sensor.as_ref().map_or(0, |s| s.line), 0),
        };
        let key = if d.key.is_empty() { String::new() } else { format!("{}: ", d.key) };
        let text = format!("validate: {key}{}", d.message);
        review.todos.push(super::one_line_text(&text));
        e.before(anchor, vec![edit::todo_line(indent, &text)]);
    }
    if e.is_empty() { lines } else { e.apply(&lines).0 }
}

/// Runs `import MANUAL --into SPEC [--out FILE] [--json]`.
pub(crate) fn run(manual: &Path, into: &Path, out: Option<&Path>, json: bool) -> anyhow::Result<ExitCode> {
    let out = out.map(Path::to_path_buf).unwrap_or_else(|| {
        let stem = into.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        // Not `.yaml`: the loader reads every `*.yaml` of spec/, and the merge is for review first.
        into.with_file_name(format!("{stem}.yaml.merged"))
    });
    let same_file =
        normalize(&out) == normalize(into) || (out.exists() && out.canonicalize().ok() == into.canonicalize().ok());
    if same_file {
        eprintln!(
            "error: --out {} is the spec itself; the merge is written beside it for review, never over it",
            out.display()
        );
        return Ok(ExitCode::from(2));
    }
    let merged = match merge_manual(manual, into) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {}: {e}", manual.display());
            return Ok(ExitCode::from(2));
        }
    };
    let mut review = merged.review;
    let Some(text) = merged.text else {
        print!("{}", if json { review.json() + "\n" } else { review.text() });
        return Ok(ExitCode::SUCCESS);
    };
    if out.exists() {
        eprintln!("error: {} exists; pass another --out (the merge never overwrites a file)", out.display());
        return Ok(ExitCode::from(2));
    }
    if let Err(e) = std::fs::write(&out, text) {
        eprintln!("error: cannot write {}: {e}", out.display());
        return Ok(ExitCode::from(2));
    }
    review.out = Some(out.display().to_string());
    print!("{}", if json { review.json() + "\n" } else { review.text() });
    if !json {
        println!(
            "review it (diff -u {} {}), resolve each `# TODO(import)`, then move it over {}",
            into.display(),
            out.display(),
            into.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

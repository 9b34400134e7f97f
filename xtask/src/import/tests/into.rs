//! `--into` on the manuals the project has: every probe of `spec/` whose
//! file merges two manual revisions (both texts in `../shared/`) loses one
//! revision in a copy of its spec, gets it back from the manual, and must
//! come out as it was, but for the differences listed in `TOLERATED`. The
//! manuals are never copied into the repository: without `../shared/` the
//! tests print a loud SKIPPED note and pass.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use yosemitech_spec::{CommandSpec, Example, Sensor, Spec, load_paths};

use super::super::accuracy::shared_manuals;
use super::super::edit::{self, Edits, Span};
use super::super::into::merge_text;
use super::super::{file_name, read_manual};

/// Differences the round trip accepts, each with why.
const TOLERATED: &[(&str, &str)] = &[
    (
        "prose",
        "titles, docs, erratum ids and notes: a person's words; the importer writes neutral placeholders and copies no sentence of a manual",
    ),
    (
        "revision title",
        "the merged revision carries the manual's cover title as printed; the reviewed spec names the manual in its own words",
    ),
    (
        "manual-wide errata",
        "top-level `errata:` of the removed manual are a person's reading of its prose; the importer drafts only frame (CRC) and register-table errata",
    ),
    (
        "procedure source",
        "a `procedure.source` citing the removed manual: procedures are not drafted; the review lists section 3's numbers and commands instead",
    ),
    (
        "cited values",
        "a reviewed copy of a frame that states fewer values (or no erratum) than the example the merge cites instead: the citation carries the cited example's values and erratum",
    ),
];

/// The manuals of `../shared/` by file name.
fn manual_paths() -> Option<BTreeMap<String, PathBuf>> {
    Some(shared_manuals()?.into_iter().map(|p| (file_name(&p), p)).collect())
}

/// `spec/`'s fragments and the sensors with a manual in `../shared/`,
/// copied into a fresh directory (the drop-in corpus stays out).
fn copy_spec(tag: &str, manuals: &BTreeMap<String, PathBuf>) -> (PathBuf, Spec) {
    let spec_dir = crate::root().join("spec");
    let dir = std::env::temp_dir().join(format!("xtask-into-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&spec_dir)
        .expect("spec/")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .collect();
    files.sort();
    for f in &files {
        let text = std::fs::read_to_string(f).expect("a spec file");
        let fragment = text.lines().any(|l| l.starts_with("fragment:"));
        let with_manual = !fragment
            && load_paths(std::slice::from_ref(f)).is_ok_and(|s| {
                s.sensors.iter().any(|s| s.manuals().any(|m| m.file.as_ref().is_some_and(|f| manuals.contains_key(f))))
            });
        if fragment || with_manual {
            std::fs::copy(f, dir.join(f.file_name().expect("a file name"))).expect("copied");
        }
    }
    let copy = load_paths(std::slice::from_ref(&dir)).expect("the copy validates");
    (dir, copy)
}

/// The sensors that merge two manuals whose texts both exist.
fn two_revision_probes<'a>(spec: &'a Spec, manuals: &BTreeMap<String, PathBuf>) -> Vec<&'a Sensor> {
    spec.sensors
        .iter()
        .filter(|s| !s.revisions.is_empty())
        .filter(|s| s.manuals().all(|m| m.file.as_ref().is_some_and(|f| manuals.contains_key(f))))
        .collect()
}

fn vkey(s: &str) -> Vec<u32> {
    s.split('.').filter_map(|x| x.parse().ok()).collect()
}

/// The key `name` of the mapping `within`, required.
fn key(lines: &[String], within: Span, name: &str) -> Option<edit::Key> {
    edit::find_key(lines, within, name)
}

/// Removes a list item, and the list's key when it was the only item.
fn remove_item(e: &mut Edits, k: &edit::Key, items: &[Span], i: usize) {
    if items.len() == 1 {
        e.remove(k.line, k.end);
    } else {
        e.remove(items[i].start, items[i].end);
    }
}

/// The spec text of `sensor` without the manual of software `sw`: its
/// revision entry, its examples and errata (`manual:`), the commands it
/// introduced (`since`), `since` values no remaining manual needs, and a
/// `procedure.source` that cites it; includes keep only the commands left.
fn without_revision(text: &str, sensor: &Sensor, spec: &Spec, sw: &str) -> String {
    let lines = edit::lines_of(text);
    let root = edit::root(&lines);
    let mut e = Edits::default();
    let default_sw = sensor.manual.as_ref().and_then(|m| m.software.clone()).unwrap_or_default();
    let remaining: Vec<String> = sensor.manuals().filter_map(|m| m.software.clone()).filter(|s| s != sw).collect();
    let oldest = remaining.iter().min_by_key(|s| vkey(s)).cloned().unwrap_or_default();
    let next_above = remaining.iter().filter(|s| vkey(s) > vkey(sw)).min_by_key(|s| vkey(s)).cloned();
    let sensor_key = key(&lines, root, "sensor").expect("sensor");
    let revisions = key(&lines, sensor_key.body(&lines), "revisions").expect("revisions");
    let revs = edit::items(&lines, &revisions);
    let i = sensor.revisions.iter().position(|r| r.manual.software.as_deref() == Some(sw)).expect("the revision");
    remove_item(&mut e, &revisions, &revs, i);
    // Commands.
    let mut removed: Vec<&CommandSpec> = Vec::new();
    let commands = key(&lines, root, "commands").expect("commands");
    let items = edit::items(&lines, &commands);
    for item in &items {
        let Some(name) = edit::item_name(&lines, *item) else { continue };
        let Some(c) = sensor.command(&name) else { continue };
        if let Some(since) = key(&lines, *item, "since") {
            let s = edit::scalar(&since);
            let moved = if s == sw { next_above.clone() } else { Some(s.clone()) };
            match moved {
                None => {
                    e.remove(item.start, item.end);
                    removed.push(c);
                    continue;
                }
                Some(m) if vkey(&m) <= vkey(&oldest) => e.remove(since.line, since.end),
                Some(m) if m != s => e.replace(since.line, format!("{}since: \"{m}\"", " ".repeat(item.indent))),
                Some(_) => {}
            }
        }
        for list in ["examples", "errata"] {
            let Some(k) = key(&lines, *item, list) else { continue };
            let its = edit::items(&lines, &k);
            let of_sw: Vec<usize> = (0..its.len())
                .filter(|&j| key(&lines, its[j], "manual").is_some_and(|m| edit::scalar(&m) == sw))
                .collect();
            if of_sw.len() == its.len() {
                e.remove(k.line, k.end);
            } else {
                for j in of_sw {
                    e.remove(its[j].start, its[j].end);
                }
            }
            if list == "examples" {
                for x in its {
                    if let Some(a) = key(&lines, x, "also_in") {
                        let cites = edit::items(&lines, &a);
                        let of_sw: Vec<usize> = (0..cites.len())
                            .filter(|&j| lines[cites[j].start].contains(&format!("\"{sw}\"")))
                            .collect();
                        if of_sw.len() == cites.len() {
                            e.remove(a.line, a.end);
                        } else {
                            for j in of_sw {
                                e.remove(cites[j].start, cites[j].end);
                            }
                        }
                    }
                }
            }
        }
    }
    // Manual-wide errata and the procedure's source.
    if let Some(k) = key(&lines, root, "errata") {
        let its = edit::items(&lines, &k);
        for x in its {
            if key(&lines, x, "manual").is_some_and(|m| edit::scalar(&m) == sw) {
                e.remove(x.start, x.end);
            }
        }
    }
    if let Some(p) = key(&lines, root, "procedure")
        && let Some(src) = key(&lines, p.body(&lines), "source")
        && (src.inline.contains(&format!("manual: \"{sw}\"")) || (src.inline.is_empty() && default_sw == sw))
    {
        e.remove(src.line, src.end);
    }
    // Includes: the fragment commands removed leave their `only:`.
    let gone: Vec<&str> = removed.iter().filter(|c| c.shared_from.is_some()).map(|c| c.name.as_str()).collect();
    if !gone.is_empty()
        && let Some(inc) = key(&lines, root, "include")
    {
        for it in edit::items(&lines, &inc) {
            let l = lines[it.start].trim_start().trim_start_matches('-').trim().to_string();
            let (file, only): (String, Option<Vec<String>>) = match l.strip_prefix('{') {
                Some(flow) => {
                    let file = flow.split("file:").nth(1).and_then(|r| r.split(',').next()).unwrap_or("").trim();
                    let only = flow
                        .split("only: [")
                        .nth(1)
                        .and_then(|r| r.split(']').next())
                        .map(|r| r.split(',').map(|n| n.trim().to_string()).collect());
                    (file.to_string(), only)
                }
                None => (l.clone(), None),
            };
            let frag = spec.fragments.iter().find(|f| file_name(&f.file) == file).expect("an included fragment");
            let all: Vec<String> = frag.commands.iter().map(|c| c.name.clone()).collect();
            let keep: Vec<String> = only.unwrap_or(all).into_iter().filter(|n| !gone.contains(&n.as_str())).collect();
            if keep.is_empty() {
                e.remove(it.start, it.end);
            } else {
                e.replace(
                    it.start,
                    format!("{}- {{file: {file}, only: [{}]}}", " ".repeat(it.indent - 2), keep.join(", ")),
                );
            }
        }
    }
    edit::text_of(&e.apply(&lines).0)
}

/// One example as compared: (manual, printed frames) -> (figures, values, erratum, cited).
type ExampleKey = (String, String, String);
#[derive(Debug, Clone, PartialEq)]
struct ExampleFacts {
    figures: Vec<String>,
    values: BTreeMap<String, String>,
    erratum: Option<String>,
    cited: bool,
}

fn frame_text(f: &Option<yosemitech_spec::PrintedFrame>) -> String {
    f.as_ref().map(|f| format!("{:?}/{}/{}", f.bytes, f.open_ended, f.crc_printed)).unwrap_or_default()
}

/// Every example of a command, citations expanded into the examples they stand for.
fn examples(c: &CommandSpec, default_sw: &str) -> Vec<(ExampleKey, ExampleFacts)> {
    let mut out = Vec::new();
    let facts = |x: &Example, figures: Vec<String>, cited: bool| ExampleFacts {
        figures,
        values: x.values.iter().map(|(k, v)| (k.clone(), format!("{v:?}"))).collect(),
        erratum: x.erratum.as_ref().map(|e| {
            format!("{} {:?} {:?} {}", e.figure, e.corrected_request, e.corrected_response, e.printed_decodes)
        }),
        cited,
    };
    for x in &c.examples {
        let frames = (frame_text(&x.request), frame_text(&x.response));
        let own = x.manual.clone().unwrap_or_else(|| default_sw.to_string());
        out.push((
            (own, frames.0.clone(), frames.1.clone()),
            facts(x, x.figures.iter().map(ToString::to_string).collect(), false),
        ));
        for a in &x.also_in {
            out.push((
                (a.manual.clone(), frames.0.clone(), frames.1.clone()),
                facts(x, a.figures.iter().map(ToString::to_string).collect(), true),
            ));
        }
    }
    out
}

fn layout(c: &CommandSpec) -> String {
    let fields: Vec<String> = c
        .fields
        .iter()
        .map(|f| {
            format!(
                "{}:{}@{}+{}/{:?}",
                f.display_name(),
                f.kind.type_name(),
                f.offset,
                f.size(),
                f.kind.byte_order_name()
            )
        })
        .collect();
    format!(
        "{:?} 0x{:04X} x{} trigger={} fixed={:?} extra={:?} role={:?} shared={:?} since={:?} source={} {:?} {:?} fields=[{}]",
        c.function,
        c.address,
        c.count,
        c.trigger,
        c.fixed_slave,
        c.extra_byte_counts,
        c.role,
        c.shared_from,
        c.since,
        c.source.section,
        c.source.figures.iter().map(ToString::to_string).collect::<Vec<_>>(),
        c.source.manual,
        fields.join(", ")
    )
}

/// The differences between the reviewed sensor and the merged one: (category, what).
fn differences(want: &Sensor, got: &Sensor, removed_sw: &str) -> Vec<(&'static str, String)> {
    let mut out: Vec<(&'static str, String)> = Vec::new();
    let default_sw = want.manual.as_ref().and_then(|m| m.software.clone()).unwrap_or_default();
    // The manuals.
    let serial = |s: &Sensor, sw: &str| s.serial_for(sw).to_string();
    for m in want.manuals() {
        let sw = m.software.clone().unwrap_or_default();
        let Some(g) = got.manuals().find(|x| x.software == m.software) else {
            out.push(("manuals", format!("SW {sw}: missing")));
            continue;
        };
        if (m.revision.as_str(), &m.file) != (g.revision.as_str(), &g.file) {
            out.push(("manuals", format!("SW {sw}: {} {:?} vs {} {:?}", m.revision, m.file, g.revision, g.file)));
        }
        if m.title != g.title {
            out.push(("revision title", format!("SW {sw}: \"{}\" vs \"{}\"", m.title, g.title)));
        }
        let claims =
            |x: &yosemitech_spec::Manual| x.serial_claims.iter().map(|c| c.serial.to_string()).collect::<Vec<_>>();
        if claims(m) != claims(g) || serial(want, &sw) != serial(got, &sw) {
            out.push((
                "serial",
                format!("SW {sw}: {:?} / {} vs {:?} / {}", claims(m), serial(want, &sw), claims(g), serial(got, &sw)),
            ));
        }
    }
    if want.revisions.iter().map(|r| &r.doc).ne(got.revisions.iter().map(|r| &r.doc)) {
        out.push(("prose", "the revision's doc".into()));
    }
    // Commands.
    let names = |s: &Sensor| s.commands.iter().map(|c| c.name.clone()).collect::<Vec<_>>();
    if names(want) != names(got) {
        out.push(("commands", format!("{:?} vs {:?}", names(want), names(got))));
    }
    for c in &want.commands {
        let Some(g) = got.command(&c.name) else { continue };
        if layout(c) != layout(g) {
            out.push(("commands", format!("{}: {} vs {}", c.name, layout(c), layout(g))));
        }
        if (&c.title, &c.doc) != (&g.title, &g.doc) {
            out.push(("prose", format!("{}: title or doc", c.name)));
        }
        let mut mine = examples(g, &default_sw);
        for (k, f) in examples(c, &default_sw) {
            match mine.iter().position(|(mk, _)| *mk == k) {
                Some(i) => {
                    let (_, m) = mine.remove(i);
                    if f.figures != m.figures {
                        out.push((
                            "examples",
                            format!("{} SW {}: figures {:?} vs {:?}", c.name, k.0, f.figures, m.figures),
                        ));
                    }
                    let fewer = f.values.iter().all(|(n, v)| m.values.get(n) == Some(v))
                        && (f.erratum.is_none() || f.erratum == m.erratum);
                    if f.values != m.values || f.erratum != m.erratum {
                        let cat = if m.cited && fewer { "cited values" } else { "examples" };
                        out.push((
                            cat,
                            format!(
                                "{} SW {} Figs {:?}: values {:?} erratum {:?} vs {:?} {:?}",
                                c.name, k.0, f.figures, f.values, f.erratum, m.values, m.erratum
                            ),
                        ));
                    }
                }
                None => out.push(("examples", format!("{} SW {} Figs {:?}: missing", c.name, k.0, f.figures))),
            }
        }
        for (k, m) in mine {
            out.push(("examples", format!("{} SW {} Figs {:?}: extra", c.name, k.0, m.figures)));
        }
        let errata = |x: &CommandSpec| {
            let mut v: Vec<String> = x
                .errata
                .iter()
                .map(|e| {
                    format!(
                        "{:?} {:?} {:?}",
                        e.manual.clone().unwrap_or_else(|| default_sw.clone()),
                        e.figure,
                        e.table_says()
                    )
                })
                .collect();
            v.sort();
            v
        };
        if errata(c) != errata(g) {
            out.push(("command errata", format!("{}: {:?} vs {:?}", c.name, errata(c), errata(g))));
        }
        let ids = |x: &CommandSpec| x.errata.iter().map(|e| (e.id.clone(), e.note.clone())).collect::<Vec<_>>();
        if ids(c) != ids(g) {
            out.push(("prose", format!("{}: erratum ids or notes {:?} vs {:?}", c.name, ids(c), ids(g))));
        }
    }
    // Manual-wide errata.
    for e in &want.errata {
        match got.errata.iter().find(|x| x.id == e.id) {
            Some(x)
                if (&x.figures, &x.sections, &x.manual, &x.note) == (&e.figures, &e.sections, &e.manual, &e.note) => {}
            Some(_) => out.push(("errata", format!("{} differs", e.id))),
            None if e.manual.as_deref() == Some(removed_sw) => {
                out.push(("manual-wide errata", format!("{} (SW {removed_sw}) not drafted", e.id)));
            }
            None => out.push(("errata", format!("{} missing", e.id))),
        }
    }
    // Procedure and constants.
    match (&want.procedure, &got.procedure) {
        (Some(a), Some(b)) => {
            let steps = |p: &yosemitech_spec::Procedure| {
                format!("{:?} {} {:?} {} {} {:?}", p.before, p.warm_up_ms, p.read, p.readings, p.interval_ms, p.after)
            };
            if steps(a) != steps(b) {
                out.push(("procedure", format!("{} vs {}", steps(a), steps(b))));
            }
            if a.source != b.source {
                let cat = if a.source.as_ref().and_then(|s| s.manual.as_deref()) == Some(removed_sw) {
                    "procedure source"
                } else {
                    "procedure"
                };
                out.push((cat, format!("source {:?} vs {:?}", a.source, b.source)));
            }
        }
        (None, None) => {}
        _ => out.push(("procedure", "present in one only".into())),
    }
    let consts = |s: &Sensor| s.constants.iter().map(|c| format!("{} {:?}", c.name, c.values)).collect::<Vec<_>>();
    if consts(want) != consts(got) {
        out.push(("constants", format!("{:?} vs {:?}", consts(want), consts(got))));
    }
    if (want.serial, &want.model, &want.model_code) != (got.serial, &got.model, &got.model_code) {
        out.push(("sensor", "serial, model or model code".into()));
    }
    out
}

#[test]
fn each_two_revision_probe_gets_a_removed_revision_back() {
    let Some(manuals) = manual_paths() else {
        eprintln!(
            "\n*** SKIPPED: ../shared (the vendor manuals) is absent next to the repository; `import --into` was NOT checked ***\n"
        );
        return;
    };
    let (dir, spec) = copy_spec("roundtrip", &manuals);
    let probes = two_revision_probes(&spec, &manuals);
    assert!(!probes.is_empty(), "spec/ has a probe that merges two manuals");
    let mut merges = 0;
    let mut untolerated = Vec::new();
    for sensor in probes {
        for rev in &sensor.revisions {
            let sw = rev.manual.software.clone().expect("a revision's software");
            let file = rev.manual.file.clone().expect("a manual file");
            let original = std::fs::read_to_string(&sensor.file).expect("the spec");
            let reduced = without_revision(&original, sensor, &spec, &sw);
            let copy = sensor.file.clone();
            std::fs::write(&copy, &reduced).expect("the reduced copy");
            if let Err(d) = load_paths(std::slice::from_ref(&dir)) {
                panic!("{}: the spec without SW {sw} does not validate:\n{d}\n{reduced}", sensor.name);
            }
            let text = read_manual(&manuals[&file]).expect("the manual");
            let started = Instant::now();
            let merged = merge_text(&text, &file, &copy).unwrap_or_else(|e| panic!("{}: {e}", sensor.name));
            let elapsed = started.elapsed();
            let out = merged.text.unwrap_or_else(|| panic!("{}: SW {sw} merged as nothing new", sensor.name));
            println!(
                "=== {} without SW {sw}, merged from {file} ({:.0} ms)\n{}",
                sensor.name,
                elapsed.as_secs_f64() * 1000.0,
                merged.review.text()
            );
            assert!(elapsed.as_secs() < 5, "{}: the merge took {elapsed:?}", sensor.name);
            assert!(merged.review.todos.is_empty(), "{}: TODOs left: {:?}\n{out}", sensor.name, merged.review.todos);
            std::fs::write(&copy, &out).expect("the merged copy");
            let got = match load_paths(std::slice::from_ref(&dir)) {
                Ok(s) => s,
                Err(d) => panic!("{}: the merged spec does not validate:\n{d}\n{out}", sensor.name),
            };
            let got = got.sensor(&sensor.name).expect("the merged sensor").clone();
            for (cat, what) in differences(sensor, &got, &sw) {
                match TOLERATED.iter().find(|(c, _)| *c == cat) {
                    Some((_, why)) => println!("  tolerated ({cat}: {why}):\n    {what}"),
                    None => untolerated.push(format!("{} SW {sw}: {cat}: {what}", sensor.name)),
                }
            }
            // The same manual again: nothing new, nothing written.
            let again = merge_text(&text, &file, &copy).unwrap_or_else(|e| panic!("{}: {e}", sensor.name));
            assert!(
                again.text.is_none() && again.review.nothing_new,
                "{}: a second merge of SW {sw}:\n{}",
                sensor.name,
                again.review.text()
            );
            std::fs::write(&copy, &original).expect("restored");
            merges += 1;
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    assert!(untolerated.is_empty(), "differences not tolerated:\n{}", untolerated.join("\n"));
    println!("import --into: {merges} revisions removed and merged back");
}

#[test]
fn every_recorded_manual_is_nothing_new() {
    let Some(manuals) = manual_paths() else {
        eprintln!("\n*** SKIPPED: ../shared is absent; `import --into` on recorded manuals was NOT checked ***\n");
        return;
    };
    let (dir, spec) = copy_spec("recorded", &manuals);
    let mut checked = 0;
    for sensor in &spec.sensors {
        for m in sensor.manuals() {
            let Some(path) = m.file.as_ref().and_then(|f| manuals.get(f)) else { continue };
            let text = read_manual(path).expect("the manual");
            let merged =
                merge_text(&text, &file_name(path), &sensor.file).unwrap_or_else(|e| panic!("{}: {e}", sensor.name));
            assert!(
                merged.text.is_none() && merged.review.nothing_new,
                "{} is recorded in {}, yet:\n{}",
                file_name(path),
                sensor.name,
                merged.review.text()
            );
            checked += 1;
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    assert!(checked > 0);
    println!("import --into: {checked} recorded manuals merged as nothing new");
}

#[test]
fn a_manual_of_another_probe_is_refused_with_its_spec_named() {
    let Some(manuals) = manual_paths() else {
        eprintln!("\n*** SKIPPED: ../shared is absent; `import --into` refusals were NOT checked ***\n");
        return;
    };
    let (dir, spec) = copy_spec("refused", &manuals);
    let mut refused = 0;
    for owner in &spec.sensors {
        let Some(file) = owner.manual.as_ref().and_then(|m| m.file.clone()).filter(|f| manuals.contains_key(f)) else {
            continue;
        };
        let text = read_manual(&manuals[&file]).expect("the manual");
        for other in spec.sensors.iter().filter(|s| s.name != owner.name) {
            match merge_text(&text, &file, &other.file) {
                Ok(m) => panic!("{file} merged into {}:\n{}", other.name, m.review.text()),
                Err(e) => {
                    let owner_file = file_name(&owner.file);
                    assert!(
                        e.0.contains(&owner_file),
                        "{file} into {}: the refusal names another spec: {e}",
                        other.name
                    );
                    assert!(!e.0.contains('\n'), "one line: {e}");
                }
            }
            refused += 1;
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    assert!(refused > 0);
    println!("import --into: {refused} manuals of other probes refused with their spec named");
}

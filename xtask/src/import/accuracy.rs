//! Accuracy against the reviewed specs.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use super::draft::{Draft, DraftFrame};
use super::parse::{dfield, import_with, shared_commands};
use super::{file_name, read_manual};

/// The accuracy of one draft.
#[derive(Debug, Clone, Default)]
pub struct Accuracy {
    /// Manual file name.
    pub manual: String,
    /// Reviewed spec file.
    pub spec: String,
    /// Commands right / reviewed.
    pub commands: (usize, usize),
    /// Fields right / reviewed.
    pub fields: (usize, usize),
    /// Frames reproduced / printed.
    pub frames: (usize, usize),
    /// TODOs in the draft.
    pub todos: usize,
    /// Import time.
    pub millis: f64,
}

fn version_le(a: &str, b: &str) -> bool {
    let p = |s: &str| -> Vec<u32> { s.split('.').filter_map(|x| x.parse().ok()).collect() };
    p(a) <= p(b)
}

pub(super) fn printed_key(f: &yosemitech_spec::PrintedFrame) -> DraftFrame {
    let n = if f.crc_printed { f.bytes.len().saturating_sub(2) } else { f.bytes.len() };
    let crc = f.crc_printed.then(|| [f.bytes[n].unwrap_or(0), f.bytes[n + 1].unwrap_or(0)]);
    DraftFrame { bytes: f.bytes[..n].to_vec(), open_ended: f.open_ended, crc }
}

/// Compares a draft with the reviewed spec of the manual `file`.
pub fn compare(draft: &Draft, spec: &yosemitech_spec::Spec, file: &str) -> Option<Accuracy> {
    let sensor = spec.sensors.iter().find(|s| s.manuals().any(|m| m.file.as_deref() == Some(file)))?;
    let manual = sensor.manuals().find(|m| m.file.as_deref() == Some(file))?;
    let software = manual.software.clone().unwrap_or_default();
    let is_default = sensor.manual.as_ref().and_then(|m| m.file.as_deref()) == Some(file);
    let mut acc = Accuracy {
        manual: file.to_string(),
        spec: file_name(&sensor.file),
        todos: draft.todo_count(),
        ..Accuracy::default()
    };
    let mut draft_frames: Vec<DraftFrame> = draft.frames().cloned().collect();
    for c in &sensor.commands {
        let in_manual = c.since.as_deref().is_none_or(|s| version_le(s, &software))
            && (c.examples.is_empty()
                || c.examples.iter().any(|e| e.manual.as_deref().map_or(is_default, |m| m == software)));
        if !in_manual {
            continue;
        }
        let f = if c.is_read() { 0x03 } else { 0x10 };
        let found = draft
            .commands
            .iter()
            .find(|d| d.function == Some(f) && d.address == Some(c.address) && d.count == Some(c.count));
        acc.commands.1 += 1;
        acc.commands.0 += usize::from(found.is_some());
        for rf in &c.fields {
            acc.fields.1 += 1;
            let r = dfield(rf);
            if found.is_some_and(|d| {
                d.fields.iter().any(|x| x.offset == r.offset && x.ty == r.ty && x.size == r.size && x.order == r.order)
            }) {
                acc.fields.0 += 1;
            }
        }
        for e in c.examples.iter().filter(|e| e.manual.as_deref().map_or(is_default, |m| m == software)) {
            for p in [&e.request, &e.response].into_iter().flatten() {
                acc.frames.1 += 1;
                let key = printed_key(p);
                if let Some(i) = draft_frames.iter().position(|d| *d == key) {
                    draft_frames.swap_remove(i);
                    acc.frames.0 += 1;
                }
            }
        }
    }
    Some(acc)
}

/// The Modbus manuals of `../shared/` (seeds and manuals), sorted.
pub fn shared_manuals() -> Option<Vec<PathBuf>> {
    let shared = crate::root().parent()?.join("shared");
    if !shared.is_dir() {
        return None;
    }
    let mut out = Vec::new();
    for dir in ["seeds", "manuals"] {
        let Ok(rd) = std::fs::read_dir(shared.join(dir)) else { continue };
        for e in rd.flatten() {
            let p = e.path();
            let n = file_name(&p);
            if n.ends_with(".txt") && n.to_ascii_lowercase().contains("modbus") && !n.contains("UserManual") {
                out.push(p);
            }
        }
    }
    out.sort();
    Some(out)
}

/// Imports every shared manual and compares it with `spec/`.
pub fn accuracy_all() -> anyhow::Result<Option<Vec<Accuracy>>> {
    let Some(manuals) = shared_manuals() else { return Ok(None) };
    let spec_dir = crate::root().join("spec");
    let spec = yosemitech_spec::load_paths(std::slice::from_ref(&spec_dir))
        .map_err(|_| anyhow::anyhow!("spec/ does not validate; run `cargo xtask validate`"))?;
    let shared = shared_commands(&spec_dir);
    let mut out = Vec::new();
    for m in manuals {
        let file = file_name(&m);
        let text = read_manual(&m).map_err(|e| anyhow::anyhow!("{}: {e}", m.display()))?;
        let t = Instant::now();
        let draft =
            import_with(&text, "imported", &file, &shared).map_err(|e| anyhow::anyhow!("{}: {e}", m.display()))?;
        let millis = t.elapsed().as_secs_f64() * 1000.0;
        // A manual no spec transcribes yet has nothing to be compared with.
        let Some(mut a) = compare(&draft, &spec, &file) else { continue };
        a.millis = millis;
        out.push(a);
    }
    Ok(Some(out))
}

fn pct((a, b): (usize, usize)) -> String {
    if b == 0 { "-".into() } else { format!("{a}/{b} ({:.0} %)", 100.0 * a as f64 / b as f64) }
}

/// The accuracy table in Markdown.
pub fn table(rows: &[Accuracy]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| manual | reviewed spec | commands (function, address, count) | fields (type, byte order, offset) | printed frames reproduced | TODOs |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    let mut tot = Accuracy::default();
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            r.manual,
            r.spec,
            pct(r.commands),
            pct(r.fields),
            pct(r.frames),
            r.todos
        );
        tot.commands = (tot.commands.0 + r.commands.0, tot.commands.1 + r.commands.1);
        tot.fields = (tot.fields.0 + r.fields.0, tot.fields.1 + r.fields.1);
        tot.frames = (tot.frames.0 + r.frames.0, tot.frames.1 + r.frames.1);
        tot.todos += r.todos;
    }
    let _ = writeln!(
        s,
        "| **all** | | {} | {} | {} | {} |",
        pct(tot.commands),
        pct(tot.fields),
        pct(tot.frames),
        tot.todos
    );
    s
}

const BEGIN: &str = "<!-- accuracy:begin (cargo xtask import --accuracy --write) -->";
const END: &str = "<!-- accuracy:end -->";

pub(super) fn accuracy_task(write: bool) -> anyhow::Result<ExitCode> {
    let Some(rows) = accuracy_all()? else {
        eprintln!("NOTE: ../shared (the vendor manuals) is absent next to the repository: no accuracy table computed.");
        return Ok(ExitCode::SUCCESS);
    };
    let t = table(&rows);
    print!("{t}");
    let slowest = rows.iter().map(|r| r.millis).fold(0.0, f64::max);
    println!("slowest import: {slowest:.1} ms");
    if write {
        let path = crate::root().join("docs").join("importer.md");
        let doc = std::fs::read_to_string(&path)?;
        let (Some(b), Some(e)) = (doc.find(BEGIN), doc.find(END)) else {
            anyhow::bail!("{} has no accuracy markers", path.display());
        };
        let new = format!("{}{BEGIN}\n\n{t}\n{}", &doc[..b], &doc[e..]);
        std::fs::write(&path, new)?;
        println!("wrote {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}

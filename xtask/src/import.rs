//! `cargo xtask import MANUAL [--name NAME] [--out FILE]`: drafts a spec file
//! from the text of a Yosemitech Modbus manual (`pdftotext -layout` output, or
//! a PDF converted with `pdftotext`).
//!
//! `cargo xtask import --accuracy [--write]`: imports every Modbus manual in
//! `../shared/seeds/` and `../shared/manuals/`, compares each draft with the
//! reviewed spec in `spec/` and prints (or writes into `docs/importer.md`) the
//! accuracy table.
//!
//! The importer reads the manuals' template, not particular files: "X.2.N
//! Title" command sections after the "Command Description" heading, a register
//! table ("Start address ... Number of registers ... Function code" over a row
//! of values), and frame tables (a "Byte 0 1 2 ..." row over a "Value 0x01
//! 0x03 ..." row) captioned "Figure N" (after) or "Table N" (before). It never
//! invents a byte: what it cannot decide becomes a `# TODO(import)` comment,
//! which `cargo xtask validate` rejects with its line and column.
//!
//! A draft is made in steps of one module each: `tokens` (a line's cells,
//! hex bytes and values), `header` (the cover and scope), `frames` (frame
//! tables), `tables` (register and code tables), `parse` (the command
//! chapter into `draft`'s types), `document` (the draft as the spec crate's
//! document types, with its TODOs at key paths), `annotate` (their YAML with
//! the TODO comments), `render` (the file);
//! `accuracy` compares drafts with the reviewed specs.
//!
//! `cargo xtask import MANUAL --into spec/NAME.yaml [--out FILE] [--json]`:
//! merges another revision of a probe's manual into its spec instead
//! (`into`: the task, `identify`: is it this probe's manual, `merge`: the
//! comparison, `procedure`: the procedure chapter, `edit`: the YAML text,
//! `review`: what changed).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use accuracy::{accuracy_task, printed_key};
pub use draft::{DCommand, DExample, DField, Draft, DraftFrame};
use parse::shared_from;
pub use parse::{import_text, import_with};
use render::q;
pub(crate) use render::{CommandRender, one_line_text, render_command};
use tokens::{bare_hex, first_word_lower, hex_token, segments, snake};

/// Largest manual accepted (the real ones are under 100 kB of text).
pub const MAX_INPUT: u64 = 8 * 1024 * 1024;

const USAGE: &str = "usage: cargo xtask import MANUAL [--name NAME] [--out FILE]   (MANUAL: pdftotext -layout text or a PDF)\n       cargo xtask import MANUAL --into spec/NAME.yaml [--out FILE] [--json]   (another revision of a probe the spec has)\n       cargo xtask import --accuracy [--write]                 (the accuracy table of docs/importer.md)";

/// An input the importer refuses: one message, exit code 2, nothing written.
#[derive(Debug)]
pub struct BadInput(pub String);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

fn bad<T>(msg: impl Into<String>) -> Result<T, BadInput> {
    Err(BadInput(msg.into()))
}

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let mut manual: Option<PathBuf> = None;
    let mut name: Option<String> = None;
    let mut out: Option<PathBuf> = None;
    let mut into: Option<PathBuf> = None;
    let mut json = false;
    let mut accuracy = false;
    let mut write = false;
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        match arg.as_str() {
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(ExitCode::SUCCESS);
            }
            "--name" => name = it.next().cloned(),
            "--out" => out = it.next().map(PathBuf::from),
            "--into" => into = it.next().map(PathBuf::from),
            "--json" => json = true,
            "--accuracy" => accuracy = true,
            "--write" => write = true,
            a if a.starts_with('-') => {
                eprintln!("error: unknown option `{a}`\n{USAGE}");
                return Ok(ExitCode::from(2));
            }
            a if manual.is_none() => manual = Some(PathBuf::from(a)),
            a => {
                eprintln!("error: unexpected argument `{a}`\n{USAGE}");
                return Ok(ExitCode::from(2));
            }
        }
    }
    if accuracy {
        return accuracy_task(write);
    }
    let Some(manual) = manual else {
        eprintln!("error: no MANUAL given\n{USAGE}");
        return Ok(ExitCode::from(2));
    };
    if let Some(into) = into {
        if name.is_some() {
            eprintln!("error: --name names a new sensor; with --into the sensor is the spec's\n{USAGE}");
            return Ok(ExitCode::from(2));
        }
        return into::run(&manual, &into, out.as_deref(), json);
    }
    if json {
        eprintln!("error: --json goes with --into\n{USAGE}");
        return Ok(ExitCode::from(2));
    }
    let name = match name {
        Some(n) => n,
        None => default_name(&manual),
    };
    if !valid_name(&name) {
        eprintln!("error: `{name}` is not a snake_case name (pass --name NAME)");
        return Ok(ExitCode::from(2));
    }
    let started = Instant::now();
    let draft = match read_manual(&manual).and_then(|text| import_text(&text, &name, &file_name(&manual))) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("error: {}: {e}", manual.display());
            return Ok(ExitCode::from(2));
        }
    };
    let elapsed = started.elapsed();
    let out = out.unwrap_or_else(|| crate::root().join("spec").join(format!("{}.yaml", name.replace('_', "-"))));
    if out.exists() {
        eprintln!("error: {} exists; pass --out to write the draft elsewhere", out.display());
        return Ok(ExitCode::from(2));
    }
    std::fs::write(&out, &draft.yaml).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", out.display()))?;
    print!("{}", draft.report());
    println!("wrote {} in {:.1} ms", out.display(), elapsed.as_secs_f64() * 1000.0);
    Ok(ExitCode::SUCCESS)
}

fn file_name(p: &Path) -> String {
    p.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

fn default_name(p: &Path) -> String {
    let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let n = snake(&stem);
    if valid_name(&n) { n } else { "imported_sensor".into() }
}

fn valid_name(n: &str) -> bool {
    !n.is_empty()
        && n.len() <= 64
        && n.starts_with(|c: char| c.is_ascii_lowercase())
        && n.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
}

/// Reads a manual: text, or a PDF through `pdftotext -layout`.
pub fn read_manual(path: &Path) -> Result<String, BadInput> {
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) => return bad(format!("cannot read the manual: {e}")),
    };
    if meta.is_dir() {
        return bad("is a directory, not a manual");
    }
    if meta.len() > MAX_INPUT {
        return bad(format!(
            "{} bytes is too large for a manual (limit {} MiB); pass the text of one Modbus manual",
            meta.len(),
            MAX_INPUT / 1024 / 1024
        ));
    }
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) => return bad(format!("cannot read the manual: {e}")),
    };
    if bytes.starts_with(b"%PDF") {
        return pdf_to_text(path);
    }
    decode_text(&bytes)
}

fn pdf_to_text(path: &Path) -> Result<String, BadInput> {
    let out =
        std::process::Command::new("pdftotext").arg("-layout").arg("-enc").arg("UTF-8").arg(path).arg("-").output();
    match out {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bad(
            "the manual is a PDF and `pdftotext` is not installed; install poppler-utils (`apt-get install poppler-utils`, `brew install poppler`) or pass the output of `pdftotext -layout MANUAL.pdf`",
        ),
        Err(e) => bad(format!("cannot run pdftotext: {e}")),
        Ok(o) if !o.status.success() => {
            bad(format!("the PDF cannot be read: pdftotext says {}", one_line(&String::from_utf8_lossy(&o.stderr))))
        }
        Ok(o) => decode_text(&o.stdout),
    }
}

/// A tool's diagnostics as one line: poppler prints a warning and an error a
/// line each for one broken file, and the importer answers with one message.
fn one_line(text: &str) -> String {
    let mut lines: Vec<&str> = Vec::new();
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if !lines.contains(&line) {
            lines.push(line);
        }
    }
    if lines.is_empty() { "nothing".to_string() } else { lines.join("; ") }
}

fn decode_text(bytes: &[u8]) -> Result<String, BadInput> {
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return bad("the manual is empty");
    }
    if bytes.contains(&0) {
        return bad("the manual is binary data, not text; pass `pdftotext -layout` output or a PDF");
    }
    match String::from_utf8(bytes.to_vec()) {
        Ok(s) => Ok(s),
        Err(_) => bad("the manual is not UTF-8 text; pass `pdftotext -layout` output or a PDF"),
    }
}

mod accuracy;
mod annotate;
mod document;
mod draft;
mod edit;
mod frames;
mod header;
mod identify;
mod into;
mod layout;
mod merge;
mod parse;
mod procedure;
mod render;
mod review;
mod tables;
mod tokens;

#[cfg(test)]
mod tests;

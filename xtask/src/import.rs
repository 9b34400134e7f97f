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
//! `cargo xtask import MANUAL --into spec/NAME.yaml [--out FILE] [--json]`:
//! merges another revision of a probe's manual into its spec instead
//! (`into`: the task, `identify`: is it this probe's manual, `merge`: the
//! comparison, `procedure`: the procedure chapter, `edit`: the YAML text,
//! `review`: what changed).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

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

// ---------------------------------------------------------------------------
// Lines and tokens

/// A line with page debris removed.
fn clean(line: &str) -> String {
    let mut l = line;
    // Debris a conversion may leave before a heading: `<|...|>`.
    if let Some(i) = l.find("|>")
        && l.trim_start().starts_with("<|")
    {
        l = &l[i + 2..];
    }
    l.replace(['\u{201c}', '\u{201d}'], "\"").replace('\u{ff1a}', ":").replace('\u{ff08}', "(").replace('\u{ff09}', ")")
}

/// Segments of a line separated by two or more spaces, with their columns.
fn segments(line: &str) -> Vec<(usize, String)> {
    let chars: Vec<char> = line.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        while i < chars.len() && chars[i].is_whitespace() {
            i += 1;
        }
        if i >= chars.len() {
            break;
        }
        let start = i;
        let mut end = i;
        while i < chars.len() {
            if chars[i].is_whitespace() {
                let mut j = i;
                while j < chars.len() && chars[j].is_whitespace() {
                    j += 1;
                }
                if j - i >= 2 || j >= chars.len() {
                    break;
                }
            }
            i += 1;
            end = i;
        }
        out.push((start, chars[start..end].iter().collect::<String>().trim().to_string()));
    }
    out
}

fn hex_token(t: &str) -> Option<Vec<u8>> {
    let t = t.trim_matches(|c: char| c == ',' || c == ';');
    let body = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X"))?;
    let digits: String = body.chars().take_while(|c| c.is_ascii_hexdigit()).collect();
    if digits.is_empty() || digits.len() % 2 == 1 && digits.len() > 1 {
        return None;
    }
    let digits = if digits.len() == 1 { format!("0{digits}") } else { digits };
    (0..digits.len()).step_by(2).map(|i| u8::from_str_radix(&digits[i..i + 2], 16).ok()).collect()
}

fn bare_hex(t: &str) -> Option<u8> {
    if (1..=2).contains(&t.len()) && t.chars().all(|c| c.is_ascii_hexdigit()) {
        u8::from_str_radix(t, 16).ok()
    } else {
        None
    }
}

fn decimal(t: &str) -> Option<f32> {
    if t.contains('.') && t.chars().all(|c| c.is_ascii_digit() || c == '.' || c == '-' || c == '+') {
        t.parse::<f32>().ok().filter(|v| v.is_finite())
    } else {
        None
    }
}

/// A cell of a frame's Value row.
#[derive(Debug, Clone, PartialEq)]
enum Item {
    Byte(u8),
    Float(String, f32),
    Text(String),
    Word(String),
}

impl Item {
    fn size(&self) -> usize {
        match self {
            Item::Byte(_) => 1,
            Item::Float(..) => 4,
            Item::Text(t) => t.len(),
            Item::Word(_) => 0,
        }
    }
}

/// The Value row's cells; with `ints_as_floats`, bare integers (no `0x`)
/// are decimal values of 4-byte floats ("1", "0" under "3~6").
fn value_items(rest: &str, ints_as_floats: bool) -> Vec<Item> {
    let mut items = Vec::new();
    let mut chars = rest.chars().peekable();
    let mut tokens: Vec<(String, bool)> = Vec::new();
    while let Some(&c) = chars.peek() {
        if c.is_whitespace() {
            chars.next();
        } else if c == '"' {
            chars.next();
            let mut s = String::new();
            for c in chars.by_ref() {
                if c == '"' {
                    break;
                }
                s.push(c);
            }
            tokens.push((s, true));
        } else {
            let mut s = String::new();
            while let Some(&c) = chars.peek() {
                if c.is_whitespace() || c == '"' {
                    break;
                }
                s.push(c);
                chars.next();
            }
            tokens.push((s, false));
        }
    }
    for (t, quoted) in tokens {
        if quoted {
            items.push(Item::Text(t));
        } else if let Some(bytes) = hex_token(&t) {
            items.extend(bytes.into_iter().map(Item::Byte));
        } else if ints_as_floats && t.chars().all(|c| c.is_ascii_digit() || c == '-') && t.parse::<f32>().is_ok() {
            let v = t.parse::<f32>().unwrap_or(0.0);
            items.push(Item::Float(t, v));
        } else if let Some(b) = bare_hex(&t) {
            items.push(Item::Byte(b));
        } else if let Some(v) = decimal(&t) {
            items.push(Item::Float(t, v));
        } else if let Some(Item::Word(w)) = items.last_mut() {
            w.push(' ');
            w.push_str(&t);
        } else {
            items.push(Item::Word(t));
        }
    }
    items
}

fn byte_indices(line: &str) -> Vec<usize> {
    line.split(|c: char| !c.is_ascii_digit()).filter_map(|t| t.parse().ok()).collect()
}

fn first_word_lower(line: &str) -> String {
    line.split_whitespace().next().unwrap_or("").to_ascii_lowercase()
}

// ---------------------------------------------------------------------------
// The draft

/// A frame as printed: bytes (`None`: a placeholder), open-ended, CRC state.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DraftFrame {
    /// Bytes before the CRC.
    pub bytes: Vec<Option<u8>>,
    /// Bytes of unknown number follow.
    pub open_ended: bool,
    /// The CRC printed, if any.
    pub crc: Option<[u8; 2]>,
}

impl DraftFrame {
    /// The correct CRC, when every byte is known.
    pub fn computed_crc(&self) -> Option<[u8; 2]> {
        if self.open_ended {
            return None;
        }
        let bytes: Option<Vec<u8>> = self.bytes.iter().copied().collect();
        bytes.map(|b| yosemitech_rtu::crc16(&b).to_le_bytes())
    }

    /// The printed CRC is right.
    pub fn crc_verified(&self) -> bool {
        self.crc.is_some() && self.crc == self.computed_crc()
    }

    /// The printed CRC is wrong (provably).
    pub fn crc_wrong(&self) -> bool {
        self.crc.is_some() && self.computed_crc().is_some_and(|c| Some(c) != self.crc)
    }

    fn spec_text(&self, with_crc: Option<[u8; 2]>) -> String {
        let mut parts: Vec<String> =
            self.bytes.iter().map(|b| b.map_or_else(|| "??".to_string(), |b| format!("{b:02X}"))).collect();
        if let Some(c) = with_crc {
            parts.extend(c.iter().map(|b| format!("{b:02X}")));
        }
        if self.open_ended {
            parts.push("...".into());
        }
        parts.join(" ")
    }

    /// As the spec writes it (printed CRC included).
    pub fn text(&self) -> String {
        self.spec_text(self.crc)
    }
}

/// A drafted field.
#[derive(Debug, Clone, PartialEq)]
pub struct DField {
    /// Name (`None`: reserved).
    pub name: Option<String>,
    /// The spec's type name.
    pub ty: &'static str,
    /// Byte order key, when the type has one.
    pub order: Option<&'static str>,
    /// Byte offset in the register data.
    pub offset: usize,
    /// Bytes.
    pub size: usize,
    /// Enum variants or flags: (value, label).
    pub codes: Vec<(u16, String)>,
}

impl DField {
    /// A field without enum variants or flags.
    fn plain(name: Option<String>, ty: &'static str, order: Option<&'static str>, offset: usize, size: usize) -> Self {
        DField { name, ty, order, offset, size, codes: Vec::new() }
    }
}

/// A drafted example.
#[derive(Debug, Clone)]
pub struct DExample {
    /// Figure labels (`16`, `T3`).
    pub figures: Vec<String>,
    /// Request as printed.
    pub request: Option<DraftFrame>,
    /// Response as printed.
    pub response: Option<DraftFrame>,
    /// Values the manual states, by data offset: (offset, YAML value).
    pub values: Vec<(usize, String)>,
}

/// A drafted command.
#[derive(Debug, Clone)]
pub struct DCommand {
    /// snake_case name.
    pub name: String,
    /// The manual's heading.
    pub title: String,
    /// Section number.
    pub section: String,
    /// Figures of the section.
    pub figures: Vec<String>,
    /// 0x03 or 0x10 (`None`: undecided).
    pub function: Option<u8>,
    /// Start address.
    pub address: Option<u16>,
    /// Registers.
    pub count: Option<u16>,
    /// Fields (empty: none or undecided).
    pub fields: Vec<DField>,
    /// The shared fragment command it equals: (file, command).
    pub uses: Option<(String, String)>,
    /// Examples.
    pub examples: Vec<DExample>,
    /// What a person must resolve.
    pub todos: Vec<String>,
    /// Table contradictions: (figure, key, table value, note).
    pub table_errata: Vec<(String, &'static str, String)>,
    /// The page the section starts on, when the text keeps page breaks.
    pub page: Option<u32>,
}

/// A drafted spec.
#[derive(Debug, Clone)]
pub struct Draft {
    /// The YAML text.
    pub yaml: String,
    /// Commands.
    pub commands: Vec<DCommand>,
    /// Manual-wide TODOs.
    pub todos: Vec<String>,
    /// The manual's header (cover, scope line, serial settings).
    pub(crate) header: Header,
    /// The manual's lines (cleaned) and where the command chapter ends.
    pub(crate) lines: Vec<String>,
    /// The first line after the command chapter (the procedure chapter).
    pub(crate) chapter_end: usize,
}

impl Draft {
    fn frames(&self) -> impl Iterator<Item = &DraftFrame> {
        self.commands.iter().flat_map(|c| c.examples.iter()).flat_map(|e| [&e.request, &e.response]).flatten()
    }

    /// TODOs in the draft.
    pub fn todo_count(&self) -> usize {
        self.todos.len() + self.commands.iter().map(|c| c.todos.len()).sum::<usize>()
    }

    /// The import report.
    pub fn report(&self) -> String {
        let frames: Vec<&DraftFrame> = self.frames().collect();
        let verified = frames.iter().filter(|f| f.crc_verified()).count();
        let wrong = frames.iter().filter(|f| f.crc_wrong()).count();
        let without = frames.iter().filter(|f| f.crc.is_none()).count();
        let mut s = String::new();
        let shared = self.commands.iter().filter(|c| c.uses.is_some()).count();
        let _ = writeln!(s, "commands found: {} ({} taken from shared fragments)", self.commands.len(), shared);
        let _ = writeln!(
            s,
            "frames found: {}; CRC verified: {verified}; CRC wrong: {wrong} (drafted as errata); without CRC: {without}",
            frames.len()
        );
        let _ = writeln!(s, "TODOs: {}", self.todo_count());
        for t in &self.todos {
            let _ = writeln!(s, "  TODO(import): {t}");
        }
        for c in &self.commands {
            for t in &c.todos {
                let _ = writeln!(s, "  TODO(import): section {} ({}): {t}", c.section, c.title);
            }
        }
        s
    }
}

// ---------------------------------------------------------------------------
// Parsing

/// What the cover and the first chapter say about the manual.
#[derive(Debug, Clone)]
pub(crate) struct Header {
    pub(crate) title: String,
    pub(crate) manual_title: String,
    pub(crate) revision: Option<String>,
    pub(crate) software: Option<String>,
    pub(crate) baud: Option<u32>,
    pub(crate) data_bits: Option<u8>,
    pub(crate) parity: Option<&'static str>,
    pub(crate) stop_bits: Option<u8>,
}

/// The revision number printed within a dozen characters after `key` in
/// `text` ("hardware Rev1.0": "1.0"), if any.
fn revision_after(text: &str, key: &str) -> Option<String> {
    let i = text.find(key)?;
    let rest = &text[i + key.len()..];
    let j = rest.find("rev")?;
    if j > 12 {
        return None;
    }
    let v: String = rest[j + 3..].trim_start().chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
    let v = v.trim_end_matches('.').to_string();
    (!v.is_empty()).then_some(v)
}

fn parse_header(lines: &[String]) -> Header {
    // Cover: the non-empty lines before the table of contents, minus the company lines.
    let mut cover = Vec::new();
    for l in lines.iter().take(40) {
        let t = l.trim();
        let lower = t.to_ascii_lowercase();
        if lower.contains("table of contents") || lower.contains("contents") && t.len() < 20 {
            break;
        }
        if t.is_empty()
            || lower.contains("technolog")
            || lower == "yosemitech"
            || t.contains(" / ")
            || t.chars().all(|c| c.is_ascii_digit())
        {
            continue;
        }
        cover.push(t.split("  ").next().unwrap_or(t).trim().to_string());
    }
    let split = cover.iter().position(|l| l.to_ascii_uppercase().contains("MODBUS")).unwrap_or(cover.len());
    let title = cover[..split].join(" ");
    let manual_title =
        if split < cover.len() { format!("{}, {}", title, cover[split..].join(" ")) } else { title.clone() };
    let text: String = lines.join("\n");
    let lower = text.to_ascii_lowercase();
    // Scope line: "... hardware Rev1.0 and software Rev1.7 or later".
    let scope = lower.find("scope").map(|i| &lower[i..]).unwrap_or("");
    let scope_end = scope.find("later").map_or(scope.len().min(600), |e| e + 5);
    let scope = &scope[..scope_end];
    let (hw, sw) = (revision_after(scope, "hardware"), revision_after(scope, "software"));
    let later = scope.contains("or later");
    let revision = match (&hw, &sw) {
        (Some(h), Some(s)) => Some(format!("HW Rev{h} / SW Rev{s}{}", if later { " or later" } else { "" })),
        (None, Some(s)) => Some(format!("SW Rev{s}{}", if later { " or later" } else { "" })),
        _ => None,
    };
    let number_before = |key: &str| -> Option<u32> {
        let i = lower.find(key)?;
        let before = lower[..i].trim_end();
        let digits: String =
            before.chars().rev().take_while(|c| c.is_ascii_digit()).collect::<Vec<_>>().into_iter().rev().collect();
        digits.parse().ok()
    };
    let baud = lower.match_indices("baud rate").find_map(|(i, k)| {
        let rest: String = lower[i + k.len()..].chars().take(40).collect();
        let d: String = rest.chars().skip_while(|c| !c.is_ascii_digit()).take_while(|c| c.is_ascii_digit()).collect();
        d.parse::<u32>().ok().filter(|b| (300..=1_000_000).contains(b))
    });
    let parity = if lower.contains("no parity") {
        Some("none")
    } else if lower.contains("even parity") {
        Some("even")
    } else if lower.contains("odd parity") {
        Some("odd")
    } else {
        None
    };
    Header {
        title,
        manual_title,
        revision,
        software: sw,
        baud,
        data_bits: number_before("data bits").and_then(|v| u8::try_from(v).ok()),
        parity,
        stop_bits: number_before("stop bit").and_then(|v| u8::try_from(v).ok()),
    }
}

struct RawFrame {
    line: usize,
    label: Option<String>,
    caption: String,
    items: Vec<Item>,
    alt: Option<Vec<Item>>,
    /// The Byte row's cells as byte ranges (`7-30` is one cell).
    labels: Vec<(usize, usize)>,
}

/// A "Byte 3 4 5 ..." / "Value 0x.. .." image outside a frame: (index, byte).
type Image = Vec<(usize, u8)>;

fn find_frames(sec: &[String]) -> (Vec<RawFrame>, Vec<Image>) {
    let mut frames = Vec::new();
    let mut images = Vec::new();
    for (i, line) in sec.iter().enumerate() {
        if first_word_lower(line) != "byte" {
            continue;
        }
        let rest = line.trim_start()[4..].to_string();
        let mut idx = byte_indices(&rest);
        let mut labels = label_ranges(&rest);
        if idx.is_empty() {
            continue;
        }
        // Continuation lines of the Byte row, then the Value row.
        let mut value_line = None;
        for (j, l) in sec.iter().enumerate().skip(i + 1).take(8) {
            let w = first_word_lower(l);
            if w == "value" || w == "meaning" {
                value_line = Some(j);
                break;
            }
            if !l.trim().is_empty() && l.trim().chars().all(|c| c.is_ascii_digit() || c.is_whitespace() || c == '~') {
                idx.extend(byte_indices(l));
                labels.extend(label_ranges(l));
            }
            if w == "byte" || w == "definition" {
                break;
            }
        }
        let Some(v) = value_line else { continue };
        let vrest = sec[v].trim_start();
        let vrest = &vrest[first_word_lower(vrest).len()..];
        let items = value_items(vrest, false);
        let alt = value_items(vrest, true);
        if idx[0] != 0 {
            // An image of some bytes of a frame.
            let bytes: Vec<u8> =
                items.iter().filter_map(|it| if let Item::Byte(b) = it { Some(*b) } else { None }).collect();
            if bytes.len() == items.len() && bytes.len() == idx.len() {
                images.push(idx.iter().copied().zip(bytes).collect());
            }
            continue;
        }
        // Caption: "Table N" before, else "Figure N" after.
        let mut label = None;
        let mut caption = String::new();
        for l in sec[i.saturating_sub(5)..i].iter().rev() {
            let t = l.trim();
            if let Some(r) = t.strip_prefix("Table") {
                let n: String = r.trim_start().chars().take_while(|c| c.is_ascii_digit()).collect();
                if !n.is_empty() {
                    label = Some(format!("T{n}"));
                    caption = t.to_string();
                }
                break;
            }
            if first_word_lower(t) == "byte" || first_word_lower(t) == "value" {
                break;
            }
        }
        if label.is_none() {
            for l in sec.iter().skip(v + 1).take(6) {
                let t = l.trim();
                if let Some(r) = t.strip_prefix("Figure") {
                    let n: String = r.trim_start().chars().take_while(|c| c.is_ascii_digit()).collect();
                    if !n.is_empty() {
                        label = Some(n);
                        caption = t.to_string();
                    }
                    break;
                }
                if first_word_lower(t) == "definition" || first_word_lower(t) == "byte" {
                    break;
                }
            }
        }
        let alt = (alt != items).then_some(alt);
        frames.push(RawFrame { line: i, label, caption, items, alt, labels });
    }
    images.extend(named_range_images(sec));
    (frames, images)
}

/// `line` with the hex digits a narrow table cell wrapped onto `next` put
/// back: `0xd` over a `b` in the same column is `0xdb`. Unchanged unless
/// every token of `next` is one hex digit under a one-digit `0x` cell.
fn with_wrapped_digits(line: &str, next: Option<&str>) -> String {
    let tokens = |l: &str| -> Vec<(usize, String)> {
        let mut out = Vec::new();
        let mut start = None;
        for (i, c) in l.chars().chain(std::iter::once(' ')).enumerate() {
            match (c.is_whitespace(), start) {
                (false, None) => start = Some(i),
                (true, Some(s0)) => {
                    out.push((s0, l.chars().skip(s0).take(i - s0).collect()));
                    start = None;
                }
                _ => {}
            }
        }
        out
    };
    let Some(next) = next.filter(|n| !n.trim().is_empty()) else { return line.to_string() };
    let mut cells = tokens(line);
    for (col, digit) in tokens(next) {
        let one_hex_digit = |t: &str| t.len() == 1 && t.chars().all(|c| c.is_ascii_hexdigit());
        let Some(cell) = cells.iter_mut().find(|(start, t)| {
            t.len() == 3 && t.to_ascii_lowercase().starts_with("0x") && (*start..*start + t.len() + 2).contains(&col)
        }) else {
            return line.to_string();
        };
        if !one_hex_digit(&digit) {
            return line.to_string();
        }
        cell.1.push_str(&digit);
    }
    cells.into_iter().map(|(_, t)| t).collect::<Vec<_>>().join("  ")
}

/// The cells of a Byte row as byte ranges: `3`, `3-14` or `3~14`.
fn label_ranges(line: &str) -> Vec<(usize, usize)> {
    line.split_whitespace()
        .filter_map(|t| {
            let (a, b) = t.split_once(['-', '~']).unwrap_or((t, t));
            let (a, b) = (a.parse().ok()?, b.parse().ok()?);
            (a <= b).then_some((a, b))
        })
        .collect()
}

/// Register images printed as a row of `K1(7~10) K2(11~14) ...` over a row
/// of exactly as many hex bytes: (frame index, byte) for each.
fn named_range_images(sec: &[String]) -> Vec<Image> {
    let mut images = Vec::new();
    for (i, line) in sec.iter().enumerate() {
        let ranges: Vec<(usize, usize)> = line
            .split_whitespace()
            .filter_map(|tok| {
                let inner = tok.split_once('(')?.1.strip_suffix(')')?;
                let (a, b) = inner.split_once('~')?;
                let (a, b) = (a.trim().parse::<usize>().ok()?, b.trim().parse::<usize>().ok()?);
                (a <= b).then_some((a, b))
            })
            .collect();
        if ranges.is_empty() {
            continue;
        }
        let Some(at) = sec.iter().skip(i + 1).position(|l| !l.trim().is_empty()).map(|k| i + 1 + k) else { continue };
        let hex_line = with_wrapped_digits(&sec[at], sec.get(at + 1).map(String::as_str));
        let Some(bytes) = hex_line.split_whitespace().map(hex_token).collect::<Option<Vec<Vec<u8>>>>() else {
            continue;
        };
        let bytes: Vec<u8> = bytes.concat();
        let at: Vec<usize> = ranges.iter().flat_map(|&(a, b)| a..=b).collect();
        if !bytes.is_empty() && at.len() == bytes.len() {
            images.push(at.into_iter().zip(bytes).collect());
        }
    }
    images
}

/// The data layout of one frame: items with their data offsets.
struct Built {
    frame: DraftFrame,
    function: u8,
    is_request: bool,
    data: Vec<(usize, Item)>,
    todo: Option<String>,
}

fn build_frame(raw: &RawFrame, is_request: bool, images: &[Image]) -> Result<Built, String> {
    match build_items(&raw.items, &raw.labels, is_request, images) {
        Err(e) => match &raw.alt {
            Some(alt) => build_items(alt, &raw.labels, is_request, images).map_err(|_| e),
            None => Err(e),
        },
        ok => ok,
    }
}

fn build_items(
    all_items: &[Item],
    labels: &[(usize, usize)],
    is_request: bool,
    images: &[Image],
) -> Result<Built, String> {
    let max_index = labels.iter().map(|&(_, last)| last).max();
    let mut items = all_items.iter().cloned().peekable();
    let mut head = Vec::new();
    while head.len() < 2 {
        match items.next() {
            Some(Item::Byte(b)) => head.push(b),
            _ => return Err("the slave address and function code are not both printed as bytes".into()),
        }
    }
    let function = head[1];
    let (head_len, count_at) = match (function, is_request) {
        (0x03, true) => (6, None),
        (0x03, false) => (3, Some(2)),
        (0x10, true) => (7, Some(6)),
        (0x10, false) => (6, None),
        (f, _) => return Err(format!("function code 0x{f:02X} is neither 0x03 nor 0x10")),
    };
    while head.len() < head_len {
        match items.next() {
            Some(Item::Byte(b)) => head.push(b),
            _ => return Err(format!("the frame header ({head_len} bytes) is not printed byte by byte")),
        }
    }
    let data_len = count_at.map_or(0, |i| usize::from(head[i]));
    let rest: Vec<Item> = items.collect();
    let total = head_len + data_len + 2;
    let consistent = max_index.is_none_or(|m| m + 1 == total);
    let mut bytes: Vec<Option<u8>> = head.iter().map(|b| Some(*b)).collect();
    let mut data = Vec::new();
    let mut todo = None;
    let has_word = rest.iter().any(|i| matches!(i, Item::Word(_)));
    if has_word && !consistent {
        if let Some(built) = build_from_labels(all_items, labels, head_len, data_len, images) {
            return Ok(Built { function, is_request, ..built });
        }
        // The labels and the byte count disagree ("meaningless" bytes, a byte
        // count over a different range): keep the header, the rest is unknown.
        return Ok(Built {
            frame: DraftFrame { bytes, open_ended: true, crc: None },
            function,
            is_request,
            data,
            todo: Some(format!(
                "the data is printed as a word and its length contradicts the byte count 0x{data_len:02X}; bytes left open"
            )),
        });
    }
    let mut pos = 0usize;
    let mut idx = 0;
    while pos < data_len && idx < rest.len() {
        let it = rest[idx].clone();
        idx += 1;
        match &it {
            Item::Word(w) => {
                let after: usize = rest[idx..].iter().map(Item::size).sum();
                let mut n = data_len.saturating_sub(pos).saturating_sub(after);
                if after >= 2 && n == 0 {
                    n = data_len.saturating_sub(pos).saturating_sub(after - 2);
                }
                let n = n.max(1).min(data_len - pos);
                for k in 0..n {
                    let at = head_len + pos + k;
                    let img = images.iter().flat_map(|im| im.iter()).find(|(i, _)| *i == at).map(|(_, b)| *b);
                    bytes.push(img);
                }
                if bytes[head_len + pos..].iter().any(Option::is_none) {
                    todo = Some(format!("bytes {}..{} are printed as \"{w}\"", head_len + pos, head_len + pos + n - 1));
                } else {
                    // Every byte came from an image of this frame.
                    for k in 0..n {
                        if let Some(b) = bytes[head_len + pos + k] {
                            data.push((pos + k, Item::Byte(b)));
                        }
                    }
                    pos += n;
                    continue;
                }
                data.push((pos, it.clone()));
                pos += n;
            }
            Item::Byte(b) => {
                bytes.push(Some(*b));
                data.push((pos, it.clone()));
                pos += 1;
            }
            Item::Float(_, v) => {
                bytes.extend(v.to_le_bytes().map(Some));
                data.push((pos, it.clone()));
                pos += 4;
            }
            Item::Text(t) => {
                bytes.extend(t.bytes().map(Some));
                data.push((pos, it.clone()));
                pos += t.len();
            }
        }
    }
    if pos != data_len {
        return Err(format!("the data is {pos} bytes where the byte count says {data_len}"));
    }
    let tail: Vec<&Item> = rest[idx..].iter().collect();
    let crc = match tail.as_slice() {
        [] => None,
        [Item::Byte(a), Item::Byte(b)] => Some([*a, *b]),
        _ => return Err("the cells after the data are not a two-byte CRC".into()),
    };
    Ok(Built { frame: DraftFrame { bytes, open_ended: false, crc }, function, is_request, data, todo })
}

/// A frame whose column labels name every cell's bytes (`7-30` under
/// "K1~K6"), rebuilt from the labels where they and the byte count disagree.
///
/// Only when every cell has a label, the labels run on without a gap and at
/// most two trailing labels (empty CRC cells, or a CRC printed under wrong
/// numbers) are left over. A word takes the bytes a register image of the
/// section prints for its range; where no image does, the labelled data must
/// at least agree with the byte count (the word's bytes stay placeholders).
/// The frame is as printed: a byte count that contradicts the data gets a
/// TODO, never a correction.
fn build_from_labels(
    items: &[Item],
    labels: &[(usize, usize)],
    head_len: usize,
    data_len: usize,
    images: &[Image],
) -> Option<Built> {
    // Adjacent words ("k1~k3 k4~k6") read as one cell; the labels may say
    // they are two.
    let split: Vec<Item> = items
        .iter()
        .flat_map(|it| match it {
            Item::Word(w) => w.split_whitespace().map(|t| Item::Word(t.to_string())).collect(),
            other => vec![other.clone()],
        })
        .collect();
    build_from_labelled_cells(items, labels, head_len, data_len, images)
        .or_else(|| build_from_labelled_cells(&split, labels, head_len, data_len, images))
}

fn build_from_labelled_cells(
    items: &[Item],
    labels: &[(usize, usize)],
    head_len: usize,
    data_len: usize,
    images: &[Image],
) -> Option<Built> {
    let image_byte = |at: usize| images.iter().flat_map(|im| im.iter()).find(|(i, _)| *i == at).map(|(_, b)| *b);
    let (crc, data_items, data_labels) = match labels.len().checked_sub(items.len())? {
        // The CRC cells are empty.
        2 => (None, items.get(head_len..)?, labels.get(head_len..items.len())?),
        // The CRC is printed; its labels may be wrong (`7-30` then `15 16`).
        0 => {
            let [.., Item::Byte(a), Item::Byte(b)] = items else { return None };
            (Some([*a, *b]), items.get(head_len..items.len() - 2)?, labels.get(head_len..labels.len() - 2)?)
        }
        _ => return None,
    };
    if labels.get(..head_len)?.iter().enumerate().any(|(i, &(a, b))| (a, b) != (i, i)) {
        return None;
    }
    let mut bytes: Vec<Option<u8>> =
        items.get(..head_len)?.iter().map(|it| if let Item::Byte(b) = it { Some(*b) } else { None }).collect();
    let mut data = Vec::new();
    let mut placeholders = Vec::new();
    for (item, &(first, last)) in data_items.iter().zip(data_labels) {
        if first != bytes.len() {
            return None;
        }
        let offset = first - head_len;
        match item {
            Item::Byte(b) if first == last => {
                bytes.push(Some(*b));
                data.push((offset, item.clone()));
            }
            Item::Word(w) => match (first..=last).map(image_byte).collect::<Option<Vec<u8>>>() {
                Some(filled) => {
                    data.extend(filled.iter().enumerate().map(|(k, b)| (offset + k, Item::Byte(*b))));
                    bytes.extend(filled.into_iter().map(Some));
                }
                None => {
                    bytes.extend((first..=last).map(|_| None));
                    data.push((offset, item.clone()));
                    placeholders.push(format!("bytes {first}..{last} are printed as \"{w}\""));
                }
            },
            _ => return None,
        }
    }
    let printed_len = bytes.len() - head_len;
    if printed_len != data_len && !placeholders.is_empty() {
        return None;
    }
    if printed_len != data_len {
        placeholders.push(format!(
            "the byte count 0x{data_len:02X} contradicts the {printed_len} data bytes the column labels give"
        ));
    }
    let todo = (!placeholders.is_empty()).then(|| placeholders.join("; "));
    Some(Built { frame: DraftFrame { bytes, open_ended: false, crc }, function: 0, is_request: false, data, todo })
}

fn snake(s: &str) -> String {
    let mut out = String::new();
    for c in s.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('_') && !out.is_empty() {
            out.push('_');
        }
    }
    let out = out.trim_end_matches('_').to_string();
    if out.starts_with(|c: char| c.is_ascii_digit()) { format!("n_{out}") } else { out }
}

fn hex_in(line: &str) -> Vec<Vec<u8>> {
    line.split_whitespace().filter_map(hex_token).collect()
}

/// The register table: (address, count, function, labels of the register columns).
fn register_table(sec: &[String]) -> Option<(u16, u16, Option<u8>, Vec<String>)> {
    for (i, l) in sec.iter().enumerate() {
        let lower = l.to_ascii_lowercase();
        if first_word_lower(l) == "definition" || !(lower.contains("start") && lower.contains("address")) {
            continue;
        }
        if !lower.contains("number") && !lower.contains("register") {
            continue;
        }
        for v in sec.iter().skip(i + 1).take(4) {
            let t = v.trim();
            if !t.starts_with("0x") && !t.starts_with("0X") {
                continue;
            }
            let hex = hex_in(t);
            if hex.len() < 2 {
                break;
            }
            let addr = hex[0].iter().fold(0u32, |a, b| a << 8 | u32::from(*b));
            let count = hex[1].iter().fold(0u32, |a, b| a << 8 | u32::from(*b));
            let function = if hex.len() >= 3 { hex.last().and_then(|h| h.last().copied()) } else { None };
            let labels: Vec<String> = segments(t)
                .into_iter()
                .map(|(_, s)| s)
                .filter(|s| hex_token(s.split_whitespace().next().unwrap_or("")).is_none())
                .collect();
            return Some((u16::try_from(addr).ok()?, u16::try_from(count).ok()?, function, labels));
        }
    }
    None
}

/// A code table in the section: a row of a label and at least two codes,
/// with the labels of each code from the neighbouring line: (value, label).
fn code_table(sec: &[String], after: usize) -> Vec<(u16, String)> {
    for (i, l) in sec.iter().enumerate().skip(after) {
        let segs = segments(l);
        if segs.len() < 3 {
            continue;
        }
        let codes: Vec<(usize, u8)> = segs[1..]
            .iter()
            .filter_map(|(c, s)| {
                hex_token(s).or_else(|| bare_hex(s).map(|b| vec![b])).and_then(|v| v.last().copied()).map(|b| (*c, b))
            })
            .collect();
        let mut distinct: Vec<u8> = codes.iter().map(|c| c.1).collect();
        distinct.sort_unstable();
        distinct.dedup();
        let label_first = hex_token(&segs[0].1).is_none() && bare_hex(&segs[0].1).is_none();
        if !label_first
            || distinct.len() != codes.len()
            || codes.len() + 1 != segs.len()
            || codes.len() < 2
            || first_word_lower(l) == "value"
            || first_word_lower(l) == "byte"
        {
            continue;
        }
        // Labels: the nearest line above or below with words.
        let neighbour = [i + 1, i.wrapping_sub(1)]
            .into_iter()
            .filter_map(|j| sec.get(j))
            .find(|n| segments(n).len() >= 2 && !n.contains("0x"));
        let words: Vec<(usize, String)> = neighbour.map(|n| segments(n)).unwrap_or_default();
        let mut out = Vec::new();
        for (k, (col, code)) in codes.iter().enumerate() {
            let next_col = codes.get(k + 1).map_or(usize::MAX, |c| c.0);
            let label: Vec<&str> = words
                .iter()
                .filter(|(c, _)| {
                    *c + 2 >= *col && *c < next_col.saturating_sub(2) || (*c < *col && *c + 12 > *col && k == 0)
                })
                .map(|(_, s)| s.as_str())
                .collect();
            out.push((u16::from(*code), label.join(" ")));
        }
        return out;
    }
    Vec::new()
}

/// A shared fragment command: (file, name, function, address, count, fields).
#[derive(Debug, Clone)]
pub struct Shared {
    file: String,
    name: String,
    function: u8,
    address: u16,
    count: u16,
    fields: Vec<DField>,
}

/// The fragments of `spec/` (empty when they do not load).
pub fn shared_commands(spec_dir: &Path) -> Vec<Shared> {
    let Ok(spec) = yosemitech_spec::load_paths(&[spec_dir.to_path_buf()]) else { return Vec::new() };
    shared_from(&spec)
}

/// The fragments' commands of a loaded spec.
pub(crate) fn shared_from(spec: &yosemitech_spec::Spec) -> Vec<Shared> {
    let mut out = Vec::new();
    for frag in &spec.fragments {
        for c in &frag.commands {
            out.push(Shared {
                file: file_name(&frag.file),
                name: c.name.clone(),
                function: if c.is_read() { 0x03 } else { 0x10 },
                address: c.address,
                count: c.count,
                fields: c.fields.iter().map(dfield).collect(),
            });
        }
    }
    out
}

fn dfield(f: &yosemitech_spec::Field) -> DField {
    use yosemitech_spec::FieldKind as K;
    let order = f.kind.byte_order_name();
    let codes = match &f.kind {
        K::Enum { variants, .. } => variants.iter().map(|v| (v.value, v.name.clone())).collect(),
        K::Flags { flags, .. } => flags.iter().map(|v| (v.mask, v.name.clone())).collect(),
        _ => Vec::new(),
    };
    DField { name: f.name.clone(), ty: f.kind.type_name(), order, offset: f.offset, size: f.kind.size(), codes }
}

/// Imports the text of a manual.
pub fn import_text(text: &str, name: &str, file: &str) -> Result<Draft, BadInput> {
    import_with(text, name, file, &shared_commands(&crate::root().join("spec")))
}

/// Imports with the given shared commands.
pub fn import_with(text: &str, name: &str, file: &str, shared: &[Shared]) -> Result<Draft, BadInput> {
    if text.trim().is_empty() {
        return bad("the manual is empty");
    }
    if text.len() as u64 > MAX_INPUT {
        return bad("the manual is too large");
    }
    if text.contains('\0') {
        return bad("the manual is binary data, not text");
    }
    let lines: Vec<String> = text.lines().map(clean).collect();
    let lower = text.to_ascii_lowercase();
    if !lower.contains("yosemite") && !lower.contains("yosemitech") {
        return bad("not a Yosemitech manual (no mention of Yosemitech)");
    }
    if !lower.contains("modbus") {
        return bad("not a Yosemitech Modbus manual (no mention of Modbus)");
    }
    // The command chapter: "N.M Command Description" (not the table of contents).
    let heading = lines.iter().position(|l| {
        let t = l.trim();
        t.to_ascii_lowercase().contains("command description")
            && !t.contains("....")
            && t.starts_with(|c: char| c.is_ascii_digit())
    });
    let Some(heading) = heading else {
        return bad("not a Yosemitech Modbus manual: no \"Command Description\" section");
    };
    let number: String = lines[heading].split_whitespace().next().unwrap_or("").to_string();
    let prefix = format!("{number}.");
    let chapter: u32 = number.split('.').next().and_then(|n| n.parse().ok()).unwrap_or(2);
    let next_chapter = format!("{}", chapter + 1);
    let mut starts = Vec::new();
    let mut end = lines.len();
    for (i, l) in lines.iter().enumerate().skip(heading + 1) {
        let t = l.trim();
        let first = t.split_whitespace().next().unwrap_or("");
        if let Some(n) = first.strip_prefix(&prefix) {
            if !n.is_empty() && n.chars().all(|c| c.is_ascii_digit()) && t.len() > first.len() {
                starts.push(i);
            }
        } else if first == next_chapter && t.len() > first.len() && t[first.len()..].starts_with(char::is_whitespace) {
            let rest = t[first.len()..].trim_start();
            if rest.starts_with(|c: char| c.is_ascii_uppercase()) {
                end = i;
                break;
            }
        }
    }
    if starts.is_empty() {
        return bad(format!(
            "not a Yosemitech Modbus manual: no command sections ({prefix}N) after \"Command Description\""
        ));
    }
    let header = parse_header(&lines);
    let mut commands = Vec::new();
    let mut used_names: BTreeMap<String, usize> = BTreeMap::new();
    // Pages, where the text keeps pdftotext's form feeds.
    let breaks = text.contains('\u{c}');
    let pages: Vec<u32> = text
        .lines()
        .scan(1u32, |page, l| {
            *page += l.matches('\u{c}').count() as u32;
            Some(*page)
        })
        .collect();
    for (k, &s) in starts.iter().enumerate() {
        let e = starts.get(k + 1).copied().unwrap_or(end);
        let mut c = import_command(&lines[s..e], shared);
        c.page = pages.get(s).copied().filter(|_| breaks);
        let n = used_names.entry(c.name.clone()).or_insert(0);
        *n += 1;
        if *n > 1 {
            c.name = format!("{}_{}", c.name, n);
        }
        commands.push(c);
    }
    // The read and the write of the same registers share one layout.
    for k in 0..commands.len() {
        let c = &commands[k];
        if !c.fields.is_empty() || c.uses.is_some() || c.address.is_none() || c.count.is_none_or(|n| n == 0) {
            continue;
        }
        let twin = commands
            .iter()
            .find(|o| o.address == c.address && o.count == c.count && o.uses.is_none() && !o.fields.is_empty());
        if let Some(o) = twin {
            let (fields, section) = (o.fields.clone(), o.section.clone());
            let c = &mut commands[k];
            c.fields = fields;
            c.todos.retain(|t| !t.starts_with("register data layout") && !t.contains("field type"));
            c.todos.push(format!("fields as in section {section} (same registers): check them"));
        }
    }
    let mut todos = Vec::new();
    if header.revision.is_none() {
        todos.push("the manual's scope line names no software revision".into());
    }
    if header.baud.is_none() {
        todos.push("the manual states no baud rate".into());
    }
    let mut draft = Draft { yaml: String::new(), commands, todos, header, lines, chapter_end: end };
    draft.yaml = render(&draft, &draft.header, name, file);
    Ok(draft)
}

fn import_command(sec: &[String], shared: &[Shared]) -> DCommand {
    let head = sec[0].trim();
    let section = head.split_whitespace().next().unwrap_or("").to_string();
    let title = head[section.len()..].trim().to_string();
    let mut c = DCommand {
        name: {
            let n = snake(&title);
            if n.is_empty() { format!("command_{}", snake(&section)) } else { n }
        },
        title,
        section,
        figures: Vec::new(),
        function: None,
        address: None,
        count: None,
        fields: Vec::new(),
        uses: None,
        examples: Vec::new(),
        todos: Vec::new(),
        table_errata: Vec::new(),
        page: None,
    };
    let mut table_figure = None;
    for l in sec {
        let t = l.trim();
        if let Some(r) = t.strip_prefix("Figure") {
            let n: String = r.trim_start().chars().take_while(|c| c.is_ascii_digit()).collect();
            if !n.is_empty() && !c.figures.contains(&n) {
                if table_figure.is_none() && t.to_ascii_lowercase().contains("definition")
                    || t.to_ascii_lowercase().contains("command") && table_figure.is_none() && c.figures.is_empty()
                {
                    table_figure = Some(n.clone());
                }
                c.figures.push(n);
            }
        }
    }
    let table = register_table(sec);
    let (frames, images) = find_frames(sec);
    for f in &frames {
        if let Some(l) = &f.label
            && !c.figures.contains(l)
        {
            c.figures.push(l.clone());
        }
    }
    // Frames, paired request/response.
    let mut built = Vec::new();
    for (k, raw) in frames.iter().enumerate() {
        let cap = raw.caption.to_ascii_lowercase();
        let is_request = if cap.contains("request") {
            true
        } else if cap.contains("response") || cap.contains("reply") {
            false
        } else {
            k % 2 == 0
        };
        let fig = raw.label.clone().unwrap_or_else(|| format!("line {}", raw.line));
        match build_frame(raw, is_request, &images) {
            Ok(b) => {
                if let Some(t) = &b.todo {
                    c.todos.push(format!("Fig {fig}: {t}"));
                }
                built.push((raw.label.clone(), b));
            }
            Err(e) => c.todos.push(format!("Fig {fig}: frame not imported: {e}")),
        }
    }
    let request = built.iter().find(|(_, b)| b.is_request).map(|(_, b)| b);
    // Function, address, count: the frames win over the table (CRC-checked bytes).
    let from_frame = request.and_then(|b| {
        let g = |i: usize| b.frame.bytes.get(i).copied().flatten();
        Some((b.function, u16::from_be_bytes([g(2)?, g(3)?]), u16::from_be_bytes([g(4)?, g(5)?])))
    });
    let tf = table_figure.clone().unwrap_or_default();
    match (table.as_ref(), from_frame) {
        (Some((ta, tc, tfun, _)), Some((ff, fa, fc))) => {
            c.function = Some(ff);
            c.address = Some(fa);
            c.count = Some(fc);
            if *ta != fa {
                c.table_errata.push((tf.clone(), "address", format!("0x{ta:04X}")));
            }
            if *tc != fc {
                c.table_errata.push((tf.clone(), "count", tc.to_string()));
            }
            if let Some(t) = tfun.filter(|t| *t != ff) {
                c.table_errata.push((
                    tf.clone(),
                    "function",
                    if t == 0x03 {
                        "read".into()
                    } else if t == 0x10 {
                        "write".into()
                    } else {
                        format!("0x{t:02X}")
                    },
                ));
            }
        }
        (Some((ta, tc, tfun, _)), None) => {
            c.function = *tfun;
            c.address = Some(*ta);
            c.count = Some(*tc);
        }
        (None, Some((ff, fa, fc))) => {
            c.function = Some(ff);
            c.address = Some(fa);
            c.count = Some(fc);
        }
        (None, None) => {
            c.todos.push("no register table and no request frame: function, address and count unknown".into())
        }
    }
    if c.function.is_some_and(|f| f != 0x03 && f != 0x10) {
        c.todos
            .push(format!("function code 0x{:02X} is neither read (0x03) nor write (0x10)", c.function.unwrap_or(0)));
        c.function = None;
    }
    if !c.table_errata.is_empty() {
        c.todos.push(format!(
            "the register table (Fig {tf}) contradicts the printed frames: check the drafted table errata"
        ));
    }
    // Fields, from the data of the example carrying it.
    let carrier =
        built.iter().find(|(_, b)| b.is_request == (c.function == Some(0x10)) && b.function == c.function.unwrap_or(0));
    let labels = table.as_ref().map(|t| t.3.clone()).unwrap_or_default();
    if let (Some((_, b)), Some(count)) = (carrier, c.count)
        && !b.frame.open_ended
        && count > 0
    {
        c.fields = infer_fields(&b.data, usize::from(count) * 2, &labels, sec, &mut c.todos);
    }
    // One register printed as a word ("Flag", "Status") over a code table.
    if let (Some((_, b)), Some(1)) = (carrier, c.count)
        && c.fields.is_empty()
        && (b.frame.open_ended || b.data.iter().any(|d| matches!(d.1, Item::Word(_))))
    {
        let mut codes = code_table(sec, 0);
        if codes.len() < 2 {
            // Text converted without `-layout`: single spaces between cells.
            let spaced: Vec<String> = sec.iter().map(|l| l.split_whitespace().collect::<Vec<_>>().join("  ")).collect();
            codes = code_table(&spaced, 0);
        }
        if codes.len() >= 2 {
            let label = labels.first().cloned().unwrap_or_default();
            let name = snake(&label);
            let name = if name.is_empty() { "value".to_string() } else { name };
            let flag_word = label.to_ascii_lowercase().contains("flag");
            c.fields.extend(code_fields(0, name, codes, Some(flag_word)));
            c.todos.retain(|t| !t.contains("field type") && !t.starts_with("fields cover"));
            c.todos.push("bytes 0..1: the code sits in the register's first byte; check the code names".into());
        }
    }
    // A byte table naming the data's bytes, printed apart from the frame.
    if let (Some((_, b)), Some(count)) = (carrier, c.count)
        && c.fields.is_empty()
        && count > 0
    {
        let data_start = if b.is_request { 7 } else { 3 };
        let printed: Vec<u8> = b.frame.bytes.iter().skip(data_start).flatten().copied().collect();
        let fields = layout::fields_from_tables(sec, data_start, usize::from(count) * 2, &printed);
        if !fields.is_empty() {
            c.todos.retain(|t| !t.contains("field type") && !t.starts_with("fields cover"));
            c.fields = fields;
        }
    }
    if c.count.is_some_and(|n| n > 0)
        && c.fields.is_empty()
        && !(c.function == Some(0x03)
            && built.iter().any(|(_, b)| !b.is_request && b.frame.open_ended && b.frame.bytes.get(2) == Some(&Some(0))))
    {
        c.todos.push("register data layout unknown: add `fields`".into());
    }
    // A shared fragment command with the same wire layout.
    if let (Some(f), Some(a), Some(n)) = (c.function, c.address, c.count) {
        let compatible = |s: &Shared| {
            s.function == f
                && s.address == a
                && s.count == n
                && c.fields.iter().filter(|d| matches!(d.ty, "f32" | "ascii")).all(|d| {
                    s.fields
                        .iter()
                        .any(|x| x.offset == d.offset && x.ty == d.ty && x.size == d.size && x.order == d.order)
                })
        };
        if let Some(s) = shared.iter().find(|s| compatible(s)) {
            c.uses = Some((s.file.clone(), s.name.clone()));
            c.fields = s.fields.clone();
            c.todos.retain(|t| !t.starts_with("register data layout") && !t.contains("field type"));
        }
    }
    // Examples: pair each request with the next response.
    let mut pending: Option<(Option<String>, DraftFrame)> = None;
    let data_of = |b: &Built| b.data.clone();
    let mut carrier_data: Vec<(usize, Item)> = Vec::new();
    for (label, b) in &built {
        if b.is_request {
            if let Some((l, f)) = pending.take() {
                c.examples.push(DExample {
                    figures: l.into_iter().collect(),
                    request: Some(f),
                    response: None,
                    values: Vec::new(),
                });
            }
            if c.function == Some(0x10) {
                carrier_data = data_of(b);
            }
            pending = Some((label.clone(), b.frame.clone()));
        } else {
            if c.function == Some(0x03) {
                carrier_data = data_of(b);
            }
            let (figs, req) = match pending.take() {
                Some((l, f)) => (l.into_iter().chain(label.clone()).collect(), Some(f)),
                None => (label.iter().cloned().collect(), None),
            };
            let values = example_values(&c.fields, &carrier_data);
            c.examples.push(DExample { figures: figs, request: req, response: Some(b.frame.clone()), values });
            carrier_data.clear();
        }
    }
    if let Some((l, f)) = pending.take() {
        let values = example_values(&c.fields, &carrier_data);
        c.examples.push(DExample { figures: l.into_iter().collect(), request: Some(f), response: None, values });
    }
    c
}

fn infer_fields(
    data: &[(usize, Item)],
    len: usize,
    labels: &[String],
    sec: &[String],
    todos: &mut Vec<String>,
) -> Vec<DField> {
    let mut fields = Vec::new();
    // Register columns are labelled in order, one label a field; `fallback`
    // names a field past the last label.
    let mut labels = labels.iter();
    let mut next_name = |fallback: String| -> String {
        let n = snake(&labels.next().cloned().unwrap_or(fallback));
        if n.is_empty() { "value".into() } else { n }
    };
    let mut k = 0;
    while k < data.len() {
        let (off, it) = &data[k];
        match it {
            Item::Float(..) => {
                fields.push(DField::plain(Some(next_name(format!("value_{off}"))), "f32", Some("dcba"), *off, 4));
            }
            Item::Text(t) => {
                fields.push(DField::plain(Some(next_name("text".into())), "ascii", None, *off, t.len()));
            }
            Item::Word(_) => {
                return Vec::new();
            }
            Item::Byte(_) => {
                // A run of bytes up to the next typed item.
                let mut j = k;
                while j < data.len() && matches!(data[j].1, Item::Byte(_)) {
                    j += 1;
                }
                let run_end = data.get(j).map_or(len, |d| d.0);
                let run = run_end - off;
                let next_is_text = matches!(data.get(j).map(|d| &d.1), Some(Item::Text(_)));
                let prev_is_text = k > 0 && matches!(data[k - 1].1, Item::Text(_));
                if next_is_text || prev_is_text {
                    fields.push(DField::plain(None, "reserved", None, *off, run));
                } else if run == 2 && off % 2 == 0 {
                    let codes = code_table(sec, 0);
                    let name = next_name(format!("value_{off}"));
                    if codes.len() >= 2 {
                        fields.extend(code_fields(*off, name, codes, None));
                        todos.push(format!(
                            "bytes {off}..{}: the code sits in the register's first byte; check the code names",
                            off + 1
                        ));
                    } else {
                        fields.push(DField::plain(Some(name), "u16", Some("ba"), *off, 2));
                        todos.push(format!(
                            "bytes {off}..{}: field type guessed as a little-endian u16; check it",
                            off + 1
                        ));
                    }
                } else if run == 4 && off % 2 == 0 && {
                    let printed: Vec<u8> = data[k..j]
                        .iter()
                        .filter_map(|d| match d.1 {
                            Item::Byte(b) => Some(b),
                            _ => None,
                        })
                        .collect();
                    printed.len() == 4 && layout::reads_as_printed_decimal(sec, &printed)
                } {
                    // The section prints the decimal these bytes read as.
                    fields.push(DField::plain(Some(next_name(format!("value_{off}"))), "f32", Some("dcba"), *off, 4));
                } else {
                    todos.push(format!("bytes {off}..{}: field type unknown", run_end - 1));
                    return Vec::new();
                }
                k = j;
                continue;
            }
        }
        k += 1;
    }
    let covered: usize = fields.iter().map(|f| f.size).sum();
    if covered != len {
        todos.push(format!("fields cover {covered} of {len} bytes"));
        return Vec::new();
    }
    fields
}

/// A one-register code: an `enum` (or `flags` when every non-zero code is
/// a single bit) in the first byte, the second reserved.
/// `flag_word`: whether the register's label calls it a flag, when known.
fn code_fields(off: usize, name: String, codes: Vec<(u16, String)>, flag_word: Option<bool>) -> [DField; 2] {
    let nonzero: Vec<u16> = codes.iter().map(|c| c.0).filter(|v| *v != 0).collect();
    let bits = nonzero.iter().all(|v| v.is_power_of_two());
    let is_flags = match flag_word {
        Some(w) => w && bits && nonzero.len() >= 2,
        None => nonzero.len() >= 3 && bits,
    };
    let codes = if is_flags { codes.into_iter().filter(|c| c.0 != 0).collect() } else { codes };
    [
        DField {
            name: Some(name),
            ty: if is_flags { "flags" } else { "enum" },
            order: None,
            offset: off,
            size: 1,
            codes,
        },
        DField::plain(None, "reserved", None, off + 1, 1),
    ]
}

fn example_values(fields: &[DField], data: &[(usize, Item)]) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let byte_at = |o: usize| -> Option<u8> {
        data.iter().find_map(|(off, it)| match it {
            Item::Byte(b) if *off == o => Some(*b),
            Item::Float(_, v) if o >= *off && o < off + 4 => Some(v.to_le_bytes()[o - off]),
            Item::Text(t) if o >= *off && o < off + t.len() => Some(t.as_bytes()[o - off]),
            _ => None,
        })
    };
    for f in fields {
        let Some(_) = &f.name else { continue };
        let v = (|| match f.ty {
            "f32" => data
                .iter()
                .find_map(|(o, it)| match it {
                    Item::Float(t, _) if *o == f.offset => Some(t.clone()),
                    _ => None,
                })
                .or_else(|| {
                    let b: Option<Vec<u8>> = (0..4).map(|i| byte_at(f.offset + i)).collect();
                    let b = b?;
                    let v = match f.order {
                        Some("dcba") => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                        _ => f32::from_be_bytes([b[0], b[1], b[2], b[3]]),
                    };
                    Some(format!("{v:?}"))
                }),
            "ascii" => data.iter().find_map(|(o, it)| match it {
                Item::Text(t) if *o == f.offset => Some(format!("{t:?}")),
                _ => None,
            }),
            "u8" => byte_at(f.offset).map(|b| b.to_string()),
            "u16" => Some(
                match f.order {
                    Some("ba") => u16::from_le_bytes([byte_at(f.offset)?, byte_at(f.offset + 1)?]),
                    _ => u16::from_be_bytes([byte_at(f.offset)?, byte_at(f.offset + 1)?]),
                }
                .to_string(),
            ),
            "version" => Some(format!("\"{}.{}\"", byte_at(f.offset)?, byte_at(f.offset + 1)?)),
            "enum" => {
                let b = u16::from(byte_at(f.offset)?);
                f.codes.iter().find(|c| c.0 == b).map(|c| variant_name(&c.1, c.0))
            }
            _ => None,
        })();
        if let Some(v) = v {
            out.push((f.offset, v));
        }
    }
    out
}

fn variant_name(label: &str, value: u16) -> String {
    let n = snake(label);
    if n.is_empty() || !valid_name(&n) { format!("code_{value:02x}") } else { n }
}

// ---------------------------------------------------------------------------
// Rendering

fn q(s: &str) -> String {
    format!("{s:?}")
}

fn fig_list(figs: &[String]) -> String {
    let items: Vec<String> =
        figs.iter().map(|f| if f.chars().all(|c| c.is_ascii_digit()) { f.clone() } else { q(f) }).collect();
    format!("[{}]", items.join(", "))
}

fn render(d: &Draft, h: &Header, name: &str, file: &str) -> String {
    let mut y = String::new();
    let _ = writeln!(y, "# yaml-language-server: $schema=schema.json");
    let _ = writeln!(y, "#");
    let _ = writeln!(y, "# DRAFT imported by `cargo xtask import` from {file}.");
    let _ = writeln!(y, "# Every byte and number below comes from the manual. Resolve each TODO");
    let _ = writeln!(y, "# point the importer left (and delete its comment) until `cargo xtask validate` passes.");
    let _ = writeln!(y, "sensor:");
    let _ = writeln!(y, "  name: {name}");
    let _ = writeln!(y, "  title: {}", q(if h.title.is_empty() { name } else { &h.title }));
    let _ = writeln!(y, "  doc: {}", q(&format!("Imported from {file}.")));
    let _ = writeln!(y, "  manual:");
    let _ = writeln!(y, "    title: {}", q(&h.manual_title));
    if let Some(r) = &h.revision {
        let _ = writeln!(y, "    revision: {}", q(r));
    }
    if let Some(s) = &h.software {
        let _ = writeln!(y, "    software: {}", q(s));
    }
    let _ = writeln!(y, "    file: {}", q(file));
    match h.baud {
        Some(b) => {
            let _ = writeln!(
                y,
                "  serial: {{baud: {b}, data_bits: {}, parity: {}, stop_bits: {}}}",
                h.data_bits.unwrap_or(8),
                h.parity.unwrap_or("none"),
                h.stop_bits.unwrap_or(1)
            );
            if h.data_bits.is_none() || h.parity.is_none() || h.stop_bits.is_none() {
                let _ = writeln!(y, "  # TODO(import): data bits, parity or stop bits not stated; defaults 8N1 shown");
            }
        }
        None => {
            let _ = writeln!(y, "  # TODO(import): the manual states no baud rate; add `serial:`");
        }
    }
    let _ = writeln!(y, "  addresses: {{min: 1, max: 247}}");
    let _ = writeln!(y, "  default_address: 1");
    // Includes.
    let mut includes: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for c in &d.commands {
        if let Some((f, n)) = &c.uses {
            includes.entry(f.as_str()).or_default().push(n.as_str());
        }
    }
    if !includes.is_empty() {
        let _ = writeln!(y, "\ninclude:");
        for (f, names) in &includes {
            let _ = writeln!(y, "  - {{file: {f}, only: [{}]}}", names.join(", "));
        }
    }
    let _ = writeln!(y, "\ncommands:");
    let mut erratum_id = 0;
    let mut next_id = || {
        erratum_id += 1;
        format!("import-{erratum_id}")
    };
    for c in &d.commands {
        let mut o =
            CommandRender { manual: None, since: None, todos: None, table_notes: Vec::new(), next_id: &mut next_id };
        render_command(&mut y, c, &mut o);
    }
    y
}

/// How [`render_command`] writes a drafted command: into a new file, or
/// merged into a spec as another revision's (`manual`, `since`).
pub(crate) struct CommandRender<'a> {
    /// The revision's software, written as `manual:` on the source, the examples and the errata.
    pub manual: Option<&'a str>,
    /// The `since:` to write.
    pub since: Option<&'a str>,
    /// The TODOs to write instead of the command's own.
    pub todos: Option<&'a [String]>,
    /// Notes of the table errata, in order (default: a neutral note).
    pub table_notes: Vec<String>,
    /// The next erratum id.
    pub next_id: &'a mut dyn FnMut() -> String,
}

/// Text on one line (a TODO comment must not end early).
pub(crate) fn one_line_text(t: &str) -> String {
    t.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Writes one drafted command as an item of `commands:` (two-space indent).
pub(crate) fn render_command(y: &mut String, c: &DCommand, o: &mut CommandRender<'_>) {
    let manual_key = o.manual.map(|m| format!("manual: {}, ", q(m))).unwrap_or_default();
    let _ = writeln!(y);
    for t in o.todos.unwrap_or(&c.todos) {
        let _ = writeln!(y, "  # TODO(import): section {}: {}", c.section, one_line_text(t));
    }
    match &c.uses {
        Some((_, n)) => {
            let _ = writeln!(y, "  - use: {n}");
            let _ = writeln!(y, "    title: {}", q(&c.title));
        }
        None => {
            let _ = writeln!(y, "  - name: {}", c.name);
            let _ = writeln!(y, "    title: {}", q(&c.title));
            let _ = writeln!(y, "    doc: {}", q(&format!("Section {} of the manual.", c.section)));
        }
    }
    let source_manual = o.manual.map(|m| format!(", manual: {}", q(m))).unwrap_or_default();
    let _ = writeln!(y, "    source: {{section: {}, figures: {}{source_manual}}}", q(&c.section), fig_list(&c.figures));
    if let Some(since) = o.since {
        let _ = writeln!(y, "    since: {}", q(since));
    }
    if c.uses.is_none() {
        match c.function {
            Some(0x03) => {
                let _ = writeln!(y, "    function: read");
            }
            Some(_) => {
                let _ = writeln!(y, "    function: write");
            }
            None => {}
        }
        if let Some(a) = c.address {
            let _ = writeln!(y, "    address: 0x{a:04X}");
        }
        if let Some(n) = c.count {
            let _ = writeln!(y, "    count: {n}");
            let is_trigger_read = c.function == Some(0x03)
                && c.fields.is_empty()
                && c.examples
                    .iter()
                    .any(|e| e.response.as_ref().is_some_and(|r| r.open_ended && r.bytes.get(2) == Some(&Some(0))));
            if n == 0 || is_trigger_read {
                let _ = writeln!(y, "    trigger: true");
            }
        }
        if c.examples.iter().any(|e| e.request.as_ref().and_then(|r| r.bytes.first().copied().flatten()) == Some(0xFF))
        {
            let _ = writeln!(y, "    fixed_slave: 0xFF");
        }
        if !c.fields.is_empty() {
            let _ = writeln!(y, "    fields:");
            for f in &c.fields {
                render_field(y, f);
            }
        }
    }
    if !c.table_errata.is_empty() {
        let _ = writeln!(y, "    errata:");
        for (k, (fig, key, val)) in c.table_errata.iter().enumerate() {
            let id = (o.next_id)();
            let figure = if fig.is_empty() { String::new() } else { format!("figure: {fig}, ") };
            let note =
                o.table_notes.get(k).cloned().unwrap_or_else(|| {
                    "The register table disagrees with the printed frames; the frames are used.".into()
                });
            let _ =
                writeln!(y, "      - {{id: {id}, {manual_key}{figure}table: {{{key}: {val}}}, note: {}}}", q(&note));
        }
    }
    if !c.examples.is_empty() {
        let _ = writeln!(y, "    examples:");
    }
    for e in &c.examples {
        let _ = writeln!(y, "      - figures: {}", fig_list(&e.figures));
        if let Some(m) = o.manual {
            let _ = writeln!(y, "        manual: {}", q(m));
        }
        let mut erratum = None;
        for (key, f) in [("request", &e.request), ("response", &e.response)] {
            let Some(f) = f else { continue };
            let _ = writeln!(y, "        {key}: {}", q(&f.text()));
            if f.crc.is_none() {
                let _ = writeln!(y, "        {key}_crc: missing");
            }
            if f.crc_wrong() {
                erratum = Some((key, f));
            }
        }
        if !e.values.is_empty() || c.fields.iter().all(|f| f.name.is_none()) {
            let vals: Vec<String> = e
                .values
                .iter()
                .filter_map(|(off, v)| {
                    c.fields.iter().find(|f| f.offset == *off).and_then(|f| f.name.clone()).map(|n| format!("{n}: {v}"))
                })
                .collect();
            let _ = writeln!(y, "        values: {{{}}}", vals.join(", "));
        }
        if let Some((key, f)) = erratum {
            let id = (o.next_id)();
            let fig = e
                .figures
                .get(if key == "request" { 0 } else { e.figures.len().saturating_sub(1) })
                .cloned()
                .unwrap_or_default();
            let correct = f.computed_crc().unwrap_or([0, 0]);
            let printed = f.crc.unwrap_or([0, 0]);
            let _ = writeln!(y, "        erratum:");
            let _ = writeln!(y, "          id: {id}");
            let _ = writeln!(
                y,
                "          figure: {}",
                if fig.chars().all(|c| c.is_ascii_digit()) { fig } else { q(&fig) }
            );
            let _ = writeln!(
                y,
                "          printed: {}",
                q(&format!(
                    "The printed CRC {:02X} {:02X} is wrong; the frame's CRC is {:02X} {:02X}.",
                    printed[0], printed[1], correct[0], correct[1]
                ))
            );
            let _ = writeln!(y, "          corrected_{key}: {}", q(&f.spec_text(Some(correct))));
            let _ = writeln!(y, "          printed_decodes: false");
        }
    }
}

fn render_field(y: &mut String, f: &DField) {
    match f.ty {
        "reserved" => {
            let _ = writeln!(y, "      - {{type: reserved, size: {}}}", f.size);
        }
        "ascii" => {
            let _ = writeln!(
                y,
                "      - {{name: {}, type: ascii, size: {}, doc: Text.}}",
                f.name.as_deref().unwrap_or("text"),
                f.size
            );
        }
        "enum" | "flags" => {
            let _ = writeln!(y, "      - name: {}", f.name.as_deref().unwrap_or("code"));
            let _ = writeln!(y, "        type: {}", f.ty);
            let _ = writeln!(y, "        size: {}", f.size);
            let _ = writeln!(y, "        doc: Code (see the section's table).");
            let _ = writeln!(y, "        {}:", if f.ty == "enum" { "variants" } else { "flags" });
            for (v, label) in &f.codes {
                let key = if f.ty == "enum" { "value" } else { "mask" };
                let _ = writeln!(
                    y,
                    "          - {{name: {}, {key}: 0x{v:02X}, doc: {}}}",
                    variant_name(label, *v),
                    q(label)
                );
            }
        }
        ty => {
            let order = f.order.map(|o| format!(", byte_order: {o}")).unwrap_or_default();
            let _ = writeln!(
                y,
                "      - {{name: {}, type: {ty}{order}, doc: Value.}}",
                f.name.as_deref().unwrap_or("value")
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Accuracy against the reviewed specs

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

fn printed_key(f: &yosemitech_spec::PrintedFrame) -> DraftFrame {
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

fn accuracy_task(write: bool) -> anyhow::Result<ExitCode> {
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

mod edit;
mod identify;
mod into;
mod layout;
mod merge;
mod procedure;
mod review;
#[cfg(test)]
mod tests;

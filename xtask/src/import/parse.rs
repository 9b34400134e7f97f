//! A manual's text to a draft: the command chapter, its sections, their fields and examples.

use std::collections::BTreeMap;
use std::path::Path;

use super::draft::{DCommand, DExample, DField, Draft, DraftFrame};
use super::frames::{Built, build_frame, find_frames};
use super::header::parse_header;
use super::render::render;
use super::tables::{code_table, register_table};
use super::tokens::{Item, clean, snake};
use super::{BadInput, MAX_INPUT, bad, file_name, layout, valid_name};

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

pub(super) fn dfield(f: &yosemitech_spec::Field) -> DField {
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

pub(super) fn variant_name(label: &str, value: u16) -> String {
    let n = snake(label);
    if n.is_empty() || !valid_name(&n) { format!("code_{value:02x}") } else { n }
}

//! Field layouts printed apart from the frames: a byte table ("Byte 3~6 7~10
//! ..." over "Value DO Tur ..." or "Meaning Second Minute ...") naming the
//! bytes of a frame's data, and the evidence that types its cells.

use super::{DField, bare_hex, first_word_lower, hex_token, segments, snake};

/// Decimal numbers printed in the section's prose ("12.31V", "7.90 mg/L"),
/// with their precision (digits after the point). Section numbers
/// ("2.2.9") are not decimals.
fn prose_decimals(sec: &[String]) -> Vec<(f64, usize)> {
    let mut out = Vec::new();
    for l in sec {
        let chars: Vec<char> = l.chars().collect();
        let mut i = 0;
        while i < chars.len() {
            if !chars[i].is_ascii_digit() || i > 0 && (chars[i - 1].is_ascii_digit() || chars[i - 1] == '.') {
                i += 1;
                continue;
            }
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            let tok: String = chars[start..i].iter().collect::<String>().trim_end_matches('.').to_string();
            let dots = tok.matches('.').count();
            if dots == 1
                && let Ok(v) = tok.parse::<f64>()
            {
                let prec = tok.len() - tok.find('.').unwrap_or(tok.len()) - 1;
                out.push((v, prec));
            }
        }
    }
    out
}

/// Byte rows printed in the section ("Value CD CC FC 40", "Value 0xC3 ...").
fn byte_rows(sec: &[String]) -> Vec<Vec<u8>> {
    let mut rows = Vec::new();
    for l in sec {
        let w = first_word_lower(l);
        if w != "value" && w != "meaning" {
            continue;
        }
        let cells: Option<Vec<u8>> = l
            .split_whitespace()
            .skip(1)
            .map(|t| hex_token(t).filter(|v| v.len() == 1).map(|v| v[0]).or_else(|| bare_hex(t)))
            .collect();
        if let Some(c) = cells
            && c.len() >= 4
        {
            rows.push(c);
        }
    }
    rows
}

/// Four bytes read, as a little-endian float (`dcba`), as a non-zero
/// decimal the section prints (to its printed precision).
pub(super) fn reads_as_printed_decimal(sec: &[String], w: &[u8]) -> bool {
    let [a, b, c, d] = *w else { return false };
    let v = f64::from(f32::from_le_bytes([a, b, c, d]));
    prose_decimals(sec).iter().any(|(x, p)| *x != 0.0 && (v - x).abs() <= 0.5 * 10f64.powi(-(*p as i32)))
}

/// Some 4-byte run printed in the section reads as a decimal the section
/// prints: the manual's own example of a `dcba` float.
pub(super) fn dcba_float_evidence(sec: &[String], extra: &[u8]) -> bool {
    let mut rows = byte_rows(sec);
    rows.push(extra.to_vec());
    rows.iter().any(|r| r.windows(4).any(|w| reads_as_printed_decimal(sec, w)))
}

/// The byte numbers of a "Byte" row and the bare-number lines wrapped under it.
fn byte_numbers(lines: &[&String]) -> Vec<usize> {
    let mut nums: Vec<usize> = lines
        .iter()
        .flat_map(|l| l.split(|c: char| !c.is_ascii_digit()).filter(|t| !t.is_empty()).filter_map(|t| t.parse().ok()))
        .collect();
    nums.sort_unstable();
    nums.dedup();
    nums
}

/// Byte ranges from sorted byte numbers for `n` cells: one number a cell
/// (single bytes) or two (first~last), contiguous.
fn ranges(nums: &[usize], n: usize) -> Option<Vec<(usize, usize)>> {
    let r: Vec<(usize, usize)> = if nums.len() == n {
        nums.iter().map(|b| (*b, *b)).collect()
    } else if nums.len() == 2 * n {
        nums.chunks(2).map(|c| (c[0], c[1])).collect()
    } else {
        return None;
    };
    r.windows(2).all(|w| w[1].0 == w[0].1 + 1).then_some(r)
}

/// A cell of a byte table: its bytes (first, last) and its label.
pub(super) struct Cell {
    pub first: usize,
    pub last: usize,
    pub label: String,
}

/// The byte tables of a section that name bytes rather than print them: a
/// "Byte" row (wrapped numbers included) over a "Value"/"Meaning" row whose
/// cells are mostly words. Frame tables (under a "Definition" row) and
/// byte images (all hex) are not layouts.
pub(super) fn byte_tables(sec: &[String]) -> Vec<Vec<Cell>> {
    let mut out = Vec::new();
    for (i, l) in sec.iter().enumerate() {
        if first_word_lower(l) != "byte" {
            continue;
        }
        let prev = sec[..i].iter().rev().find(|p| !p.trim().is_empty());
        if prev.is_some_and(|p| first_word_lower(p) == "definition") {
            continue;
        }
        let mut j = i + 1;
        let mut rows = vec![l];
        while let Some(n) = sec.get(j) {
            let t = n.trim();
            if !t.is_empty() && t.chars().all(|c| c.is_ascii_digit() || c.is_whitespace() || c == '~') {
                rows.push(n);
                j += 1;
            } else {
                break;
            }
        }
        let Some(label_row) = sec.get(j) else { continue };
        let w = first_word_lower(label_row);
        if w != "value" && w != "meaning" {
            continue;
        }
        let cells: Vec<String> = segments(label_row).into_iter().skip(1).map(|(_, s)| s).collect();
        let words = cells.iter().filter(|c| hex_token(c).is_none() && bare_hex(c).is_none()).count();
        if cells.len() < 2 || words * 2 < cells.len() {
            continue;
        }
        let first_row = l.trim_start()[4..].to_string();
        let mut nums_rows: Vec<&String> = rows[1..].to_vec();
        nums_rows.insert(0, &first_row);
        let Some(r) = ranges(&byte_numbers(&nums_rows), cells.len()) else { continue };
        out.push(r.into_iter().zip(cells).map(|((first, last), label)| Cell { first, last, label }).collect());
    }
    out
}

/// Cells printed as `NAME(a~b)` anywhere in the section (a register-image
/// figure naming the frame bytes of each value), in byte order.
pub(super) fn named_ranges(sec: &[String]) -> Vec<Cell> {
    let mut out: Vec<Cell> = Vec::new();
    for l in sec {
        for tok in l.split_whitespace() {
            let Some((name, rest)) = tok.split_once('(') else { continue };
            let Some(inner) = rest.strip_suffix(')') else { continue };
            let Some((a, b)) = inner.split_once('~') else { continue };
            let (Ok(first), Ok(last)) = (a.trim().parse::<usize>(), b.trim().parse::<usize>()) else { continue };
            if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') || last < first {
                continue;
            }
            out.push(Cell { first, last, label: name.to_string() });
        }
    }
    out.sort_by_key(|c| c.first);
    if out.windows(2).all(|w| w[1].first == w[0].last + 1) { out } else { Vec::new() }
}

/// The section says its values are little-endian floating-point numbers.
fn says_le_float(sec: &[String]) -> bool {
    let t = sec.join(" ").to_ascii_lowercase();
    (t.contains("floating point") || t.contains("floating-point"))
        && (t.contains("little-endian") || t.contains("little endian"))
}

/// Fields for `len` bytes of data starting at frame byte `data_start`, from a
/// byte table of the section covering exactly those bytes. A "00" cell is
/// reserved; a one-byte cell is `bcd` when the section says BCD; a four-byte
/// cell is an `f32` `dcba` when the section's own example reads so. Anything
/// else: no fields.
pub(super) fn fields_from_tables(sec: &[String], data_start: usize, len: usize, extra: &[u8]) -> Vec<DField> {
    let says_bcd = sec.iter().any(|l| l.split(|c: char| !c.is_ascii_alphanumeric()).any(|w| w == "BCD"));
    let floats = dcba_float_evidence(sec, extra) || says_le_float(sec);
    let mut tables = byte_tables(sec);
    tables.push(named_ranges(sec));
    for table in tables {
        if table.first().map(|c| c.first) != Some(data_start)
            || table.last().map(|c| c.last + 1) != Some(data_start + len)
        {
            continue;
        }
        let mut fields = Vec::new();
        for c in &table {
            let size = c.last - c.first + 1;
            let offset = c.first - data_start;
            let zero = bare_hex(&c.label) == Some(0) || hex_token(&c.label).is_some_and(|v| v.iter().all(|b| *b == 0));
            let name = snake(&c.label);
            let (ty, order) = if zero {
                ("reserved", None)
            } else if size == 1 && says_bcd && !name.is_empty() {
                ("bcd", None)
            } else if size == 4 && floats && !name.is_empty() {
                ("f32", Some("dcba"))
            } else {
                fields.clear();
                break;
            };
            fields.push(DField {
                name: (ty != "reserved").then_some(name),
                ty,
                order,
                offset,
                size,
                codes: Vec::new(),
            });
        }
        if !fields.is_empty() {
            return fields;
        }
    }
    Vec::new()
}

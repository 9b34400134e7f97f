//! Frame tables: the Byte and Value rows of a section as frames and their data.

use super::draft::DraftFrame;
use super::tokens::{Item, byte_indices, first_word_lower, hex_token, value_items};

pub(super) struct RawFrame {
    pub(super) line: usize,
    pub(super) label: Option<String>,
    pub(super) caption: String,
    pub(super) items: Vec<Item>,
    alt: Option<Vec<Item>>,
    /// The Byte row's cells as byte ranges (`7-30` is one cell).
    pub(super) labels: Vec<(usize, usize)>,
}

/// A "Byte 3 4 5 ..." / "Value 0x.. .." image outside a frame: (index, byte).
pub(super) type Image = Vec<(usize, u8)>;

pub(super) fn find_frames(sec: &[String]) -> (Vec<RawFrame>, Vec<Image>) {
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
pub(super) struct Built {
    pub(super) frame: DraftFrame,
    pub(super) function: u8,
    pub(super) is_request: bool,
    pub(super) data: Vec<(usize, Item)>,
    pub(super) todo: Option<String>,
}

pub(super) fn build_frame(raw: &RawFrame, is_request: bool, images: &[Image]) -> Result<Built, String> {
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
